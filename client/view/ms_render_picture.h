/* One picture of a stitched mesh, drawn offscreen by the renderer and read
 * back: what a test or a study compares with the CPU reference renderer's
 * (server/study, meshrender), e.g. the albedo picture of a coloured model
 * (MS_SHADING_ALBEDO) against meshrender --albedo.
 *
 * A fresh renderer over the model (header and its whole index, as
 * ms_render_new takes them) is given the mesh and the APO chunks (apo may be
 * NULL when apo_count is 0), uploads all of it, draws it once at the camera
 * with the options into an RGBA8 + 24-bit depth framebuffer of the camera's
 * viewport, and the picture is read back; everything is freed again and the
 * window's framebuffer (0) is bound. *rgb (malloc'd, the caller frees) holds
 * width x height RGB pixels, top row first, as ms_png_write takes them.
 *
 * Requires a current OpenGL 4.1 core context (a hidden ms_gl_window will do).
 * Errors: ms_render_new's, ms_render_set_frame's, ms_render_draw's;
 * MS_ERR_UNSUPPORTED for a framebuffer the driver refuses, MS_ERR_NOMEM.
 * Thread-safety: the context's thread.
 */
#ifndef MS_RENDER_PICTURE_H
#define MS_RENDER_PICTURE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_render.h"

ms_status ms_render_picture(const ms_archive_header *header, const ms_archive_cell *cells, const ms_view_mesh *mesh,
                            const ms_core_apo_chunk *apo, size_t apo_count, const ms_camera *camera,
                            const ms_render_options *options, uint8_t **rgb, ms_error *err);

#endif
