/* The browser client's decoding core: see ms_web_view.h. */
#include "ms_web_view.h"
#include "ms_web_budget.h"

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_grow.h"
#include "ms_parallel.h"
#include "ms_subtree.h"
#include "ms_view_decoder.h"
#include "ms_view_refine.h"
#include "ms_web_cast.h"

/* Rounds of select + apply before a plan gives up on the cut settling (the
 * study's cut uses the same bound). */
#define MAX_ROUNDS 64u

/* Every cell whose record the view knows (all of them with a whole index). */
#define FOR_KNOWN(v, c)                                                                            \
    for (uint32_t c = ms_view_next_known((v)->view, MS_ARCHIVE_NONE); c != MS_ARCHIVE_NONE;          \
         c = ms_view_next_known((v)->view, c))

typedef struct planned {
    uint32_t cell, bits, bytes;
    uint32_t depth; /* the cell's level (the ahead part's order) */
} planned;

/* A subtree a plan wants, and the order it was listed in (priority). */
typedef struct wanted_subtree {
    uint32_t id, order;
} wanted_subtree;

struct ms_web_view {
    ms_archive *index;
    ms_view *view;
    ms_camera camera;
    bool has_camera;
    ms_view_select_params params;
    planned *plan;
    size_t plan_count, plan_cap;
    planned *colour_plan;   /* colour prefixes the target cut lacks (a colour model) */
    size_t colour_count, colour_cap;
    ms_view_mesh mesh;
    float *positions, *normals;
    size_t positions_cap;
    uint8_t *stitched_bits; /* per cell: its bits at the last stitch (the mesh's) */
    bool ahead;             /* plans list the whole target cut (ms_web_view_plan_ahead) */
    bool partial;           /* the index comes by subtree (ms_web_view_new_head) */
    ms_view_select_report report; /* the last selection's blocked and near cells (partial) */
    wanted_subtree *subtrees; /* the last plan's missing subtrees, in priority order */
    size_t subtree_count, subtree_cap;
    ms_pool *pool;          /* NULL: decoding on the caller's thread alone */
    ms_view_refine_jobs jobs; /* the pool's job list, kept between plans */
    uint64_t budget;        /* ms_web_view_budget: stream bytes held at most (0: no limit) */
    uint64_t forgotten_cells, forgotten_bytes; /* what the budget forgot, summed */
    ms_error err;
};

static ms_status fail(ms_web_view *v, ms_status st, const char *what)
{
    ms_error_set(&v->err, st, "%s", what);
    return st;
}

ms_status ms_web_view_new(const uint8_t *blob, size_t size, const char *name, ms_web_view **out,
                          ms_error *err)
{
    *out = NULL;
    ms_web_view *v = calloc(1, sizeof *v);
    if (!v)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", name);
    ms_status st = ms_archive_open_index(blob, size, name, &v->index, err);
    if (st == MS_OK)
        st = ms_view_create_from_archive(v->index, &v->view, err);
    if (st != MS_OK) {
        ms_web_view_free(v);
        return st;
    }
    ms_view_select_params_default(&v->params);
    *out = v;
    return MS_OK;
}

/* The view learns the records of held subtree id. */
static ms_status learn_subtree(ms_web_view *v, uint32_t id, ms_error *err)
{
    const uint32_t *ids;
    const ms_archive_cell *recs;
    size_t n;
    if (!ms_archive_held_subtree(v->index, id, &ids, &recs, &n))
        return ms_error_set(err, MS_ERR_CORRUPT, "subtree %u is not held", id);
    return ms_view_learn(v->view, ids, recs, n, err);
}

ms_status ms_web_view_new_head(const uint8_t *head, size_t size, const char *name, ms_web_view **out,
                               ms_error *err)
{
    *out = NULL;
    ms_web_view *v = calloc(1, sizeof *v);
    if (!v)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", name);
    ms_status st = ms_archive_open_head(head, size, name, &v->index, err);
    if (st == MS_OK)
        st = ms_view_create_partial(ms_archive_get_header(v->index), &v->view, err);
    if (st == MS_OK)
        st = learn_subtree(v, 0, err);
    if (st != MS_OK) {
        ms_web_view_free(v);
        return st;
    }
    v->partial = true;
    ms_view_select_params_default(&v->params);
    *out = v;
    return MS_OK;
}

