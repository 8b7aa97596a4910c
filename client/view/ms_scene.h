/* Scene files: a room holding several catalogue models, their materials, the
 * lights, haze and the effects the scene allows (docs/SCENES.md has the format
 * with an example). JSON read with jansson and validated whole: any error is one
 * line naming the file and the element, e.g.
 *
 *     scene gallery.json: models[2].material.shininess: 0 out of range [1, 1000]
 *
 * Units: the scene is in metres, y up. A model is scaled uniformly so that its
 * bounds (ms_viewer_model_bounds) are `height` metres tall along the model's own
 * up axis, turned by `yaw` degrees about y, and stands with the centre of the
 * bottom of its bounds at `position`.
 *
 * Effects. The scene lists the effects it allows; ms_scene_effects says which of
 * them it calls for (a glossy material for specular, a two-sided material for
 * two-sided lighting, haze with a density for haze, a surface declaring relief
 * for displacement, a model small enough on screen for impostors). Only those
 * are compiled into the shader program (ms_render_program_source).
 *
 * Ownership: an ms_scene owns its arrays and strings (ms_scene_free, safe on a
 * zeroed scene). Thread-safety: a loaded scene is read-only; parsing touches no
 * shared state.
 */
#ifndef MS_SCENE_H
#define MS_SCENE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_catalog.h"
#include "ms_error.h"
#include "ms_render.h"
#include "ms_viewer_model.h"

#define MS_SCENE_VERSION 1
#define MS_SCENE_MAX_BYTES (1u << 20)
#define MS_SCENE_MAX_MODELS 64
#define MS_SCENE_MAX_POINT_LIGHTS 4
#define MS_SCENE_MAX_PLINTHS 64

typedef enum ms_material_kind {
    MS_MATERIAL_DIFFUSE = 0,
    MS_MATERIAL_GLOSSY = 1
} ms_material_kind;

typedef struct ms_scene_material {
    ms_material_kind kind;
    float albedo[3];     /* linear RGB in [0, 1]; default 0.72 0.69 0.64 */
    float specular;      /* glossy: strength in [0, 1] (default 0.18); diffuse: 0 */
    float shininess;     /* glossy: Blinn-Phong exponent in [1, 1000] (default 40) */
    bool two_sided;      /* open scans: a back face is lit as its other side */
} ms_scene_material;

/* Procedural relief (seed 004): height atoms scattered over a surface. */
typedef struct ms_scene_displacement {
    bool on;
    float amplitude;     /* metres, in (0, 0.5] */
    float atom_radius;   /* metres, in [0.005, 2] */
    float density;       /* atoms per square metre, in (0, 10000] */
    uint32_t seed;
} ms_scene_displacement;

typedef struct ms_scene_surface {
    ms_scene_material material;
    ms_scene_displacement displacement;
} ms_scene_surface;

typedef struct ms_scene_model {
    char model[MS_MODEL_NAME_MAX + 1]; /* catalogue name */
    double position[3];  /* metres: the centre of the bottom of its bounds */
    double yaw_degrees;  /* about y, in [-360, 360] */
    double height;       /* metres, in (0, 100] */
    int up_axis;         /* the model's own up axis: 0 x, 1 y, 2 z (default 1) */
    ms_scene_material material;
} ms_scene_model;

typedef enum ms_light_kind {
    MS_LIGHT_HEAD = 0,        /* at the camera, shining where it looks */
    MS_LIGHT_DIRECTIONAL = 1, /* from direction (unit, towards the light) */
    MS_LIGHT_POINT = 2        /* at position, falling off with 1 / (1 + (d / range)^2) */
} ms_light_kind;

typedef struct ms_scene_light {
    ms_light_kind kind;
    float colour[3];     /* linear RGB in [0, 1], default white */
    float intensity;     /* in [0, 10], default 1 */
    double vector[3];    /* directional: unit direction towards the light; point: position */
    double range;        /* point: metres, in (0, 1000], default 5 */
} ms_scene_light;

