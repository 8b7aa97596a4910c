/* The client core's scheduler (client/core/ms_core_sched.h) on hand-made
 * snapshots: no threads, no sockets, no view decoder. The model is the
 * synthetic archive of tests/support/ms_test_archive.c (129 cells, p = 12,
 * n = 4, root precision 7, APO on cells not a multiple of 3); each test
 * states what the view holds of a few cells and checks the exact wants
 * (stream, byte range, priority, decoded growth), their order, the counts
 * and the subtrees a cut needs. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_core_sched.h"
#include "ms_subtree.h"
#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_view_decoder.h"

typedef struct fixture {
    char dir[512], path[600];
    ms_archive *index;
    ms_sched_input in;
} fixture;

/* A camera 1 unit in front of the root cube's centre (+z), looking at it;
 * `away` turns it round. */
static frame_view camera_view(const ms_archive *index, bool away, double tolerance)
{
    const ms_archive_header *h = ms_archive_get_header(index);
    double centre[3], eye[3], target[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; ++a)
        centre[a] = h->box_origin[a] + 0.5 * h->box_side;
    memcpy(eye, centre, sizeof eye);
    eye[2] += 1.0;
    memcpy(target, centre, sizeof target);
    if (away)
        target[2] = eye[2] + 1.0;
    frame_view fv = {.tolerance = tolerance};
    ms_error err;
    assert_int_equal(ms_camera_look_at(eye, target, up, 60.0, 800, 600, 0.01, 100.0, &fv.cam,
                                       &err), MS_OK);
    ms_camera_frustum(&fv.cam, &fv.frustum);
    return fv;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->path, sizeof f->path, "%s/model.msa", f->dir);
    ms_test_write_archive(f->path, 0);
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &f->index, &err), MS_OK);
    f->in = (ms_sched_input){.index = f->index,
                             .fv = camera_view(f->index, false, 1.0),
                             .margin = 0.0,
                             .apo_levels = 16,
                             .apo_tolerance_px = 1.0};
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_archive_close(f->index);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* The need of the root for the fixture's camera, worked out apart: its cube
 * is 0.875 units from the eye (1 unit from its centre, half its 0.25 side). */
static double root_need(const fixture *f)
{
    return ms_screen_bits_needed(&f->in.fv.cam, 0.25, 0.875, f->in.fv.tolerance);
}

static double estimate(const ms_archive_cell *rec, unsigned bits)
{
    return rec->vertex_count * ldexp(1.0, -2 * (int)(rec->bits_max - bits)) < 1
               ? BYTES_PER_VERTEX
               : rec->vertex_count * ldexp(1.0, -2 * (int)(rec->bits_max - bits)) *
                     BYTES_PER_VERTEX;
}

static uint8_t clamp(double p)
{
    return p < 0 ? 0 : p > 255 ? 255 : (uint8_t)p;
}

static ms_sched_plan plan_for(fixture *f, const ms_sched_cell *cells, size_t n)
{
    f->in.cells = cells;
    f->in.cell_count = n;
    ms_sched_plan plan = {0};
    ms_sched_plan_make(&f->in, &plan);
    assert_false(plan.out_of_memory);
    return plan;
}

/* The root shown at its first bit, nothing received past it, target 7: one
 * want a bit, from the first byte, each at 128 - 8 (need - bit). */