ms_status ms_web_view_give_subtree(ms_web_view *v, uint32_t id, const uint8_t *data, uint32_t length)
{
    if (!v->partial)
        return fail(v, MS_ERR_ARG, "the view holds the whole index: no subtree to add");
    if (ms_archive_subtree_held(v->index, id))
        return MS_OK;
    ms_status st = ms_archive_add_subtree(v->index, id, data, length, &v->err);
    if (st == MS_OK && (st = learn_subtree(v, id, &v->err)) != MS_OK)
        ms_archive_drop_subtree(v->index, id); /* the archive took it, the view did not */
    return st;
}

uint32_t ms_web_view_subtrees_held(const ms_web_view *v)
{
    return (uint32_t)ms_archive_subtrees_held(v->index);
}

uint64_t ms_web_view_index_bytes_held(const ms_web_view *v)
{
    return ms_archive_index_bytes_held(v->index);
}

void ms_web_view_free(ms_web_view *v)
{
    if (!v)
        return;
    ms_pool_free(v->pool);
    ms_view_refine_jobs_free(&v->jobs);
    ms_view_select_report_free(&v->report);
    free(v->subtrees);
    ms_view_mesh_free(&v->mesh);
    ms_view_destroy(v->view);
    ms_archive_close(v->index);
    free(v->plan);
    free(v->colour_plan);
    free(v->positions);
    free(v->normals);
    free(v->stitched_bits);
    free(v);
}

const char *ms_web_view_error(const ms_web_view *v) { return v->err.text; }

void ms_web_view_box(const ms_web_view *v, double out[4])
{
    const ms_archive_header *h = ms_archive_get_header(v->index);
    for (int a = 0; a < 3; ++a)
        out[a] = h->box_origin[a];
    out[3] = h->box_side;
}

uint32_t ms_web_view_cell_count(const ms_web_view *v) { return ms_view_cell_count(v->view); }

ms_status ms_web_view_bounds(ms_web_view *v, double out[6])
{
    if (ms_view_state(v->view, 0) != MS_VIEW_SHOWN)
        return fail(v, MS_ERR_RANGE, "the root is no longer the whole cut");
    unsigned bits = ms_view_available_bits(v->view, 0);
    ms_status st = MS_OK;
    if (bits != ms_view_bits(v->view, 0))
        st = ms_view_set_bits(v->view, 0, bits, &v->err);
    if (st == MS_OK)
        st = ms_view_cell_bounds(v->view, 0, out, out + 3, &v->err);
    return st;
}

ms_status ms_web_view_camera(ms_web_view *v, const double position[3], const double target[3],
                             const double up[3], double fovy_degrees, double width, double height,
                             double near_distance, double far_distance, double tolerance_px)
{
    if (!(tolerance_px > 0) || !isfinite(tolerance_px))
        return fail(v, MS_ERR_ARG, "the screen tolerance must be a positive number of pixels");
    if (!(far_distance > 0)) {
        /* as meshrender: just past the farthest corner of the box */
        double box[4], unused;
        ms_web_view_box(v, box);
        double lo[3] = {box[0], box[1], box[2]};
        double hi[3] = {box[0] + box[3], box[1] + box[3], box[2] + box[3]};
        ms_camera_depth_range(position, lo, hi, &unused, &far_distance);
    }
    if (!(near_distance > 0))
        near_distance = far_distance * 1e-5;
    ms_camera camera;
    ms_status st = ms_camera_look_at(position, target, up, fovy_degrees, width, height,
                                     near_distance, far_distance, &camera, &v->err);
    if (st != MS_OK)
        return st;
    v->camera = camera;
    v->has_camera = true;
    v->params.tolerance_px = tolerance_px;
    return MS_OK;
}

void ms_web_view_permit(ms_web_view *v, unsigned steps) { v->params.permitted_steps = steps; }

ms_status ms_web_view_plan_ahead(ms_web_view *v, int on)
{
    v->ahead = on != 0;
    return MS_OK;
}

unsigned ms_web_view_threads(ms_web_view *v, unsigned helpers)
{
    ms_pool_free(v->pool);
    v->pool = NULL;
    if (helpers > MS_WEB_VIEW_HELPERS_MAX)
        helpers = MS_WEB_VIEW_HELPERS_MAX;
    ms_error err;
    if (helpers == 0 || ms_pool_new(helpers, &v->pool, &err) != MS_OK)
        return 0;
    if (ms_pool_helpers(v->pool) == 0) {
        ms_pool_free(v->pool);
        v->pool = NULL;
        return 0;
    }
    return ms_pool_helpers(v->pool);
}

