/* The decoder's side of scheduling (decode thread): the snapshot of what the
 * view decoder and the reception buffers hold, handed to the scheduler
 * (ms_core_sched.h, a pure function), and its plan taken back: the pass's
 * wants and cell counts, and the subtrees the cut needs
 * (ms_core_subtrees_keep). Geometry bytes held back for a cell's goal
 * (dcell.pending) are handed over here first, since the goal comes from the
 * selection just made. */
#include "ms_client_core_internal.h"

#include <stdlib.h>

double ms_core_cell_need(const ms_core *c, const frame_view *fv, uint32_t cell, bool *visible)
{
    return ms_sched_cell_need(c->index, fv, c->o.frustum_margin, cell, visible);
}

static bool grow(void **p, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return true;
    size_t n = *cap ? *cap : 256;
    while (n < need)
        n *= 2;
    void *g = realloc(*p, n * size);
    if (!g)
        return false;
    *p = g;
    *cap = n;
    return true;
}

/* One known cell as the scheduler sees it. A shown cell's error bound is
 * taken before its held-back bytes are handed over (as the pass always did),
 * its goal's prefix noted for the hand-over's steps. */
static ms_sched_cell snapshot_cell(ms_core *c, const dec_pass *pass, uint32_t i,
                                   unsigned root_goal_min)
{
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    dcell *d = ms_core_dcell(c, i);
    ms_sched_cell e = {.id = i,
                       .state = (uint8_t)ms_view_state(c->dec.view, i),
                       .target = ms_view_target(c->dec.view, i),
                       .parent_state = rec->parent == MS_ARCHIVE_NONE
                                           ? MS_VIEW_HIDDEN
                                           : (uint8_t)ms_view_state(c->dec.view, rec->parent),
                       .failed = d->failed,
                       .blocked = d->blocked,
                       .error_bound = -1.0};
    if (e.state == MS_VIEW_SHOWN) {
        e.bits = (uint8_t)ms_view_bits(c->dec.view, i);
        if (rec->geometry_length > 0 &&
            ms_sched_cell_visible(c->index, &pass->fv, c->o.frustum_margin, i))
            e.error_bound = ms_view_cell_error_bound(c->dec.view, i);
        unsigned goal = ms_sched_goal(rec, i, e.target, root_goal_min);
        d->goal_bytes = ms_archive_geometry_prefix(c->index, i, goal);
        if (d->pending)
            ms_core_hand_over(c, i);
    } else if (e.state == MS_VIEW_HIDDEN) {
        e.cached = ms_view_held_bytes(c->dec.view, i) > 0;
    }
    e.avail = (uint8_t)ms_view_available_bits(c->dec.view, i);
    e.geo_end = d->geo.end;
    e.apo_end = d->apo.end;
    e.col_end = d->col.end;
    return e;
}

void ms_core_schedule(ms_core *c, dec_pass *pass)
{
    pass->wl = (want_list){0};
    pass->worst = 0;
    pass->shown = pass->split = pass->cached = pass->loading = pass->failed = 0;
    pass->complete = true;
    /* a cell held back only by its children's records is about to split too */
    for (size_t k = 0; k < c->dec.report.blocked_count; ++k)
        ms_core_dcell(c, c->dec.report.blocked[k])->blocked = true;
    unsigned root_goal_min = ms_core_content_goal(c, 0, 0);
    size_t n = 0;
    bool ok = true;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE && ok; i = ms_view_next_known(c->dec.view, i)) {
        ok = grow((void **)&c->dec.sched_cells, &c->dec.sched_cells_cap, n + 1, sizeof *c->dec.sched_cells);
        if (ok)
            c->dec.sched_cells[n++] = snapshot_cell(c, pass, i, root_goal_min);
    }
    for (size_t k = 0; k < c->dec.report.blocked_count; ++k)
        ms_core_dcell(c, c->dec.report.blocked[k])->blocked = false;
    if (!ok) {
        ms_core_warn(c, "out of memory for the pass's schedule");
        pass->complete = false;
        return;
    }
    ms_sched_input in = {.index = c->index,
                         .fv = pass->fv,
                         .margin = c->o.frustum_margin,
                         .apo_on = pass->apo_on,
                         .colour_on = pass->colour_on,
                         .apo_levels = c->o.apo_levels,
                         .apo_tolerance_px = c->o.tolerance_px * c->dec.tolerance_factor,
                         .preview_steps = c->dec.preview_steps,
                         .root_goal_min = root_goal_min,
                         .cells = c->dec.sched_cells,
                         .cell_count = n,
                         .by_subtree = c->dec.by_subtree,
                         .blocked = c->dec.report.blocked,
                         .near = c->dec.report.near,
                         .blocked_count = c->dec.report.blocked_count,
                         .near_count = c->dec.report.near_count};
    in.subtrees = ms_core_subtrees_snapshot(c, &in.subtree_count);
    ms_sched_plan plan = {0};
    ms_sched_plan_make(&in, &plan);
    pass->wl = plan.wl;
    plan.wl = (want_list){0};
    pass->worst = plan.worst;
    pass->shown = plan.shown, pass->split = plan.split, pass->cached = plan.cached;
    pass->loading = plan.loading, pass->failed = plan.failed;
    pass->complete = plan.complete;
    /* the index's subtrees, with an index by subtree: the others go */
    ms_core_subtrees_keep(c, pass, plan.needs, plan.need_count);
    ms_sched_plan_free(&plan);
}

void ms_core_schedule_free(ms_core *c)
{
    free(c->dec.sched_cells);
    c->dec.sched_cells = NULL;
    c->dec.sched_cells_cap = 0;
}
