/* The filtered APO lookup (ms_apo_filter.h, docs/APO.md "Filtering"): exact
 * interpolated normals on hand-made trees (a step that the nearest lookup shows
 * across a face and the filter removes, a deeper neighbour, a missing neighbour,
 * the cube's faces), the footprint depth, and random trees against a
 * brute-force version of the same rule in doubles. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_apo_chunk.h"
#include "ms_apo_filter.h"
#include "ms_apo_testtree.h"
#include "ms_apo_traverse.h"

typedef struct fixture {
    ms_apo_tree tree;
    ms_apo_chunk chunk;
    ms_apo_view view;
} fixture;

static void fixture_make(fixture *f)
{
    assert_int_equal(ms_apo_tree_check(&f->tree, NULL), MS_OK);
    assert_int_equal(ms_apo_chunk_encode(&f->tree, &f->chunk, NULL), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&f->view, &f->chunk, NULL), MS_OK);
}

static void fixture_free(fixture *f)
{
    ms_apo_chunk_free(&f->chunk);
    ms_apo_tree_free(&f->tree);
}

static const float X[3] = {1.0f, 0.0f, 0.0f}, Y[3] = {0.0f, 1.0f, 0.0f}, Z[3] = {0.0f, 0.0f, 1.0f};

/* A root whose octant o is stored when bit o of root_mask is set; a stored
 * child is a leaf, or, when bit o of deep_mask is set, an internal node with all
 * 8 children (leaves at depth 2). Leaf normals: normal_of(depth, cell); means
 * averaged. */
typedef const float *(*normal_fn)(uint32_t depth, const uint32_t cell[3]);

static void small_tree(uint8_t root_mask, uint8_t deep_mask, normal_fn normal_of, ms_apo_tree *t)
{
    memset(t, 0, sizeof *t);
    size_t cap = 1 + 8 + 64;
    t->nodes = calloc(cap, sizeof *t->nodes);
    assert_non_null(t->nodes);
    ms_apo_node *root = &t->nodes[0];
    root->child_mask = root_mask;
    root->first_child = 1;
    size_t n = 1;
    for (uint32_t o = 0; o < 8; ++o)
        if (root_mask >> o & 1u) {
            ms_apo_node *c = &t->nodes[n++];
            c->depth = 1;
            c->cell[0] = o >> 2 & 1u, c->cell[1] = o >> 1 & 1u, c->cell[2] = o & 1u;
            memcpy(c->normal, normal_of(1, c->cell), sizeof c->normal);
        }
    size_t level2 = n;
    for (size_t i = 1; i < level2; ++i) {
        ms_apo_node *c = &t->nodes[i];
        uint32_t o = c->cell[0] << 2 | c->cell[1] << 1 | c->cell[2];
        if (!(deep_mask >> o & 1u))
            continue;
        c->child_mask = 0xFF;
        c->first_child = (uint32_t)n;
        for (uint32_t k = 0; k < 8; ++k) {
            ms_apo_node *g = &t->nodes[n++];
            g->depth = 2;
            g->cell[0] = 2 * c->cell[0] + (k >> 2 & 1u);
            g->cell[1] = 2 * c->cell[1] + (k >> 1 & 1u);
            g->cell[2] = 2 * c->cell[2] + (k & 1u);
            memcpy(g->normal, normal_of(2, g->cell), sizeof g->normal);
        }
    }
    t->node_count = n;
    t->level_count = n > level2 ? 3 : 2;
    t->level_start[0] = 0, t->level_start[1] = 1, t->level_start[2] = level2, t->level_start[3] = n;
    if (t->level_count == 2)
        t->level_start[3] = 0;
    ms_apo_tree_average_normals(t);
}

/* +z on the lower half in x, +x on the upper half (depth 1); at depth 2 the
 * upper-half cells with x = 2 (next to the mid-plane) carry +y. */
static const float *step_normal(uint32_t depth, const uint32_t cell[3])
{
    if (depth == 2 && cell[0] == 2)
        return Y;
    return cell[0] >= (depth == 1 ? 1u : 2u) ? X : Z;
}