void ms_web_view_culled(ms_web_view *v, double bits_less)
{
    if (bits_less >= 0 && isfinite(bits_less))
        v->params.culled_bits_less = bits_less;
}

ms_status ms_web_view_sections(ms_web_view *v, const double *planes, uint32_t count)
{
    if (count > MS_SECTIONS_MAX)
        return ms_error_set(&v->err, MS_ERR_ARG, "%u section planes, at most %d", count, MS_SECTIONS_MAX);
    for (uint32_t k = 0; k < count; ++k) {
        const double *p = planes + 4 * k;
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]) || !isfinite(p[3]) ||
            !(p[0] * p[0] + p[1] * p[1] + p[2] * p[2] > 0))
            return ms_error_set(&v->err, MS_ERR_ARG, "section plane %u has a zero normal or a number not finite",
                                k);
    }
    for (uint32_t k = 0; k < count; ++k)
        memcpy(v->params.sections[k], planes + 4 * k, sizeof v->params.sections[k]);
    v->params.section_count = count;
    return MS_OK;
}

int ms_web_view_cast(ms_web_view *v, const double origin[3], const double direction[3], double t_min,
                     double t_near, double out[7])
{
    double len2 = direction[0] * direction[0] + direction[1] * direction[1] + direction[2] * direction[2];
    if (!(len2 > 0) || !isfinite(len2) || !isfinite(origin[0]) || !isfinite(origin[1]) || !isfinite(origin[2]))
        return 0;
    double t;
    size_t tri;
    if (!ms_web_cast(&v->mesh, origin, direction, t_min, t_near, (const double(*)[4])v->params.sections,
                     v->params.section_count, &t, &tri))
        return 0;
    for (int a = 0; a < 3; ++a)
        out[a] = origin[a] + t * direction[a];
    out[3] = t;
    uint32_t cell = v->mesh.triangle_cell ? v->mesh.triangle_cell[tri] : 0;
    const ms_archive_header *h = ms_archive_get_header(v->index);
    unsigned bits = v->stitched_bits && cell < ms_view_cell_count(v->view) ? v->stitched_bits[cell] : 0;
    out[4] = bits;
    out[5] = ldexp(h->box_side, -(int)bits);
    out[6] = h->bits;
    return 1;
}

/* The precision a known cell's target needs held: its bits, or bits_max for a
 * cell that splits (its children start from its complex at bits_max); 0 for a
 * hidden one. */
static unsigned goal_bits(const ms_web_view *v, uint32_t cell, const ms_archive_cell *rec)
{
    uint8_t t = ms_view_target(v->view, cell);
    if (t == MS_VIEW_TARGET_HIDDEN)
        return 0;
    unsigned goal = t == MS_VIEW_TARGET_SPLIT ? rec->bits_max : t;
    return goal > rec->bits_max ? rec->bits_max : goal;
}

/* With a pool: the shown cells whose bytes allow it go up on every thread
 * (ms_view_refine_parallel) before ms_view_apply does the rest (splits, merges,
 * coarsening) on the caller's. Returns how many cells went up. */
static size_t parallel_refine(ms_web_view *v)
{
    return v->pool ? ms_view_refine_parallel(v->view, v->pool, &v->jobs) : 0;
}

static int compare_planned_by_depth(const void *x, const void *y)
{
    const planned *a = x, *b = y;
    if (a->depth != b->depth)
        return a->depth < b->depth ? -1 : 1;
    return a->cell < b->cell ? -1 : a->cell > b->cell;
}

static bool plan_push(planned **list, size_t *count, size_t *cap, planned p)
{
    if (!ms_grow((void **)list, cap, *count + 1, sizeof **list))
        return false;
    (*list)[(*count)++] = p;
    return true;
}

/* On a colour model: every cell of the target cut (shown, or split: a
 * child's colour starts from its parent's whole colour) whose colour stream
 * is not held to its goal's bits, root first, in the cells' order. */
