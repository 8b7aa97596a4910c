/* The client core's scheduling: for the pass's camera, what each cell still
 * needs and in which order to ask for it (the request order of
 * ms_client_core.h: priority by the screen error each missing bit removes). */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdlib.h>

#include "ms_preview.h"

/* The side of a cell's cube, world units. */
double ms_core_cell_side(const ms_archive_header *h, const ms_archive_cell *rec)
{
    double side = h->box_side;
    for (unsigned l = 0; l < rec->level; ++l)
        side /= h->n;
    return side;
}

void ms_core_cell_box(const ms_archive_header *h, const ms_archive_cell *rec, double lo[3],
                     double hi[3])
{
    double side = ms_core_cell_side(h, rec);
    for (int a = 0; a < 3; ++a) {
        lo[a] = h->box_origin[a] + side * rec->position[a];
        hi[a] = lo[a] + side;
    }
}

/* The precision (real bits) the camera wants of cell; *visible tells whether
 * its cube meets the frustum. */
double ms_core_cell_need(const ms_core *c, const frame_view *fv, uint32_t cell, bool *visible)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    double lo[3], hi[3];
    ms_core_cell_box(h, ms_archive_get_cell(c->index, cell), lo, hi);
    *visible = ms_frustum_keeps_box(&fv->frustum, lo, hi, c->o.frustum_margin);
    double d = ms_camera_box_distance(&fv->cam, lo, hi);
    double need = ms_screen_bits_needed(&fv->cam, h->box_side, d, fv->tolerance);
    return isfinite(need) ? need : 64.0;
}

/* The true error on screen of what shown cell `cell` draws now: its error
 * bound (ms_view_cell_error_bound) projected at its cube's nearest point. */
static double cell_error_px(const ms_core *c, const frame_view *fv, uint32_t cell, unsigned bits)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    double lo[3], hi[3];
    ms_core_cell_box(h, ms_archive_get_cell(c->index, cell), lo, hi);
    double d = ms_camera_box_distance(&fv->cam, lo, hi);
    /* nothing nearer than the near plane is drawn */
    if (d < fv->cam.near_distance)
        d = fv->cam.near_distance;
    double e = ms_view_cell_error_bound(c->view, cell);
    if (e < 0)
        return ms_screen_error_px(&fv->cam, h->box_side, bits, d);
    return e * ms_camera_pixels_per_unit(&fv->cam) / d;
}

uint8_t ms_core_clamp_priority(double p)
{
    return p < 0 ? 0 : p > 255 ? 255 : (uint8_t)p;
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

bool ms_core_want_push(want_list *l, want w)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? l->cap * 2 : 256;
        want *g = realloc(l->w, cap * sizeof *g);
        if (!g)
            return false;
        l->w = g;
        l->cap = cap;
    }
    l->w[l->n++] = w;
    return true;
}

/* Decoded bytes of a cell shown at `bits` (an estimate: the vertex count
 * grows about 4x a bit on a surface). */
double ms_core_decoded_estimate(const ms_archive_cell *rec, unsigned bits)
{
    if (rec->geometry_length == 0)
        return 0;
    double v = rec->vertex_count * ldexp(1.0, -2 * (int)(rec->bits_max - bits));
    return (v < 1 ? 1 : v) * BYTES_PER_VERTEX;
}

/* The children of a shown cell about to split can receive their bytes while
 * it finishes (they decode once it splits), which keeps the link busy across
 * the split: the hidden cell i's missing bits, 16 later than a shown cell's. */
static void schedule_prefetch(ms_core *c, dec_pass *pass, uint32_t i)
{
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    const dcell *d = ms_core_dcell(c, i);
    uint8_t t = ms_view_target(c->view, i);
    if (t == MS_VIEW_TARGET_HIDDEN || rec->parent == MS_ARCHIVE_NONE ||
        ms_view_state(c->view, rec->parent) != MS_VIEW_SHOWN || rec->geometry_length == 0 ||
        d->failed)
        return;
    unsigned goal = t == MS_VIEW_TARGET_SPLIT ? rec->bits_max : t;
    if (goal > rec->bits_max)
        goal = rec->bits_max;
    bool visible;
    double need = ms_core_cell_need(c, &pass->fv, i, &visible);
    unsigned have = ms_view_available_bits(c->view, i);
    for (unsigned s2 = have + 1; s2 <= goal; ++s2) {
        uint32_t a = s2 == have + 1 ? d->geo.end : ms_archive_geometry_prefix(c->index, i, s2 - 1);
        uint32_t b = ms_archive_geometry_prefix(c->index, i, s2);
        if (a < d->geo.end)
            a = d->geo.end;
        if (a >= b)
            continue;
        double p = (visible ? 144.0 : 208.0) - 8.0 * (need - s2);
        double grow = ms_core_decoded_estimate(rec, s2) - ms_core_decoded_estimate(rec, s2 - 1);
        ms_core_want_push(&pass->wl, (want){i, a, b, STREAM_GEOMETRY, ms_core_clamp_priority(p),
                                            (uint32_t)(grow > 4e9 ? 4e9 : grow)});
    }
}

