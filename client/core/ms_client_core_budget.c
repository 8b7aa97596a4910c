/* The client core's memory budget (ms_client_core.h, "Memory budget"): what
 * the decoded cells hold, the steps that keep it near the target, eviction of
 * hidden cells, and the ceiling on loading. Decode thread only, except the
 * shared budget (ms_core_budget), which has its own mutex.
 *
 * Over the target the budget gives up what the view no longer shows before
 * anything it shows: first the cached cells (hidden, culled ones first), then
 * precision outside the frustum (the culled give-up: culled cells' need
 * lowered CULLED_GIVE_UP_STEP bits a step, so what left the view merges and its
 * bytes become cached, hence evictable), and only then the screen tolerance
 * of the cells in view. It gives them back in the reverse order, a step at a
 * time, when a what-if selection at the finer step says the cut would fit
 * under 90 % of the target (before, it waited for memory to fall below 70 %
 * of the target, so after a zoom-in whose close-up fits the budget but not
 * in 70 % of it the tolerance stayed raised for good). A what-if cannot see
 * all that a finer cut will hold (reception buffers grow by doubling): when
 * the cut it stepped to goes over the ceiling, no step goes that fine again
 * for TOO_FINE_SECONDS, or the view would swing between two tolerances and
 * never complete.
 *
 * A shared budget changes three things and nothing else: the memory compared
 * with the target and ceiling is every member's (each publishes its own after
 * each pass, with what its plan accepted as on its way; members plan one at
 * a time), the tolerance factor is one for all members, and a core evicts a
 * hidden cell only when it is the least useful candidate of all the members
 * (or when another member was refused a range at least one bit more useful).
 * Without one the figures below reduce to the core's own: others 0, the
 * others' least useful candidate +infinity, nothing refused elsewhere. */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "ms_progress.h"

typedef struct budget_member {
    bool used;
    uint64_t memory;
    uint64_t in_flight; /* on its way: requested (or received, not yet taken), or
                           accepted by its last plan and not yet arrived */
    uint64_t finer_memory;  /* what its cut would hold one step finer (what-if); memory
                               when it did not ask */
    double least_useful;   /* usefulness of its least useful eviction candidate; +inf none */
    double refused_need;   /* usefulness of the want the ceiling refused it last pass */
    uint64_t refused_bytes; /* that want's bytes; 0 none */
} budget_member;

struct ms_core_budget {
    pthread_mutex_t lock;
    /* One member plans at a time (ms_core_budget_step: read the others'
     * figures, accept wants, publish), so that two members never both accept
     * wants against figures that leave out the other's: taken before lock,
     * never under it. */
    pthread_mutex_t planning;
    uint64_t target, ceiling, peak;
    double tolerance_factor, culled_give_up;
    double last_step, last_blocked; /* ms_now_seconds */
    double too_fine_factor, too_fine_until; /* ms_core_decoder's, too_fine_until in ms_now_seconds */
    budget_member members[MS_CORE_BUDGET_MAX_MEMBERS];
};

ms_status ms_core_budget_new(uint64_t memory_target, uint64_t memory_ceiling,
                             ms_core_budget **budget, ms_error *err)
{
    *budget = NULL;
    if (!memory_ceiling)
        memory_ceiling = memory_target + memory_target / 4;
    if (!memory_target || memory_ceiling < memory_target)
        return ms_error_set(err, MS_ERR_ARG, "shared budget: the target must be above 0 and "
                            "at most the ceiling");
    ms_core_budget *b = calloc(1, sizeof *b);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a shared budget");
    pthread_mutex_init(&b->lock, NULL);
    pthread_mutex_init(&b->planning, NULL);
    b->target = memory_target;
    b->ceiling = memory_ceiling;
    b->tolerance_factor = 1.0;
    b->culled_give_up = 0.0;
    b->last_step = ms_now_seconds();
    b->last_blocked = -1e9;
    b->too_fine_until = -1e9;
    *budget = b;
    return MS_OK;
}

