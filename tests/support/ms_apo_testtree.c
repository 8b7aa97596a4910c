#include "ms_apo_testtree.h"

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_demo_model.h"

void ms_test_demo_mesh(uint32_t grid, ms_mesh *mesh)
{
    ms_demo_model model = {.grid = grid, .seed = 0};
    memset(mesh, 0, sizeof *mesh);
    assert_int_equal(ms_demo_build(&model, mesh, NULL), MS_OK);
}

void ms_test_apo_cube_around(const ms_mesh *mesh, ms_apo_build_options *o)
{
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < mesh->vertex_count; ++i)
        for (int a = 0; a < 3; ++a) {
            lo[a] = fmin(lo[a], mesh->positions[3 * i + a]);
            hi[a] = fmax(hi[a], mesh->positions[3 * i + a]);
        }
    double size = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2])) * 1.02;
    for (int a = 0; a < 3; ++a)
        o->cube_origin[a] = 0.5 * (lo[a] + hi[a]) - 0.5 * size;
    o->cube_size = size;
}

uint64_t ms_test_rand(uint64_t *s)
{
    uint64_t x = *s;
    x ^= x >> 12;
    x ^= x << 25;
    x ^= x >> 27;
    *s = x;
    return x * 2685821657736338717ull;
}

float ms_test_randf(uint64_t *s) { return (float)(ms_test_rand(s) >> 40) / 16777216.0f; }

static void random_unit(uint64_t *s, float n[3])
{
    for (;;) {
        double v[3], l2 = 0;
        for (int a = 0; a < 3; ++a) {
            v[a] = 2.0 * ms_test_randf(s) - 1.0;
            l2 += v[a] * v[a];
        }
        if (l2 > 1e-4 && l2 <= 1.0) {
            for (int a = 0; a < 3; ++a)
                n[a] = (float)(v[a] / sqrt(l2));
            return;
        }
    }
}

/* Appends the children of every node of the last level according to decide(). */
typedef uint8_t (*mask_fn)(void *ctx, const ms_apo_node *node);

static void grow(ms_apo_tree *t, uint32_t max_depth, mask_fn decide, void *ctx, uint64_t *rng)
{
    size_t cap = 1024;
    t->nodes = calloc(cap, sizeof *t->nodes);
    assert_non_null(t->nodes);
    t->node_count = 1;
    random_unit(rng, t->nodes[0].normal);
    t->level_start[0] = 0;
    t->level_start[1] = 1;
    t->level_count = 1;
    for (uint32_t d = 0; d < max_depth; ++d) {
        size_t begin = t->level_start[d], end = t->level_start[d + 1];
        for (size_t i = begin; i < end; ++i) {
            uint8_t mask = decide(ctx, &t->nodes[i]);
            t->nodes[i].child_mask = mask;
            if (!mask)
                continue;
            t->nodes[i].first_child = (uint32_t)t->node_count;
            for (uint32_t o = 0; o < 8; ++o) {
                if (!(mask >> o & 1u))
                    continue;
                if (t->node_count == cap) {
                    cap *= 2;
                    t->nodes = realloc(t->nodes, cap * sizeof *t->nodes);
                    assert_non_null(t->nodes);
                }
                ms_apo_node *c = &t->nodes[t->node_count++];
                const ms_apo_node *p = &t->nodes[i];
                memset(c, 0, sizeof *c);
                c->depth = (uint8_t)(d + 1);
                c->cell[0] = 2 * p->cell[0] + (o >> 2 & 1u);
                c->cell[1] = 2 * p->cell[1] + (o >> 1 & 1u);
                c->cell[2] = 2 * p->cell[2] + (o & 1u);
                random_unit(rng, c->normal);
            }
        }
        if (t->node_count == end)
            break;
        t->level_count = d + 2;
        t->level_start[d + 2] = t->node_count;
    }
    ms_apo_tree_average_normals(t);
    assert_int_equal(ms_apo_tree_check(t, NULL), MS_OK);
}

typedef struct random_ctx {
    uint64_t *rng;
    uint32_t max_depth;
    double p;
} random_ctx;

static uint8_t random_mask(void *vctx, const ms_apo_node *n)
{
    random_ctx *c = vctx;
    if (n->depth >= c->max_depth)
        return 0;
    if (n->depth > 0 && ms_test_randf(c->rng) >= c->p)
        return 0;
    uint8_t m = 0;
    while (!m)
        m = (uint8_t)ms_test_rand(c->rng);
    return m;
}

