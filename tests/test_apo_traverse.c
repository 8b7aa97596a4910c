/* The CPU reference traversal against a brute-force lookup in the unencoded tree,
 * and its exact outcomes on the hard cases: mid-planes at every level, cube
 * faces and corners, depth 20, depth caps, missing children (both rules). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_apo_chunk.h"
#include "ms_apo_testtree.h"
#include "ms_apo_traverse.h"

/* Word index of every node of a tree, as the encoder lays them out. */
static uint32_t *word_indices(const ms_apo_tree *t)
{
    uint32_t *w = malloc((t->node_count + 1) * sizeof *w);
    assert_non_null(w);
    uint32_t next = 0;
    for (size_t i = 0; i < t->node_count; ++i) {
        w[i] = next;
        next += t->nodes[i].child_mask ? 2u : 1u;
    }
    return w;
}

typedef struct fixture {
    ms_apo_tree tree;
    ms_apo_chunk chunk;
    ms_apo_view view;
    uint32_t *word_of;
} fixture;

static void fixture_make(fixture *f)
{
    assert_int_equal(ms_apo_chunk_encode(&f->tree, &f->chunk, NULL), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&f->view, &f->chunk, NULL), MS_OK);
    f->word_of = word_indices(&f->tree);
}

static void fixture_free(fixture *f)
{
    free(f->word_of);
    ms_apo_chunk_free(&f->chunk);
    ms_apo_tree_free(&f->tree);
}

/* One lookup checked against the oracle: same node, same stop, same normal code
 * (the leaf's own, or the internal node's mean). */
static uint64_t stop_counts[5], substitutions, deepest;

static void check_point(const fixture *f, const uint32_t fixed[3], uint32_t cap, ms_apo_missing_rule rule)
{
    ms_apo_lookup_result r;
    ms_apo_stop stop;
    ms_apo_lookup_fixed(&f->view, fixed, cap, rule, &r);
    size_t node = ms_test_brute_lookup(&f->tree, fixed, cap, f->view.complete_levels, rule, &stop);
    if (r.word != f->word_of[node] || r.stop != stop)
        fail_msg("point %08x %08x %08x cap %u rule %d: traversal word %u stop %d, brute force word %u stop %d",
                 fixed[0], fixed[1], fixed[2], cap, (int)rule, r.word, (int)r.stop, f->word_of[node], (int)stop);
    const ms_apo_node *n = &f->tree.nodes[node];
    stop_counts[r.stop]++;
    substitutions += r.substitutions;
    if (r.depth > deepest)
        deepest = r.depth;
    if (stop == MS_APO_STOP_MISSING) {
        /* no texel: the smooth normal, at the absent child's cell */
        assert_int_equal(r.depth, n->depth + 1u);
        for (int a = 0; a < 3; ++a)
            assert_int_equal(r.cell[a], 2 * n->cell[a] + (fixed[a] >> (31 - n->depth) & 1u));
        assert_true(r.smooth);
        assert_int_equal(r.code, MS_APO_NORMAL_SMOOTH);
        assert_true(r.normal[0] == 0.0f && r.normal[1] == 0.0f && r.normal[2] == 0.0f);
        return;
    }
    assert_int_equal(r.depth, n->depth);
    assert_memory_equal(r.cell, n->cell, sizeof r.cell);
    if (n->child_mask && n->smooth) {
        assert_true(r.smooth);
        assert_int_equal(r.code, MS_APO_NORMAL_SMOOTH);
    } else {
        assert_false(r.smooth);
        assert_int_equal(r.code, ms_apo_normal_encode(n->normal));
    }
}

/* A million random points (float positions, as the shader gets them), over
 * several random trees, both missing-child rules and random depth caps. Under
 * ASan this takes a few seconds. */