void ms_core_budget_free(ms_core_budget *b)
{
    if (!b)
        return;
    pthread_mutex_destroy(&b->lock);
    pthread_mutex_destroy(&b->planning);
    free(b);
}

static uint64_t members_held_locked(const ms_core_budget *b)
{
    uint64_t m = 0;
    for (int i = 0; i < MS_CORE_BUDGET_MAX_MEMBERS; ++i)
        if (b->members[i].used)
            m += b->members[i].memory;
    return m;
}

uint64_t ms_core_budget_held(ms_core_budget *b)
{
    pthread_mutex_lock(&b->lock);
    uint64_t m = members_held_locked(b);
    pthread_mutex_unlock(&b->lock);
    return m;
}

uint64_t ms_core_budget_peak(ms_core_budget *b)
{
    pthread_mutex_lock(&b->lock);
    uint64_t m = b->peak;
    pthread_mutex_unlock(&b->lock);
    return m;
}

ms_status ms_core_budget_join(ms_core_budget *b, int *member, ms_error *err)
{
    pthread_mutex_lock(&b->lock);
    int found = -1;
    for (int i = 0; i < MS_CORE_BUDGET_MAX_MEMBERS && found < 0; ++i)
        if (!b->members[i].used)
            found = i;
    if (found >= 0)
        b->members[found] = (budget_member){.used = true, .least_useful = INFINITY};
    pthread_mutex_unlock(&b->lock);
    *member = found;
    if (found < 0)
        return ms_error_set(err, MS_ERR_ARG, "shared budget: already %d cores share it",
                            MS_CORE_BUDGET_MAX_MEMBERS);
    return MS_OK;
}

void ms_core_budget_leave(ms_core_budget *b, int member)
{
    pthread_mutex_lock(&b->lock);
    b->members[member] = (budget_member){0};
    pthread_mutex_unlock(&b->lock);
}

void ms_core_budget_sync(ms_core *c)
{
    if (!c->shared)
        return;
    pthread_mutex_lock(&c->shared->lock);
    c->dec.tolerance_factor = c->shared->tolerance_factor;
    c->dec.culled_give_up = c->shared->culled_give_up;
    pthread_mutex_unlock(&c->shared->lock);
}

/* The budget a pass answers to. */
typedef struct budget_terms {
    uint64_t target, ceiling;
    uint64_t others_memory;     /* held by the other members */
    uint64_t others_planned;    /* held and in flight */
    uint64_t others_finer;      /* what they would hold one step finer */
    double others_least;        /* the other members' least useful candidate */
    double refused_need;        /* the most useful want another member was refused */
    uint64_t refused_bytes;
} budget_terms;

static budget_terms read_terms(const ms_core *c)
{
    budget_terms bt = {c->o.memory_target, c->o.memory_ceiling, 0, 0, 0, INFINITY, -INFINITY, 0};
    ms_core_budget *b = c->shared;
    if (!b)
        return bt;
    pthread_mutex_lock(&b->lock);
    bt.target = b->target, bt.ceiling = b->ceiling;
    for (int i = 0; i < MS_CORE_BUDGET_MAX_MEMBERS; ++i) {
        const budget_member *m = &b->members[i];
        if (!m->used || i == c->member)
            continue;
        bt.others_memory += m->memory;
        bt.others_planned += m->memory + m->in_flight;
        bt.others_finer += m->finer_memory;
        bt.others_least = fmin(bt.others_least, m->least_useful);
        if (m->refused_bytes && m->refused_need > bt.refused_need)
            bt.refused_need = m->refused_need, bt.refused_bytes = m->refused_bytes;
    }
    pthread_mutex_unlock(&b->lock);
    return bt;
}