static void test_root_bits(void **state)
{
    fixture *f = *state;
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    assert_int_equal(root->bits_min, 0);
    assert_int_equal(root->bits_max, 7);
    assert_int_equal(root->geometry_length, 20);
    ms_sched_cell cells[] = {{.id = 0, .state = MS_VIEW_SHOWN, .target = 7, .bits = 0,
                              .avail = 0, .parent_state = MS_VIEW_HIDDEN, .error_bound = -1}};
    ms_sched_plan plan = plan_for(f, cells, 1);
    /* the writer's table: prefix(b) = 8 + 12 b / 7, the last 20 */
    static const uint32_t prefix[8] = {8, 9, 11, 13, 14, 16, 18, 20};
    for (unsigned b = 0; b <= 7; ++b)
        assert_int_equal(ms_archive_geometry_prefix(f->index, 0, b), prefix[b]);
    double need = root_need(f);
    assert_int_equal(plan.wl.n, 7);
    for (unsigned s = 1; s <= 7; ++s) {
        const want *w = &plan.wl.w[s - 1];
        assert_int_equal(w->cell, 0);
        assert_int_equal(w->stream, STREAM_GEOMETRY);
        assert_int_equal(w->start, s == 1 ? 0 : prefix[s - 1]);
        assert_int_equal(w->end, prefix[s]);
        assert_int_equal(w->priority, clamp(128.0 - 8.0 * (need - s)));
        assert_int_equal(w->decoded_growth, (uint32_t)(estimate(root, s) - estimate(root, s - 1)));
    }
    assert_int_equal(plan.shown, 1);
    assert_int_equal(plan.loading, 1);
    assert_int_equal(plan.split + plan.cached + plan.failed, 0);
    assert_false(plan.complete);
    /* the writer's default table: the half-diagonal, rounded up to 1/256 step */
    assert_true(fabs(plan.worst / ms_screen_error_px(&f->in.fv.cam, 0.25, 0, 0.875) - 1) < 1e-4);
    ms_sched_plan_free(&plan);

    /* part of bit 3 received: bit 3 resumes from the byte after it */
    cells[0].avail = 2, cells[0].geo_end = 12;
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 5);
    assert_int_equal(plan.wl.w[0].start, 12);
    assert_int_equal(plan.wl.w[0].end, 13);
    ms_sched_plan_free(&plan);

    /* everything: nothing wanted, complete */
    cells[0].bits = cells[0].avail = 7, cells[0].geo_end = 20;
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 0);
    assert_int_equal(plan.loading, 0);
    assert_true(plan.complete);
    ms_sched_plan_free(&plan);

    /* every byte here but decoded to 5 of its 7 bits: nothing wanted, and yet
     * not complete (the next pass draws it finer; a pass once said complete
     * with leaves at 11 of their 14 bits) */
    cells[0].bits = 5;
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 0);
    assert_false(plan.complete);
    ms_sched_plan_free(&plan);

    /* the content bounds want the root at root precision whatever its target */
    cells[0].bits = cells[0].avail = 0, cells[0].geo_end = 8, cells[0].target = 2;
    f->in.root_goal_min = 4;
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 4);
    assert_int_equal(plan.wl.w[3].end, prefix[4]);
    ms_sched_plan_free(&plan);
    /* those bytes held and the root drawn at its own target: complete, though
     * it shows fewer bits than it holds */
    cells[0].bits = 2, cells[0].avail = 4, cells[0].geo_end = prefix[4];
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 0);
    assert_true(plan.complete);
    f->in.root_goal_min = 0;
    ms_sched_plan_free(&plan);
}

/* Looking away: the root is culled, its bits come 64 later (192 - ...); a
 * failed cell asks for nothing and keeps the view incomplete. */
static void test_culled_and_failed(void **state)
{
    fixture *f = *state;
    f->in.fv = camera_view(f->index, true, 1.0);
    ms_sched_cell cells[] = {{.id = 0, .state = MS_VIEW_SHOWN, .target = 2, .bits = 0,
                              .avail = 0, .geo_end = 8, .error_bound = -1}};
    ms_sched_plan plan = plan_for(f, cells, 1);
    double need = root_need(f);
    assert_int_equal(plan.wl.n, 2);
    assert_int_equal(plan.wl.w[0].start, 8);
    assert_int_equal(plan.wl.w[0].end, 9);
    assert_int_equal(plan.wl.w[0].priority, clamp(192.0 - 8.0 * (need - 1)));
    assert_int_equal(plan.wl.w[1].priority, clamp(192.0 - 8.0 * (need - 2)));
    assert_true(plan.worst == 0.0); /* nothing visible */
    ms_sched_plan_free(&plan);

    cells[0].failed = true;
    plan = plan_for(f, cells, 1);
    assert_int_equal(plan.wl.n, 0);
    assert_int_equal(plan.failed, 1);
    assert_int_equal(plan.loading, 0);
    assert_false(plan.complete);
    ms_sched_plan_free(&plan);
    f->in.fv = camera_view(f->index, false, 1.0);
}

