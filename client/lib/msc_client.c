/* libmeshstream-client: the thin C facade over the client core
 * (client/core/ms_client_core.h) that meshstream-client.h promises. It adds
 * no behaviour of its own: it copies options into ms_core_options, translates
 * cameras, statuses and frames, and keeps the core's types out of the public
 * header so that the library's ABI does not follow the core's structures. */
/* Marks the msc_* definitions for export (every other symbol is hidden). */
#define MSC_BUILDING_LIBRARY
#include "meshstream-client.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_error.h"
#include "ms_progress.h"
#include "ms_version.h"

/* The public codes are the core's, value for value. */
_Static_assert(MSC_OK == (int)MS_OK && MSC_ERR_IO == (int)MS_ERR_IO &&
                   MSC_ERR_FORMAT == (int)MS_ERR_FORMAT && MSC_ERR_NOMEM == (int)MS_ERR_NOMEM &&
                   MSC_ERR_RANGE == (int)MS_ERR_RANGE && MSC_ERR_CORRUPT == (int)MS_ERR_CORRUPT &&
                   MSC_ERR_ARG == (int)MS_ERR_ARG &&
                   MSC_ERR_UNSUPPORTED == (int)MS_ERR_UNSUPPORTED &&
                   MSC_ERR_EMPTY == (int)MS_ERR_EMPTY,
               "msc_status follows ms_status");
_Static_assert(MSC_ERROR_TEXT_MAX == MS_ERROR_TEXT_MAX, "msc_error follows ms_error");

struct msc_options {
    char *host, *archive, *model, *token;
    unsigned port;
    double tolerance_px;
    unsigned apo_levels;
    uint64_t memory_budget;
    double bandwidth;
};

struct msc_stream {
    ms_core *core;
};

struct msc_frame {
    ms_core_frame *frame;
};

static msc_status fail(msc_error *err, msc_status code, const char *text)
{
    if (err) {
        err->code = code;
        snprintf(err->text, sizeof err->text, "%s", text);
    }
    return code;
}

static msc_status from_core(msc_error *err, ms_status code, const ms_error *core_err)
{
    return fail(err, (msc_status)code, code == MS_OK ? "" : core_err->text);
}

static msc_status ok(msc_error *err)
{
    return fail(err, MSC_OK, "");
}

MSC_API const char *msc_version(void)
{
    return ms_version();
}

MSC_API const char *msc_status_name(msc_status status)
{
    return ms_status_name((ms_status)status);
}

MSC_API msc_options *msc_options_new(void)
{
    msc_options *o = calloc(1, sizeof *o);
    if (o)
        o->tolerance_px = 1.0;
    return o;
}

MSC_API void msc_options_free(msc_options *options)
{
    if (!options)
        return;
    free(options->host);
    free(options->archive);
    free(options->model);
    free(options->token);
    free(options);
}

/* Replaces *slot by a copy of text (NULL clears it). */
static msc_status set_text(char **slot, const char *text, msc_error *err)
{
    char *copy = NULL;
    if (text && !(copy = strdup(text)))
        return fail(err, MSC_ERR_NOMEM, "out of memory copying an option");
    free(*slot);
    *slot = copy;
    return ok(err);
}

MSC_API msc_status msc_options_set_server(msc_options *options, const char *host, unsigned port,
                                          msc_error *err)
{
    if (!options || !host || !*host)
        return fail(err, MSC_ERR_ARG, "server: no host given");
    if (port < 1 || port > 65535)
        return fail(err, MSC_ERR_ARG, "server: the port must be in [1, 65535]");
    msc_status s = set_text(&options->host, host, err);
    if (s != MSC_OK)
        return s;
    options->port = port;
    return set_text(&options->archive, NULL, err);
}

MSC_API msc_status msc_options_set_archive(msc_options *options, const char *path, msc_error *err)
{
    if (!options || !path || !*path)
        return fail(err, MSC_ERR_ARG, "archive: no path given");
    msc_status s = set_text(&options->archive, path, err);
    if (s != MSC_OK)
        return s;
    options->port = 0;
    return set_text(&options->host, NULL, err);
}

MSC_API msc_status msc_options_set_model(msc_options *options, const char *name, msc_error *err)
{
    if (!options || !name || !*name)
        return fail(err, MSC_ERR_ARG, "model: no name given");
    return set_text(&options->model, name, err);
}

MSC_API msc_status msc_options_set_token(msc_options *options, const char *token, msc_error *err)
{
    if (!options)
        return fail(err, MSC_ERR_ARG, "token: no options");
    return set_text(&options->token, token && *token ? token : NULL, err);
}