static void assert_normal_within(const float got[3], double x, double y, double z, double tolerance)
{
    double len = sqrt(x * x + y * y + z * z);
    for (int a = 0; a < 3; ++a) {
        double want = (a == 0 ? x : a == 1 ? y : z) / len;
        if (fabs(got[a] - want) > tolerance)
            fail_msg("normal (%.9f %.9f %.9f), want (%.9f %.9f %.9f)", got[0], got[1], got[2], x / len, y / len,
                     z / len);
    }
}

static void assert_normal(const float got[3], double x, double y, double z)
{
    assert_normal_within(got, x, y, z, 1e-6);
}

/* The fixed-point point at (x, y, z) * 2^-32 given as 2^32 fractions. */
static void at(double x, double y, double z, uint32_t u[3])
{
    u[0] = (uint32_t)(x * 4294967296.0), u[1] = (uint32_t)(y * 4294967296.0), u[2] = (uint32_t)(z * 4294967296.0);
}

/* Across the mid-plane x = 1/2 between a +z cell and a +x cell the nearest
 * lookup steps from +z to +x; the filter gives (+z + +x)/2 on both sides, and
 * the exact trilinear blend inside. */
static void test_step_across_a_face(void **state)
{
    (void)state;
    fixture f;
    small_tree(0xFF, 0, step_normal, &f.tree);
    fixture_make(&f);
    uint32_t below[3] = {0x7FFFFFFFu, 0x40000000u, 0x40000000u}, above[3] = {0x80000000u, 0x40000000u, 0x40000000u};
    ms_apo_lookup_result a, b;
    ms_apo_lookup_fixed(&f.view, below, 30, MS_APO_MISSING_NEAREST, &a);
    ms_apo_lookup_fixed(&f.view, above, 30, MS_APO_MISSING_NEAREST, &b);
    assert_normal(a.normal, 0, 0, 1); /* today's lookup: a step of 90 degrees */
    assert_normal(b.normal, 1, 0, 0);
    ms_apo_filter_result fa, fb;
    ms_apo_lookup_filtered_fixed(&f.view, below, 30, MS_APO_MISSING_NEAREST, NULL, &fa);
    ms_apo_lookup_filtered_fixed(&f.view, above, 30, MS_APO_MISSING_NEAREST, NULL, &fb);
    assert_normal(fa.normal, 1, 0, 1);
    assert_normal(fb.normal, 1, 0, 1);
    assert_int_equal(fa.lookups, 8);
    assert_int_equal(fa.missing, 0);
    /* a quarter of the cell's width from its centre towards the face: weight
     * (2^29 + 1/2) / 2^31 on +x; y and z at the centres (weights 2^-32) */
    uint32_t p[3] = {0x60000000u, 0x40000000u, 0x40000000u};
    ms_apo_filter_result r;
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    double t = (536870912.0 + 0.5) / 2147483648.0;
    assert_true(fabsf(r.weight[0] - (float)t) < 1e-9f);
    assert_true(r.weight[1] < 1e-9f && r.weight[2] < 1e-9f);
    assert_normal(r.normal, t, 0, 1 - t);
    /* at the cell's centre: its own normal */
    at(0.25, 0.25, 0.25, p);
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, 0, 0, 1);
    /* continuous across the face: sweep x over the face in small steps, the
     * filtered normal moves by at most the step's share of 90 degrees */
    double last = -1;
    float prev[3] = {0};
    for (int i = -64; i <= 64; ++i) {
        uint32_t q[3] = {0x80000000u + (uint32_t)(i * (1 << 22)), 0x40000000u, 0x40000000u};
        ms_apo_lookup_filtered_fixed(&f.view, q, 30, MS_APO_MISSING_NEAREST, NULL, &r);
        if (last >= 0) {
            double c = prev[0] * r.normal[0] + prev[1] * r.normal[1] + prev[2] * r.normal[2];
            double step = acos(c > 1 ? 1 : c);
            assert_true(step < 0.01); /* 2^22 / 2^31 of the blend: under 0.2 degrees a step */
        }
        memcpy(prev, r.normal, sizeof prev);
        last = 0;
    }
    fixture_free(&f);
}