/* The missing precision bits of shown cell i up to `goal`, one want a bit;
 * true when the cell is loading. */
static bool schedule_geometry(ms_core *c, dec_pass *pass, uint32_t i, unsigned goal,
                              unsigned avail, bool visible, double need)
{
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    const dcell *d = ms_core_dcell(c, i);
    if (goal <= avail || rec->geometry_length == 0)
        return false;
    pass->complete = false;
    if (d->failed)
        return false;
    for (unsigned s = avail + 1; s <= goal; ++s) {
        uint32_t a = s == avail + 1 ? d->geo.end : ms_archive_geometry_prefix(c->index, i, s - 1);
        uint32_t b = ms_archive_geometry_prefix(c->index, i, s);
        if (a < d->geo.end)
            a = d->geo.end;
        if (a >= b)
            continue;
        double p = (visible ? 128.0 : 192.0) - 8.0 * (need - s);
        double grow = ms_core_decoded_estimate(rec, s) - ms_core_decoded_estimate(rec, s - 1);
        if (s == rec->bits_max && ms_view_target(c->view, i) == MS_VIEW_TARGET_SPLIT)
            grow += rec->vertex_count * BYTES_PER_VERTEX; /* the children */
        ms_core_want_push(&pass->wl, (want){i, a, b, STREAM_GEOMETRY, ms_core_clamp_priority(p),
                                            (uint32_t)(grow > 4e9 ? 4e9 : grow)});
    }
    return true;
}

/* APO by footprint: down to the level whose texel projects to the detail
 * tolerance, at most apo_levels and what a preview lets this reader read
 * (ms_archive_preview_apo_levels); none for a cell about to split (its children
 * replace it as soon as its last bits arrive: on the demo close-up such
 * passing cells would take half the APO bytes). True when the cell is loading. */
static bool schedule_apo(ms_core *c, dec_pass *pass, uint32_t i, bool visible, double need,
                         unsigned bits)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    const dcell *d = ms_core_dcell(c, i);
    if (!(pass->apo_on && visible && rec->apo_length > 0 && !d->failed &&
          ms_view_target(c->view, i) != MS_VIEW_TARGET_SPLIT && !d->blocked))
        return false;
    unsigned cap = c->o.apo_levels < rec->apo_levels ? c->o.apo_levels : rec->apo_levels;
    if (c->preview_steps) {
        /* a preview reads no texel finer than its own grid step (the server's
         * rule, the same function) */
        unsigned readable = ms_archive_preview_apo_levels(h, rec, c->preview_steps);
        if (readable < cap)
            cap = readable;
        if (cap == 0)
            return false;
    }
    double lo[3], hi[3];
    ms_core_cell_box(h, rec, lo, hi);
    unsigned levels = ms_apo_footprint_levels(&pass->fv.cam, lo, ms_core_cell_side(h, rec),
                                              c->o.tolerance_px * c->tolerance_factor, cap);
    /* levels 0 .. levels - 1; ms_archive_apo_prefix(depth) ends depth's level */
    uint32_t b = ms_archive_apo_prefix(c->index, i, levels - 1, NULL);
    if (d->apo.end >= b)
        return false;
    pass->complete = false;
    for (unsigned l = 1; l <= levels; ++l) {
        uint32_t lb = ms_archive_apo_prefix(c->index, i, l - 1, NULL);
        uint32_t la = l == 1 ? 0 : ms_archive_apo_prefix(c->index, i, l - 2, NULL);
        if (la < d->apo.end)
            la = d->apo.end;
        if (la >= lb)
            continue;
        uint8_t priority = ms_core_clamp_priority(136.0 + 8.0 * l - 8.0 * (need - bits));
        ms_core_want_push(&pass->wl, (want){i, la, lb, STREAM_APO, priority, 0});
    }
    return true;
}