/* The root about to split: its last bit counts its children's decoded bytes;
 * a hidden child with a target (the root shown) prefetches at 144 - ...; a
 * child with no target asks for nothing; wants come best first. */
static void test_split_and_prefetch(void **state)
{
    fixture *f = *state;
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    uint32_t child = root->first_child + 1;
    const ms_archive_cell *rec = ms_archive_get_cell(f->index, child);
    ms_sched_cell cells[] = {
        {.id = 0, .state = MS_VIEW_SHOWN, .target = MS_VIEW_TARGET_SPLIT, .bits = 6, .avail = 6,
         .geo_end = 18, .error_bound = -1},
        {.id = child, .state = MS_VIEW_HIDDEN, .target = rec->bits_min + 1,
         .parent_state = MS_VIEW_SHOWN, .avail = rec->bits_min},
        {.id = child + 1, .state = MS_VIEW_HIDDEN, .target = MS_VIEW_TARGET_HIDDEN,
         .parent_state = MS_VIEW_SHOWN, .avail = 1}};
    ms_sched_plan plan = plan_for(f, cells, 3);
    assert_int_equal(plan.wl.n, 2);
    const want *last = &plan.wl.w[0], *pre = &plan.wl.w[1];
    assert_int_equal(last->cell, 0);
    assert_int_equal(last->start, 18);
    assert_int_equal(last->end, 20);
    assert_int_equal(last->decoded_growth,
                     (uint32_t)(estimate(root, 7) - estimate(root, 6) +
                                root->vertex_count * BYTES_PER_VERTEX));
    bool visible;
    double need = ms_sched_cell_need(f->index, &f->in.fv, 0.0, child, &visible);
    assert_true(visible);
    assert_int_equal(pre->cell, child);
    assert_int_equal(pre->start, 0);
    assert_int_equal(pre->end, 25); /* cell 2: 94 bytes, bits 7..12, prefix(8) = 25 */
    assert_int_equal(pre->priority, clamp(144.0 - 8.0 * (need - (rec->bits_min + 1))));
    assert_true(last->priority <= pre->priority);
    assert_int_equal(plan.shown, 1);
    assert_int_equal(plan.cached, 0);
    ms_sched_plan_free(&plan);

    /* the parent split: a hidden cell is cached, not prefetched */
    cells[0].state = MS_VIEW_SPLIT;
    cells[1].parent_state = MS_VIEW_SPLIT, cells[1].cached = true;
    plan = plan_for(f, cells, 3);
    assert_int_equal(plan.wl.n, 0);
    assert_int_equal(plan.split, 1);
    assert_int_equal(plan.cached, 1);
    assert_true(plan.complete);
    ms_sched_plan_free(&plan);
}

/* APO by footprint: a visible shown cell with a chunk asks for its levels
 * down to the footprint's depth (ms_apo_footprint_levels), one want a level at
 * 136 + 8 l - 8 (need - bits); none about to split, none blocked, none with
 * APO off. */