MSC_API msc_status msc_options_set_tolerance(msc_options *options, double pixels, msc_error *err)
{
    if (!options || !isfinite(pixels) || pixels <= 0)
        return fail(err, MSC_ERR_ARG, "tolerance: wants a finite number of pixels > 0");
    options->tolerance_px = pixels;
    return ok(err);
}

MSC_API msc_status msc_options_set_apo_levels(msc_options *options, unsigned levels,
                                              msc_error *err)
{
    if (!options)
        return fail(err, MSC_ERR_ARG, "apo levels: no options");
    options->apo_levels = levels;
    return ok(err);
}

MSC_API msc_status msc_options_set_memory_budget(msc_options *options, uint64_t bytes,
                                                 msc_error *err)
{
    if (!options)
        return fail(err, MSC_ERR_ARG, "memory budget: no options");
    options->memory_budget = bytes;
    return ok(err);
}

MSC_API msc_status msc_options_set_bandwidth(msc_options *options, double bytes_per_second,
                                             msc_error *err)
{
    if (!options || !isfinite(bytes_per_second) || bytes_per_second < 0)
        return fail(err, MSC_ERR_ARG, "bandwidth: wants a finite number of bytes per second >= 0");
    options->bandwidth = bytes_per_second;
    return ok(err);
}

MSC_API msc_status msc_stream_new(const msc_options *options, msc_stream **stream, msc_error *err)
{
    if (!stream)
        return fail(err, MSC_ERR_ARG, "stream: nowhere to put it");
    *stream = NULL;
    if (!options || (!options->archive && !options->host))
        return fail(err, MSC_ERR_ARG, "stream: give a server or an archive");
    if (options->host && !options->model)
        return fail(err, MSC_ERR_ARG, "stream: a server needs a model name");
    msc_stream *s = calloc(1, sizeof *s);
    if (!s)
        return fail(err, MSC_ERR_NOMEM, "out of memory starting a stream");
    ms_core_options co = {0};
    co.host = options->host;
    co.port = (uint16_t)options->port;
    co.archive_path = options->archive;
    co.model = options->model;
    co.token = options->token;
    co.agent = "libmeshstream-client";
    co.tolerance_px = options->tolerance_px;
    co.apo_levels = options->apo_levels;
    co.memory_target = options->memory_budget;
    co.bandwidth = options->bandwidth;
    co.export_frames = true;
    ms_error e;
    ms_status st = ms_core_start(&co, &s->core, &e);
    if (st != MS_OK) {
        free(s);
        return from_core(err, st, &e);
    }
    *stream = s;
    return ok(err);
}

MSC_API void msc_stream_free(msc_stream *stream)
{
    if (!stream)
        return;
    ms_core_stop(stream->core);
    free(stream);
}

MSC_API msc_status msc_stream_wait_open(msc_stream *stream, double timeout_s, msc_model_info *info,
                                        msc_error *err)
{
    if (!stream || !info || !isfinite(timeout_s) || timeout_s <= 0)
        return fail(err, MSC_ERR_ARG, "wait open: wants a stream, an info and a time-out > 0");
    ms_core_opening opening = {0};
    ms_error e;
    ms_status st = ms_core_wait_open(stream->core, timeout_s, &opening, &e);
    if (st != MS_OK) {
        ms_core_opening_free(&opening);
        return from_core(err, st, &e);
    }
    const ms_archive_header *h = &opening.header;
    *info = (msc_model_info){
        .cell_count = h->cell_count,
        .vertex_count = h->vertex_count,
        .triangle_count = h->triangle_count,
        .bits = h->bits,
        .box_side = h->box_side,
        .has_apo = h->has_apo,
        .bounds_known = opening.content_known,
    };
    for (int k = 0; k < 3; ++k) {
        info->box_origin[k] = h->box_origin[k];
        info->bounds_lo[k] = opening.content_lo[k];
        info->bounds_hi[k] = opening.content_hi[k];
    }
    ms_core_opening_free(&opening);
    return ok(err);
}

