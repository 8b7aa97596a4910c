#include "ms_viewer_stream.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct ms_viewer_stream {
    ms_viewer_model *model;     /* filled in at open (the caller's) */
    ms_core *core;
    ms_render *render;
    ms_core_frame *frame;       /* the frame the renderer was last given */
    double start_tolerance, tolerance;
    double open_timeout_s;      /* the source's, for ms_viewer_stream_wait_open */
    ms_camera last_camera;      /* as last handed to the core */
    bool have_camera;
    bool settled;               /* as of the last step */
};

ms_status ms_viewer_stream_start(const ms_viewer_source *source, ms_viewer_model *model,
                                 const ms_viewer_stream_settings *settings,
                                 ms_viewer_stream **out, ms_error *err)
{
    *out = NULL;
    ms_viewer_stream *s = calloc(1, sizeof *s);
    if (!s)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a stream");
    s->model = model;
    s->open_timeout_s = source->timeout_s > 0 ? source->timeout_s : 5.0;
    /* With APO the core refines geometry to apo_geometry_tolerance_px (the
     * normals carry the finer detail), else to tolerance_px: the viewer's
     * tolerance is whichever of the two is in effect. */
    bool apo = settings->apo_levels > 0 && model->apo;
    /* 1 px with APO too: coarser geometry under APO costs more image error than
     * the bytes it saves (docs/ACCURACY.md) */
    s->start_tolerance = s->tolerance = settings->tolerance_px > 0 ? settings->tolerance_px : 1.0;
    ms_core_options co = {0};
    if (source->archive_dir) {
        co.archive_path = model->archive_path;
        co.whole_index = settings->whole_index;
    } else if (settings->shared_link) {
        co.shared_link = settings->shared_link;
    } else {
        co.host = source->host, co.port = source->port, co.token = source->token;
        co.agent = MS_VIEWER_AGENT;
        co.bandwidth = settings->bandwidth;
        co.give_up_seconds = MS_VIEWER_GIVE_UP_S;
        co.whole_index = settings->whole_index;
    }
    co.model = model->name;
    if (apo)
        co.apo_geometry_tolerance_px = s->start_tolerance;
    else
        co.tolerance_px = s->start_tolerance;
    co.apo_levels = settings->apo_levels;
    co.apo_min_tolerance_px = settings->apo_min_tolerance_px;
    if (settings->memory_mb > 0) {
        co.memory_target = (uint64_t)(settings->memory_mb * 1048576.0);
        co.memory_ceiling = co.memory_target + co.memory_target / 2;
    }
    co.shared_budget = settings->shared_budget;
    co.decode_threads = settings->decode_threads;
    co.export_frames = true;
    /* The core first: while it connects and its index head is on the way,
     * this thread compiles the renderer's programs, so the first frame that
     * holds the root finds the renderer ready. */
    ms_status st = ms_core_start(&co, &s->core, err);
    if (st == MS_OK)
        st = ms_render_new(NULL, NULL, &s->render, err);
    if (st == MS_OK) {
        double crease = settings->crease_angle_deg >= 0 ? settings->crease_angle_deg
                        : model->has_crease_angle       ? model->crease_angle_deg
                                                        : MS_RENDER_CREASE_ANGLE_DEFAULT;
        st = ms_render_set_crease_angle(s->render, crease, err);
    }
    if (st != MS_OK) {
        ms_viewer_stream_close(s);
        return st;
    }
    *out = s;
    return MS_OK;
}

ms_status ms_viewer_stream_wait_open(ms_viewer_stream *s, ms_error *err)
{
    ms_viewer_model *model = s->model;
    ms_core_opening_free(&model->index);
    ms_status st = ms_core_wait_open(s->core, s->open_timeout_s, &model->index, err);
    if (st == MS_OK) {
        model->header = model->index.header;
        st = ms_render_set_model(s->render, &model->header, err);
    }
    return st;
}

ms_status ms_viewer_stream_open(const ms_viewer_source *source, ms_viewer_model *model,
                                const ms_viewer_stream_settings *settings,
                                ms_viewer_stream **out, ms_error *err)
{
    ms_status st = ms_viewer_stream_start(source, model, settings, out, err);
    if (st == MS_OK && (st = ms_viewer_stream_wait_open(*out, err)) != MS_OK) {
        ms_viewer_stream_close(*out);
        *out = NULL;
    }
    return st;
}