/* The colour stream of shown cell i up to `goal` bits, one want a bit,
 * following its geometry (docs/CLIENT.md); true when the cell is loading. */
static bool schedule_colour(ms_core *c, dec_pass *pass, uint32_t i, unsigned goal, bool visible,
                            double need)
{
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    const dcell *d = ms_core_dcell(c, i);
    if (!pass->colour_on || rec->vertex_count == 0 || d->failed ||
        d->col.end >= ms_archive_colour_prefix(c->index, i, goal))
        return false;
    pass->complete = false;
    for (unsigned s = rec->bits_min; s <= goal; ++s) {
        uint32_t a = s == rec->bits_min ? 0 : ms_archive_colour_prefix(c->index, i, s - 1);
        uint32_t b = ms_archive_colour_prefix(c->index, i, s);
        if (a < d->col.end)
            a = d->col.end;
        if (a >= b)
            continue;
        double p = (visible ? 132.0 : 196.0) - 8.0 * (need - s);
        ms_core_want_push(&pass->wl, (want){i, a, b, STREAM_COLOUR, ms_core_clamp_priority(p), 0});
    }
    return true;
}

/* Shown cell i: its screen error, then its missing geometry, colour and APO bytes. */
static void schedule_shown(ms_core *c, dec_pass *pass, uint32_t i)
{
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
    dcell *d = ms_core_dcell(c, i);
    pass->shown++;
    bool visible;
    double need = ms_core_cell_need(c, &pass->fv, i, &visible);
    unsigned bits = ms_view_bits(c->view, i);
    if (visible && rec->geometry_length > 0) {
        double e = cell_error_px(c, &pass->fv, i, bits);
        if (e > pass->worst)
            pass->worst = e;
    }
    uint8_t t = ms_view_target(c->view, i);
    unsigned goal = t == MS_VIEW_TARGET_SPLIT || t == MS_VIEW_TARGET_HIDDEN ? rec->bits_max : t;
    if (goal > rec->bits_max)
        goal = rec->bits_max;
    goal = ms_core_content_goal(c, i, goal); /* the root's bytes the bounds need */
    unsigned avail = ms_view_available_bits(c->view, i);
    d->goal_bytes = ms_archive_geometry_prefix(c->index, i, goal);
    if (d->pending)
        ms_core_hand_over(c, i);
    bool loading = schedule_geometry(c, pass, i, goal, avail, visible, need);
    loading |= schedule_colour(c, pass, i, goal, visible, need);
    loading |= schedule_apo(c, pass, i, visible, need, bits);
    pass->loading += loading;
}

void ms_core_schedule(ms_core *c, dec_pass *pass)
{
    pass->wl = (want_list){0};
    pass->worst = 0;
    pass->shown = pass->split = pass->cached = pass->loading = pass->failed = 0;
    pass->complete = true;
    /* a cell held back only by its children's records is about to split too */
    for (size_t k = 0; k < c->report.blocked_count; ++k)
        ms_core_dcell(c, c->report.blocked[k])->blocked = true;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->view, i)) {
        ms_view_cell_state st = ms_view_state(c->view, i);
        pass->failed += ms_core_dcell(c, i)->failed;
        if (st == MS_VIEW_SPLIT) {
            pass->split++;
            /* its children take their base colours from its whole stream */
            const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
            bool visible;
            double need = ms_core_cell_need(c, &pass->fv, i, &visible);
            pass->loading += schedule_colour(c, pass, i, rec->bits_max, visible, need);
        } else if (st == MS_VIEW_HIDDEN) {
            pass->cached += ms_view_held_bytes(c->view, i) > 0;
            schedule_prefetch(c, pass, i);
        } else {
            schedule_shown(c, pass, i);
        }
    }
    for (size_t k = 0; k < c->report.blocked_count; ++k)
        ms_core_dcell(c, c->report.blocked[k])->blocked = false;
    if (pass->failed)
        pass->complete = false;
    ms_core_schedule_subtrees(c, pass); /* the index's subtrees, with an index by subtree */
    if (pass->wl.n)
        qsort(pass->wl.w, pass->wl.n, sizeof *pass->wl.w, compare_wants);
}
