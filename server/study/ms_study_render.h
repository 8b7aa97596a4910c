/* The CPU reference renderer: Embree ray casting of a study scene at an
 * ms_camera, giving a normal buffer, a depth buffer, the triangle seen and a
 * shaded image. It renders the full-resolution input model and any decoded cut
 * (an ms_view_mesh), optionally with APO normals (ms_study_apo.h), so that images
 * of what the client shows can be made without a GPU.
 *
 * Projection: the viewer's (client/view/ms_render.h): OpenGL perspective from
 * fovy, aspect width / height, near and far. Pixel (i, j), column i, row j, top
 * row first, is the ray from the camera position through the pixel centre:
 *     x = (2 (i + 1/2) / W - 1) tan(fovy / 2) W / H
 *     y = (1 - 2 (j + 1/2) / H) tan(fovy / 2)
 *     direction = forward + x right + y up      (not normalised)
 * so the ray parameter t is the eye depth (distance along the view axis); hits
 * are kept for t in [near, far], as OpenGL's near and far planes clip.
 *
 * Buffers, per pixel (background: no hit):
 *   depth     eye depth of the nearest hit; +infinity for background;
 *   triangle  the scene triangle hit; MS_STUDY_NO_HIT for background;
 *   normal    the shading normal N, unit, world axes: the hit triangle's
 *             geometric normal Ng turned to face the camera (two-sided); with
 *             `smooth`, the barycentric interpolation of the area-weighted vertex
 *             normals (the rule the APO builder samples M with), normalised,
 *             where it lies on Ng's side (from a fold, against Ng, Ng stands in,
 *             as in the client's shader); with APO, the APO normal of the
 *             drawing cell at the hit (ms_study_apo_normal: by default the
 *             client's filtered lookup, limited by the pixel's footprint),
 *             turned to Ng's side (where the cell has a chunk); (0, 0, 0) for
 *             background;
 *   rgb       the shaded colour, 8-bit sRGB.
 *
 * Shading (head light at the camera, as the viewer's MS_SHADING_LIT): with L = V
 * the unit vector from the hit to the camera, H = L, in linear RGB
 *     c = ambient + max(0, L.N) (diffuse max(0, N.L) + specular max(0, N.H)^shininess)
 * (the factor max(0, L.N) is the viewer's self-shadowing term, from the normal
 * it shades with: Ng when flat, the vertex or APO normal otherwise), grey albedo,
 * constants MS_STUDY_AMBIENT, _DIFFUSE, _SPECULAR, _SHININESS; background
 * MS_STUDY_BACKGROUND. Output is sRGB-encoded (the exact sRGB transfer function)
 * and rounded to nearest.
 *
 * Colour (options.colours: r g b a per scene vertex, 8-bit sRGB as scanned):
 * the hit's colour C is the barycentric interpolation of its triangle's
 * vertex colours (as sRGB values, as the viewer's rasteriser interpolates
 * them), A = C made linear is the albedo, per channel
 *     c = A (ambient + max(0, L.N) diffuse max(0, N.L)) + max(0, L.N) specular max(0, N.H)^shininess
 * (the same law as the grey one, which is A = 1, and as the viewer's: the
 * albedo times the ambient and diffuse terms, a white highlight; the normals
 * only shade). options.albedo gives the unlit picture (the viewer's
 * MS_SHADING_ALBEDO): rgb = C rounded to nearest, or MS_STUDY_ALBEDO
 * sRGB-encoded without colours; the background as the lit picture's.
 *
 * Sections (options.sections, docs/RENDERER.md "Sections"): planes a b c d
 * cutting away the side a x + b y + c z + d > 0 (world coordinates); each
 * ray's interval [near, far] is narrowed to the kept side of every plane (the
 * kept region is convex: one interval), and a hit on a back face (the ray
 * along the triangle's stored normal: the model's inside, seen through the
 * cut) is drawn flat in the section colour MS_SECTION_R G B (lit and albedo
 * pictures alike; its depth, triangle and normal as any hit's).
 *
 * Determinism: rows are rendered in fixed blocks on the project's thread pool
 * (ms_parallel.h), each pixel from its own ray: the buffers do not depend on the
 * thread count.
 *
 * Ownership: the caller owns the image (ms_study_image_free). Thread-safety: the
 * scene and APO set are only read; distinct images may be rendered at once.
 */
