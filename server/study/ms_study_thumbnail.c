/* A model's thumbnail (ms_study_thumbnail.h). */
#include "ms_study_thumbnail.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_png.h"
#include "ms_progress.h"
#include "ms_study_cut.h"
#include "ms_study_render.h"
#include "ms_view_decoder.h"

#define SUPERSAMPLE 2u

void ms_study_thumbnail_options_default(ms_study_thumbnail_options *o)
{
    memset(o, 0, sizeof *o);
    o->up_axis = 2;
    o->permitted_bits = 64;
}

/* The box meshview frames: the root's complex at the root's precision (the
 * preview's when coarser); the archive's cube when the root has no vertex. */
static ms_status content_bounds(const ms_archive *a, ms_view *view, unsigned cap, double lo[3],
                                double hi[3], ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    const ms_archive_cell *root = ms_archive_get_cell(a, 0);
    unsigned bits = root->bits_max < h->root_bits ? root->bits_max : h->root_bits;
    if (cap < bits)
        bits = cap;
    if (bits < root->bits_min)
        bits = root->bits_min;
    ms_status st = ms_view_set_bits(view, 0, bits, err);
    if (st == MS_OK)
        st = ms_view_cell_bounds(view, 0, lo, hi, err);
    if (st == MS_ERR_EMPTY) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = h->box_origin[k];
            hi[k] = h->box_origin[k] + h->box_side;
        }
        st = MS_OK;
    }
    return st;
}

/* 2 x 2 box filter in linear light, from the supersampled picture. */
static void downsample(const ms_study_image *big, uint8_t *out, uint32_t width, uint32_t height)
{
    for (uint32_t y = 0; y < height; ++y)
        for (uint32_t x = 0; x < width; ++x)
            for (int ch = 0; ch < 3; ++ch) {
                double sum = 0;
                for (uint32_t dy = 0; dy < SUPERSAMPLE; ++dy)
                    for (uint32_t dx = 0; dx < SUPERSAMPLE; ++dx) {
                        size_t p = (size_t)(y * SUPERSAMPLE + dy) * big->width +
                                   x * SUPERSAMPLE + dx;
                        sum += ms_study_srgb_decode(big->rgb[3 * p + ch] / 255.0);
                    }
                out[3 * ((size_t)y * width + x) + ch] =
                    ms_study_srgb8(sum / (SUPERSAMPLE * SUPERSAMPLE));
            }
}

static ms_status render_cut(const ms_archive *a, ms_view *view,
                            const ms_study_thumbnail_options *o, const char *png_path,
                            ms_study_thumbnail_report *r, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    bool preview = o->permitted_bits < h->bits;
    double lo[3], hi[3];
    ms_status st = content_bounds(a, view, preview ? o->permitted_bits : h->bits, lo, hi, err);
    ms_camera camera;
    if (st == MS_OK)
        st = ms_camera_home(lo, hi, o->up_axis, MS_THUMBNAIL_WIDTH * SUPERSAMPLE,
                            MS_THUMBNAIL_HEIGHT * SUPERSAMPLE, &camera, err);
    if (st != MS_OK)
        return st;
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = SUPERSAMPLE; /* one pixel of the picture */
    params.permitted_steps = preview ? o->permitted_bits + 1 : 0;
    ms_view_mesh cut = {0};
    ms_study_cut_report cut_report;
    ms_study_scene *scene = NULL;
    ms_study_image image = {0};
    uint8_t *pixels = NULL;
    st = ms_study_cut(a, view, &camera, &params, NULL, &cut, &cut_report, err);
    if (st == MS_OK)
        st = ms_study_scene_new(cut.positions, cut.vertex_count, cut.triangles,
                                cut.triangle_count, &scene, err);
    if (st == MS_OK) {
        ms_study_render_options ro = {.threads = o->threads, .smooth = true,
                                      .colours = cut.colours};
        st = ms_study_render(scene, &camera, &ro, &image, err);
    }
    if (st == MS_OK && !(pixels = malloc(3u * MS_THUMBNAIL_WIDTH * MS_THUMBNAIL_HEIGHT)))
        st = ms_error_set(err, MS_ERR_NOMEM, "thumbnail: out of memory");
    if (st == MS_OK) {
        downsample(&image, pixels, MS_THUMBNAIL_WIDTH, MS_THUMBNAIL_HEIGHT);
        st = ms_png_write_compact(png_path, pixels, MS_THUMBNAIL_WIDTH, MS_THUMBNAIL_HEIGHT, 3,
                                  err);
    }
    if (st == MS_OK) {
        r->triangles = cut.triangle_count;
        for (uint32_t c = 0; c < ms_view_cell_count(view); ++c)
            if (ms_view_state(view, c) == MS_VIEW_SHOWN && ms_view_bits(view, c) > r->bits)
                r->bits = ms_view_bits(view, c);
    }
    free(pixels);
    ms_study_image_free(&image);
    ms_study_scene_free(scene);
    ms_view_mesh_free(&cut);
    return st;
}

ms_status ms_study_thumbnail(const char *archive_path, const char *png_path,
                             const ms_study_thumbnail_options *o,
                             ms_study_thumbnail_report *r, ms_error *err)
{
    memset(r, 0, sizeof *r);
    double start = ms_now_seconds();
    ms_archive *a = NULL;
    ms_view *view = NULL;
    ms_status st = ms_archive_open(archive_path, &a, err);
    if (st == MS_OK)
        st = ms_view_create_from_archive(a, &view, err);
    if (st == MS_OK)
        st = render_cut(a, view, o, png_path, r, err);
    ms_view_destroy(view);
    ms_archive_close(a);
    if (st != MS_OK)
        return st;
    struct stat sb;
    r->png_bytes = stat(png_path, &sb) == 0 ? (uint64_t)sb.st_size : 0;
    r->width = MS_THUMBNAIL_WIDTH;
    r->height = MS_THUMBNAIL_HEIGHT;
    r->seconds = ms_now_seconds() - start;
    return MS_OK;
}
