/* The client core's scheduler (ms_core_sched.h): for one pass's snapshot,
 * what each cell still needs and in which order to ask for it (the request
 * order of docs/CLIENT.md: priority by the screen error each missing bit
 * removes), and the index subtrees the cut needs. Pure: reads the snapshot
 * and the index, writes the plan. */
#include "ms_core_sched.h"

#include <math.h>
#include <stdlib.h>

#include "ms_preview.h"
#include "ms_subtree.h"
#include "ms_view_decoder.h"

double ms_sched_cell_side(const ms_archive_header *h, const ms_archive_cell *rec)
{
    double side = h->box_side;
    for (unsigned l = 0; l < rec->level; ++l)
        side /= h->n;
    return side;
}

void ms_sched_cell_box(const ms_archive_header *h, const ms_archive_cell *rec, double lo[3],
                       double hi[3])
{
    double side = ms_sched_cell_side(h, rec);
    for (int a = 0; a < 3; ++a) {
        lo[a] = h->box_origin[a] + side * rec->position[a];
        hi[a] = lo[a] + side;
    }
}

double ms_sched_cell_need(const ms_archive *index, const frame_view *fv, double margin,
                          uint32_t cell, bool *visible)
{
    const ms_archive_header *h = ms_archive_get_header(index);
    double lo[3], hi[3];
    const ms_archive_cell *rec = ms_archive_get_cell(index, cell);
    ms_sched_cell_box(h, rec, lo, hi);
    *visible = ms_frustum_keeps_box(&fv->frustum, lo, hi, margin);
    double d = ms_camera_box_distance(&fv->cam, lo, hi);
    double ppu = d > 0 ? ms_camera_pixels_per_unit(&fv->cam) / d : INFINITY;
    double need = ms_archive_bits_needed(h, rec, ppu, fv->tolerance);
    return isfinite(need) ? need : 64.0;
}

bool ms_sched_cell_visible(const ms_archive *index, const frame_view *fv, double margin,
                           uint32_t cell)
{
    double lo[3], hi[3];
    ms_sched_cell_box(ms_archive_get_header(index), ms_archive_get_cell(index, cell), lo, hi);
    return ms_frustum_keeps_box(&fv->frustum, lo, hi, margin);
}

unsigned ms_sched_goal(const ms_archive_cell *rec, uint32_t cell, uint8_t target,
                       unsigned root_goal_min)
{
    unsigned goal = target == MS_VIEW_TARGET_SPLIT || target == MS_VIEW_TARGET_HIDDEN
                        ? rec->bits_max : target;
    if (goal > rec->bits_max)
        goal = rec->bits_max;
    if (cell == 0 && goal < root_goal_min)
        goal = root_goal_min; /* the root's bytes the content bounds need */
    return goal;
}

uint8_t ms_sched_clamp_priority(double p)
{
    return p < 0 ? 0 : p > 255 ? 255 : (uint8_t)p;
}

/* Decoded bytes of a cell shown at `bits` (an estimate: the vertex count
 * grows about 4x a bit on a surface). */
double ms_sched_decoded_estimate(const ms_archive_cell *rec, unsigned bits)
{
    if (rec->geometry_length == 0)
        return 0;
    double v = rec->vertex_count * ldexp(1.0, -2 * (int)(rec->bits_max - bits));
    return (v < 1 ? 1 : v) * BYTES_PER_VERTEX;
}

static int compare_wants(const void *x, const void *y)
{
    const want *a = x, *b = y;
    if (a->priority != b->priority)
        return a->priority < b->priority ? -1 : 1;
    if (a->cell != b->cell)
        return a->cell < b->cell ? -1 : 1;
    return a->start < b->start ? -1 : a->start > b->start;
}

static void push(ms_sched_plan *plan, want w)
{
    want_list *l = &plan->wl;
    if (l->n == l->cap) {
        size_t cap = l->cap ? l->cap * 2 : 256;
        want *g = realloc(l->w, cap * sizeof *g);
        if (!g) {
            plan->out_of_memory = true;
            return;
        }
        l->w = g;
        l->cap = cap;
    }
    l->w[l->n++] = w;
}

static uint32_t clamp_growth(double grow)
{
    return (uint32_t)(grow > 4e9 ? 4e9 : grow);
}

