/* Impostors for far objects (seed 002, "images with parallax"; docs/RENDERER.md,
 * "Impostors"): an object small on screen is drawn as an image with depth of
 * its current cut instead of its triangles.
 *
 * Capture: the renderer's model (through ms_render_draw, with the caller's
 * options: placement, material, lights; haze left out) seen along the direction from the
 * camera to the object's bounding sphere (centre, radius; world units) by a
 * near-orthographic camera (50 radii away, the sphere filling a size x size
 * image), colour and depth kept in textures. Draw: a camera-facing quad over
 * the sphere whose fragments march their view ray through the image's height
 * field (48 steps, 6 halvings) to the captured surface, taking its colour and
 * writing its depth: exact from the capture's direction, parallax-corrected
 * as the view turns; the caller captures again once the view has turned by
 * more than a set angle (ms_impostor_angle). coverage < 1 draws only the
 * pixels of a 4x4 Bayer pattern below it, and ms_render_options.dissolve
 * (MS_EFFECT_IMPOSTORS) makes the geometry draw exactly the others: a
 * cross-fade without sorting.
 *
 * Requires a current GL 4.1 context on the calling thread (but for
 * ms_impostor_angle). Errors: one line, MS_ERR_UNSUPPORTED (shader or
 * framebuffer), MS_ERR_ARG, MS_ERR_NOMEM. Ownership: _new / _free. Thread-safety:
 * the context's thread.
 */
#ifndef MS_RENDER_IMPOSTOR_H
#define MS_RENDER_IMPOSTOR_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_render.h"

typedef struct ms_impostor ms_impostor;

/* An impostor of size x size pixels (16..2048). */
ms_status ms_impostor_new(int size, ms_impostor **out, ms_error *err);
void ms_impostor_free(ms_impostor *imp);

/* Bytes of GL storage the impostor holds (ms_render.h, "GL memory"): its colour
 * texture (RGBA8, 4 bytes a pixel), depth texture (32-bit float, 4 bytes a
 * pixel) and quad (32 bytes): 8 size^2 + 32. 0 for NULL. No GL needed. */
uint64_t ms_impostor_gl_bytes(const ms_impostor *imp);

/* Captures the model of r, drawn with options (clear, the camera and the
 * viewport are the capture's own; wireframe and dissolve are ignored), as seen
 * from camera's position towards centre. Restores the bound draw framebuffer
 * and the viewport. */
ms_status ms_impostor_capture(ms_impostor *imp, ms_render *r, const ms_render_options *options,
                              const double centre[3], double radius, const ms_camera *camera, ms_error *err);

/* Degrees between the capture's direction and the direction from camera to
 * the object's centre; 180 when nothing was captured. */
double ms_impostor_angle(const ms_impostor *imp, const ms_camera *camera);

/* Draws the impostor into the bound framebuffer (viewport and depth test as
 * ms_render_draw leaves them), coverage in [0, 1]; haze as ms_render_options'
 * (density 0: none), applied at each pixel's true distance (the capture has
 * none). */
ms_status ms_impostor_draw(ms_impostor *imp, const ms_camera *camera, float coverage, float haze_density,
                           const float haze_colour[3], ms_error *err);

#endif