void ms_viewer_stream_close(ms_viewer_stream *s)
{
    if (!s)
        return;
    ms_core_stop(s->core);
    ms_core_frame_free(s->frame);
    ms_render_free(s->render);
    free(s);
}

void ms_viewer_stream_set_tolerance(ms_viewer_stream *s, double tolerance_px)
{
    if (!(tolerance_px >= 0.05))
        tolerance_px = 0.05;
    if (tolerance_px > 256)
        tolerance_px = 256;
    s->tolerance = tolerance_px;
}

double ms_viewer_stream_tolerance(const ms_viewer_stream *s) { return s->tolerance; }

const ms_core_frame *ms_viewer_stream_frame(const ms_viewer_stream *s) { return s->frame; }

/* k: core pixels per screen pixel. */
static double core_scale(const ms_viewer_stream *s) { return s->start_tolerance / s->tolerance; }

ms_status ms_viewer_stream_step(ms_viewer_stream *s, const ms_camera *camera,
                                uint64_t budget_bytes, ms_viewer_step *step, ms_error *err)
{
    memset(step, 0, sizeof *step);
    ms_camera asked = *camera;
    double k = core_scale(s);
    asked.width = camera->width * k;
    asked.height = camera->height * k;
    if (asked.width < 1)
        asked.width = 1;
    if (asked.height < 1)
        asked.height = 1;
    /* Only a changed camera goes to the core: each set-call starts a selection
     * pass there, and view_complete answers the latest call only. */
    if (!s->have_camera || memcmp(&asked, &s->last_camera, sizeof asked) != 0) {
        ms_core_set_camera(s->core, &asked);
        s->last_camera = asked;
        s->have_camera = true;
    }
    /* The core publishes a frame and the figures that describe it together, so
     * figures read before the take describe the frame taken (or one already
     * taken): complete then means the complete frame is in hand. */
    ms_core_stats stats;
    ms_core_get_stats(s->core, &stats);
    if (stats.error[0])
        return ms_error_set(err, MS_ERR_IO, "%s", stats.error);
    ms_core_frame *frame = ms_core_take_frame(s->core);
    if (frame) {
        ms_status st = ms_render_learn(s->render, frame->record_ids, frame->records,
                                       frame->record_count, err);
        if (st == MS_OK)
            st = ms_render_set_frame(s->render, &frame->mesh, frame->apo, frame->apo_count, err);
        if (st != MS_OK) {
            ms_core_frame_free(frame);
            return st;
        }
        ms_core_frame_free(s->frame);
        s->frame = frame;
        step->new_frame = true;
    }
    if (s->frame) {
        step->generation = s->frame->generation;
        step->frame_triangles = s->frame->mesh.triangle_count;
    }
    ms_status st = ms_render_upload(s->render, budget_bytes, &step->upload, err);
    if (st != MS_OK)
        return st;
    s->settled = stats.view_complete && step->upload.cells_pending == 0;
    step->settled = s->settled;
    return MS_OK;
}

ms_status ms_viewer_stream_draw(ms_viewer_stream *s, const ms_camera *camera,
                                const ms_render_options *options, ms_render_draw_stats *stats,
                                ms_error *err)
{
    return ms_render_draw(s->render, camera, options, stats, err);
}

void ms_viewer_stream_stats(ms_viewer_stream *s, ms_core_stats *stats)
{
    ms_core_get_stats(s->core, stats);
    double k = core_scale(s);
    stats->achieved_error_px /= k;
    stats->tolerance_px /= k;
}

bool ms_viewer_stream_settled(const ms_viewer_stream *s) { return s->settled; }

const ms_viewer_model *ms_viewer_stream_model(const ms_viewer_stream *s) { return s->model; }

ms_render *ms_viewer_stream_render(ms_viewer_stream *s)
{
    return s->render;
}

ms_status ms_viewer_stream_set_crease_angle(ms_viewer_stream *s, double degrees, ms_error *err)
{
    ms_status st = ms_render_set_crease_angle(s->render, degrees, err);
    if (st == MS_OK && s->frame) /* the same cells, so every record is still known */
        st = ms_render_set_frame(s->render, &s->frame->mesh, s->frame->apo, s->frame->apo_count, err);
    return st;
}

double ms_viewer_stream_crease_angle(const ms_viewer_stream *s) { return ms_render_crease_angle(s->render); }

ms_status ms_viewer_stream_set_sections(ms_viewer_stream *s, const double (*planes)[4], size_t count, ms_error *err)
{
    return ms_core_set_sections(s->core, planes, count, err);
}
