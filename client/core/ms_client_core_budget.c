/* The client core's memory budget (ms_client_core.h, "Memory budget"): what
 * the decoded cells hold, the tolerance steps that keep it near the target,
 * eviction of hidden cells, and the ceiling on loading. Decode thread only. */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdlib.h>

/* What a cell holds: payload bytes and, shown, its decoded estimate. */
static uint64_t cell_memory(const ms_core *c, uint32_t cell)
{
    const dcell *d = &c->cells[cell];
    uint64_t m = ms_view_held_bytes(c->view, cell) + d->geo.cap + d->apo.cap;
    if (ms_view_state(c->view, cell) != MS_VIEW_HIDDEN)
        m += (uint64_t)ms_core_decoded_estimate(ms_archive_get_cell(c->index, cell),
                                                ms_view_bits(c->view, cell));
    return m;
}

static void evict(ms_core *c, uint32_t cell)
{
    dcell *d = &c->cells[cell];
    ms_view_forget(c->view, cell, NULL);
    ms_core_rx_free(&d->geo);
    ms_core_rx_free(&d->apo);
    free(d->header);
    d->header = NULL;
    d->given = d->apo_given = 0;
    pthread_mutex_lock(&c->lock);
    c->stats.evictions++;
    pthread_mutex_unlock(&c->lock);
}

typedef struct evict_candidate {
    uint32_t cell;
    double usefulness;
    uint64_t bytes;
} evict_candidate;

static int compare_candidates(const void *x, const void *y)
{
    const evict_candidate *a = x, *b = y;
    return a->usefulness < b->usefulness ? -1 : a->usefulness > b->usefulness;
}

/* What every cell holds, the budget's measure. */
static uint64_t memory_held(const ms_core *c)
{
    uint64_t m = 0;
    for (uint32_t i = 0; i < ms_view_cell_count(c->view); ++i)
        m += cell_memory(c, i);
    return m;
}

/* Hidden cells the view does not target that hold memory, least useful first
 * (culled ones least); *count of them. NULL (and 0) when there is none or no
 * memory for the list. */
static evict_candidate *evict_candidates(ms_core *c, const frame_view *fv, size_t *count)
{
    uint32_t n = ms_view_cell_count(c->view);
    *count = 0;
    evict_candidate *cand = malloc(n * sizeof *cand);
    if (!cand)
        return NULL;
    size_t nc = 0;
    for (uint32_t i = 1; i < n; ++i) {
        if (ms_view_state(c->view, i) != MS_VIEW_HIDDEN || c->target[i] != MS_VIEW_TARGET_HIDDEN)
            continue;
        uint64_t b = cell_memory(c, i);
        if (!b)
            continue;
        bool visible;
        double u = ms_core_cell_need(c, fv, i, &visible);
        cand[nc++] = (evict_candidate){i, visible ? u : u - 64.0, b};
    }
    if (nc)
        qsort(cand, nc, sizeof *cand, compare_candidates);
    *count = nc;
    return cand;
}

/* Evicts hidden cells the view does not target, least useful first, until
 * memory is at most limit. */
static void evict_unneeded(ms_core *c, const frame_view *fv, uint64_t limit)
{
    size_t nc;
    evict_candidate *cand = evict_candidates(c, fv, &nc);
    uint64_t m = memory_held(c);
    for (size_t k = 0; k < nc && m > limit; ++k) {
        m -= cand[k].bytes < m ? cand[k].bytes : m;
        evict(c, cand[k].cell);
    }
    free(cand);
}

/* Selects and applies the view for the pass's tolerance; false when decoding
 * failed (the core is then fatal). */
static bool reselect(ms_core *c, dec_pass *pass)
{
    ms_view_apply_report report;
    ms_error err;
    ms_view_select(c->view, pass->cam, &pass->sp, c->target);
    if (ms_view_apply(c->view, c->target, &report, &err) != MS_OK) {
        pthread_mutex_lock(&c->lock);
        ms_core_fail_locked(c, "decoding failed: %.200s", err.text);
        pthread_mutex_unlock(&c->lock);
        return false;
    }
    return true;
}