typedef struct ms_scene_plinth {
    double position[2];  /* x, z of its centre on the floor */
    double size[3];      /* width (x), height (y), depth (z), metres, each in (0, 10] */
    ms_scene_material material;
} ms_scene_plinth;

typedef struct ms_scene_room {
    bool on;
    double size[3];      /* width (x), height (y), depth (z), metres, each in (0, 1000];
                            the floor spans x in [-w/2, w/2], z in [-d/2, d/2] at y = 0 */
    ms_scene_surface floor, walls;
    ms_scene_plinth *plinths;
    size_t plinth_count;
} ms_scene_room;

typedef struct ms_scene_haze {
    float density;       /* per metre, in [0, 10]: visibility exp(-density * distance) */
    float colour[3];     /* linear RGB in [0, 1] */
} ms_scene_haze;

typedef struct ms_scene {
    char *name;          /* owned; "" when the file gives none */
    char *camera_path;   /* owned: the path file resolved against the scene's folder, or NULL */
    ms_scene_model *models;
    size_t model_count;  /* 1..MS_SCENE_MAX_MODELS */
    ms_scene_light *lights;
    size_t light_count;  /* default when the file lists none: one head light */
    ms_scene_room room;
    ms_scene_haze haze;
    unsigned effects_allowed;  /* MS_EFFECT_* bits; default all */
    double impostor_threshold_px; /* in [1, 4096], default 100 */
    double impostor_angle_degrees; /* in (0, 90], default 5 */
} ms_scene;

/* Parses text (size bytes, not NUL-terminated). label names the scene in errors
 * ("scene LABEL: ..."); base_dir resolves a relative camera_path (NULL: as
 * given). MS_ERR_FORMAT for bad JSON, an unknown key, a wrong type or a missing
 * field; MS_ERR_RANGE for a value out of range; MS_ERR_NOMEM. */
ms_status ms_scene_parse(const char *text, size_t size, const char *label, const char *base_dir,
                         ms_scene *scene, ms_error *err);

/* Reads and parses a scene file (at most MS_SCENE_MAX_BYTES); MS_ERR_IO when it
 * cannot be read. Errors name the file as given. */
ms_status ms_scene_load(const char *path, ms_scene *scene, ms_error *err);
void ms_scene_free(ms_scene *scene);

/* MS_ERR_RANGE naming the first model of the scene that the list does not hold:
 * "scene LABEL: models[1].model: \"armadillo\" is not in the catalogue". */
ms_status ms_scene_check_models(const ms_scene *scene, const char *label,
                                const ms_viewer_model_list *list, ms_error *err);

/* The effects the scene calls for (MS_EFFECT_* bits), within those it allows:
 *   DETAIL_NORMALS  allowed (the models' APO normals, with self-shadowing
 *                   from the triangle's own normal)
 *   SPECULAR        some material is glossy
 *   TWO_SIDED       some material is two-sided
 *   HAZE            haze density > 0
 *   DISPLACEMENT    the floor or the walls declare displacement
 *   IMPOSTORS       some model, seen from across the room (the room's diagonal;
 *                   20 m without a room) at the reference view (45 degrees over
 *                   720 pixels), is shorter than impostor_threshold_px */
unsigned ms_scene_effects(const ms_scene *scene);

/* The model's placement: column-major 4x4 from the model's coordinates to the
 * scene's, given the model's bounds (lo, hi as ms_viewer_model_bounds). */
void ms_scene_model_transform(const ms_scene_model *model, const double lo[3], const double hi[3],
                              double out[16]);

/* The sphere about placed bounds: centre = placement of the bounds' centre,
 * radius = half their diagonal times the placement's (uniform) scale. */
void ms_scene_placed_sphere(const double placement[16], const double lo[3], const double hi[3],
                            double centre[3], double *radius);

#endif
