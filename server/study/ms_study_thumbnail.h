/* A model's thumbnail: a small picture of an archive from meshview's home view
 * (ms_camera_home), rendered by the reference renderer (ms_study_render.h) and
 * written as a compact PNG beside the archive, DIR/NAME.thumb.png
 * (docs/ARCHIVE.md, "Thumbnails"). meshbake makes it at bake and again with
 * --thumbnail NAME; meshserve serves it and the catalogue screens show it.
 *
 * What is drawn: the cut a client shows for the home camera at 1 pixel of
 * screen tolerance on the picture (ms_study_cut: every payload held, the
 * selection converged), capped at the preview precision when the model is a
 * preview (permitted_bits < the archive's bits: no cell is refined past
 * permitted_bits, exactly as a reader without a token is capped), so a
 * preview model's thumbnail shows only the preview (docs/SECURITY.md).
 * The home view frames the box of the root's complex at the root's precision
 * (or the preview's, when coarser): the content bounds meshview frames.
 * Shading: the renderer's lit picture (head light), smooth vertex normals, the
 * archive's vertex colours where it carries them, no APO. Rendered at twice
 * the size and averaged 2 x 2 in linear light (anti-aliasing).
 *
 * The PNG is written under a temporary name, synced and renamed over the old
 * one (ms_png_write_compact), so a server never reads half a picture.
 * Thread-safety: none shared; renders on the project's thread pool.
 */
#ifndef MS_STUDY_THUMBNAIL_H
#define MS_STUDY_THUMBNAIL_H

#include <stdint.h>

#include "ms_error.h"

#define MS_THUMBNAIL_WIDTH 160
#define MS_THUMBNAIL_HEIGHT 120
/* Largest thumbnail file a server sends or a client reads. */
#define MS_THUMBNAIL_MAX_BYTES (256u << 10)

typedef struct ms_study_thumbnail_options {
    int up_axis;             /* world up as meshview's --up: 0 x, 1 y, 2 z (default) */
    unsigned permitted_bits; /* the preview's precision (public_max_bits); >= bits: none */
    unsigned threads;        /* 0: every core */
} ms_study_thumbnail_options;

typedef struct ms_study_thumbnail_report {
    uint32_t width, height;
    unsigned bits;           /* the finest precision drawn (<= permitted_bits) */
    uint64_t triangles;      /* of the cut */
    uint64_t png_bytes;
    double seconds;
} ms_study_thumbnail_report;

/* z up, no preview, every core. */
void ms_study_thumbnail_options_default(ms_study_thumbnail_options *options);

/* Renders the archive at archive_path into png_path. Errors: the archive
 * reader's, the cut's and renderer's, MS_ERR_IO writing. */
ms_status ms_study_thumbnail(const char *archive_path, const char *png_path,
                             const ms_study_thumbnail_options *options,
                             ms_study_thumbnail_report *report, ms_error *err);

#endif