MSC_API msc_status msc_stream_set_camera(msc_stream *stream, const msc_camera *camera,
                                         msc_error *err)
{
    if (!stream || !camera)
        return fail(err, MSC_ERR_ARG, "camera: wants a stream and a camera");
    ms_camera c;
    ms_error e;
    ms_status st = ms_camera_look_at(camera->position, camera->target, camera->up,
                                     camera->fovy_degrees, camera->width, camera->height,
                                     camera->near_distance, camera->far_distance, &c, &e);
    if (st == MS_OK && !(camera->near_distance > 0 && camera->far_distance > camera->near_distance))
        st = ms_error_set(&e, MS_ERR_ARG, "camera: wants 0 < near_distance < far_distance");
    if (st != MS_OK)
        return from_core(err, st, &e);
    ms_core_set_camera(stream->core, &c);
    return ok(err);
}

MSC_API void msc_stream_get_progress(msc_stream *stream, msc_progress *progress)
{
    if (!stream || !progress)
        return;
    ms_core_stats st;
    ms_core_get_stats(stream->core, &st);
    *progress = (msc_progress){
        .seconds = st.time,
        .model_open = st.model_open,
        .view_complete = st.view_complete,
        .achieved_error_px = st.achieved_error_px,
        .cells_shown = st.cells_shown,
        .cells_loading = st.cells_loading,
        .cells_failed = st.cells_failed,
        .bytes_received = st.bytes_received,
        .memory = st.memory,
    };
    snprintf(progress->error, sizeof progress->error, "%s", st.error);
    snprintf(progress->warning, sizeof progress->warning, "%s", st.warning);
}

MSC_API msc_status msc_stream_wait_complete(msc_stream *stream, double timeout_s,
                                            msc_progress *progress, msc_error *err)
{
    if (!stream || !isfinite(timeout_s) || timeout_s <= 0)
        return fail(err, MSC_ERR_ARG, "wait complete: wants a stream and a time-out > 0");
    msc_progress p;
    double until = ms_now_seconds() + timeout_s;
    for (;;) {
        msc_stream_get_progress(stream, &p);
        if (p.view_complete || p.error[0] || ms_now_seconds() >= until)
            break;
        nanosleep(&(struct timespec){0, 5000000}, NULL); /* 5 ms: a poll, not a wait on data */
    }
    if (progress)
        *progress = p;
    if (p.error[0])
        return fail(err, MSC_ERR_IO, p.error);
    if (!p.view_complete)
        return fail(err, MSC_ERR_IO, "wait complete: the view did not complete in time");
    return ok(err);
}

MSC_API msc_frame *msc_stream_take_frame(msc_stream *stream)
{
    if (!stream)
        return NULL;
    ms_core_frame *frame = ms_core_take_frame(stream->core);
    if (!frame)
        return NULL;
    msc_frame *f = malloc(sizeof *f);
    if (!f) {
        ms_core_frame_free(frame);
        return NULL;
    }
    f->frame = frame;
    return f;
}

MSC_API void msc_frame_free(msc_frame *frame)
{
    if (!frame)
        return;
    ms_core_frame_free(frame->frame);
    free(frame);
}

MSC_API uint64_t msc_frame_generation(const msc_frame *frame)
{
    return frame ? frame->frame->generation : 0;
}

MSC_API size_t msc_frame_vertex_count(const msc_frame *frame)
{
    return frame ? frame->frame->mesh.vertex_count : 0;
}

MSC_API const double *msc_frame_positions(const msc_frame *frame)
{
    return frame ? frame->frame->mesh.positions : NULL;
}

MSC_API size_t msc_frame_triangle_count(const msc_frame *frame)
{
    return frame ? frame->frame->mesh.triangle_count : 0;
}

MSC_API const uint32_t *msc_frame_triangles(const msc_frame *frame)
{
    return frame ? frame->frame->mesh.triangles : NULL;
}

MSC_API const uint32_t *msc_frame_triangle_cells(const msc_frame *frame)
{
    return frame ? frame->frame->mesh.triangle_cell : NULL;
}

MSC_API size_t msc_frame_cell_count(const msc_frame *frame)
{
    return frame ? frame->frame->record_count : 0;
}

MSC_API msc_status msc_frame_cell(const msc_frame *frame, size_t i, msc_cell *cell)
{
    if (!frame || !cell || i >= frame->frame->record_count)
        return MSC_ERR_ARG;
    const ms_core_frame *f = frame->frame;
    const ms_archive_cell *r = &f->records[i];
    *cell = (msc_cell){
        .id = f->record_ids[i],
        .level = r->level,
        .bits = ms_core_frame_cell_bits(f, f->record_ids[i]),
        .bits_max = r->bits_max,
        .leaf = r->first_child == MS_ARCHIVE_NONE,
        .triangle_count = r->triangle_count,
    };
    return MSC_OK;
}