#ifndef MS_STUDY_RENDER_H
#define MS_STUDY_RENDER_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_camera.h"
#include "ms_camera_path.h"
#include "ms_error.h"
#include "ms_study_apo.h"
#include "ms_study_scene.h"

#define MS_STUDY_NO_HIT UINT32_MAX
#define MS_STUDY_AMBIENT 0.05
#define MS_STUDY_DIFFUSE 0.75
#define MS_STUDY_SPECULAR 0.20
#define MS_STUDY_SHININESS 32.0
#define MS_STUDY_BACKGROUND 0.02 /* linear grey */
/* The albedo picture of a model without colour: the viewer's default
 * material (ms_render_options_default), linear. */
#define MS_STUDY_ALBEDO_R 0.72
#define MS_STUDY_ALBEDO_G 0.69
#define MS_STUDY_ALBEDO_B 0.64

typedef struct ms_study_image {
    uint32_t width, height;
    float *depth;       /* width * height */
    uint32_t *triangle; /* width * height */
    float *normal;      /* 3 * width * height */
    uint8_t *rgb;       /* 3 * width * height, top row first */
} ms_study_image;

/* Allocates zeroed buffers (background: call ms_study_image_clear). *image must be
 * zeroed or freed. width, height in [1, 65535]. MS_ERR_RANGE, MS_ERR_NOMEM. */
ms_status ms_study_image_alloc(ms_study_image *image, uint32_t width, uint32_t height, ms_error *err);
/* Sets every pixel to background. */
void ms_study_image_clear(ms_study_image *image);
void ms_study_image_free(ms_study_image *image);
/* True for a pixel (index j * width + i) with a hit. */
static inline int ms_study_image_covered(const ms_study_image *image, size_t pixel)
{
    return image->triangle[pixel] != MS_STUDY_NO_HIT;
}

typedef struct ms_study_render_options {
    unsigned threads;               /* 0: every core */
    const ms_study_apo *apo;        /* NULL: geometric normals */
    const uint32_t *triangle_cell;  /* with apo: the drawing cell of every scene triangle */
    bool smooth;                    /* interpolated vertex normals instead of flat ones */
    const uint8_t *colours;         /* NULL, or r g b a per scene vertex: the albedo ("Colour") */
    bool albedo;                    /* the unlit albedo picture instead of the lit one */
    unsigned section_count;         /* at most MS_SECTIONS_MAX ("Sections") */
    double sections[MS_SECTIONS_MAX][4];
} ms_study_render_options;

/* Renders scene at camera into *image, (re)allocated to the camera's viewport
 * (width and height must be whole numbers in [1, 65535]: MS_ERR_RANGE). options
 * may be NULL (all cores, no APO). MS_ERR_ARG for apo without triangle_cell,
 * more than MS_SECTIONS_MAX sections or one with a zero normal or a number
 * not finite; MS_ERR_NOMEM. */
ms_status ms_study_render(const ms_study_scene *scene, const ms_camera *camera,
                          const ms_study_render_options *options, ms_study_image *image, ms_error *err);

/* Writes the shaded image as PNG (ms_png.h). */
ms_status ms_study_image_write_png(const ms_study_image *image, const char *path, ms_error *err);

/* The normal buffer as an RGB image, rgb = (N + 1) / 2 (linear, as the viewer's
 * MS_SHADING_NORMALS), background black; written as PNG. */
ms_status ms_study_image_write_normals_png(const ms_study_image *image, const char *path, ms_error *err);

/* The camera of keyframe `key` of a path for a width x height viewport. A near or
 * far distance <= 0 is chosen from the box [lo, hi] the scene lies in: far = 1.01
 * times the distance to the box's farthest corner, near = far / 10^5 (the
 * renderer casts rays, so a deep range costs nothing). MS_ERR_RANGE for a key
 * out of range; the camera's errors. */
ms_status ms_study_key_camera(const ms_camera_path *path, size_t key, double width, double height,
                              double near_distance, double far_distance, const double lo[3], const double hi[3],
                              ms_camera *camera, ms_error *err);

/* sRGB encoding of a linear value in [0, 1] (clamped), rounded to 8 bits. */
uint8_t ms_study_srgb8(double linear);
/* The linear value of an sRGB value in [0, 1] (the exact transfer function). */
double ms_study_srgb_decode(double srgb);

#endif
