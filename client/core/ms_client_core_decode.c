/* The client core's decode thread: its loop and the pass (dec_step) whose
 * steps the other parts provide: reception (ms_core_receive.c), selection
 * and decoding by the view decoder, scheduling, the budget and publication.
 * Everything here is the decode thread's own. */
#include "ms_client_core_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "ms_progress.h"

/* The pass's camera, tolerance and selection parameters. */
static void dec_pass_begin(ms_core *c, const ms_camera *cam, dec_pass *pass)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    memset(pass, 0, sizeof *pass);
    pass->cam = cam;
    pass->fv.cam = *cam;
    ms_camera_frustum(cam, &pass->fv.frustum);
    ms_core_budget_sync(c);
    pass->factor = c->dec.tolerance_factor;
    /* APO where the geometry it shades is coarse enough to gain from it */
    pass->apo_on = c->o.apo_levels > 0 && h->has_apo &&
                   c->o.apo_geometry_tolerance_px * pass->factor >= c->o.apo_min_tolerance_px;
    pass->base_tol = pass->apo_on ? c->o.apo_geometry_tolerance_px : c->o.tolerance_px;
    pass->fv.tolerance = pass->base_tol * pass->factor;
    /* With APO on, geometry refines only to apo_geometry_tolerance_px where a
     * chunk carries the shading; a cell baked without one (its geometry renders
     * the input: every leaf, docs/APO.md) is shaded by its triangles alone, so
     * it refines to tolerance_px as with APO off. */
    double chunkless = pass->apo_on ? c->o.tolerance_px / c->o.apo_geometry_tolerance_px : 0.0;
    /* A public preview: no cell is wanted beyond what this reader may read
     * (PROTOCOL.md sections 4.10 and 8: a client need never trip FORBIDDEN). */
    pthread_mutex_lock(&c->lock);
    c->dec.preview_steps = c->permitted_geometry_steps;
    /* colour: from a local archive, or a connection that negotiated CAP_COLOUR */
    pass->colour_on = h->has_colour && c->colour_served;
    unsigned sections = c->section_count;
    double planes[MS_SECTIONS_MAX][4];
    memcpy(planes, c->sections, sizeof planes);
    pthread_mutex_unlock(&c->lock);
    /* the sections cull as the frustum's sides do (selection and schedule) */
    for (unsigned k = 0; k < sections; ++k)
        ms_frustum_add_section(&pass->fv.frustum, planes[k]);
    pass->sp = (ms_view_select_params){.tolerance_px = pass->fv.tolerance,
                                       .margin = c->o.frustum_margin,
                                       .hysteresis = c->o.hysteresis_bits,
                                       .culled_bits_less = c->o.culled_bits_less + c->dec.culled_give_up,
                                       .chunkless_tolerance_scale = chunkless,
                                       .permitted_steps = c->dec.preview_steps,
                                       .section_count = sections};
    memcpy(pass->sp.sections, planes, sizeof planes);
}

/* The decode thread's CPU seconds since *mark, and *mark moved to now. */
static double cpu_lap(unsigned long long *mark)
{
    unsigned long long now = ms_thread_cpu_ns();
    double lap = (double)(now - *mark) * 1e-9;
    *mark = now;
    return lap;
}

/* Rounds of selection in one pass at most: a round that changed the view is
 * selected again (a split shows children no round has selected yet), so the
 * pass's plan and its "complete" are those of the view it leaves. */
#define SELECT_ROUNDS 4

/* Selects the cells for the camera, refines and splits in waves on the pool
 * what can go down the cut (ms_view_refine_parallel), and applies the rest
 * (merges, coarsening), again while that changed the view; false when
 * decoding failed (then fatal). */
static bool dec_select(ms_core *c, dec_pass *pass, unsigned long long *mark)
{
    ms_core_decode_work *w = &c->dec.work;
    bool changed = true;
    for (unsigned round = 0; changed && round < SELECT_ROUNDS; ++round) {
        ms_view_select(c->dec.view, pass->cam, &pass->sp, &c->dec.report);
        w->select_cpu += cpu_lap(mark);
        size_t refined_in_parallel = ms_view_refine_parallel(c->dec.view, c->dec.pool, &c->dec.jobs);
        w->refine_cpu += cpu_lap(mark);
        ms_view_apply_report report;
        ms_error err;
        ms_status st = ms_view_apply(c->dec.view, &report, &err);
        w->apply_cpu += cpu_lap(mark);
        if (st != MS_OK) {
            pthread_mutex_lock(&c->lock);
            ms_core_fail_locked(c, "decoding failed: %.200s", err.text);
            pthread_mutex_unlock(&c->lock);
            return false;
        }
        w->apply_refined += report.refined;
        w->apply_splits += report.splits;
        changed = refined_in_parallel || report.splits || report.merges || report.refined ||
                  report.coarsened;
        pass->changed |= changed;
    }
    /* the view complete: the last pass's verdict (published by this thread) */
    ms_core_content_note(c, pass->for_content || c->stats.view_complete, pass->for_content);
    w->content_cpu += cpu_lap(mark);
    return true;
}

/* The passes' work into the published figures (the job figures from the
 * refine list's sums). */