static void publish(ms_core *c, uint64_t memory, uint64_t in_flight, uint64_t finer_memory,
                    double least_useful, double refused_need, uint64_t refused_bytes)
{
    ms_core_budget *b = c->shared;
    if (!b)
        return;
    pthread_mutex_lock(&b->lock);
    b->members[c->member] = (budget_member){true, memory, in_flight, finer_memory, least_useful,
                                            refused_need, refused_bytes};
    uint64_t held = members_held_locked(b);
    if (held > b->peak)
        b->peak = held;
    pthread_mutex_unlock(&b->lock);
}

/* The tolerance factor and its step times: the shared ones are copied into the
 * core's fields between factor_begin and factor_end (the budget locked). */
static void factor_begin(ms_core *c)
{
    ms_core_budget *b = c->shared;
    if (!b)
        return;
    pthread_mutex_lock(&b->lock);
    c->dec.tolerance_factor = b->tolerance_factor;
    c->dec.culled_give_up = b->culled_give_up;
    c->dec.last_budget_step = b->last_step - c->t0;
    c->dec.last_blocked = b->last_blocked - c->t0;
    c->dec.too_fine_factor = b->too_fine_factor;
    c->dec.too_fine_until = b->too_fine_until - c->t0;
}

static void factor_end(ms_core *c)
{
    ms_core_budget *b = c->shared;
    if (!b)
        return;
    b->tolerance_factor = c->dec.tolerance_factor;
    b->culled_give_up = c->dec.culled_give_up;
    b->last_step = c->dec.last_budget_step + c->t0;
    b->last_blocked = c->dec.last_blocked + c->t0;
    b->too_fine_factor = c->dec.too_fine_factor;
    b->too_fine_until = c->dec.too_fine_until + c->t0;
    pthread_mutex_unlock(&b->lock);
}

/* What a cell holds: payload bytes and, shown (or split with its decoder),
 * its decoded estimate. */
static uint64_t cell_memory(const ms_core *c, uint32_t cell)
{
    const dcell *d = ms_core_dcell(c, cell);
    uint64_t m = ms_view_held_bytes(c->dec.view, cell) + d->geo.cap + d->apo.cap + d->col.cap;
    ms_view_cell_state state = ms_view_state(c->dec.view, cell);
    if (state == MS_VIEW_SHOWN || (state == MS_VIEW_SPLIT && ms_view_holds_decoder(c->dec.view, cell)))
        m += (uint64_t)ms_sched_decoded_estimate(ms_archive_get_cell(c->index, cell),
                                                ms_view_bits(c->dec.view, cell));
    return m;
}

typedef ms_sched_candidate evict_candidate;

static void evict(ms_core *c, const evict_candidate *e)
{
    uint32_t cell = e->cell;
    if (c->o.eviction_hook)
        c->o.eviction_hook(cell, e->visible, c->dec.tolerance_factor, c->dec.culled_give_up,
                           c->o.eviction_hook_arg);
    dcell *d = ms_core_dcell(c, cell);
    ms_view_forget(c->dec.view, cell, NULL);
    ms_core_rx_free(&d->geo);
    ms_core_apo_drop(d);
    ms_core_rx_free(&d->col);
    free(d->header);
    d->header = NULL;
    d->given = d->apo_given = d->colour_given = 0;
    pthread_mutex_lock(&c->lock);
    c->stats.evictions++;
    pthread_mutex_unlock(&c->lock);
}

/* What every cell holds, and with an index by subtree the index's subtrees
 * and the per-cell state of their cells (a whole index and its state are held
 * whatever the view), the budget's measure. */
static uint64_t memory_held(const ms_core *c)
{
    uint64_t m = c->dec.by_subtree ? c->dec.index_bytes_held + ms_core_state_bytes_held(c) : 0;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i))
        m += cell_memory(c, i);
    return m;
}

/* Hidden cells the view does not target that hold memory, least useful first
 * (culled ones least: the scheduler's ranking); *count of them. NULL (and 0)
 * when there is none or no memory for the list. */