static void test_random_points_against_brute_force(void **state)
{
    (void)state;
    uint64_t rng = 2024;
    const int trees = 8, points = 1000000 / 8;
    for (int k = 0; k < trees; ++k) {
        fixture f;
        ms_test_random_tree(100 + (uint64_t)k, 6 + (uint32_t)k, 0.55, &f.tree);
        for (size_t i = 0; i < f.tree.node_count; ++i) /* a quarter of the means "smooth" */
            f.tree.nodes[i].smooth = f.tree.nodes[i].child_mask && ms_test_rand(&rng) % 4 == 0;
        fixture_make(&f);
        for (int i = 0; i < points; ++i) {
            float p[3] = {ms_test_randf(&rng), ms_test_randf(&rng), ms_test_randf(&rng)};
            uint32_t fixed[3];
            ms_apo_position_to_fixed(p, fixed);
            uint32_t cap = (i & 7) == 0 ? (uint32_t)(ms_test_rand(&rng) % 12) : 30;
            check_point(&f, fixed, cap, (i & 1) ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP);
        }
        fixture_free(&f);
    }
    print_message("stops: leaf %llu, cap %llu, missing %llu; %llu substitutions; deepest %llu\n",
                  (unsigned long long)stop_counts[MS_APO_STOP_LEAF], (unsigned long long)stop_counts[MS_APO_STOP_CAP],
                  (unsigned long long)stop_counts[MS_APO_STOP_MISSING], (unsigned long long)substitutions,
                  (unsigned long long)deepest);
    assert_true(stop_counts[MS_APO_STOP_MISSING] > 10000 && substitutions > 10000 && deepest >= 10);
}

/* Points exactly on the mid-planes of the cell they are in, at every level down
 * to depth 20: they must take the upper child on all three axes, and the cell
 * reached must be the exact integer one. */
static void test_mid_planes_every_level(void **state)
{
    (void)state;
    uint8_t path[20];
    for (int d = 0; d < 20; ++d)
        path[d] = (uint8_t)((d * 5 + 3) % 8);
    fixture f;
    ms_test_chain_tree(20, path, &f.tree);
    fixture_make(&f);
    assert_int_equal(f.view.level_count, 21);
    uint32_t cell[3] = {0, 0, 0};
    for (uint32_t d = 0; d <= 20; ++d) {
        /* Centre of the depth-d internal cell: (cell + 1/2) * 2^-d, exact in float. */
        float p[3];
        for (int a = 0; a < 3; ++a)
            p[a] = (float)ldexp(2.0 * cell[a] + 1.0, -(int)d - 1);
        ms_apo_lookup_result r;
        ms_apo_lookup(&f.view, p, 30, MS_APO_MISSING_STOP, &r);
        if (d < 20) {
            /* Upper child on every axis: octant 7, a leaf at depth d+1, cell 2c+1;
             * where octant 7 is the path's internal child, the point sits on that
             * child's lower faces and goes to its octant 0 (a leaf: the path never
             * takes octant 0 right after 7), cell 4c+2 at depth d+2. */
            assert_int_equal(r.stop, MS_APO_STOP_LEAF);
            if (path[d] != 7) {
                assert_int_equal(r.depth, d + 1);
                for (int a = 0; a < 3; ++a)
                    assert_int_equal(r.cell[a], 2 * cell[a] + 1);
            } else {
                assert_int_equal(r.depth, d + 2);
                for (int a = 0; a < 3; ++a)
                    assert_int_equal(r.cell[a], 4 * cell[a] + 2);
            }
        } else {
            assert_int_equal(r.stop, MS_APO_STOP_LEAF);
            assert_int_equal(r.depth, 20);
            assert_memory_equal(r.cell, cell, sizeof cell);
        }
        uint32_t fixed[3];
        ms_apo_position_to_fixed(p, fixed);
        check_point(&f, fixed, 30, MS_APO_MISSING_STOP);
        /* A depth cap on the way stops on the mean normal of that level's node. */
        if (d > 0 && d < 20) {
            ms_apo_lookup(&f.view, p, d, MS_APO_MISSING_STOP, &r);
            assert_int_equal(r.depth, d);
            assert_int_equal(r.stop, MS_APO_STOP_CAP);
            assert_memory_equal(r.cell, cell, sizeof cell);
        }
        if (d < 20)
            for (int a = 0; a < 3; ++a)
                cell[a] = 2 * cell[a] + (path[d] >> (2 - a) & 1u);
    }
    /* Depth 20: the deepest leaf along the path, reached with 20 descents. */
    float deep[3];
    for (int a = 0; a < 3; ++a)
        deep[a] = (float)ldexp(cell[a] + 0.25, -20);
    ms_apo_lookup_result r;
    assert_int_equal(ms_apo_lookup(&f.view, deep, 30, MS_APO_MISSING_NEAREST, &r), MS_APO_STOP_LEAF);
    assert_int_equal(r.depth, 20);
    fixture_free(&f);
}