static void dec_work_publish(ms_core *c)
{
    ms_core_decode_work *w = &c->dec.work;
    const ms_view_refine_stats *r = &c->dec.jobs.stats;
    w->waves = r->waves, w->jobs = r->jobs, w->splits = r->splits;
    w->jobs_on_helpers = r->jobs_on_helpers;
    w->jobs_cpu = (double)(r->caller_cpu_ns + r->helper_cpu_ns) * 1e-9;
    w->helper_cpu = (double)r->helper_cpu_ns * 1e-9;
    w->jobs_span2_cpu = (double)r->span2_ns * 1e-9;
    pthread_mutex_lock(&c->lock);
    c->stats.decode_work = *w;
    pthread_mutex_unlock(&c->lock);
}

/* One pass: take inputs, decode, select, plan, publish. Before the caller's
 * first camera, passes serve the content bounds' camera while they are
 * pending (ms_client_core_content.c). */
static void dec_step(ms_core *c, chunk_msg *chunks, const ms_camera *cam, uint64_t serial,
                     bool have_camera)
{
    double t_start = ms_now_seconds();
    unsigned long long mark = ms_thread_cpu_ns();
    ms_core_decode_work *w = &c->dec.work;
    bool apo_changed = ms_core_take_chunks(c, chunks);
    w->take_cpu += cpu_lap(&mark);
    ms_camera content_camera;
    bool for_content = !have_camera && ms_core_content_camera(c, &content_camera);
    if (!have_camera && !for_content)
        return;
    w->passes++;
    /* the frame's stitch works out its cells' caches and pieces on the pool too
     * (the view may be new since the last pass) */
    ms_view_set_pool(c->dec.view, c->dec.pool);
    dec_pass pass;
    dec_pass_begin(c, for_content ? &content_camera : cam, &pass);
    pass.apo_on &= !for_content; /* the root's geometry alone */
    pass.for_content = for_content;
    pass.sp.no_root_floor = for_content; /* the bounds' camera draws for nobody */
    pass.changed = apo_changed;
    w->plan_cpu += cpu_lap(&mark);
    if (!dec_select(c, &pass, &mark))
        return;
    bool ceiling = ms_core_budget_ceiling(c, &pass);
    w->plan_cpu += cpu_lap(&mark);
    if (!ceiling)
        return;
    ms_core_schedule(c, &pass);    /* what is missing, and in which order */
    ms_core_budget_step(c, &pass); /* memory: the budget */
    pass.complete &= !for_content; /* no caller's view to be complete */
    w->plan_cpu += cpu_lap(&mark);
    /* the work before the figures that say view complete (publication's own
     * CPU time shows from the next pass on) */
    dec_work_publish(c);
    ms_core_publish(c, &pass, serial, t_start);
    w->publish_cpu += cpu_lap(&mark);
}

void *ms_core_decode_main(void *arg)
{
    ms_core *c = arg;
    pthread_mutex_lock(&c->lock);
    uint64_t done_serial = 0;
    for (;;) {
        while (!c->stopping && !c->fatal && !c->inbox && !c->index_new &&
               !(c->dec.view && c->have_camera && (c->camera_serial != done_serial || c->republish))) {
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 20 * 1000000L;
            if (until.tv_nsec >= 1000000000L)
                until.tv_sec++, until.tv_nsec -= 1000000000L;
            if (pthread_cond_timedwait(&c->wake, &c->lock, &until) == ETIMEDOUT)
                break; /* periodic pass: budget steps, memory figures */
        }
        if (c->stopping || c->fatal)
            break;
        if (c->index_new) {
            c->index_new = false;
            pthread_mutex_unlock(&c->lock);
            ms_error err;
            bool ok = ms_core_take_index(c, &err);
            pthread_mutex_lock(&c->lock);
            if (!ok) {
                ms_core_fail_locked(c, "%.240s", err.text);
                break;
            }
        }
        if (!c->dec.view)
            continue;
        chunk_msg *chunks = c->inbox;
        c->inbox = c->inbox_tail = NULL;
        c->bytes_queued = 0; /* this pass takes them all */
        ms_camera cam = c->camera;
        uint64_t serial = c->camera_serial;
        bool have = c->have_camera;
        pthread_mutex_unlock(&c->lock);
        dec_step(c, chunks, &cam, serial, have);
        done_serial = serial;
        pthread_mutex_lock(&c->lock);
    }
    pthread_mutex_unlock(&c->lock);
    return NULL;
}

ms_status ms_core_decoder_init(ms_core *c, unsigned helpers, ms_error *err)
{
    c->dec.tolerance_factor = 1.0;
    c->dec.last_blocked = -1e9;
    c->dec.too_fine_until = -1e9;
    return ms_pool_new(helpers, &c->dec.pool, err);
}

void ms_core_decoder_free(ms_core *c)
{
    ms_pool_free(c->dec.pool);
    c->dec.pool = NULL;
    ms_view_refine_jobs_free(&c->dec.jobs);
    ms_core_dcells_free(c);
    ms_core_frames_free(c);
    ms_core_subtrees_free(c);
    ms_core_schedule_free(c);
    ms_view_destroy(c->dec.view);
    c->dec.view = NULL;
}