static evict_candidate *evict_candidates(ms_core *c, const frame_view *fv, size_t *count)
{
    uint32_t n = ms_view_known_count(c->dec.view);
    *count = 0;
    evict_candidate *cand = malloc((n ? n : 1) * sizeof *cand);
    ms_sched_cell *cells = malloc((n ? n : 1) * sizeof *cells);
    if (!cand || !cells) {
        free(cells);
        free(cand);
        return NULL;
    }
    size_t k = 0;
    for (uint32_t i = ms_view_next_known(c->dec.view, 0); i != MS_ARCHIVE_NONE;
         i = ms_view_next_known(c->dec.view, i))
        if (ms_view_state(c->dec.view, i) == MS_VIEW_HIDDEN &&
            ms_view_target(c->dec.view, i) == MS_VIEW_TARGET_HIDDEN)
            cells[k++] = (ms_sched_cell){.id = i, .state = MS_VIEW_HIDDEN,
                                         .target = MS_VIEW_TARGET_HIDDEN,
                                         .held = cell_memory(c, i)};
    *count = ms_sched_rank_evictions(c->index, fv, c->o.frustum_margin, cells, k, cand);
    free(cells);
    return cand;
}

/* Evicts hidden cells the view does not target, least useful first, until
 * memory is at most limit, none more useful than at_most. */
static void evict_unneeded(ms_core *c, const frame_view *fv, uint64_t limit, double at_most)
{
    size_t nc;
    evict_candidate *cand = evict_candidates(c, fv, &nc);
    uint64_t m = memory_held(c);
    for (size_t k = 0; k < nc && m > limit && cand[k].usefulness <= at_most; ++k) {
        m -= cand[k].bytes < m ? cand[k].bytes : m;
        evict(c, &cand[k]);
    }
    free(cand);
}

/* Under a budget a split cell keeps no decoder: its complex at bits_max is
 * what its children hold, refined, and on a close-up the ancestors held most
 * of the decoded memory (a merge decodes it again from its bytes). */
static void drop_split_decoders(ms_core *c)
{
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i))
        if (ms_view_state(c->dec.view, i) == MS_VIEW_SPLIT) {
            if (ms_view_holds_decoder(c->dec.view, i))
                (void)ms_view_drop_decoder(c->dec.view, i, NULL);
            /* nor APO: a split cell is not drawn */
            dcell *d = ms_core_dcell(c, i);
            if (d->apo.cap) {
                ms_core_apo_drop(d);
            }
        }
}

/* Over the target with the cache spent: the APO chunks of shown cells
 * outside the view (fetched while they were in it; a culled cell fetches
 * none) go before any precision; returns the bytes freed. */
static uint64_t drop_culled_apo(ms_core *c, dec_pass *pass)
{
    uint64_t freed = 0;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i)) {
        dcell *d = ms_core_dcell(c, i);
        if (!d->apo.cap || ms_view_state(c->dec.view, i) != MS_VIEW_SHOWN)
            continue;
        bool visible;
        (void)ms_core_cell_need(c, &pass->fv, i, &visible);
        if (visible)
            continue;
        freed += d->apo.cap;
        if (c->o.eviction_hook)
            c->o.eviction_hook(i, false, c->dec.tolerance_factor, c->dec.culled_give_up,
                               c->o.eviction_hook_arg);
        ms_core_apo_drop(d);
        pass->changed = true;
    }
    return freed;
}

/* Selects and applies the view for the pass's tolerance; false when decoding
 * failed (the core is then fatal). */
static bool reselect(ms_core *c, dec_pass *pass)
{
    ms_view_apply_report report;
    ms_error err;
    ms_view_select(c->dec.view, pass->cam, &pass->sp, &c->dec.report);
    if (ms_view_apply(c->dec.view, &report, &err) != MS_OK) {
        pthread_mutex_lock(&c->lock);
        ms_core_fail_locked(c, "decoding failed: %.200s", err.text);
        pthread_mutex_unlock(&c->lock);
        return false;
    }
    return true;
}