/* Faces and corners of the cube, and positions outside it: the clamp rule. */
static void test_faces_and_corners(void **state)
{
    (void)state;
    uint8_t path[4] = {7, 7, 0, 0};
    fixture f;
    ms_test_chain_tree(4, path, &f.tree); /* complete enough near both corners */
    fixture_make(&f);
    struct {
        float p;
        uint32_t u;
    } cases[] = {
        {0.0f, 0u}, {-0.0f, 0u}, {-1e-30f, 0u}, {-5.0f, 0u}, {NAN, 0u}, {-INFINITY, 0u},
        {1.0f, UINT32_MAX}, {1.0000001f, UINT32_MAX}, {7.0f, UINT32_MAX}, {INFINITY, UINT32_MAX},
        {0.99999994f, 0xFFFFFF00u}, {0.5f, 0x80000000u}, {0.25f, 0x40000000u}, {1e-30f, 0u},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        float p[3] = {cases[i].p, cases[i].p, cases[i].p};
        uint32_t u[3];
        ms_apo_position_to_fixed(p, u);
        assert_int_equal(u[0], cases[i].u);
        assert_int_equal(u[2], cases[i].u);
    }
    /* The corner 1.0 stays inside: the last cell on every level (path 7,7 goes
     * there), the same as the largest float below 1. */
    ms_apo_lookup_result a, b;
    float one[3] = {1.0f, 1.0f, 1.0f}, below[3] = {0.99999994f, 0.99999994f, 0.99999994f};
    ms_apo_lookup(&f.view, one, 30, MS_APO_MISSING_STOP, &a);
    ms_apo_lookup(&f.view, below, 30, MS_APO_MISSING_STOP, &b);
    assert_int_equal(a.word, b.word);
    assert_int_equal(a.depth, 3);
    assert_int_equal(a.cell[0], 7);
    assert_int_equal(a.cell[1], 7);
    assert_int_equal(a.cell[2], 7);
    /* The corner 0 and the mixed corners: exact cells. */
    float zero[3] = {0.0f, 0.0f, 0.0f};
    ms_apo_lookup(&f.view, zero, 30, MS_APO_MISSING_STOP, &a);
    assert_int_equal(a.depth, 1);
    assert_int_equal(a.cell[0] + a.cell[1] + a.cell[2], 0);
    float mixed[3] = {1.0f, 0.0f, 1.0f};
    ms_apo_lookup(&f.view, mixed, 30, MS_APO_MISSING_STOP, &a);
    assert_int_equal(a.depth, 1);
    assert_int_equal(a.cell[0], 1);
    assert_int_equal(a.cell[1], 0);
    assert_int_equal(a.cell[2], 1);
    /* Points on faces, checked against the oracle. */
    for (int i = 0; i <= 64; ++i) {
        float t = (float)i / 64.0f;
        float faces[6][3] = {{0, t, 0.5f}, {1, t, 0.5f}, {t, 0, 1}, {t, 1, 0}, {0.5f, 1, t}, {1, 1, t}};
        for (int k = 0; k < 6; ++k) {
            uint32_t u[3];
            ms_apo_position_to_fixed(faces[k], u);
            check_point(&f, u, 30, MS_APO_MISSING_STOP);
            check_point(&f, u, 30, MS_APO_MISSING_NEAREST);
        }
    }
    fixture_free(&f);
}

/* Missing children: STOP returns "smooth" (no texel); NEAREST goes to the
 * nearest existing sibling (exact integer distances) and keeps descending. */
