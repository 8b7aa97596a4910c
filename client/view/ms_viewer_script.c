#include "ms_viewer_script.h"

#include <epoxy/gl.h>
#include <GLFW/glfw3.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>

#include "ms_camera_path.h"
#include "ms_json_out.h"
#include "ms_process_memory.h"
#include "ms_viewer_catalogue.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_hud.h"
#include "ms_viewer_inspect.h"
#include "ms_viewer_readback.h"
#include "ms_viewer_scene.h"
#include "ms_viewer_signals.h"
#include "ms_viewer_stream.h"
#include "ms_viewer_text.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static void nap(double seconds)
{
    struct timespec ts = {0, (long)(seconds * 1e9)};
    nanosleep(&ts, NULL);
}

static int by_value(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double ms_viewer_quantile(double *values, size_t n, double q)
{
    if (!n)
        return 0;
    qsort(values, n, sizeof *values, by_value);
    size_t rank = (size_t)ceil(q * (double)n);
    return values[rank ? rank - 1 : 0];
}

/* Per-frame figures of a run. */
typedef struct frame_log {
    double *ms, *step_ms;       /* whole frame; of it, the stream step */
    uint64_t *upload;
    size_t count, cap;
} frame_log;

static ms_status log_frame(frame_log *log, double ms, double step_ms, uint64_t upload,
                           ms_error *err)
{
    if (log->count == log->cap) {
        size_t cap = log->cap ? 2 * log->cap : 1024;
        double *m = realloc(log->ms, cap * sizeof *m);
        if (m)
            log->ms = m;
        double *sm = realloc(log->step_ms, cap * sizeof *sm);
        if (sm)
            log->step_ms = sm;
        uint64_t *u = realloc(log->upload, cap * sizeof *u);
        if (u)
            log->upload = u;
        if (!m || !sm || !u)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for frame figures");
        log->cap = cap;
    }
    log->ms[log->count] = ms;
    log->step_ms[log->count] = step_ms;
    log->upload[log->count++] = upload;
    return MS_OK;
}

/* A growing list of timings. */
typedef struct samples {
    double *v;
    size_t count, cap;
} samples;

static bool push_sample(samples *list, double value)
{
    if (list->count == list->cap) {
        size_t cap = list->cap ? 2 * list->cap : 256;
        double *grown = realloc(list->v, cap * sizeof *grown);
        if (!grown)
            return false;
        list->v = grown;
        list->cap = cap;
    }
    list->v[list->count++] = value;
    return true;
}

static ms_status make_dir(const char *dir, ms_error *err)
{
    if (mkdir(dir, 0777) != 0 && errno != EEXIST)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", dir, strerror(errno));
    return MS_OK;
}

static ms_status catalogue_shot(const ms_viewer_options *o, const ms_viewer_source *source,
                                json_t **report, ms_error *err)
{
    ms_viewer_model_list list;
    ms_status st = ms_viewer_list_page(source, NULL, &list, err);
    if (st != MS_OK)
        return st;
    char where[128], png[4200];
    if (source->archive_dir)
        snprintf(where, sizeof where, "%.120s", source->archive_dir);
    else
        snprintf(where, sizeof where, "server %s:%u", source->host, source->port);
    snprintf(png, sizeof png, "%s/catalogue.png", o->screenshot_dir);
    ms_viewer_text *text = NULL;
    ms_viewer_target target = {0};
    if ((st = make_dir(o->screenshot_dir, err)) != MS_OK ||
        (st = ms_viewer_text_new(&text, err)) != MS_OK ||
        (st = ms_viewer_target_init(&target, o->width, o->height, err)) != MS_OK)
        goto done;
    ms_viewer_target_bind(&target);
    glViewport(0, 0, o->width, o->height);
    glClearColor(0.08f, 0.08f, 0.09f, 1);
    ms_viewer_catalogue cat = {.list = &list, .where = where, .archive_dir = source->archive_dir,
                               .source = source};
    /* frames until the selected (first) model's panel is whole: from a
     * server its documents come from the catalogue's worker meanwhile, each
     * bounded by the time-out; the states the panel showed, in order */
    static const char *const panel_names[] = {"none", "loading", "picture", "no picture"};
    json_t *panel = json_array();
    ms_catalogue_panel shows, was = MS_PANEL_NONE;
    double start = now_s(), slowest_ms = 0;
    double limit = 2 * (source->timeout_s > 0 ? source->timeout_s : 5) + 1;
    int frames = 0;
    do {
        double t0 = now_s();
        glClear(GL_COLOR_BUFFER_BIT | GL_DEPTH_BUFFER_BIT);
        ms_viewer_text_begin(text, o->width, o->height,
                             ms_viewer_text_auto_scale(o->height, 1, true));
        ms_viewer_catalogue_draw(text, &cat, o->width, o->height);
        st = ms_viewer_text_draw(text, err);
        glFinish();
        double ms = (now_s() - t0) * 1e3;
        slowest_ms = ms > slowest_ms ? ms : slowest_ms;
        ++frames;
        if ((shows = ms_viewer_catalogue_panel(&cat)) != was || frames == 1)
            json_array_append_new(panel, json_string(panel_names[shows]));
        was = shows;
        if (shows == MS_PANEL_LOADING) {
            struct timespec nap = {0, 5000000};
            nanosleep(&nap, NULL);
        }
    } while (st == MS_OK && shows == MS_PANEL_LOADING && now_s() - start < limit);
    bool pictured = cat.thumbnail != NULL; /* the selected (first) model's */
    ms_viewer_catalogue_free(&cat);
    if (st != MS_OK || (st = ms_viewer_screenshot(png, o->width, o->height, err)) != MS_OK) {
        json_decref(panel);
        goto done;
    }
    json_t *models = json_array();
    for (size_t i = 0; i < list.count; ++i)
        json_array_append_new(models, json_pack("{s:s, s:I, s:I, s:b, s:b, s:o}", "name",
                                                list.entries[i].name, "triangles",
                                                (json_int_t)list.entries[i].triangles, "bytes",
                                                (json_int_t)list.entries[i].bytes, "apo",
                                                list.entries[i].apo, "thumbnail",
                                                list.entries[i].has_thumbnail, "title",
                                                ms_json_text(ms_metadata_field(
                                                    list.entries[i].metadata, 0))));
    *report = json_pack("{s:s, s:o, s:b, s:I, s:i, s:o, s:f}", "png", png, "models", models,
                        "picture_shown", pictured, "total",
                        (json_int_t)(list.total > list.count ? list.total : list.count),
                        "frames", frames, "panel", panel, "slowest_frame_ms", slowest_ms);
done:
    ms_viewer_target_free(&target);
    ms_viewer_text_free(text);
    ms_viewer_model_list_free(&list);
    return st;
}

/* The run's state while it plays the path. */
typedef struct script {
    const ms_viewer_options *o;
    ms_viewer_stream *stream;   /* one model, or */
    ms_viewer_scene *scene;     /* a scene (--scene) */
    const char *name;           /* the model's or the scene's, for the HUD */
    const char *scene_path;     /* the scene's camera path, or NULL */
    unsigned effects_ran;       /* of the last frame */
    uint64_t effect_frames[MS_EFFECT_COUNT]; /* frames (with a triangle) each effect ran in */
    ms_viewer_target target;
    ms_render_options render;
    GLFWwindow *window;
    ms_viewer_text *text;       /* with --hud */
    double last_ms;
    frame_log log;
    samples apo_draw_ms, plain_draw_ms; /* --compare-apo */
    bool first_written;
    char first_png[4200];
    double opened_at;           /* now_s() when the model (or scene) began to open */
    double first_display;       /* seconds from opened_at to the first frame drawn with a
                                   triangle; < 0 none yet */
    uint64_t first_generation;  /* the core frame that first picture drew (one model) */
    double first_frame_ms;      /* that frame's step, draw and glFinish */
    uint64_t last_triangles;
    ms_viewer_rss rss;          /* the caller's two stages, then the run's */
    uint64_t rss_shaders, rss_first_frame; /* VmRSS at those stages; 0: not read */
    json_t *inspect;            /* the report's light, view and measure (one model) */
    ms_viewer_inspect look;     /* the light, the measuring chain drawn with --hud */
} script;

/* VmRSS now, 0 when it cannot be read (the report then says 0). */
static uint64_t rss_now(void)
{
    ms_process_memory m;
    ms_error ignored;
    return ms_process_memory_read(&m, &ignored) == MS_OK ? m.rss : 0;
}

/* GL storage the run holds (ms_render.h, "GL memory"): the renderers' (and a
 * scene's impostors'), the offscreen framebuffer's and the HUD's. peak: the
 * renderers' peaks plus the rest as now (the framebuffer and the HUD's atlas
 * are made once, before any renderer). */
static void gl_memory(script *s, uint64_t *bytes, uint64_t *peak)
{
    *bytes = *peak = 0;
    if (s->scene)
        ms_viewer_scene_gl_memory(s->scene, bytes, peak);
    else if (s->stream) {
        ms_render_memory_stats m;
        ms_render_memory(ms_viewer_stream_render(s->stream), &m);
        *bytes = m.gl_bytes;
        *peak = m.gl_bytes_peak;
    }
    uint64_t own = ms_viewer_target_gl_bytes(&s->target) + ms_viewer_text_gl_bytes(s->text);
    *bytes += own;
    *peak += own;
}

/* The stream's or the scene's step, draw and figures. */
static ms_status run_step(script *s, const ms_camera *camera, ms_viewer_step *step, ms_error *err)
{
    return s->scene ? ms_viewer_scene_step(s->scene, camera, s->o->upload_budget, step, err)
                    : ms_viewer_stream_step(s->stream, camera, s->o->upload_budget, step, err);
}

static ms_status run_draw(script *s, const ms_camera *camera, const ms_render_options *ro,
                          ms_render_draw_stats *drawn, ms_error *err)
{
    return s->scene ? ms_viewer_scene_draw(s->scene, camera, ro, drawn, err)
                    : ms_viewer_stream_draw(s->stream, camera, ro, drawn, err);
}

static void run_stats(script *s, ms_core_stats *cs)
{
    if (s->scene)
        ms_viewer_scene_stats(s->scene, cs);
    else
        ms_viewer_stream_stats(s->stream, cs);
}

/* The effects' names as a JSON array. */
static json_t *effect_names(unsigned effects)
{
    json_t *list = json_array();
    for (unsigned bit = 1; bit <= MS_EFFECTS_ALL; bit <<= 1)
        if (effects & bit)
            json_array_append_new(list, json_string(ms_effect_name(bit)));
    return list;
}

/* One frame at camera: step, draw, finish; logs its figures. */
static ms_status frame(script *s, const ms_camera *camera, ms_viewer_step *step, ms_error *err)
{
    glfwPollEvents();
    if (glfwWindowShouldClose(s->window))
        return ms_error_set(err, MS_ERR_IO, "the window was closed while the model streamed");
    if (ms_viewer_signals_pending())
        return ms_error_set(err, MS_ERR_IO, "interrupted while the model streamed");
    double t0 = now_s();
    ms_status st = run_step(s, camera, step, err);
    if (s->stream) /* --light, --view: the light in the camera's frame, the chain cast */
        ms_viewer_inspect_frame(&s->look, s->stream, camera, &s->render);
    if (st != MS_OK)
        return st;
    glFinish(); /* the upload's share of the GPU's work counts to the step */
    double step_ms = (now_s() - t0) * 1e3;
    ms_viewer_target_bind(&s->target);
    ms_render_draw_stats drawn;
    if (s->o->compare_apo) {
        /* Both shadings of the same uploaded frame, back to back, each timed to
         * glFinish, in alternating order (neither always warms the caches for
         * the other); the run's own shading is drawn last for the picture. */
        ms_render_options other = s->render;
        other.apo = !s->render.apo;
        bool other_first = s->log.count % 2 == 0;
        for (int pass = 0; pass < 2; ++pass) {
            bool primary = (pass == 1) == other_first;
            const ms_render_options *ro = primary ? &s->render : &other;
            double d0 = now_s();
            if ((st = run_draw(s, camera, ro, &drawn, err)) != MS_OK)
                return st;
            glFinish();
            double ms = (now_s() - d0) * 1e3;
            if (drawn.triangles_drawn > 0 &&
                !push_sample(ro->apo ? &s->apo_draw_ms : &s->plain_draw_ms, ms))
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory for frame figures");
        }
        if (!other_first) /* the picture must show the run's own shading */
            if ((st = run_draw(s, camera, &s->render, &drawn, err)) != MS_OK)
                return st;
    } else if ((st = run_draw(s, camera, &s->render, &drawn, err)) != MS_OK)
        return st;
    s->effects_ran = drawn.effects_ran;
    if (s->text) {
        ms_core_stats cs;
        run_stats(s, &cs);
        uint64_t gl_bytes, gl_peak;
        gl_memory(s, &gl_bytes, &gl_peak);
        ms_viewer_hud_info info = {.model = s->name,
                                   .gl_bytes = gl_bytes,
                                   .show_effects = s->scene != NULL,
                                   .effects_ran = drawn.effects_ran,
                                   .mode = s->render.shading == MS_SHADING_NORMALS ? "normals"
                                           : s->render.shading == MS_SHADING_ALBEDO ? "albedo"
                                           : s->render.apo                        ? "APO lit"
                                                                                  : "geometry lit",
                                   .frame_ms = s->last_ms,
                                   .fps = s->last_ms > 0 ? 1e3 / s->last_ms : 0,
                                   .triangles_drawn = drawn.triangles_drawn,
                                   .cells_drawn = drawn.cells_drawn,
                                   .core = &cs,
                                   .settled = step->settled,
                                   .extra = s->look.lines,
                                   .extra_count = s->stream ? ms_viewer_inspect_hud(&s->look, s->stream) : 0};
        ms_viewer_text_begin(s->text, s->o->width, s->o->height,
                             ms_viewer_text_auto_scale(s->o->height, 1, false));
        ms_viewer_hud_draw(s->text, &info, s->o->width, s->o->height, true);
        ms_viewer_inspect_markers(&s->look, s->text);
        if ((st = ms_viewer_text_draw(s->text, err)) != MS_OK)
            return st;
    }
    glFinish();
    s->last_ms = (now_s() - t0) * 1e3;
    s->last_triangles = drawn.triangles_drawn;
    /* Frames before the first triangle (opening, the first bytes) draw nothing
     * and would only dilute the figures. */
    if (drawn.triangles_drawn > 0 &&
        (st = log_frame(&s->log, s->last_ms, step_ms, step->upload.bytes, err)) != MS_OK)
        return st;
    for (unsigned e = 0; e < MS_EFFECT_COUNT && drawn.triangles_drawn > 0; ++e)
        s->effect_frames[e] += (drawn.effects_ran >> e) & 1u;
    if (!s->first_written && drawn.triangles_drawn > 0) {
        s->first_written = true;
        s->first_display = now_s() - s->opened_at;
        s->first_generation = step->generation;
        s->first_frame_ms = s->last_ms;
        s->rss_first_frame = rss_now();
        snprintf(s->first_png, sizeof s->first_png, "%s/first-frame.png", s->o->screenshot_dir);
        if ((st = ms_viewer_screenshot(s->first_png, s->o->width, s->o->height, err)) != MS_OK)
            return st;
    }
    return MS_OK;
}

/* Holds the camera until the view settles or the time-out; returns the wait. */
static ms_status hold(script *s, const ms_camera *camera, bool *settled, double *waited,
                      ms_error *err)
{
    double start = now_s();
    *settled = false;
    for (;;) {
        ms_viewer_step step;
        ms_status st = frame(s, camera, &step, err);
        if (st != MS_OK)
            return st;
        *waited = now_s() - start;
        /* a server's annotations count to the picture (markers, the selected one) */
        if (step.settled && !ms_viewer_annotate_pending(&s->look.notes)) {
            *settled = true;
            return MS_OK;
        }
        if (*waited >= s->o->keyframe_timeout)
            return MS_OK;
        /* Nothing arrived: let the decode threads (or the fetch) have the CPU for a moment. */
        if (!step.new_frame && !step.upload.bytes)
            nap(0.004);
    }
}

/* The memory figures (docs/VIEWER.md, "Memory"): the core's, the GL storage
 * the viewer asked for, and the process's resident memory now, at its peak
 * and at the run's stages. */
static void add_memory_figures(json_t *report, script *s, const ms_core_stats *cs)
{
    if (!report)
        return;
    uint64_t gl_bytes, gl_peak;
    gl_memory(s, &gl_bytes, &gl_peak);
    ms_process_memory m;
    ms_error ignored;
    if (ms_process_memory_read(&m, &ignored) != MS_OK)
        memset(&m, 0, sizeof m);
    json_object_set_new(report, "core_memory", json_integer((json_int_t)cs->memory));
    const ms_core_frame_work *w = &cs->frame_work;
    json_object_set_new(report, "core_frames",
                        json_pack("{s:I, s:f, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I}", "frames",
                                  (json_int_t)cs->frames_made, "seconds", cs->frame_seconds, "triangles",
                                  (json_int_t)cs->frame_triangles, "apo_bytes", (json_int_t)cs->frame_apo_bytes,
                                  "apo_bytes_copied", (json_int_t)w->apo_bytes_copied, "apo_chunks_copied",
                                  (json_int_t)w->apo_chunks_copied, "apo_chunks_shared",
                                  (json_int_t)w->apo_chunks_shared, "cells_stitched",
                                  (json_int_t)w->cells_stitched, "triangles_stitched",
                                  (json_int_t)w->triangles_stitched, "cells_changed", (json_int_t)w->cells_changed,
                                  "cells_removed", (json_int_t)w->cells_removed));
    if (s->stream) { /* the renderer's work on those frames (docs/RENDERER.md, "Work per frame") */
        ms_render_frame_totals t;
        ms_render_frame_totals_get(ms_viewer_stream_render(s->stream), &t);
        json_t *rf = json_object();
        const char *names[] = {"frames", "cells_present", "cells_changed", "cells_left", "cells_derived",
                               "vertex_fans", "face_normals", "cells_rebuilt", "neighbours_moved",
                               "cells_queued", "triangles_rebuilt", "triangles_walked"};
        const uint64_t values[] = {t.frames, t.cells_present, t.cells_changed, t.cells_left, t.cells_derived,
                                   t.vertex_fans, t.face_normals, t.cells_rebuilt, t.neighbours_moved,
                                   t.cells_queued, t.triangles_rebuilt, t.triangles_walked};
        for (size_t i = 0; i < sizeof values / sizeof *values; ++i)
            json_object_set_new(rf, names[i], json_integer((json_int_t)values[i]));
        json_object_set_new(report, "render_frames", rf);
    }
    json_object_set_new(report, "core_peak_memory", json_integer((json_int_t)cs->peak_memory));
    json_object_set_new(report, "gl_bytes", json_integer((json_int_t)gl_bytes));
    json_object_set_new(report, "gl_bytes_peak", json_integer((json_int_t)gl_peak));
    json_object_set_new(report, "rss_bytes", json_integer((json_int_t)m.rss));
    json_object_set_new(report, "rss_peak_bytes", json_integer((json_int_t)m.rss_peak));
    json_object_set_new(report, "rss_anon_bytes", json_integer((json_int_t)m.rss_anon));
    json_object_set_new(report, "rss_file_bytes", json_integer((json_int_t)m.rss_file));
    json_object_set_new(report, "rss_stages",
                        json_pack("{s:I, s:I, s:I, s:I, s:I}", "start", (json_int_t)s->rss.start, "context",
                                  (json_int_t)s->rss.context, "shaders", (json_int_t)s->rss_shaders,
                                  "first_frame", (json_int_t)s->rss_first_frame, "end", (json_int_t)m.rss));
}

/* The core's index figures (docs/CLIENT.md, "An index by subtree"), and its
 * time to first display, added to a report. */
static void add_index_figures(json_t *report, const script *s, const ms_core_stats *cs)
{
    if (!report)
        return;
    /* meshview's own: from the start of opening (catalogue check, the core's
     * index head or whole index, the first bytes) to the first picture with a
     * triangle; the core's counts from its own start only */
    json_object_set_new(report, "time_to_first_display", json_real(s->first_display));
    json_object_set_new(report, "core_first_display", json_real(cs->first_display));
    if (!s->scene) {
        /* which core frame the first picture drew: the core's first frame with
         * a triangle when the renderer was ready for it (docs/VIEWER.md) */
        json_object_set_new(report, "first_frame_generation",
                            json_integer((json_int_t)s->first_generation));
        json_object_set_new(report, "core_first_display_generation",
                            json_integer((json_int_t)cs->first_display_generation));
        json_object_set_new(report, "first_frame_ms", json_real(s->first_frame_ms));
    }
    json_object_set_new(report, "index",
                        json_pack("{s:b, s:I, s:I, s:I, s:I}", "by_subtree", cs->index_by_subtree,
                                  "subtrees_received", (json_int_t)cs->subtrees_received,
                                  "index_bytes_received", (json_int_t)cs->index_bytes_received,
                                  "index_bytes_held", (json_int_t)cs->index_bytes_held,
                                  "peak_index_bytes_held",
                                  (json_int_t)cs->peak_index_bytes_held));
}

static json_t *frame_summary(frame_log *log, uint64_t budget)
{
    uint64_t upload_max = 0, upload_sum = 0;
    for (size_t i = 0; i < log->count; ++i) {
        upload_sum += log->upload[i];
        if (log->upload[i] > upload_max)
            upload_max = log->upload[i];
    }
    double mean = log->count ? (double)upload_sum / (double)log->count : 0;
    double p50 = ms_viewer_quantile(log->ms, log->count, 0.50);
    double p95 = ms_viewer_quantile(log->ms, log->count, 0.95);
    double max = log->count ? log->ms[log->count - 1] : 0; /* sorted by the quantiles */
    double step_p50 = ms_viewer_quantile(log->step_ms, log->count, 0.50);
    double step_p95 = ms_viewer_quantile(log->step_ms, log->count, 0.95);
    return json_pack("{s:I, s:f, s:f, s:f, s:f, s:f, s:I, s:f, s:I}", "frames",
                     (json_int_t)log->count, "frame_ms_p50", p50, "frame_ms_p95", p95,
                     "frame_ms_max", max, "step_ms_p50", step_p50, "step_ms_p95", step_p95,
                     "upload_bytes_max", (json_int_t)upload_max, "upload_bytes_mean", mean,
                     "upload_budget", (json_int_t)budget);
}

static ms_status play(script *s, const ms_viewer_model *model, json_t *keys, bool *all_complete,
                      ms_error *err)
{
    const ms_viewer_options *o = s->o;
    ms_camera_path path = {0};
    ms_status st;
    const char *path_file = o->path_file;
    if (!path_file && s->scene)
        path_file = s->scene_path;
    double lo[3], hi[3];
    if (s->scene)
        ms_viewer_scene_bounds(s->scene, lo, hi);
    else
        ms_viewer_model_bounds(model, lo, hi);
    if (path_file) {
        if ((st = ms_camera_path_load(path_file, &path, err)) != MS_OK)
            return st;
    } else if (s->scene) { /* from the room's +z end towards its middle, at eye height */
        path.keys = calloc(1, sizeof *path.keys);
        if (!path.keys)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a path");
        path.count = 1;
        double eye[3] = {0.5 * (lo[0] + hi[0]), lo[1] + 0.4 * (hi[1] - lo[1]), hi[2] - 0.05 * (hi[2] - lo[2])};
        double target[3] = {0.5 * (lo[0] + hi[0]), lo[1] + 0.3 * (hi[1] - lo[1]), 0.5 * (lo[2] + hi[2])};
        memcpy(path.keys[0].position, eye, sizeof eye);
        memcpy(path.keys[0].target, target, sizeof target);
        path.keys[0].up[1] = 1;
        path.keys[0].fovy_degrees = 50;
    } else { /* the home view as a path of one keyframe */
        ms_viewer_controls c;
        ms_viewer_controls_init(&c, lo, hi, o->up_axis, (double)o->width / o->height);
        ms_viewer_inspect_view(o, &c); /* --view */
        path.keys = calloc(1, sizeof *path.keys);
        if (!path.keys)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a path");
        path.count = 1;
        ms_viewer_controls_eye(&c, path.keys[0].position);
        memcpy(path.keys[0].target, c.target, sizeof c.target);
        path.keys[0].up[c.up_axis] = 1;
        path.keys[0].fovy_degrees = c.fovy_degrees;
    }
    *all_complete = true;
    for (size_t k = 0; k < path.count; ++k) {
        ms_camera camera;
        if (k > 0)
            for (unsigned f = 1; f < o->frames; ++f) {
                double t = path.keys[k - 1].time +
                           (path.keys[k].time - path.keys[k - 1].time) * f / (double)o->frames;
                if ((st = ms_camera_path_sample_framing(&path, t, o->width, o->height, lo,
                                                        hi, &camera, err)) != MS_OK)
                    goto done;
                ms_viewer_step step;
                if ((st = frame(s, &camera, &step, err)) != MS_OK)
                    goto done;
            }
        if ((st = ms_camera_path_sample_framing(&path, path.keys[k].time, o->width, o->height,
                                                lo, hi, &camera, err)) != MS_OK)
            goto done;
        bool settled;
        double waited;
        if ((st = hold(s, &camera, &settled, &waited, err)) != MS_OK)
            goto done;
        char png[4200];
        snprintf(png, sizeof png, "%s/keyframe-%02zu.png", o->screenshot_dir, k);
        if ((st = ms_viewer_screenshot(png, o->width, o->height, err)) != MS_OK)
            goto done;
        if (k == 0 && s->stream && s->inspect && ms_viewer_inspect_report_measure(o, &s->look, s->stream, &camera,
                                                                               s->inspect) && o->hud) {
            ms_viewer_step again; /* the picture again, with the points and the distance */
            if ((st = frame(s, &camera, &again, err)) != MS_OK ||
                (st = ms_viewer_screenshot(png, o->width, o->height, err)) != MS_OK)
                goto done;
        }
        ms_core_stats cs;
        run_stats(s, &cs);
        *all_complete &= settled;
        json_array_append_new(
            keys, json_pack("{s:I, s:f, s:s, s:b, s:f, s:I, s:I, s:I, s:I, s:f, s:f, s:o*}", "keyframe",
                            (json_int_t)k, "time", path.keys[k].time, "png", png, "complete",
                            settled, "seconds_to_complete", waited, "triangles_drawn",
                            (json_int_t)s->last_triangles, "bytes", (json_int_t)cs.bytes_received,
                            "geometry_bytes", (json_int_t)cs.geometry_bytes_received, "apo_bytes",
                            (json_int_t)cs.apo_bytes_received, "achieved_error_px",
                            cs.achieved_error_px, "tolerance_px", cs.tolerance_px, "effects_ran",
                            s->scene ? effect_names(s->effects_ran) : NULL));
        if (cs.preview) { /* complete at a public preview: a token gives more */
            json_t *key = json_array_get(keys, json_array_size(keys) - 1);
            json_object_set_new(key, "preview_bits", json_integer((json_int_t)cs.preview_bits));
            json_object_set_new(key, "preview_limited", json_boolean(cs.preview_limited));
        }
    }
    st = MS_OK;
done:
    ms_camera_path_free(&path);
    return st;
}

/* The figures every report ends with, and its release. */
static void script_free(script *s)
{
    ms_viewer_stream_close(s->stream);
    ms_viewer_scene_close(s->scene);
    ms_viewer_target_free(&s->target);
    ms_viewer_text_free(s->text);
    free(s->log.ms);
    free(s->log.step_ms);
    free(s->apo_draw_ms.v);
    free(s->plain_draw_ms.v);
    free(s->log.upload);
    json_decref(s->inspect);
    ms_viewer_inspect_close(&s->look);
}

/* --scene: the scene's models streamed and drawn together along its path. */
static ms_status scene_run(const ms_viewer_options *o, const ms_viewer_source *source, GLFWwindow *window,
                           const ms_viewer_rss *rss, json_t **report, bool *complete, ms_error *err)
{
    ms_scene scene;
    ms_status st = ms_scene_load(o->scene_file, &scene, err);
    if (st != MS_OK)
        return st;
    script s = {.o = o, .window = window, .name = scene.name[0] ? scene.name : "scene",
                .scene_path = scene.camera_path, .opened_at = now_s(), .first_display = -1, .rss = *rss};
    ms_render_options_default(&s.render);
    s.render.shading = o->shading;
    s.render.apo = o->apo_shading;
    s.render.smooth = !o->flat;
    s.render.apo_filter = o->apo_filter;
    s.render.apo_footprint = o->apo_footprint;
    ms_viewer_scene_settings settings = ms_viewer_options_scene_settings(o);
    json_t *keys = json_array();
    double started = now_s();
    if ((o->hud && (st = ms_viewer_text_new(&s.text, err)) != MS_OK) ||
        (st = ms_viewer_target_init(&s.target, o->width, o->height, err)) != MS_OK ||
        (st = ms_viewer_scene_open(source, &scene, o->scene_file, &settings, &s.scene, err)) != MS_OK)
        goto done;
    s.rss_shaders = rss_now(); /* the pieces' renderers built, their models opened */
    if ((st = play(&s, NULL, keys, complete, err)) != MS_OK)
        goto done;
    ms_core_stats cs;
    ms_viewer_scene_stats(s.scene, &cs);
    json_t *ran = json_object();
    for (unsigned e = 0; e < MS_EFFECT_COUNT; ++e)
        json_object_set_new(ran, ms_effect_name(1u << e), json_integer((json_int_t)s.effect_frames[e]));
    *report = json_pack("{s:o, s:s, s:i, s:i, s:b, s:O, s:o, s:s?, s:I, s:I, s:f, s:o, s:o, s:o}", "scene",
                        ms_json_text(o->scene_file), "source", source->archive_dir ? "archive" : "server", "width",
                        o->width, "height", o->height, "complete", *complete, "keyframes", keys, "frames",
                        frame_summary(&s.log, o->upload_budget), "first_frame_png",
                        s.first_written ? s.first_png : NULL, "geometry_bytes",
                        (json_int_t)cs.geometry_bytes_received, "apo_bytes", (json_int_t)cs.apo_bytes_received,
                        "seconds", now_s() - started, "effects_called_for", effect_names(ms_scene_effects(&scene)),
                        "effects_compiled", effect_names(ms_viewer_scene_effects(s.scene)), "effect_frames", ran);
    add_index_figures(*report, &s, &cs);
    add_memory_figures(*report, &s, &cs);
    if (*report) {
        json_object_set_new(*report, "connections",
                            json_integer((json_int_t)ms_viewer_scene_connections(s.scene)));
        json_object_set_new(*report, "socket_bytes", json_integer((json_int_t)cs.socket_bytes));
    }
    if (!*report)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the report");
done:
    json_decref(keys);
    script_free(&s);
    ms_scene_free(&scene);
    return st;
}

ms_status ms_viewer_script_run(const ms_viewer_options *o, const ms_viewer_source *source,
                               GLFWwindow *window, const ms_viewer_rss *rss, json_t **report, bool *complete,
                               ms_error *err)
{
    *report = NULL;
    *complete = false;
    ms_status st = make_dir(o->screenshot_dir, err);
    if (st != MS_OK)
        return st;
    if (o->scene_file)
        return scene_run(o, source, window, rss, report, complete, err);
    if (!o->model) {
        *complete = true;
        return catalogue_shot(o, source, report, err);
    }
    double opened_at = now_s();
    ms_viewer_model model;
    if ((st = ms_viewer_model_open(source, o->model, &model, err)) != MS_OK)
        return st;
    script s = {.o = o, .window = window, .name = o->model, .opened_at = opened_at, .first_display = -1,
                .rss = *rss, .inspect = json_object()};
    ms_viewer_inspect_init(&s.look, o, source);
    ms_render_options_default(&s.render);
    s.render.shading = o->shading;
    s.render.apo = o->apo_shading;
    s.render.smooth = !o->flat;
    s.render.apo_filter = o->apo_filter;
    s.render.apo_footprint = o->apo_footprint;
    ms_viewer_stream_settings settings = ms_viewer_options_stream_settings(o);
    json_t *keys = json_array();
    double started = now_s();
    if ((o->hud && (st = ms_viewer_text_new(&s.text, err)) != MS_OK) ||
        (st = ms_viewer_target_init(&s.target, o->width, o->height, err)) != MS_OK)
        goto done;
    ms_viewer_target_bind(&s.target); /* the renderer warms up drawing into it */
    if ((st = ms_viewer_stream_start(source, &model, &settings, &s.stream, err)) != MS_OK)
        goto done;
    s.rss_shaders = rss_now(); /* the renderer built (its programs compiled), the core started */
    if ((st = ms_viewer_stream_wait_open(s.stream, err)) != MS_OK)
        goto done;
    if ((st = play(&s, &model, keys, complete, err)) != MS_OK)
        goto done;
    ms_core_stats cs;
    ms_viewer_stream_stats(s.stream, &cs);
    json_t *compare = NULL;
    if (o->compare_apo) {
        double a50 = ms_viewer_quantile(s.apo_draw_ms.v, s.apo_draw_ms.count, 0.5);
        double a95 = ms_viewer_quantile(s.apo_draw_ms.v, s.apo_draw_ms.count, 0.95);
        double p50 = ms_viewer_quantile(s.plain_draw_ms.v, s.plain_draw_ms.count, 0.5);
        double p95 = ms_viewer_quantile(s.plain_draw_ms.v, s.plain_draw_ms.count, 0.95);
        compare = json_pack("{s:I, s:f, s:f, s:f, s:f, s:f, s:f}", "draws",
                            (json_int_t)s.apo_draw_ms.count, "apo_draw_ms_p50", a50,
                            "apo_draw_ms_p95", a95, "plain_draw_ms_p50", p50,
                            "plain_draw_ms_p95", p95, "ratio_p50", p50 > 0 ? a50 / p50 : 0,
                            "ratio_p95", p95 > 0 ? a95 / p95 : 0);
    }
    *report = json_pack("{s:s, s:s, s:s, s:i, s:i, s:f, s:b, s:O, s:o, s:s?, s:I, s:I, s:f, s:o*}",
                        "model", model.name, "source", source->archive_dir ? "archive" : "server",
                        "shading",
                        o->shading == MS_SHADING_NORMALS ? "normals"
                        : o->shading == MS_SHADING_CELLS ? "cells"
                        : o->shading == MS_SHADING_ALBEDO ? "albedo"
                        : o->apo_shading                 ? "apo"
                                                         : "geometry",
                        "width", o->width, "height", o->height, "tolerance_px",
                        ms_viewer_stream_tolerance(s.stream),
                        "complete", *complete, "keyframes", keys, "frames",
                        frame_summary(&s.log, o->upload_budget), "first_frame_png",
                        s.first_written ? s.first_png : NULL, "geometry_bytes",
                        (json_int_t)cs.geometry_bytes_received, "apo_bytes",
                        (json_int_t)cs.apo_bytes_received, "seconds", now_s() - started,
                        "compare_apo", compare);
    add_index_figures(*report, &s, &cs);
    add_memory_figures(*report, &s, &cs);
    if (*report) {
        json_object_set_new(*report, "flat", json_boolean(o->flat));
        json_object_set_new(*report, "crease_angle_deg", json_real(ms_viewer_stream_crease_angle(s.stream)));
        ms_viewer_inspect_report_light(o, *report);
        ms_viewer_inspect_report_annotations(&s.look, *report);
        json_object_update(*report, s.inspect);
    }
    if (!*report)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the report");
done:
    json_decref(keys);
    script_free(&s);
    ms_viewer_model_close(&model);
    return st;
}

void ms_viewer_script_print(const json_t *report, bool json)
{
    if (json) {
        char *text = json_dumps(report, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(17));
        if (text)
            printf("%s\n", text);
        free(text);
    } else {
        json_t *keys = json_object_get(report, "keyframes");
        size_t i;
        json_t *k;
        json_array_foreach(keys, i, k)
            printf("keyframe %zu: %s, %s in %.2f s, %lld triangles, error %.2f px\n", i,
                   json_string_value(json_object_get(k, "png")),
                   json_is_true(json_object_get(k, "complete")) ? "complete" : "NOT complete",
                   json_real_value(json_object_get(k, "seconds_to_complete")),
                   (long long)json_integer_value(json_object_get(k, "triangles_drawn")),
                   json_real_value(json_object_get(k, "achieved_error_px")));
        if (!json_array_size(keys))
            printf("wrote %s\n", json_string_value(json_object_get(report, "png")));
    }
}