bool ms_core_budget_ceiling(ms_core *c, dec_pass *pass)
{
    /* Hard ceiling: evict what the view does not need; if that is not enough,
     * coarsen at once (double the tolerance) and evict what that frees. */
    for (int round = 0; c->o.memory_ceiling && round < 8; ++round) {
        if (memory_held(c) <= c->o.memory_ceiling)
            break;
        evict_unneeded(c, &pass->fv, (uint64_t)(0.9 * c->o.memory_target));
        if (memory_held(c) <= c->o.memory_ceiling || c->tolerance_factor >= MAX_TOLERANCE_FACTOR)
            break;
        c->tolerance_factor *= 2;
        c->last_budget_step = ms_core_since_start(c);
        pass->fv.tolerance = pass->sp.tolerance_px = pass->base_tol * c->tolerance_factor;
        if (!reselect(c, pass))
            return false;
        pass->changed = true;
    }
    return true;
}

/* Over the target: raise the tolerance half a bit (every 0.1 s at most);
 * well below it and not blocked lately: lower it back. */
static void step_tolerance(ms_core *c, uint64_t memory, double t)
{
    if (memory > c->o.memory_target && c->tolerance_factor < MAX_TOLERANCE_FACTOR &&
        t - c->last_budget_step > 0.1) {
        c->tolerance_factor *= M_SQRT2;
        c->last_budget_step = t;
    } else if (memory < 0.7 * c->o.memory_target && c->tolerance_factor > 1.0 &&
               t - c->last_budget_step > 0.1 && t - c->last_blocked > 2.0) {
        c->tolerance_factor /= M_SQRT2;
        if (c->tolerance_factor < 1.0)
            c->tolerance_factor = 1.0;
        c->last_budget_step = t;
    }
}

/* Loading stays under the ceiling; to make room, evicts only cells clearly
 * (one bit) less useful than the one being loaded (candidates from *next on).
 * Returns how many of the pass's wants fit. */
static size_t fit_wants(ms_core *c, dec_pass *pass, const evict_candidate *cand, size_t nc,
                        size_t *next, uint64_t *memory, uint64_t in_flight)
{
    uint64_t ceiling = c->o.memory_ceiling ? c->o.memory_ceiling : UINT64_MAX;
    uint64_t planned = *memory + in_flight;
    size_t keep = 0;
    for (; keep < pass->wl.n; ++keep) {
        const want *w = &pass->wl.w[keep];
        uint64_t need_bytes = (uint64_t)(w->end - w->start) + w->decoded_growth;
        if (planned + need_bytes <= ceiling) {
            planned += need_bytes;
            continue;
        }
        bool visible;
        double u = ms_core_cell_need(c, &pass->fv, w->cell, &visible);
        if (!visible)
            u -= 64.0;
        while (planned + need_bytes > ceiling && *next < nc && cand[*next].usefulness + 1.0 < u) {
            planned -= cand[*next].bytes < planned ? cand[*next].bytes : planned;
            *memory -= cand[*next].bytes < *memory ? cand[*next].bytes : *memory;
            evict(c, cand[(*next)++].cell);
        }
        if (planned + need_bytes > ceiling)
            break;
        planned += need_bytes;
    }
    return keep;
}

void ms_core_budget_step(ms_core *c, dec_pass *pass)
{
    pass->memory = memory_held(c);
    pthread_mutex_lock(&c->lock);
    uint64_t in_flight = c->bytes_in_flight;
    pthread_mutex_unlock(&c->lock);
    if (!c->o.memory_target)
        return;
    double t = ms_core_since_start(c);
    step_tolerance(c, pass->memory, t);
    size_t nc;
    evict_candidate *cand = evict_candidates(c, &pass->fv, &nc);
    size_t next = 0;
    /* over the target: free down to 90 % of it, least useful first */
    if (pass->memory > c->o.memory_target)
        while (pass->memory > 0.9 * c->o.memory_target && next < nc) {
            pass->memory -= cand[next].bytes;
            evict(c, cand[next++].cell);
        }
    size_t keep = fit_wants(c, pass, cand, nc, &next, &pass->memory, in_flight);
    if (keep < pass->wl.n && in_flight == 0) {
        /* blocked by the ceiling with nothing on its way: the view cannot
         * complete at this tolerance, so raise it (as over the target) */
        c->last_blocked = t;
        if (t - c->last_budget_step > 0.1 && c->tolerance_factor < MAX_TOLERANCE_FACTOR) {
            c->tolerance_factor *= M_SQRT2;
            c->last_budget_step = t;
        }
    }
    pass->wl.n = keep;
    free(cand);
}
