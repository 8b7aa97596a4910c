/* One picture of a stitched mesh, offscreen (ms_render_picture.h). */
#include "ms_render_picture.h"

#include <epoxy/gl.h>
#include <math.h>
#include <stdlib.h>

#include "ms_viewer_readback.h"

ms_status ms_render_picture(const ms_archive_header *header, const ms_archive_cell *cells, const ms_view_mesh *mesh,
                            const ms_core_apo_chunk *apo, size_t apo_count, const ms_camera *camera,
                            const ms_render_options *options, uint8_t **rgb, ms_error *err)
{
    if (!rgb || !camera || !options)
        return ms_error_set(err, MS_ERR_ARG, "render picture: no camera, options or result pointer");
    *rgb = NULL;
    if (!header || !cells)
        return ms_error_set(err, MS_ERR_ARG, "render picture: no model header and index");
    int width = (int)lround(camera->width), height = (int)lround(camera->height);
    if (!(camera->width >= 1 && camera->width <= 16384 && camera->height >= 1 && camera->height <= 16384))
        return ms_error_set(err, MS_ERR_ARG, "render picture: a %g x %g viewport", camera->width, camera->height);
    ms_render *r = NULL;
    ms_status st = ms_render_new(header, cells, &r, err);
    if (st == MS_OK)
        st = ms_render_set_frame(r, mesh, apo, apo_count, err);
    ms_render_upload_stats up = {.cells_pending = 1};
    while (st == MS_OK && up.cells_pending > 0)
        st = ms_render_upload(r, UINT64_MAX / 2, &up, err);
    ms_viewer_target target = {0};
    if (st == MS_OK)
        st = ms_viewer_target_init(&target, width, height, err);
    if (st == MS_OK) {
        ms_viewer_target_bind(&target);
        st = ms_render_draw(r, camera, options, NULL, err);
    }
    if (st == MS_OK)
        st = ms_viewer_read_rgb(width, height, rgb, err);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    ms_viewer_target_free(&target);
    ms_render_free(r);
    return st;
}