static void test_apo_levels(void **state)
{
    fixture *f = *state;
    const ms_archive_header *h = ms_archive_get_header(f->index);
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    uint32_t child = root->first_child; /* cell 1, APO: 1 + 1 % 5 = 2 levels */
    const ms_archive_cell *rec = ms_archive_get_cell(f->index, child);
    assert_int_equal(rec->apo_levels, 2);
    ms_sched_cell cells[] = {
        {.id = 0, .state = MS_VIEW_SPLIT, .target = MS_VIEW_TARGET_SPLIT, .bits = 7, .avail = 7,
         .geo_end = 20},
        {.id = child, .state = MS_VIEW_SHOWN, .target = rec->bits_max, .bits = rec->bits_max,
         .avail = rec->bits_max, .parent_state = MS_VIEW_SPLIT,
         .geo_end = rec->geometry_length, .error_bound = 0.0}};
    f->in.apo_on = true;
    ms_sched_plan plan = plan_for(f, cells, 2);
    double lo[3], hi[3];
    ms_sched_cell_box(h, rec, lo, hi);
    unsigned levels = ms_apo_footprint_levels(&f->in.fv.cam, lo, 0.25 / 4, 1.0, 2);
    assert_true(levels >= 1);
    bool visible;
    double need = ms_sched_cell_need(f->index, &f->in.fv, 0.0, child, &visible);
    assert_int_equal(plan.wl.n, levels);
    for (unsigned l = 1; l <= levels; ++l) {
        const want *w = &plan.wl.w[l - 1];
        assert_int_equal(w->stream, STREAM_APO);
        assert_int_equal(w->cell, child);
        assert_int_equal(w->start, 40 * (l - 1)); /* 40 bytes a level */
        assert_int_equal(w->end, 40 * l);
        assert_int_equal(w->priority, clamp(136.0 + 8.0 * l - 8.0 * (need - rec->bits_max)));
        assert_int_equal(w->decoded_growth, 0);
    }
    assert_int_equal(plan.loading, 1);
    assert_false(plan.complete);
    ms_sched_plan_free(&plan);

    /* levels held: complete */
    cells[1].apo_end = 40 * levels;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 0);
    assert_true(plan.complete);
    ms_sched_plan_free(&plan);

    cells[1].apo_end = 0;
    cells[1].blocked = true;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 0);
    cells[1].blocked = false;
    cells[1].target = MS_VIEW_TARGET_SPLIT;
    ms_sched_plan_free(&plan);
    plan = plan_for(f, cells, 2);
    for (size_t k = 0; k < plan.wl.n; ++k)
        assert_int_not_equal(plan.wl.w[k].stream, STREAM_APO);
    ms_sched_plan_free(&plan);
    cells[1].target = rec->bits_max;
    f->in.apo_on = false;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 0);
    assert_true(plan.complete);
    ms_sched_plan_free(&plan);
}

/* Many cells: the list is sorted by priority, then cell, then start. */
static void test_order(void **state)
{
    fixture *f = *state;
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    ms_sched_cell cells[65];
    cells[0] = (ms_sched_cell){.id = 0, .state = MS_VIEW_SPLIT, .target = MS_VIEW_TARGET_SPLIT,
                               .bits = 7, .avail = 7, .geo_end = 20};
    for (uint32_t k = 0; k < 64; ++k) {
        const ms_archive_cell *rec = ms_archive_get_cell(f->index, root->first_child + k);
        cells[k + 1] = (ms_sched_cell){.id = root->first_child + k, .state = MS_VIEW_SHOWN,
                                       .target = rec->bits_max, .bits = rec->bits_min,
                                       .avail = rec->bits_min, .parent_state = MS_VIEW_SPLIT,
                                       .error_bound = -1};
    }
    ms_sched_plan plan = plan_for(f, cells, 65);
    assert_true(plan.wl.n > 64);
    for (size_t k = 1; k < plan.wl.n; ++k) {
        const want *a = &plan.wl.w[k - 1], *b = &plan.wl.w[k];
        assert_true(a->priority < b->priority ||
                    (a->priority == b->priority &&
                     (a->cell < b->cell || (a->cell == b->cell && a->start < b->start))));
    }
    assert_int_equal(plan.shown, 64);
    assert_int_equal(plan.loading, 64);
    assert_int_equal(plan.split, 1);
    ms_sched_plan_free(&plan);
}

/* An index by subtree (n = 4: one level a subtree, the children of a cell
 * in the subtree its first child starts): a cell split, or about to split,
 * needs its children's subtree; a missing one is wanted whole (priority 0:
 * before everything) or from what arrived, a held one is kept, a failed one
 * keeps the view incomplete; a blocked cell's children come just before its
 * next bit, a near cell's after the cut's bits. */