/* The neighbour one unit past the face is the immediate one, even when deeper:
 * from the lower +z cell, next to the deep +x cell whose near layer carries +y,
 * the blend takes +y (depth 2), not +x. */
static void test_deeper_neighbour(void **state)
{
    (void)state;
    fixture f;
    small_tree(0xFF, 0x10, step_normal, &f.tree); /* octant 4 (x upper, y, z lower) split */
    fixture_make(&f);
    uint32_t p[3] = {0x60000000u, 0x40000000u, 0x40000000u};
    ms_apo_filter_result r;
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_int_equal(r.centre.depth, 1);
    assert_int_equal(r.neighbour_depth[4], 2); /* x neighbour: depth-2 cell (2, 1, 1) */
    assert_int_equal(r.neighbour_depth[6], 1); /* x and y: octant 6, a depth-1 leaf */
    double t = (536870912.0 + 0.5) / 2147483648.0, s = 1.0 / 4294967296.0; /* s: (0 + 1/2) / 2^31 */
    /* corners (x, y, z bits as octants): 0..3 stay in x: +z; 4, x only: the deep
     * cell (2, 1, 1), +y; 5..7 move in y or z too: depth-1 leaves, +x */
    double w[8], n[3] = {0, 0, 0};
    for (int k = 0; k < 8; ++k) {
        w[k] = ((k & 4) ? t : 1 - t) * ((k & 2) ? s : 1 - s) * ((k & 1) ? s : 1 - s);
        const float *c = k < 4 ? Z : (k == 4 ? Y : X);
        for (int a = 0; a < 3; ++a)
            n[a] += w[k] * c[a];
    }
    assert_normal(r.normal, n[0], n[1], n[2]);
    /* with a depth cap of 1 the deep cell is not read: its mean instead */
    ms_apo_lookup_filtered_fixed(&f.view, p, 1, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_int_equal(r.neighbour_depth[4], 1);
    fixture_free(&f);
}

/* A neighbour that was not stored gives the caller's smooth normal (a chunk is
 * a correction of it: docs/APO.md), not its ancestor's mean; so does a centre
 * that was not stored, whose cell is then the absent child's, so that the
 * texels next to it blend into it. Without a texel in any corner the smooth
 * normal comes back exactly as given (not renormalised). */
static const float S[3] = {0.0f, 0.6f, 0.8f};

static void test_missing_neighbour(void **state)
{
    (void)state;
    fixture f;
    small_tree(0x11, 0, step_normal, &f.tree); /* only octants 0 (+z) and 4 (+x) */
    fixture_make(&f);
    uint32_t p[3] = {0x60000000u, 0x60000000u, 0x40000000u};
    ms_apo_filter_result r;
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_STOP, S, &r);
    assert_int_equal(r.missing, 6); /* every corner but 0 (the centre) and 4 (+x) */
    assert_int_equal(r.smooth, 6);
    double t = (536870912.0 + 0.5) / 2147483648.0, s = 1.0 / 4294967296.0, n[3] = {0, 0, 0};
    for (int k = 0; k < 8; ++k) {
        double w = ((k & 4) ? t : 1 - t) * ((k & 2) ? t : 1 - t) * ((k & 1) ? s : 1 - s);
        const float *c = k == 0 ? Z : (k == 4 ? X : S);
        for (int a = 0; a < 3; ++a)
            n[a] += w * c[a];
    }
    assert_normal(r.normal, n[0], n[1], n[2]);
    /* the centre absent (octant 2: y upper), its cell the child's at depth 1:
     * blended with octant 0 below it (+z) by the same weights */
    uint32_t q[3] = {0x20000000u, 0x90000000u, 0x20000000u};
    ms_apo_lookup_filtered_fixed(&f.view, q, 30, MS_APO_MISSING_STOP, S, &r);
    assert_int_equal(r.centre.stop, MS_APO_STOP_MISSING);
    assert_true(r.centre.smooth);
    assert_int_equal(r.centre.depth, 1);
    assert_int_equal(r.centre.cell[0], 0);
    assert_int_equal(r.centre.cell[1], 1);
    assert_int_equal(r.centre.cell[2], 0);
    /* per axis t = (W/2 - 1 - r + 0.5) / W, r the offset in the cell (W = 2^31) */
    double ty = (0x40000000 - 1 - 0x10000000 + 0.5) / 2147483648.0;
    double tx = (0x40000000 - 1 - 0x20000000 + 0.5) / 2147483648.0, tz = tx;
    double m[3] = {0, 0, 0};
    for (int k = 0; k < 8; ++k) {
        double w = ((k & 4) ? tx : 1 - tx) * ((k & 2) ? ty : 1 - ty) * ((k & 1) ? tz : 1 - tz);
        /* x lower side: no neighbour (cube face), z likewise: only y moves, to octant 0 */
        bool y = k & 2;
        const float *c = y ? Z : S;
        for (int a = 0; a < 3; ++a)
            m[a] += w * c[a];
    }
    assert_normal(r.normal, m[0], m[1], m[2]);
    /* far from every texel: the smooth normal as given */
    const float longer[3] = {0.0f, 1.2f, 1.6f};
    uint32_t far_point[3] = {0x20000000u, 0xE0000000u, 0xE0000000u};
    ms_apo_lookup_filtered_fixed(&f.view, far_point, 30, MS_APO_MISSING_STOP, longer, &r);
    assert_int_equal(r.texels, 0);
    assert_true(r.normal[0] == 0.0f && r.normal[1] == 1.2f && r.normal[2] == 1.6f);
    fixture_free(&f);
}