/* The pass's selection parameters for the core's factor and give-up. */
static void pass_params(const ms_core *c, dec_pass *pass)
{
    pass->fv.tolerance = pass->sp.tolerance_px = pass->base_tol * c->dec.tolerance_factor;
    pass->sp.culled_bits_less = c->o.culled_bits_less + c->dec.culled_give_up;
}

static uint64_t what_if_memory(ms_core *c, dec_pass *pass, double factor, double give_up);

bool ms_core_budget_ceiling(ms_core *c, dec_pass *pass)
{
    if (c->o.memory_target || c->shared)
        drop_split_decoders(c);
    /* Hard ceiling: evict what the view does not need; if that is not enough,
     * give up at once every bit outside the view it can, then coarsen the
     * view (double the tolerance), evicting what each step frees. */
    for (int round = 0; round < 8; ++round) {
        budget_terms bt = read_terms(c);
        if (!bt.ceiling || memory_held(c) + bt.others_memory <= bt.ceiling)
            break;
        uint64_t limit = (uint64_t)(0.9 * bt.target);
        evict_unneeded(c, &pass->fv, limit > bt.others_memory ? limit - bt.others_memory : 0,
                       bt.others_least);
        /* shared: another member holds less useful cells; it evicts them */
        if (memory_held(c) + bt.others_memory <= bt.ceiling || bt.others_least < INFINITY)
            break;
        /* the cut selected now would fit: what is over is a transient (bytes
         * arriving, another member's figure from its last pass) that the view
         * sheds by itself; coarsening for it would throw the view away, a
         * doubling a round, down to its root */
        double give_up = pass->sp.culled_bits_less - c->o.culled_bits_less;
        if (what_if_memory(c, pass, pass->factor, give_up) + bt.others_memory <= bt.ceiling)
            break;
        factor_begin(c);
        if (round == 0) { /* the pass's own factor (later rounds see what it still holds) */
            double t = ms_core_since_start(c);
            c->dec.too_fine_factor = t < c->dec.too_fine_until ? fmax(c->dec.too_fine_factor, pass->factor)
                                                                : pass->factor;
            c->dec.too_fine_until = t + TOO_FINE_SECONDS;
        }
        bool at_most = c->dec.tolerance_factor >= MAX_TOLERANCE_FACTOR &&
                       c->dec.culled_give_up >= MAX_CULLED_GIVE_UP;
        if (c->dec.culled_give_up < MAX_CULLED_GIVE_UP)
            c->dec.culled_give_up = MAX_CULLED_GIVE_UP;
        else if (!at_most)
            c->dec.tolerance_factor *= 2;
        if (!at_most)
            c->dec.last_budget_step = ms_core_since_start(c);
        factor_end(c);
        if (at_most)
            break;
        pass->factor = c->dec.tolerance_factor;
        pass_params(c, pass);
        if (!reselect(c, pass))
            return false;
        drop_split_decoders(c);
        pass->changed = true;
    }
    return true;
}

/* One step coarser (every 0.1 s at most): first CULLED_GIVE_UP_STEP
 * bits off the cells outside the view, and only when those are at their
 * coarsest, the tolerance of the view half a bit (x1.41). */
static void coarsen_step(ms_core *c, double t)
{
    factor_begin(c);
    if (t - c->dec.last_budget_step > 0.1) {
        if (c->dec.culled_give_up < MAX_CULLED_GIVE_UP) {
            c->dec.culled_give_up = fmin(MAX_CULLED_GIVE_UP, c->dec.culled_give_up + CULLED_GIVE_UP_STEP);
            c->dec.last_budget_step = t;
        } else if (c->dec.tolerance_factor < MAX_TOLERANCE_FACTOR) {
            c->dec.tolerance_factor = fmin(MAX_TOLERANCE_FACTOR, c->dec.tolerance_factor * M_SQRT2);
            c->dec.last_budget_step = t;
        }
    }
    factor_end(c);
}