static ms_status plan_colour(ms_web_view *v)
{
    v->colour_count = 0;
    if (!ms_archive_get_header(v->index)->has_colour)
        return MS_OK;
    FOR_KNOWN(v, c) {
        const ms_archive_cell *rec = ms_view_cell(v->view, c);
        if (!rec || rec->vertex_count == 0)
            continue;
        unsigned goal = goal_bits(v, c, rec);
        if (goal == 0)
            continue;
        uint32_t bytes = ms_archive_colour_prefix(v->index, c, goal);
        if (bytes <= ms_view_held_colour_bytes(v->view, c))
            continue;
        if (!plan_push(&v->colour_plan, &v->colour_count, &v->colour_cap, (planned){c, goal, bytes, rec->level}))
            return fail(v, MS_ERR_NOMEM, "out of memory for the colour plan");
    }
    return MS_OK;
}

static int compare_wanted_by_id(const void *x, const void *y)
{
    const wanted_subtree *a = x, *b = y;
    if (a->id != b->id)
        return a->id < b->id ? -1 : 1;
    return a->order < b->order ? -1 : a->order > b->order;
}

static int compare_wanted_by_order(const void *x, const void *y)
{
    const wanted_subtree *a = x, *b = y;
    return a->order < b->order ? -1 : a->order > b->order;
}

/* Lists cell's children's subtree when it is not held (nothing for a leaf or
 * children within cell's own subtree). */
static bool want_children(ms_web_view *v, uint32_t cell)
{
    uint32_t id = ms_archive_children_subtree(v->index, cell);
    if (id == MS_ARCHIVE_NONE || id == ms_archive_subtree_of(v->index, cell) ||
        ms_archive_subtree_held(v->index, id))
        return true;
    if (!ms_grow((void **)&v->subtrees, &v->subtree_cap, v->subtree_count + 1, sizeof *v->subtrees))
        return false;
    v->subtrees[v->subtree_count] = (wanted_subtree){id, (uint32_t)v->subtree_count};
    v->subtree_count++;
    return true;
}

/* On a partial index, the subtrees the view needs and lacks, as the client
 * core asks for them (client/core/ms_client_core_subtrees.c): those holding
 * the children of the cells the selection would split (blocked: ahead of
 * everything), then, with plans that look ahead, those of the cells within a
 * bit of splitting (near: one level beyond the cut); each once, in that
 * order. Subtrees are never dropped here: the page keeps what it learned. */
static ms_status plan_subtrees(ms_web_view *v)
{
    v->subtree_count = 0;
    if (!v->partial)
        return MS_OK;
    if (v->report.out_of_memory)
        return fail(v, MS_ERR_NOMEM, "out of memory for the selection's report");
    for (size_t k = 0; k < v->report.blocked_count; ++k)
        if (!want_children(v, v->report.blocked[k]))
            return fail(v, MS_ERR_NOMEM, "out of memory for the plan's subtrees");
    for (size_t k = 0; v->ahead && k < v->report.near_count; ++k)
        if (!want_children(v, v->report.near[k]))
            return fail(v, MS_ERR_NOMEM, "out of memory for the plan's subtrees");
    if (v->subtree_count > 1) {
        qsort(v->subtrees, v->subtree_count, sizeof *v->subtrees, compare_wanted_by_id);
        uint32_t kept = 0;
        for (uint32_t k = 0; k < v->subtree_count; ++k)
            if (kept == 0 || v->subtrees[kept - 1].id != v->subtrees[k].id)
                v->subtrees[kept++] = v->subtrees[k];
        v->subtree_count = kept;
        qsort(v->subtrees, v->subtree_count, sizeof *v->subtrees, compare_wanted_by_order);
    }
    return MS_OK;
}

uint32_t ms_web_view_plan_subtree_count(const ms_web_view *v) { return (uint32_t)v->subtree_count; }

uint32_t ms_web_view_plan_subtree(const ms_web_view *v, uint32_t k)
{
    return k < v->subtree_count ? v->subtrees[k].id : MS_ARCHIVE_NONE;
}