void ms_test_random_tree(uint64_t seed, uint32_t max_depth, double p_internal, ms_apo_tree *tree)
{
    uint64_t rng = seed * 0x9E3779B97F4A7C15ull + 1;
    random_ctx c = {&rng, max_depth, p_internal};
    memset(tree, 0, sizeof *tree);
    grow(tree, max_depth, random_mask, &c, &rng);
}

typedef struct chain_ctx {
    const uint8_t *path;
    uint32_t depth;
    uint32_t cell[MS_APO_MAX_LEVELS][3]; /* the internal node's cell per depth */
} chain_ctx;

static uint8_t chain_mask(void *vctx, const ms_apo_node *n)
{
    chain_ctx *c = vctx;
    if (n->depth >= c->depth || memcmp(n->cell, c->cell[n->depth], sizeof n->cell) != 0)
        return 0;
    uint32_t o = c->path[n->depth];
    c->cell[n->depth + 1][0] = 2 * n->cell[0] + (o >> 2 & 1u);
    c->cell[n->depth + 1][1] = 2 * n->cell[1] + (o >> 1 & 1u);
    c->cell[n->depth + 1][2] = 2 * n->cell[2] + (o & 1u);
    return 0xFF;
}

void ms_test_chain_tree(uint32_t depth, const uint8_t *path, ms_apo_tree *tree)
{
    uint64_t rng = 12345;
    chain_ctx c;
    memset(&c, 0, sizeof c);
    c.path = path;
    c.depth = depth;
    memset(tree, 0, sizeof *tree);
    grow(tree, depth, chain_mask, &c, &rng);
}

size_t ms_test_brute_lookup(const ms_apo_tree *t, const uint32_t fixed[3], uint32_t depth_cap,
                            uint32_t complete_levels, ms_apo_missing_rule rule, ms_apo_stop *stop)
{
    double p[3];
    for (int a = 0; a < 3; ++a)
        p[a] = fixed[a] / 4294967296.0;
    size_t i = 0;
    for (;;) {
        const ms_apo_node *n = &t->nodes[i];
        if (!n->child_mask) {
            *stop = MS_APO_STOP_LEAF;
            return i;
        }
        if (n->depth >= depth_cap) {
            *stop = MS_APO_STOP_CAP;
            return i;
        }
        if ((uint32_t)n->depth + 1 >= complete_levels) {
            *stop = MS_APO_STOP_PREFIX;
            return i;
        }
        double w = ldexp(1.0, -(int)n->depth - 1); /* child width */
        size_t k = n->first_child, found = SIZE_MAX;
        for (uint32_t o = 0; o < 8; ++o) {
            if (!(n->child_mask >> o & 1u))
                continue;
            const ms_apo_node *c = &t->nodes[k];
            bool inside = true;
            for (int a = 0; a < 3; ++a)
                inside = inside && p[a] >= c->cell[a] * w && p[a] < (c->cell[a] + 1) * w;
            if (inside)
                found = k;
            ++k;
        }
        if (found == SIZE_MAX) {
            if (rule == MS_APO_MISSING_STOP) {
                *stop = MS_APO_STOP_MISSING;
                return i;
            }
            /* Nearest child by L-infinity distance to its cell; ties: fewer axes
             * outside, then lower octant. Then clamp the point into it. */
            double best = INFINITY;
            int best_axes = 4;
            k = n->first_child;
            for (uint32_t o = 0; o < 8; ++o) {
                if (!(n->child_mask >> o & 1u))
                    continue;
                const ms_apo_node *c = &t->nodes[k];
                double dist = 0;
                int axes = 0;
                for (int a = 0; a < 3; ++a) {
                    double lo = c->cell[a] * w, hi = (c->cell[a] + 1) * w;
                    double g = p[a] < lo ? lo - p[a] : p[a] >= hi ? p[a] - hi : 0.0;
                    if (p[a] < lo || p[a] >= hi)
                        ++axes;
                    if (g > dist)
                        dist = g;
                }
                if (dist < best || (dist == best && axes < best_axes)) {
                    best = dist;
                    best_axes = axes;
                    found = k;
                }
                ++k;
            }
            const ms_apo_node *c = &t->nodes[found];
            for (int a = 0; a < 3; ++a) {
                double lo = c->cell[a] * w, hi = (c->cell[a] + 1) * w;
                if (p[a] < lo)
                    p[a] = lo;
                else if (p[a] >= hi)
                    p[a] = hi - 1.0 / 4294967296.0;
            }
        }
        i = found;
    }
}