/* The step back, finer, from (factor, give_up): the view's tolerance first,
 * then the bits outside the view. False when at the finest already. */
static bool finer_step(double factor, double give_up, double *finer_factor,
                       double *finer_give_up)
{
    *finer_factor = factor, *finer_give_up = give_up;
    if (factor > 1.0)
        *finer_factor = fmax(1.0, factor / M_SQRT2);
    else if (give_up > 0.0)
        *finer_give_up = fmax(0.0, give_up - CULLED_GIVE_UP_STEP);
    else
        return false;
    return true;
}

/* What the cut would hold with the selection at (factor, give_up): every cell
 * it would show or split, at that precision (its payload prefix, or what it
 * holds if more, its APO bytes and its decoded estimate), and the index and
 * state held; cached cells are left out (they are evicted first). A what-if:
 * the view's targets are the pass's again after it. */
static uint64_t what_if_memory(ms_core *c, dec_pass *pass, double factor, double give_up)
{
    ms_view_select_params sp = pass->sp;
    sp.tolerance_px = pass->base_tol * factor;
    sp.culled_bits_less = c->o.culled_bits_less + give_up;
    ms_view_select(c->dec.view, pass->cam, &sp, &c->dec.what_if_report);
    uint64_t m = c->dec.by_subtree ? c->dec.index_bytes_held + ms_core_state_bytes_held(c) : 0;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i)) {
        uint8_t target = ms_view_target(c->dec.view, i);
        if (target == MS_VIEW_TARGET_HIDDEN)
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        unsigned bits = target == MS_VIEW_TARGET_SPLIT ? rec->bits_max : target;
        const dcell *d = ms_core_dcell(c, i);
        uint64_t held = ms_view_held_bytes(c->dec.view, i) + d->geo.cap;
        uint64_t prefix = ms_archive_geometry_prefix(c->index, i, bits);
        m += (held > prefix ? held : prefix) + d->apo.cap;
        if (target != MS_VIEW_TARGET_SPLIT) /* a split cell's decoder is dropped */
            m += (uint64_t)ms_sched_decoded_estimate(rec, bits);
    }
    ms_view_select(c->dec.view, pass->cam, &pass->sp, &c->dec.report);
    return m;
}

/* Below the target: one step finer when the cut would then fit under 90 % of
 * it (the others' cuts too, with a shared budget: each member publishes what
 * its cut would hold one step finer), at most every 0.1 s and not within 2 s
 * of loading having been blocked. *finer_memory: this core's what-if (its
 * memory when there is no finer step to weigh). */
static void relax_step(ms_core *c, dec_pass *pass, const budget_terms *bt, double t,
                       uint64_t *finer_memory)
{
    *finer_memory = pass->memory;
    factor_begin(c);
    double factor = c->dec.tolerance_factor, give_up = c->dec.culled_give_up;
    bool due = t - c->dec.last_budget_step > 0.1 && t - c->dec.last_blocked > 2.0;
    double too_fine = c->dec.too_fine_factor, too_fine_until = c->dec.too_fine_until;
    factor_end(c);
    double finer_factor, finer_give_up;
    if (!finer_step(factor, give_up, &finer_factor, &finer_give_up))
        return;
    if (t < too_fine_until && finer_factor <= too_fine * (1.0 + 1e-9))
        return;
    *finer_memory = what_if_memory(c, pass, finer_factor, finer_give_up);
    if (!due || *finer_memory + bt->others_finer > 0.9 * (double)bt->target)
        return;
    factor_begin(c);
    /* shared: another member may have stepped meanwhile; step from where it is */
    if (c->dec.tolerance_factor == factor && c->dec.culled_give_up == give_up) {
        c->dec.tolerance_factor = finer_factor;
        c->dec.culled_give_up = finer_give_up;
        c->dec.last_budget_step = t;
    }
    factor_end(c);
}