ms_status ms_web_view_plan(ms_web_view *v, uint32_t max, int *settled)
{
    if (settled)
        *settled = 0;
    v->plan_count = 0;
    if (!v->has_camera)
        return fail(v, MS_ERR_ARG, "no camera set");
    bool changed = true;
    for (unsigned round = 0; changed; ++round) {
        if (round == MAX_ROUNDS)
            return ms_error_set(&v->err, MS_ERR_RANGE,
                                "the selection still changes after %u rounds", MAX_ROUNDS);
        ms_view_select(v->view, &v->camera, &v->params, v->partial ? &v->report : NULL);
        size_t refined = parallel_refine(v);
        ms_view_apply_report r;
        ms_status st = ms_view_apply(v->view, &r, &v->err);
        if (st != MS_OK)
            return st;
        changed = refined || r.splits || r.merges || r.refined || r.coarsened;
    }
    /* over the budget: the cells this cut does not want go before it asks for more */
    ms_status forgot = ms_web_budget_apply(v->view, v->index, v->camera.position, v->budget,
                                           &v->forgotten_cells, &v->forgotten_bytes, &v->err);
    if (forgot != MS_OK)
        return forgot;
    /* pass 0: the next step (cells of the cut, and the children of a shown
     * cell about to split: the first rounds are small and each round's mesh
     * shows more); pass 1, ahead: the rest of the target cut, level by level */
    for (int pass = 0; pass < (v->ahead ? 2 : 1); ++pass) {
        size_t first = v->plan_count;
        for (uint32_t c = ms_view_next_known(v->view, MS_ARCHIVE_NONE);
             c != MS_ARCHIVE_NONE && (max == 0 || v->plan_count < max); c = ms_view_next_known(v->view, c)) {
            const ms_archive_cell *rec = ms_view_cell(v->view, c);
            if (!rec || rec->geometry_length == 0)
                continue;
            bool next = ms_view_state(v->view, c) != MS_VIEW_HIDDEN ||
                        (rec->parent != MS_ARCHIVE_NONE && ms_view_state(v->view, rec->parent) == MS_VIEW_SHOWN);
            if (next != (pass == 0))
                continue;
            unsigned goal = goal_bits(v, c, rec);
            if (goal == 0 || ms_view_available_bits(v->view, c) >= goal)
                continue;
            uint32_t bytes = ms_archive_geometry_prefix(v->index, c, goal);
            if (bytes <= ms_view_held_bytes(v->view, c))
                continue;
            if (!plan_push(&v->plan, &v->plan_count, &v->plan_cap, (planned){c, goal, bytes, rec->level}))
                return fail(v, MS_ERR_NOMEM, "out of memory for the plan");
        }
        if (pass == 1 && v->plan_count - first > 1)
            qsort(v->plan + first, v->plan_count - first, sizeof *v->plan, compare_planned_by_depth);
    }
    ms_status st = plan_subtrees(v);
    if (st == MS_OK)
        st = plan_colour(v);
    if (st != MS_OK)
        return st;
    if (settled)
        *settled = v->plan_count == 0 && v->subtree_count == 0 && v->colour_count == 0;
    return MS_OK;
}

/* The k-th entry of a plan's list; out of range: no cell, no bits, no bytes. */
static planned plan_entry(const planned *list, size_t count, uint32_t k)
{
    return k < count ? list[k] : (planned){MS_ARCHIVE_NONE, 0, 0, 0};
}

uint32_t ms_web_view_plan_count(const ms_web_view *v) { return (uint32_t)v->plan_count; }
uint32_t ms_web_view_plan_cell(const ms_web_view *v, uint32_t k) { return plan_entry(v->plan, v->plan_count, k).cell; }
uint32_t ms_web_view_plan_bits(const ms_web_view *v, uint32_t k) { return plan_entry(v->plan, v->plan_count, k).bits; }
uint32_t ms_web_view_plan_bytes(const ms_web_view *v, uint32_t k)
{
    return plan_entry(v->plan, v->plan_count, k).bytes;
}

int ms_web_view_has_colour(const ms_web_view *v)
{
    return ms_archive_get_header(v->index)->has_colour;
}

uint32_t ms_web_view_plan_colour_count(const ms_web_view *v) { return (uint32_t)v->colour_count; }

uint32_t ms_web_view_plan_colour_cell(const ms_web_view *v, uint32_t k)
{
    return plan_entry(v->colour_plan, v->colour_count, k).cell;
}

uint32_t ms_web_view_plan_colour_bits(const ms_web_view *v, uint32_t k)
{
    return plan_entry(v->colour_plan, v->colour_count, k).bits;
}

uint32_t ms_web_view_plan_colour_bytes(const ms_web_view *v, uint32_t k)
{
    return plan_entry(v->colour_plan, v->colour_count, k).bytes;
}

