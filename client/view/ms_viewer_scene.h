/* A scene on screen (docs/SCENES.md): every model of an ms_scene streamed by its
 * own stream (ms_viewer_stream.h: a client core and a renderer), placed in the
 * room, plus the room's generated geometry (floor, walls, plinths: boxes as
 * one-cell models, flat shaded, the floor and walls in 0.5 m tiles), drawn
 * into one picture with shader programs composed of the effects each piece
 * calls for.
 *
 * Streaming. One core per model, all fed the same scene camera expressed in
 * the model's own coordinates (the placement inverted: a uniformly scaled
 * model seen from the scaled camera projects exactly as placed), so every
 * model refines by the same screen-error rule and tolerance, near pieces finer
 * than far ones. One memory budget: the scene's (settings.stream.memory_mb),
 * one ms_core_budget shared by every model's core (ms_client_core.h): one
 * tolerance factor for all, and over the budget the least useful cells of all
 * the models go first, so near pieces refine first and far ones stay coarse.
 * Uploads: each frame's byte budget goes to the models nearest the camera
 * first, so near pieces reach the GPU first. From a server the cores share
 * one connection (ms_core_link, ms_client_core.h: one OPEN_MODEL handle per
 * model, their requests merged by priority under one window and the scene's
 * bandwidth, so near pieces' bytes go first); with
 * settings.connection_per_model each core holds its own, the bandwidth split
 * evenly over them (for comparisons).
 *
 * Effects: ms_scene_effects(scene), minus settings.effects_off, or every
 * effect with settings.force_all (what "only the effects the scene calls
 * for" saves, for make bench); each piece's program holds only its own
 * (specular for glossy materials, two-sided for open ones, displacement for
 * the floor and walls that declare a relief, detail normals and impostors for
 * models, haze everywhere), or all of them with force_all. A model smaller on
 * screen than the scene's impostor threshold is drawn as an impostor
 * (ms_render_impostor.h), captured again past the scene's angle or when its
 * cut changes, with a 4-frame dissolve on the switch.
 *
 * Requires the GL context current on the calling thread for every function
 * but _effects, _settled and the pieces' (_piece_count, _piece_info), which
 * only read what the last step and draw left. Ownership: the scene is borrowed (it must outlive
 * the object); everything else is owned. Errors: ms_status with one line (a
 * model not in the catalogue names the scene element; a stream's errors as
 * ms_viewer_stream.h). Thread-safety: the drawing thread only.
 */
#ifndef MS_VIEWER_SCENE_H
#define MS_VIEWER_SCENE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_render.h"
#include "ms_scene.h"
#include "ms_viewer_model.h"
#include "ms_viewer_stream.h"

typedef struct ms_viewer_scene ms_viewer_scene;

typedef struct ms_viewer_scene_settings {
    ms_viewer_stream_settings stream; /* memory_mb: the scene's, one budget shared by the
                                         models; bandwidth: the scene's (the link's, or
                                         split evenly over connections per model) */
    unsigned effects_off;             /* MS_EFFECT_* not compiled in even if called for */
    bool force_all;                   /* compile every effect (then effects_off still applies) */
    bool connection_per_model;        /* from a server: one connection per model, each with
                                         bandwidth / models (default: one link for all) */
} ms_viewer_scene_settings;

/* Checks the scene's models against the source's catalogue (label names the
 * scene in errors), opens each model's index and stream, and builds the room. */
ms_status ms_viewer_scene_open(const ms_viewer_source *source, const ms_scene *scene, const char *label,
                               const ms_viewer_scene_settings *settings, ms_viewer_scene **out, ms_error *err);
void ms_viewer_scene_close(ms_viewer_scene *vs);

/* Steps every stream with the scene camera (in metres): new frames to the
 * renderers, budget_bytes of upload shared nearest model first. step sums the
 * streams': new_frame if any, generation the largest, upload bytes and cells
 * summed, triangles summed, settled when all are. */
ms_status ms_viewer_scene_step(ms_viewer_scene *vs, const ms_camera *camera, uint64_t budget_bytes,
                               ms_viewer_step *step, ms_error *err);

/* Clears to the background (the haze's colour when the scene has haze) and
 * draws the room and the models. base gives the shading mode, APO, wireframe
 * and smooth; the scene gives the effects, materials, lights, haze and
 * placements. stats: cells and triangles summed, effects compiled, and the
 * effects that ran in any of the draws. */
ms_status ms_viewer_scene_draw(ms_viewer_scene *vs, const ms_camera *camera, const ms_render_options *base,
                               ms_render_draw_stats *stats, ms_error *err);

/* The streams' figures: bytes, requests, cells and memory summed, achieved
 * error and tolerance the largest, view_complete when all are, the first error. */
void ms_viewer_scene_stats(ms_viewer_scene *vs, ms_core_stats *stats);

/* The GL storage of the scene's renderers (each model's and the room's parts')
 * and impostors, bytes (ms_render.h, "GL memory"): *bytes held now; *peak the
 * sum of each renderer's own peak and the impostors' bytes (an upper bound of
 * the scene's peak: the pieces need not peak together). */
void ms_viewer_scene_gl_memory(ms_viewer_scene *vs, uint64_t *bytes, uint64_t *peak);

/* TCP connections the scene's models opened to the server so far: the link's
 * (1 plus its reconnections), or with connection_per_model one per model plus
 * each one's reconnection attempts; 0 from a local directory. */
uint64_t ms_viewer_scene_connections(ms_viewer_scene *vs);

bool ms_viewer_scene_settled(const ms_viewer_scene *vs);

/* The effects compiled into the scene's programs. */
unsigned ms_viewer_scene_effects(const ms_viewer_scene *vs);

/* The room's box (or the models' when the scene has no room), metres: for
 * the camera's near and far distances. */
void ms_viewer_scene_bounds(const ms_viewer_scene *vs, double lo[3], double hi[3]);

/* A piece of the scene: one of its models (the room's floor, walls and
 * plinths are not pieces), for picking and the HUD. */
typedef struct ms_viewer_scene_piece {
    const char *model;                 /* catalogue name (the scene's string) */
    const ms_scene_material *material; /* the scene's */
    double placement[16];              /* model to scene, column-major (ms_scene_model_transform) */
    double lo[3], hi[3];               /* the model's bounds it was placed by, its own units */
    float impostor;                    /* at the last draw: 0 geometry .. 1 impostor (dissolving between) */
    uint64_t triangles;                /* drawn as geometry at the last draw */
    uint32_t cells;
    uint64_t bytes;                    /* received, geometry and APO */
    double achieved_error_px;          /* its core's, screen pixels */
} ms_viewer_scene_piece;

/* The number of pieces (the scene's models, in the scene's order). */
size_t ms_viewer_scene_piece_count(const ms_viewer_scene *vs);
/* Piece i (zeroed for i >= count). */
void ms_viewer_scene_piece_info(ms_viewer_scene *vs, size_t i, ms_viewer_scene_piece *piece);

#endif