/* What loading a want adds to the budget's measure: the bytes the view will
 * hold, the growth of the reception buffer that takes them (it doubles, and
 * its capacity is counted) and the decoded growth. */
static uint64_t want_bytes(const ms_core *c, const want *w)
{
    const dcell *d = ms_core_dcell(c, w->cell);
    const rx *r = w->stream == STREAM_APO      ? &d->apo
                  : w->stream == STREAM_COLOUR ? &d->col
                                               : &d->geo;
    return (uint64_t)(w->end - w->start) + (ms_core_rx_cap_for(r, w->end) - r->cap) +
           w->decoded_growth;
}

/* The root's geometry up to MS_ARCHIVE_ROOT_FLOOR_BITS, the model's coarsest
 * picture: loaded whatever the budget, as the index subtrees are, so that no
 * model in view vanishes under a tight one. */
static bool root_floor_want(const ms_core *c, const want *w)
{
    return w->cell == 0 && w->stream == STREAM_GEOMETRY && c->index &&
           w->end <= ms_archive_geometry_prefix(c->index, 0, MS_ARCHIVE_ROOT_FLOOR_BITS);
}

/* Loading stays under the ceiling; to make room, evicts only cells clearly
 * (one bit) less useful than the one being loaded (candidates from *next on).
 * Returns how many of the pass's wants fit; the first refused one's
 * usefulness and bytes in *refused_need, *refused_bytes (0: none). */
static size_t fit_wants(ms_core *c, dec_pass *pass, const evict_candidate *cand, size_t nc,
                        size_t *next, uint64_t *memory, uint64_t in_flight,
                        const budget_terms *bt, double *refused_need, uint64_t *refused_bytes,
                        uint64_t *accepted)
{
    /* Loading plans to 1/64 under the ceiling: what it cannot see in advance
     * (an index subtree of unknown size, the per-cell state a decoded level
     * adds, the other members' first wants, which go past the ceiling since
     * no cut can start without them) comes out of that margin, not over the
     * ceiling (a far view's root index, 235 bytes, once went over it after
     * the near view had planned to the byte) */
    uint64_t ceiling = bt->ceiling ? bt->ceiling - bt->ceiling / 64 : UINT64_MAX;
    uint64_t planned = *memory + in_flight + bt->others_planned;
    *refused_need = -INFINITY;
    *refused_bytes = 0;
    *accepted = 0;
    size_t keep = 0;
    for (; keep < pass->wl.n; ++keep) {
        const want *w = &pass->wl.w[keep];
        if (w->stream == STREAM_INDEX || ms_core_content_want(c, w) || root_floor_want(c, w))
            continue; /* a subtree (the root's first bits) is small, and the cut cannot
                         refine (the model cannot be placed) without it; nor can the
                         model be seen without its root's first bits */
        uint64_t need_bytes = want_bytes(c, w);
        if (planned + need_bytes <= ceiling) {
            planned += need_bytes;
            *accepted += need_bytes;
            continue;
        }
        bool visible;
        double u = ms_core_cell_need(c, &pass->fv, w->cell, &visible);
        if (!visible)
            u -= 64.0;
        while (planned + need_bytes > ceiling && *next < nc && cand[*next].usefulness + 1.0 < u) {
            planned -= cand[*next].bytes < planned ? cand[*next].bytes : planned;
            *memory -= cand[*next].bytes < *memory ? cand[*next].bytes : *memory;
            evict(c, &cand[(*next)++]);
        }
        if (planned + need_bytes > ceiling) {
            *refused_need = u;
            *refused_bytes = need_bytes;
            break;
        }
        planned += need_bytes;
        *accepted += need_bytes;
    }
    return keep;
}