/* A node whose mean word says "smooth", where a depth cap stops: the smooth
 * normal there; the same point one level deeper reaches its texel. */
static void test_smooth_mean(void **state)
{
    (void)state;
    fixture f;
    small_tree(0x01, 0x01, step_normal, &f.tree); /* octant 0 internal, 8 leaves below */
    f.tree.nodes[1].smooth = 1;
    fixture_make(&f);
    uint32_t p[3] = {0x10000000u, 0x10000000u, 0x10000000u};
    ms_apo_lookup_result plain;
    ms_apo_lookup_fixed(&f.view, p, 1, MS_APO_MISSING_STOP, &plain);
    assert_int_equal(plain.stop, MS_APO_STOP_CAP);
    assert_true(plain.smooth);
    assert_int_equal(plain.code, MS_APO_NORMAL_SMOOTH);
    ms_apo_filter_result r;
    ms_apo_lookup_filtered_fixed(&f.view, p, 1, MS_APO_MISSING_STOP, S, &r);
    assert_int_equal(r.texels, 0);
    assert_normal(r.normal, S[0], S[1], S[2]);
    ms_apo_lookup_fixed(&f.view, p, 30, MS_APO_MISSING_STOP, &plain);
    assert_int_equal(plain.stop, MS_APO_STOP_LEAF);
    assert_false(plain.smooth);
    fixture_free(&f);
}

/* (-x - z)/sqrt(2) on the upper half (a scan whose faces are wound
 * inconsistently, or a sample from the other sheet of a thin part), facing away
 * from the +z of the lower half: taken turned over, so the blend across x = 1/2
 * is the mean of +z and (x + z)/sqrt(2), not of two normals that half cancel. */
static const float away[3] = {-0.70710678f, 0.0f, -0.70710678f};

static const float *flipped_normal(uint32_t depth, const uint32_t cell[3])
{
    (void)depth;
    return cell[0] ? away : Z;
}