static void test_subtrees(void **state)
{
    fixture *f = *state;
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    const uint32_t five = 5;
    const ms_archive_cell *rec5 = ms_archive_get_cell(f->index, five);
    assert_int_not_equal(rec5->first_child, MS_ARCHIVE_NONE);
    assert_int_equal(ms_archive_children_subtree(f->index, 0), root->first_child);
    assert_int_equal(ms_archive_children_subtree(f->index, five), rec5->first_child);
    ms_sched_cell cells[] = {
        {.id = 0, .state = MS_VIEW_SPLIT, .target = MS_VIEW_TARGET_SPLIT, .bits = 7, .avail = 7,
         .geo_end = 20},
        {.id = five, .state = MS_VIEW_SPLIT, .target = MS_VIEW_TARGET_SPLIT,
         .bits = rec5->bits_max, .avail = rec5->bits_max, .parent_state = MS_VIEW_SPLIT,
         .geo_end = rec5->geometry_length}};
    ms_sched_subtree held[] = {{0, MS_SCHED_SUBTREE_HELD, 0, 0},
                               {root->first_child, MS_SCHED_SUBTREE_HELD, 0, 0},
                               {rec5->first_child, MS_SCHED_SUBTREE_RECEIVING, 100, 500}};
    f->in.by_subtree = true;
    f->in.subtrees = held;
    f->in.subtree_count = 2; /* five's children's not there yet */
    ms_sched_plan plan = plan_for(f, cells, 2);
    assert_int_equal(plan.need_count, 2);
    assert_int_equal(plan.needs[0].id, root->first_child);
    assert_int_equal(plan.needs[0].parent, 0);
    assert_int_equal(plan.needs[1].id, rec5->first_child);
    assert_int_equal(plan.needs[1].parent, five);
    assert_int_equal(plan.wl.n, 1);
    assert_int_equal(plan.wl.w[0].stream, STREAM_INDEX);
    assert_int_equal(plan.wl.w[0].cell, rec5->first_child);
    assert_int_equal(plan.wl.w[0].start, 0);
    assert_int_equal(plan.wl.w[0].end, UINT32_MAX);
    assert_int_equal(plan.wl.w[0].priority, 0);
    assert_false(plan.complete);
    ms_sched_plan_free(&plan);

    /* part of it arrived: the rest, to its stored size */
    f->in.subtree_count = 3;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 1);
    assert_int_equal(plan.wl.w[0].start, 100);
    assert_int_equal(plan.wl.w[0].end, 500);
    ms_sched_plan_free(&plan);
    /* held: nothing wanted, complete */
    held[2].state = MS_SCHED_SUBTREE_HELD;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 0);
    assert_int_equal(plan.need_count, 2);
    assert_true(plan.complete);
    ms_sched_plan_free(&plan);
    /* failed: not asked for again, the view incomplete */
    held[2].state = MS_SCHED_SUBTREE_FAILED;
    plan = plan_for(f, cells, 2);
    assert_int_equal(plan.wl.n, 0);
    assert_false(plan.complete);
    ms_sched_plan_free(&plan);

    /* five shown and blocked at 9 bits: its children's records just before
     * its 10th bit; near instead: after the cut's bits */
    held[2].state = MS_SCHED_SUBTREE_RECEIVING, held[2].end = 0, held[2].total = 0;
    cells[1].state = MS_VIEW_SHOWN, cells[1].target = rec5->bits_max, cells[1].bits = 9;
    cells[1].avail = 9, cells[1].geo_end = ms_archive_geometry_prefix(f->index, five, 9);
    cells[1].error_bound = -1;
    uint32_t blocked[] = {five};
    f->in.blocked = blocked, f->in.blocked_count = 1;
    plan = plan_for(f, cells, 2);
    bool visible;
    double need = ms_sched_cell_need(f->index, &f->in.fv, 0.0, five, &visible);
    assert_true(visible);
    const want *index_want = NULL;
    for (size_t k = 0; k < plan.wl.n; ++k)
        if (plan.wl.w[k].stream == STREAM_INDEX)
            index_want = &plan.wl.w[k];
    assert_non_null(index_want);
    assert_int_equal(index_want->priority, clamp(128.0 - 8.0 * (need - 10) - 1.0));
    assert_int_equal(plan.wl.w[0].cell, rec5->first_child); /* before the bit */
    ms_sched_plan_free(&plan);
    f->in.blocked_count = 0;
    f->in.near = blocked, f->in.near_count = 1;
    plan = plan_for(f, cells, 2);
    index_want = NULL;
    for (size_t k = 0; k < plan.wl.n; ++k)
        if (plan.wl.w[k].stream == STREAM_INDEX)
            index_want = &plan.wl.w[k];
    assert_non_null(index_want);
    assert_int_equal(index_want->priority, clamp(144.0 - 8.0 * (need - (rec5->bits_max + 1.0))));
    ms_sched_plan_free(&plan);
    f->in = (ms_sched_input){.index = f->index, .fv = f->in.fv, .apo_levels = 16,
                             .apo_tolerance_px = 1.0};
}