static void test_missing_child_rules(void **state)
{
    (void)state;
    /* Root with children 0 (leaf) and 3 (internal with children 0 and 7). */
    ms_apo_tree t;
    memset(&t, 0, sizeof t);
    t.nodes = calloc(5, sizeof *t.nodes);
    assert_non_null(t.nodes);
    t.node_count = 5;
    t.level_count = 3;
    t.level_start[1] = 1;
    t.level_start[2] = 3;
    t.level_start[3] = 5;
    t.nodes[0] = (ms_apo_node){.first_child = 1, .child_mask = 0x09, .normal = {0, 0, 1}};
    t.nodes[1] = (ms_apo_node){.depth = 1, .normal = {1, 0, 0}};
    t.nodes[2] = (ms_apo_node){.first_child = 3, .child_mask = 0x81, .depth = 1, .cell = {0, 1, 1}, .normal = {0, 1, 0}};
    t.nodes[3] = (ms_apo_node){.depth = 2, .cell = {0, 2, 2}, .normal = {-1, 0, 0}};
    t.nodes[4] = (ms_apo_node){.depth = 2, .cell = {1, 3, 3}, .normal = {0, -1, 0}};
    fixture f = {.tree = t};
    fixture_make(&f);
    ms_apo_lookup_result r;
    /* (0.9, 0.9, 0.9): octant 7 is missing at the root. */
    float p[3] = {0.9f, 0.9f, 0.9f};
    assert_int_equal(ms_apo_lookup(&f.view, p, 30, MS_APO_MISSING_STOP, &r), MS_APO_STOP_MISSING);
    assert_int_equal(r.word, 0);
    assert_true(r.smooth); /* no texel: the client's smooth normal */
    assert_int_equal(r.code, MS_APO_NORMAL_SMOOTH);
    assert_int_equal(r.depth, 1);
    assert_int_equal(r.cell[0] + r.cell[1] + r.cell[2], 3);
    /* Nearest: octant 3 (one axis away, distance 0.4) beats octant 0 (three axes
     * away, 0.4 too: the tie goes to fewer axes); the point moves to x = 0.5 - 2^-32
     * and then lands in octant 7 of node 2 (y, z >= 0.75). */
    assert_int_equal(ms_apo_lookup(&f.view, p, 30, MS_APO_MISSING_NEAREST, &r), MS_APO_STOP_LEAF);
    assert_int_equal(r.substitutions, 1);
    assert_int_equal(r.depth, 2);
    assert_int_equal(r.cell[0], 1);
    assert_int_equal(r.cell[1], 3);
    assert_int_equal(r.cell[2], 3);
    /* (0.9, 0.1, 0.1): octant 4 missing; octant 0 is one axis away (0.4), octant
     * 3 two axes (max 0.4): octant 0 wins on fewer axes. */
    float q[3] = {0.9f, 0.1f, 0.1f};
    ms_apo_lookup(&f.view, q, 30, MS_APO_MISSING_NEAREST, &r);
    assert_int_equal(r.word, 2);
    assert_int_equal(r.depth, 1);
    /* (0.6, 0.9, 0.9): octant 7 missing; octant 3 is 0.1 away: it wins. */
    float s[3] = {0.6f, 0.9f, 0.9f};
    ms_apo_lookup(&f.view, s, 30, MS_APO_MISSING_NEAREST, &r);
    assert_int_equal(r.depth, 2);
    /* Exactly on the root's x mid-plane (x = 0.5) the point belongs to the
     * upper side, whose child is missing: distance 0 to octant 3. Moved to
     * x = 0.5 - 2^-32, it is then in octant 4 of node 2, missing too; octant 7
     * (y, z 0.15 away) beats octant 0 (x 0.25 away). */
    float m[3] = {0.5f, 0.6f, 0.6f};
    ms_apo_lookup(&f.view, m, 30, MS_APO_MISSING_NEAREST, &r);
    assert_int_equal(r.substitutions, 2);
    assert_int_equal(r.depth, 2);
    assert_int_equal(r.cell[0], 1);
    assert_int_equal(r.cell[1], 3);
    assert_int_equal(r.cell[2], 3);
    fixture_free(&f);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_random_points_against_brute_force),
        cmocka_unit_test(test_mid_planes_every_level),
        cmocka_unit_test(test_faces_and_corners),
        cmocka_unit_test(test_missing_child_rules),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