static void test_neighbour_facing_away(void **state)
{
    (void)state;
    fixture f;
    small_tree(0xFF, 0, flipped_normal, &f.tree);
    fixture_make(&f);
    uint32_t below[3] = {0x7FFFFFFFu, 0x40000000u, 0x40000000u}, p[3] = {0x60000000u, 0x40000000u, 0x40000000u};
    ms_apo_filter_result r;
    float dec[3]; /* the stored code of `away`, decoded */
    ms_apo_normal_decode(ms_apo_normal_encode(away), dec);
    ms_apo_lookup_filtered_fixed(&f.view, below, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, -0.5 * dec[0], 0, 0.5 - 0.5 * dec[2]);
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    double t = 0.25;
    assert_normal(r.normal, -t * dec[0], 0, (1 - t) - t * dec[2]);
    /* and from the upper side, +z is turned over to its side */
    uint32_t above[3] = {0x80000000u, 0x40000000u, 0x40000000u};
    ms_apo_lookup_filtered_fixed(&f.view, above, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, 0.5 * dec[0], 0, 0.5 * dec[2] - 0.5);
    fixture_free(&f);
}

/* At the cube's faces the neighbour belongs to another chunk: the axis stays
 * (clamp to edge), so near x = 0 the +z cell keeps its normal. */
static void test_cube_faces_clamp(void **state)
{
    (void)state;
    fixture f;
    small_tree(0xFF, 0, step_normal, &f.tree);
    fixture_make(&f);
    uint32_t p[3] = {0x01000000u, 0x40000000u, 0x40000000u};
    ms_apo_filter_result r;
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, 0, 0, 1);
    assert_true(r.weight[0] > 0.49f);
    uint32_t q[3] = {0xFFFFFFFFu, 0xFFFFFFFFu, 0xFFFFFFFFu};
    ms_apo_lookup_filtered_fixed(&f.view, q, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, 1, 0, 0);
    assert_int_equal(r.lookups, 1);
    /* a leaf root: no neighbours */
    ms_apo_tree_free(&f.tree);
    ms_apo_chunk_free(&f.chunk);
    memset(&f.tree, 0, sizeof f.tree);
    f.tree.nodes = calloc(1, sizeof *f.tree.nodes);
    assert_non_null(f.tree.nodes);
    memcpy(f.tree.nodes[0].normal, Y, sizeof Y);
    f.tree.level_count = 1, f.tree.node_count = 1, f.tree.level_start[1] = 1;
    fixture_make(&f);
    ms_apo_lookup_filtered_fixed(&f.view, p, 30, MS_APO_MISSING_NEAREST, NULL, &r);
    assert_normal(r.normal, 0, 1, 0);
    assert_int_equal(r.lookups, 1);
    fixture_free(&f);
    /* an empty chunk: the smooth normal (zero without one) */
    ms_apo_view empty;
    memset(&empty, 0, sizeof empty);
    assert_int_equal(ms_apo_lookup_filtered_fixed(&empty, p, 30, MS_APO_MISSING_NEAREST, NULL, &r), MS_APO_STOP_EMPTY);
    assert_true(r.normal[0] == 0.0f && r.normal[1] == 0.0f && r.normal[2] == 0.0f);
    assert_int_equal(ms_apo_lookup_filtered_fixed(&empty, p, 30, MS_APO_MISSING_STOP, S, &r), MS_APO_STOP_EMPTY);
    assert_true(r.normal[0] == S[0] && r.normal[1] == S[1] && r.normal[2] == S[2]);
}