/* The need of a child of the root for the fixture's camera, worked out
 * apart: its cube is a quarter of the root's side at its position. */
static double child_need(const fixture *f, uint32_t id)
{
    const ms_archive_header *h = ms_archive_get_header(f->index);
    const ms_archive_cell *rec = ms_archive_get_cell(f->index, id);
    double lo[3], hi[3], side = h->box_side / 4;
    for (int a = 0; a < 3; ++a) {
        lo[a] = h->box_origin[a] + side * rec->position[a];
        hi[a] = lo[a] + side;
    }
    /* the bits its measured error table asks for at its cube's nearest point */
    double d = ms_camera_box_distance(&f->in.fv.cam, lo, hi);
    return ms_archive_bits_needed(h, rec, ms_camera_pixels_per_unit(&f->in.fv.cam) / d, 1.0);
}

/* The eviction order: cells holding nothing are left out, the others least
 * useful first, usefulness the precision the camera wants of the cell (its
 * cube's nearest point), 64 bits less outside the frustum. */
static void test_eviction_order(void **state)
{
    fixture *f = *state;
    const ms_archive_cell *root = ms_archive_get_cell(f->index, 0);
    ms_sched_cell cells[64];
    for (uint32_t k = 0; k < 64; ++k)
        cells[k] = (ms_sched_cell){.id = root->first_child + k, .state = MS_VIEW_HIDDEN,
                                   .target = MS_VIEW_TARGET_HIDDEN, .held = k % 4 ? 100 + k : 0};
    for (int away = 0; away < 2; ++away) {
        f->in.fv = camera_view(f->index, away, 1.0);
        ms_sched_candidate out[64];
        size_t n = ms_sched_rank_evictions(f->index, &f->in.fv, 0.0, cells, 64, out);
        assert_int_equal(n, 48);
        for (size_t i = 0; i < n; ++i) {
            uint32_t k = out[i].cell - root->first_child;
            assert_int_not_equal(k % 4, 0);
            assert_int_equal(out[i].bytes, 100 + k);
            assert_int_equal(out[i].visible, !away); /* the whole cube in view, or none */
            double u = child_need(f, out[i].cell) - (away ? 64.0 : 0.0);
            assert_true(fabs(out[i].usefulness - u) < 1e-4);
            if (i)
                assert_true(out[i - 1].usefulness <= out[i].usefulness);
        }
    }
    f->in.fv = camera_view(f->index, false, 1.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_root_bits, setup, teardown),
        cmocka_unit_test_setup_teardown(test_culled_and_failed, setup, teardown),
        cmocka_unit_test_setup_teardown(test_split_and_prefetch, setup, teardown),
        cmocka_unit_test_setup_teardown(test_apo_levels, setup, teardown),
        cmocka_unit_test_setup_teardown(test_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_eviction_order, setup, teardown),
        cmocka_unit_test_setup_teardown(test_subtrees, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