/* The snapshot's entry of a known cell (NULL: not known). */
static const ms_sched_cell *find_cell(const ms_sched_input *in, uint32_t id)
{
    size_t lo = 0, hi = in->cell_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (in->cells[mid].id < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < in->cell_count && in->cells[lo].id == id ? &in->cells[lo] : NULL;
}

/* The true error on screen of what shown cell c draws now: its error bound
 * projected at its cube's nearest point. */
static double cell_error_px(const ms_sched_input *in, const ms_sched_cell *c)
{
    const ms_archive_header *h = ms_archive_get_header(in->index);
    double lo[3], hi[3];
    ms_sched_cell_box(h, ms_archive_get_cell(in->index, c->id), lo, hi);
    double d = ms_camera_box_distance(&in->fv.cam, lo, hi);
    /* nothing nearer than the near plane is drawn */
    if (d < in->fv.cam.near_distance)
        d = in->fv.cam.near_distance;
    if (c->error_bound < 0)
        return ms_archive_cell_error(h, ms_archive_get_cell(in->index, c->id), c->bits) *
               ms_camera_pixels_per_unit(&in->fv.cam) / d;
    return c->error_bound * ms_camera_pixels_per_unit(&in->fv.cam) / d;
}

/* Geometry bits have..goal of cell c, from the received end, at priority
 * base - 8 (need - bit); `split_growth` adds the children's decoded bytes to
 * the last bit's growth. */
static void geometry_bits(const ms_sched_input *in, ms_sched_plan *plan, const ms_sched_cell *c,
                          unsigned have, unsigned goal, double base, double need,
                          bool split_growth)
{
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    for (unsigned s = have + 1; s <= goal; ++s) {
        uint32_t a = s == have + 1 ? c->geo_end : ms_archive_geometry_prefix(in->index, c->id, s - 1);
        uint32_t b = ms_archive_geometry_prefix(in->index, c->id, s);
        if (a < c->geo_end)
            a = c->geo_end;
        if (a >= b)
            continue;
        double p = base - 8.0 * (need - s);
        double grow = ms_sched_decoded_estimate(rec, s) - ms_sched_decoded_estimate(rec, s - 1);
        if (split_growth && s == rec->bits_max)
            grow += rec->vertex_count * BYTES_PER_VERTEX; /* the children */
        push(plan, (want){c->id, a, b, STREAM_GEOMETRY, ms_sched_clamp_priority(p),
                          clamp_growth(grow)});
    }
}

/* The children of a shown cell about to split can receive their bytes while
 * it finishes (they decode once it splits), which keeps the link busy across
 * the split: the hidden cell's missing bits, 16 later than a shown cell's. */
static void schedule_prefetch(const ms_sched_input *in, ms_sched_plan *plan,
                              const ms_sched_cell *c)
{
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    if (c->target == MS_VIEW_TARGET_HIDDEN || rec->parent == MS_ARCHIVE_NONE ||
        c->parent_state != MS_VIEW_SHOWN || rec->geometry_length == 0 || c->failed)
        return;
    unsigned goal = c->target == MS_VIEW_TARGET_SPLIT ? rec->bits_max : c->target;
    if (goal > rec->bits_max)
        goal = rec->bits_max;
    bool visible;
    double need = ms_sched_cell_need(in->index, &in->fv, in->margin, c->id, &visible);
    geometry_bits(in, plan, c, c->avail, goal, visible ? 144.0 : 208.0, need, false);
}

/* The missing precision bits of shown cell c up to `goal`, one want a bit;
 * true when the cell is loading. */
static bool schedule_geometry(const ms_sched_input *in, ms_sched_plan *plan,
                              const ms_sched_cell *c, unsigned goal, bool visible, double need)
{
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    if (goal <= c->avail || rec->geometry_length == 0)
        return false;
    plan->complete = false;
    if (c->failed)
        return false;
    geometry_bits(in, plan, c, c->avail, goal, visible ? 128.0 : 192.0, need,
                  c->target == MS_VIEW_TARGET_SPLIT);
    return true;
}

/* APO by footprint: down to the level whose texel projects to the detail
 * tolerance, at most apo_levels and what a preview lets this reader read
 * (ms_archive_preview_apo_levels); none for a cell about to split (its children
 * replace it as soon as its last bits arrive: on the demo close-up such
 * passing cells would take half the APO bytes). True when the cell is loading. */
static bool schedule_apo(const ms_sched_input *in, ms_sched_plan *plan, const ms_sched_cell *c,
                         bool visible, double need)
{
    const ms_archive_header *h = ms_archive_get_header(in->index);
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    if (!(in->apo_on && visible && rec->apo_length > 0 && !c->failed &&
          c->target != MS_VIEW_TARGET_SPLIT && !c->blocked))
        return false;
    unsigned cap = in->apo_levels < rec->apo_levels ? in->apo_levels : rec->apo_levels;
    if (in->preview_steps) {
        /* a preview reads no texel finer than its own grid step (the server's
         * rule, the same function) */
        unsigned readable = ms_archive_preview_apo_levels(h, rec, in->preview_steps);
        if (readable < cap)
            cap = readable;
        if (cap == 0)
            return false;
    }
    double lo[3], hi[3];
    ms_sched_cell_box(h, rec, lo, hi);
    unsigned levels = ms_apo_footprint_levels(&in->fv.cam, lo, ms_sched_cell_side(h, rec),
                                              in->apo_tolerance_px, cap);
    /* levels 0 .. levels - 1; ms_archive_apo_prefix(depth) ends depth's level */
    uint32_t b = ms_archive_apo_prefix(in->index, c->id, levels - 1, NULL);
    if (c->apo_end >= b)
        return false;
    plan->complete = false;
    for (unsigned l = 1; l <= levels; ++l) {
        uint32_t lb = ms_archive_apo_prefix(in->index, c->id, l - 1, NULL);
        uint32_t la = l == 1 ? 0 : ms_archive_apo_prefix(in->index, c->id, l - 2, NULL);
        if (la < c->apo_end)
            la = c->apo_end;
        if (la >= lb)
            continue;
        uint8_t priority = ms_sched_clamp_priority(136.0 + 8.0 * l - 8.0 * (need - c->bits));
        push(plan, (want){c->id, la, lb, STREAM_APO, priority, 0});
    }
    return true;
}

/* The colour stream of cell c up to `goal` bits, one want a bit, following
 * its geometry (docs/CLIENT.md); true when the cell is loading. */
static bool schedule_colour(const ms_sched_input *in, ms_sched_plan *plan,
                            const ms_sched_cell *c, unsigned goal, bool visible, double need)
{
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    if (!in->colour_on || rec->vertex_count == 0 || c->failed ||
        c->col_end >= ms_archive_colour_prefix(in->index, c->id, goal))
        return false;
    plan->complete = false;
    for (unsigned s = rec->bits_min; s <= goal; ++s) {
        uint32_t a = s == rec->bits_min ? 0 : ms_archive_colour_prefix(in->index, c->id, s - 1);
        uint32_t b = ms_archive_colour_prefix(in->index, c->id, s);
        if (a < c->col_end)
            a = c->col_end;
        if (a >= b)
            continue;
        double p = (visible ? 132.0 : 196.0) - 8.0 * (need - s);
        push(plan, (want){c->id, a, b, STREAM_COLOUR, ms_sched_clamp_priority(p), 0});
    }
    return true;
}

/* Shown cell c: its screen error, then its missing geometry, colour and APO bytes. */
static void schedule_shown(const ms_sched_input *in, ms_sched_plan *plan, const ms_sched_cell *c)
{
    const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
    plan->shown++;
    bool visible;
    double need = ms_sched_cell_need(in->index, &in->fv, in->margin, c->id, &visible);
    if (visible && rec->geometry_length > 0) {
        double e = cell_error_px(in, c);
        if (e > plan->worst)
            plan->worst = e;
    }
    unsigned goal = ms_sched_goal(rec, c->id, c->target, in->root_goal_min);
    /* its bytes are here but not yet decoded to the precision the view wants
     * (the goal may be more: the root's bytes the content bounds need): the
     * next pass draws it finer, so this one's cut is not the view's */
    unsigned shown_goal = c->target < rec->bits_max ? c->target : rec->bits_max;
    if (visible && c->target != MS_VIEW_TARGET_SPLIT && c->bits < shown_goal && c->avail >= shown_goal && !c->failed)
        plan->complete = false;
    bool loading = schedule_geometry(in, plan, c, goal, visible, need);
    loading |= schedule_colour(in, plan, c, goal, visible, need);
    loading |= schedule_apo(in, plan, c, visible, need);
    plan->loading += loading;
}

/* ---- the index's subtrees ------------------------------------------------------ */

static const ms_sched_subtree *find_subtree(const ms_sched_input *in, uint32_t id)
{
    size_t lo = 0, hi = in->subtree_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (in->subtrees[mid].id < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < in->subtree_count && in->subtrees[lo].id == id ? &in->subtrees[lo] : NULL;
}

/* Cell's children's subtree is needed: a held one stays, a missing one is
 * asked for at `priority` (none: < 0). */
static void need_children(const ms_sched_input *in, ms_sched_plan *plan, uint32_t cell,
                          double priority)
{
    uint32_t children = ms_archive_children_subtree(in->index, cell);
    if (children == MS_ARCHIVE_NONE || children == ms_archive_subtree_of(in->index, cell))
        return; /* a leaf, or its children are in its own subtree */
    if (plan->need_count == plan->need_cap) {
        size_t cap = plan->need_cap ? plan->need_cap * 2 : 64;
        ms_sched_need *g = realloc(plan->needs, cap * sizeof *g);
        if (!g) {
            plan->out_of_memory = true;
            return;
        }
        plan->needs = g;
        plan->need_cap = cap;
    }
    plan->needs[plan->need_count++] = (ms_sched_need){children, cell};
    const ms_sched_subtree *e = find_subtree(in, children);
    ms_sched_subtree fresh = {children, MS_SCHED_SUBTREE_RECEIVING, 0, 0};
    if (!e)
        e = &fresh; /* the decoder starts receiving it */
    if (e->state == MS_SCHED_SUBTREE_HELD)
        return;
    plan->complete = false;
    if (e->state == MS_SCHED_SUBTREE_RECEIVING)
        push(plan, (want){e->id, e->end, e->total ? e->total : UINT32_MAX, STREAM_INDEX,
                          ms_sched_clamp_priority(priority), 0});
}

/* The subtrees of the cut (docs/CLIENT.md, "An index by subtree"): the
 * children's of every cell split or about to split at a subtree's last level,
 * of the blocked cells (ahead of their next bit) and of the near ones
 * (prefetch, as the bits of a cell about to split). */
static void schedule_subtrees(const ms_sched_input *in, ms_sched_plan *plan)
{
    for (size_t k = 0; k < in->cell_count; ++k) {
        const ms_sched_cell *c = &in->cells[k];
        if (c->state == MS_VIEW_SPLIT || c->target == MS_VIEW_TARGET_SPLIT)
            need_children(in, plan, c->id, 0);
    }
    for (size_t k = 0; k < in->blocked_count; ++k) {
        uint32_t cell = in->blocked[k];
        const ms_archive_cell *rec = ms_archive_get_cell(in->index, cell);
        const ms_sched_cell *c = find_cell(in, cell);
        bool visible;
        double need = ms_sched_cell_need(in->index, &in->fv, in->margin, cell, &visible);
        unsigned next = c ? c->avail : 0;
        next = (next < rec->bits_max ? next : rec->bits_max) + 1;
        need_children(in, plan, cell, (visible ? 128.0 : 192.0) - 8.0 * (need - next) - 1.0);
    }
    for (size_t k = 0; k < in->near_count; ++k) {
        uint32_t cell = in->near[k];
        const ms_archive_cell *rec = ms_archive_get_cell(in->index, cell);
        bool visible;
        double need = ms_sched_cell_need(in->index, &in->fv, in->margin, cell, &visible);
        need_children(in, plan, cell,
                      (visible ? 144.0 : 208.0) - 8.0 * (need - (rec->bits_max + 1.0)));
    }
    /* a subtree that failed and is needed left the plan incomplete above
     * (need_children); one not needed is dropped by the decoder */
}

void ms_sched_plan_make(const ms_sched_input *in, ms_sched_plan *plan)
{
    plan->complete = true;
    for (size_t k = 0; k < in->cell_count; ++k) {
        const ms_sched_cell *c = &in->cells[k];
        plan->failed += c->failed;
        if (c->state == MS_VIEW_SPLIT) {
            plan->split++;
            /* its children take their base colours from its whole stream */
            const ms_archive_cell *rec = ms_archive_get_cell(in->index, c->id);
            bool visible;
            double need = ms_sched_cell_need(in->index, &in->fv, in->margin, c->id, &visible);
            plan->loading += schedule_colour(in, plan, c, rec->bits_max, visible, need);
        } else if (c->state == MS_VIEW_HIDDEN) {
            plan->cached += c->cached;
            schedule_prefetch(in, plan, c);
        } else {
            schedule_shown(in, plan, c);
        }
    }
    if (plan->failed)
        plan->complete = false;
    if (in->by_subtree)
        schedule_subtrees(in, plan);
    if (plan->wl.n)
        qsort(plan->wl.w, plan->wl.n, sizeof *plan->wl.w, compare_wants);
}

static int compare_candidates(const void *x, const void *y)
{
    const ms_sched_candidate *a = x, *b = y;
    return a->usefulness < b->usefulness ? -1 : a->usefulness > b->usefulness;
}

size_t ms_sched_rank_evictions(const ms_archive *index, const frame_view *fv, double margin,
                               const ms_sched_cell *cells, size_t n, ms_sched_candidate *out)
{
    size_t nc = 0;
    for (size_t k = 0; k < n; ++k) {
        if (!cells[k].held)
            continue;
        bool visible;
        double u = ms_sched_cell_need(index, fv, margin, cells[k].id, &visible);
        out[nc++] = (ms_sched_candidate){cells[k].id, visible ? u : u - 64.0, cells[k].held, visible};
    }
    if (nc)
        qsort(out, nc, sizeof *out, compare_candidates);
    return nc;
}

void ms_sched_plan_free(ms_sched_plan *plan)
{
    free(plan->wl.w);
    free(plan->needs);
    *plan = (ms_sched_plan){0};
}