static void test_footprint_depth(void **state)
{
    (void)state;
    assert_int_equal(ms_apo_footprint_depth(1.0f), 0);
    assert_int_equal(ms_apo_footprint_depth(7.0f), 0);
    assert_int_equal(ms_apo_footprint_depth(INFINITY), 0);
    assert_int_equal(ms_apo_footprint_depth(0.99f), 1); /* 2^-1 <= 0.99 < 2^0 */
    assert_int_equal(ms_apo_footprint_depth(0.5f), 1);
    assert_int_equal(ms_apo_footprint_depth(0.3f), 2);
    assert_int_equal(ms_apo_footprint_depth(0.25f), 2);
    assert_int_equal(ms_apo_footprint_depth(nextafterf(0.25f, 1.0f)), 2);
    assert_int_equal(ms_apo_footprint_depth(nextafterf(0.25f, 0.0f)), 3);
    assert_int_equal(ms_apo_footprint_depth(ldexpf(1.0f, -20)), 20);
    assert_int_equal(ms_apo_footprint_depth(ldexpf(1.5f, -21)), 21);
    assert_int_equal(ms_apo_footprint_depth(ldexpf(1.0f, -40)), 40);
    assert_int_equal(ms_apo_footprint_depth(0.0f), UINT32_MAX);
    assert_int_equal(ms_apo_footprint_depth(-1.0f), UINT32_MAX);
    assert_int_equal(ms_apo_footprint_depth(NAN), UINT32_MAX);
    /* every depth d >= 1: 2^-d <= footprint < 2^-(d-1), the first depth whose
     * cells are no wider than the footprint */
    uint64_t rng = 7;
    for (int i = 0; i < 100000; ++i) {
        float f = ldexpf(0.5f + 0.5f * ms_test_randf(&rng), -(int)(ms_test_rand(&rng) % 30));
        uint32_t d = ms_apo_footprint_depth(f);
        assert_true(d >= 1);
        assert_true(ldexpf(1.0f, -(int)d) <= f);
        assert_true(ldexpf(1.0f, 1 - (int)d) > f);
    }
}

/* The normal the brute-force lookup gives at a fixed point: a texel, or the
 * smooth normal S where the node is absent (STOP) or says "smooth"; the node's
 * depth and cell (an absent child's where it is absent). */
static bool brute_normal(const ms_apo_tree *tree, const uint32_t u[3], uint32_t cap, uint32_t complete,
                         ms_apo_missing_rule rule, float n[3], uint32_t *depth, uint32_t cell[3])
{
    ms_apo_stop stop;
    const ms_apo_node *c = &tree->nodes[ms_test_brute_lookup(tree, u, cap, complete, rule, &stop)];
    *depth = c->depth;
    memcpy(cell, c->cell, 3 * sizeof *cell);
    if (stop == MS_APO_STOP_MISSING) {
        *depth = c->depth + 1u;
        for (int a = 0; a < 3; ++a)
            cell[a] = 2 * c->cell[a] + (u[a] >> (31 - c->depth) & 1u);
    }
    if (stop == MS_APO_STOP_MISSING || (c->child_mask && c->smooth)) {
        memcpy(n, S, 3 * sizeof *n);
        return false;
    }
    ms_apo_normal_decode(ms_apo_normal_encode(c->normal), n);
    return true;
}

/* Random trees (a third of their internal nodes "smooth") and points: the
 * filter against the same rule written with the brute-force lookup (cells
 * tested in doubles), both missing-child rules and random depth caps. */