void ms_core_budget_step(ms_core *c, dec_pass *pass)
{
    pass->memory = memory_held(c);
    pthread_mutex_lock(&c->lock);
    /* bytes received and not yet taken are held, though not yet counted */
    uint64_t in_flight = c->bytes_in_flight + c->bytes_queued;
    pthread_mutex_unlock(&c->lock);
    if (!c->o.memory_target && !c->shared)
        return;
    if (c->shared)
        pthread_mutex_lock(&c->shared->planning);
    budget_terms bt = read_terms(c);
    double t = ms_core_since_start(c);
    size_t nc;
    evict_candidate *cand = evict_candidates(c, &pass->fv, &nc);
    size_t next = 0;
    /* over the target: free down to 90 % of it, least useful first (of all
     * the members: shared, this core evicts while it holds the least useful);
     * cached cells go before anything shown is coarsened */
    if (pass->memory + bt.others_memory > bt.target)
        while (pass->memory + bt.others_memory > 0.9 * bt.target && next < nc &&
               cand[next].usefulness <= bt.others_least) {
            pass->memory -= cand[next].bytes;
            evict(c, &cand[next++]);
        }
    /* another member was refused a range clearly (one bit) more useful than
     * this core's candidates: make room for it */
    while (bt.refused_bytes && next < nc && cand[next].usefulness + 1.0 < bt.refused_need &&
           pass->memory + in_flight + bt.others_planned + bt.refused_bytes > bt.ceiling) {
        pass->memory -= cand[next].bytes < pass->memory ? cand[next].bytes : pass->memory;
        evict(c, &cand[next++]);
    }
    /* still over the target with the cache spent: the cut itself is too big,
     * so a step coarser (outside the view first); below it, perhaps finer */
    uint64_t finer_memory = pass->memory;
    if (pass->memory + bt.others_memory > bt.target) {
        uint64_t freed = drop_culled_apo(c, pass);
        pass->memory -= freed < pass->memory ? freed : pass->memory;
    }
    if (pass->memory + bt.others_memory > bt.target)
        coarsen_step(c, t);
    else
        relax_step(c, pass, &bt, t, &finer_memory);
    double refused_need;
    uint64_t refused_bytes, accepted;
    size_t keep = fit_wants(c, pass, cand, nc, &next, &pass->memory, in_flight, &bt,
                            &refused_need, &refused_bytes, &accepted);
    if (keep < pass->wl.n && in_flight == 0) {
        /* blocked by the ceiling with nothing on its way: the view cannot
         * complete at this tolerance, so a step coarser (as over the target) */
        factor_begin(c);
        c->dec.last_blocked = t;
        factor_end(c);
        coarsen_step(c, t);
        if (pass->factor >= MAX_TOLERANCE_FACTOR && !c->dec.budget_floor_warned) {
            /* nothing more can be given up: this pass selected at the coarsest
             * and is still blocked, so the view cannot complete in this budget,
             * which the user must hear once rather than wait. The warning goes
             * out with this pass's figures (ms_core_publish), never before the
             * tolerance it names. */
            snprintf(pass->warning, sizeof pass->warning,
                     "memory budget too small: %.2f MB cannot hold this view even at its "
                     "coarsest (the tolerance is %.0fx)",
                     (double)bt.ceiling / 1048576.0, MAX_TOLERANCE_FACTOR);
            c->dec.budget_floor_warned = true;
        }
    }
    pass->wl.n = keep;
    /* What this plan accepted is on its way as far as the others are
     * concerned (the local responder's bytes were counted nowhere until
     * they arrived); the larger of it and what is in flight, since the
     * wants list the ranges already requested again. */
    publish(c, pass->memory, accepted > in_flight ? accepted : in_flight, finer_memory,
            next < nc ? cand[next].usefulness : INFINITY, refused_need, refused_bytes);
    if (c->shared)
        pthread_mutex_unlock(&c->shared->planning);
    free(cand);
}