uint32_t ms_web_view_colour_prefix(const ms_web_view *v, uint32_t cell, uint32_t bits)
{
    return ms_view_cell(v->view, cell) ? ms_archive_colour_prefix(v->index, cell, bits) : 0;
}

uint32_t ms_web_view_colour_held(const ms_web_view *v, uint32_t cell)
{
    return (uint32_t)ms_view_held_colour_bytes(v->view, cell);
}


const uint8_t *ms_web_view_colours(const ms_web_view *v)
{
    return v->mesh.vertex_count ? v->mesh.colours : NULL;
}

uint32_t ms_web_view_prefix(const ms_web_view *v, uint32_t cell, uint32_t bits)
{
    return ms_view_cell(v->view, cell) ? ms_archive_geometry_prefix(v->index, cell, bits) : 0;
}

uint32_t ms_web_view_held(const ms_web_view *v, uint32_t cell)
{
    return (uint32_t)ms_view_held_bytes(v->view, cell);
}

/* Bytes [offset, offset + length) of one of a cell's streams, `held` of
 * which the view has: what is new goes to `append`; a gap is refused. */
static ms_status give_tail(ms_web_view *v, uint32_t cell, const char *what, size_t held, uint32_t offset,
                           const uint8_t *data, uint32_t length,
                           ms_status (*append)(ms_view *, uint32_t, const uint8_t *, size_t, ms_error *))
{
    if (offset > held)
        return ms_error_set(&v->err, MS_ERR_ARG, "cell %u: %s from %u leave a gap after the %zu held", cell,
                            what, offset, held);
    if ((uint64_t)offset + length <= held)
        return MS_OK; /* nothing new */
    uint32_t skip = (uint32_t)(held - offset);
    return append(v->view, cell, data + skip, length - skip, &v->err);
}

ms_status ms_web_view_give(ms_web_view *v, uint32_t cell, uint32_t offset, const uint8_t *data,
                           uint32_t length)
{
    if (!ms_view_cell(v->view, cell))
        return ms_error_set(&v->err, MS_ERR_ARG, "no cell %u in the model", cell);
    return give_tail(v, cell, "bytes", ms_view_held_bytes(v->view, cell), offset, data, length,
                     ms_view_append_bytes);
}

ms_status ms_web_view_give_colour(ms_web_view *v, uint32_t cell, uint32_t offset, const uint8_t *data,
                                  uint32_t length)
{
    if (!ms_view_cell(v->view, cell))
        return ms_error_set(&v->err, MS_ERR_ARG, "no cell %u in the model", cell);
    if (!ms_web_view_has_colour(v))
        return ms_error_set(&v->err, MS_ERR_ARG, "cell %u: the model has no colour", cell);
    if ((uint64_t)offset + length > ms_archive_colour_length(v->index, cell))
        return ms_error_set(&v->err, MS_ERR_RANGE, "cell %u: colour bytes up to %llu, past its stream's %u",
                            cell, (unsigned long long)offset + length, ms_archive_colour_length(v->index, cell));
    return give_tail(v, cell, "colour bytes", ms_view_held_colour_bytes(v->view, cell), offset, data, length,
                     ms_view_append_colour_bytes);
}

/* Per vertex, the sum of its triangles' (area-weighted) normals, normalised;
 * a vertex of degenerate triangles only gets (0, 0, 0). */