static void test_random_against_brute_force(void **state)
{
    (void)state;
    uint64_t rng = 99;
    uint64_t missing = 0, deeper = 0, flipped = 0, smooth = 0, plain_smooth = 0;
    for (int k = 0; k < 6; ++k) {
        fixture f;
        ms_test_random_tree(500 + (uint64_t)k, 5 + (uint32_t)k, 0.6, &f.tree);
        for (size_t i = 0; i < f.tree.node_count; ++i)
            f.tree.nodes[i].smooth = f.tree.nodes[i].child_mask && ms_test_rand(&rng) % 3 == 0;
        fixture_make(&f);
        for (int i = 0; i < 20000; ++i) {
            float p[3] = {ms_test_randf(&rng), ms_test_randf(&rng), ms_test_randf(&rng)};
            uint32_t u[3];
            ms_apo_position_to_fixed(p, u);
            uint32_t cap = (i & 3) == 0 ? (uint32_t)(ms_test_rand(&rng) % 8) : 30;
            ms_apo_missing_rule rule = (i & 1) ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP;
            ms_apo_filter_result r;
            ms_apo_lookup_filtered_fixed(&f.view, u, cap, rule, S, &r);
            missing += r.missing;
            smooth += r.smooth;
            float own[3];
            uint32_t depth, cell[3];
            bool texels = brute_normal(&f.tree, u, cap, f.view.complete_levels, rule, own, &depth, cell);
            assert_int_equal(r.centre.depth, depth);
            assert_int_equal(r.centre.smooth, !texels);
            if (depth == 0) {
                assert_normal(r.normal, own[0], own[1], own[2]);
                continue;
            }
            double w = ldexp(1.0, -(int)depth), unit = ldexp(1.0, -32), lo[3], x[3], t[3], q[3];
            bool moves[3];
            for (int a = 0; a < 3; ++a) {
                lo[a] = cell[a] * w;
                double v = u[a] * unit;
                x[a] = v < lo[a] ? lo[a] : (v > lo[a] + w - unit ? lo[a] + w - unit : v);
                bool upper = x[a] >= lo[a] + w / 2;
                t[a] = (upper ? x[a] - (lo[a] + w / 2) + unit / 2 : (lo[a] + w / 2) - x[a] - unit / 2) / w;
                q[a] = upper ? lo[a] + w : lo[a] - unit;
                moves[a] = q[a] >= 0 && q[a] < 1;
                assert_true(fabs(r.weight[a] - t[a]) < 1e-6);
            }
            double n[3] = {0, 0, 0};
            for (int corner = 0; corner < 8; ++corner) {
                double wk = 1;
                uint32_t pt[3];
                for (int a = 0; a < 3; ++a) {
                    bool bit = corner >> (2 - a) & 1;
                    wk *= bit ? t[a] : 1 - t[a];
                    pt[a] = (uint32_t)((bit && moves[a] ? q[a] : x[a]) * 4294967296.0);
                }
                float dec[3];
                memcpy(dec, own, sizeof dec);
                if (corner && (pt[0] != (uint32_t)(x[0] * 4294967296.0) || pt[1] != (uint32_t)(x[1] * 4294967296.0) ||
                               pt[2] != (uint32_t)(x[2] * 4294967296.0))) {
                    uint32_t nd, nc[3];
                    texels |= brute_normal(&f.tree, pt, cap, f.view.complete_levels, MS_APO_MISSING_STOP, dec, &nd,
                                           nc);
                    deeper += nd > depth;
                }
                if (dec[0] * own[0] + dec[1] * own[1] + dec[2] * own[2] < 0)
                    wk = -wk, flipped++;
                for (int a = 0; a < 3; ++a)
                    n[a] += wk * dec[a];
            }
            if (!texels) {
                plain_smooth++;
                assert_true(r.texels == 0 && r.normal[0] == S[0] && r.normal[1] == S[1] && r.normal[2] == S[2]);
            } else if (sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) > 1e-2) {
                assert_true(r.texels > 0);
                assert_normal_within(r.normal, n[0], n[1], n[2], 1e-4);
            }
        }
        fixture_free(&f);
    }
    print_message("neighbours missing %llu, smooth %llu, deeper than the centre %llu, turned over %llu; "
                  "points without a texel around %llu\n",
                  (unsigned long long)missing, (unsigned long long)smooth, (unsigned long long)deeper,
                  (unsigned long long)flipped, (unsigned long long)plain_smooth);
    assert_true(missing > 1000 && deeper > 1000 && flipped > 1000 && smooth > missing && plain_smooth > 100);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_step_across_a_face),  cmocka_unit_test(test_deeper_neighbour),
        cmocka_unit_test(test_missing_neighbour),   cmocka_unit_test(test_cube_faces_clamp),
        cmocka_unit_test(test_footprint_depth),     cmocka_unit_test(test_random_against_brute_force),
        cmocka_unit_test(test_neighbour_facing_away), cmocka_unit_test(test_smooth_mean),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