static void vertex_normals(ms_web_view *v)
{
    const ms_view_mesh *m = &v->mesh;
    float *n = v->normals;
    memset(n, 0, 3 * m->vertex_count * sizeof *n);
    for (size_t t = 0; t < m->triangle_count; ++t) {
        const uint32_t *c = m->triangles + 3 * t;
        const double *a = m->positions + 3 * c[0], *b = m->positions + 3 * c[1],
                     *d = m->positions + 3 * c[2];
        double e[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double f[3] = {d[0] - a[0], d[1] - a[1], d[2] - a[2]};
        double x[3] = {e[1] * f[2] - e[2] * f[1], e[2] * f[0] - e[0] * f[2], e[0] * f[1] - e[1] * f[0]};
        for (int k = 0; k < 3; ++k)
            for (int a3 = 0; a3 < 3; ++a3)
                n[3 * c[k] + a3] += (float)x[a3];
    }
    for (size_t i = 0; i < m->vertex_count; ++i) {
        float *p = n + 3 * i;
        float length = sqrtf(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
        if (length > 0)
            for (int a = 0; a < 3; ++a)
                p[a] /= length;
    }
}

ms_status ms_web_view_stitch(ms_web_view *v)
{
    ms_status st = ms_view_stitch(v->view, NULL, &v->mesh, &v->err);
    if (st != MS_OK)
        return st;
    size_t need = 3 * v->mesh.vertex_count;
    if (need > v->positions_cap) {
        float *grown = realloc(v->positions, need * sizeof *grown);
        if (grown)
            v->positions = grown;
        float *grown_normals = grown ? realloc(v->normals, need * sizeof *grown_normals) : NULL;
        if (!grown_normals)
            return fail(v, MS_ERR_NOMEM, "out of memory for the positions");
        v->normals = grown_normals;
        v->positions_cap = need;
    }
    for (size_t i = 0; i < need; ++i)
        v->positions[i] = (float)v->mesh.positions[i];
    uint32_t cells = ms_view_cell_count(v->view);
    if (!v->stitched_bits && !(v->stitched_bits = malloc(cells ? cells : 1)))
        return fail(v, MS_ERR_NOMEM, "out of memory for the cells' bits");
    memset(v->stitched_bits, 0, cells ? cells : 1);
    FOR_KNOWN(v, c) {
        unsigned b = ms_view_state(v->view, c) == MS_VIEW_SHOWN ? ms_view_bits(v->view, c) : 0;
        v->stitched_bits[c] = (uint8_t)(b < 255 ? b : 255);
    }
    vertex_normals(v);
    return MS_OK;
}

uint32_t ms_web_view_vertex_count(const ms_web_view *v) { return (uint32_t)v->mesh.vertex_count; }
uint32_t ms_web_view_triangle_count(const ms_web_view *v) { return (uint32_t)v->mesh.triangle_count; }
const float *ms_web_view_positions(const ms_web_view *v) { return v->positions; }
const uint32_t *ms_web_view_triangles(const ms_web_view *v) { return v->mesh.triangles; }
const float *ms_web_view_normals(const ms_web_view *v) { return v->normals; }

uint32_t ms_web_view_shown_cells(const ms_web_view *v)
{
    uint32_t shown = 0;
    FOR_KNOWN(v, c)
        shown += ms_view_state(v->view, c) == MS_VIEW_SHOWN;
    return shown;
}

uint32_t ms_web_view_max_bits(const ms_web_view *v)
{
    uint32_t best = 0;
    FOR_KNOWN(v, c)
        if (ms_view_state(v->view, c) == MS_VIEW_SHOWN && ms_view_bits(v->view, c) > best)
            best = ms_view_bits(v->view, c);
    return best;
}

uint64_t ms_web_view_bytes_held(const ms_web_view *v)
{
    uint64_t total = 0;
    FOR_KNOWN(v, c)
        total += ms_view_held_bytes(v->view, c);
    return total;
}

uint32_t ms_web_view_run_count(const ms_web_view *v)
{
    return v->mesh.run_first && v->mesh.run_cell ? (uint32_t)v->mesh.run_count : 0;
}

const uint32_t *ms_web_view_run_cells(const ms_web_view *v)
{
    return ms_web_view_run_count(v) ? v->mesh.run_cell : NULL;
}

const uint32_t *ms_web_view_run_firsts(const ms_web_view *v)
{
    return ms_web_view_run_count(v) ? v->mesh.run_first : NULL;
}

ms_status ms_web_view_cell_cube(ms_web_view *v, uint32_t cell, double out[4])
{
    return ms_web_cell_cube(v->index, cell, out) ? MS_OK : fail(v, MS_ERR_ARG, "no such cell");
}

void ms_web_view_budget(ms_web_view *v, uint32_t bytes)
{
    v->budget = bytes;
}

uint32_t ms_web_view_forgotten_cells(const ms_web_view *v)
{
    return v->forgotten_cells > UINT32_MAX ? UINT32_MAX : (uint32_t)v->forgotten_cells;
}

double ms_web_view_forgotten_bytes(const ms_web_view *v)
{
    return (double)v->forgotten_bytes;
}

void ms_web_view_parts_get(ms_web_view *v, ms_web_view_parts *out)
{
    out->index = v->index;
    out->view = v->view;
    out->camera = v->has_camera ? &v->camera : NULL;
    out->params = &v->params;
    out->err = &v->err;
}
