/* The codec complex's decoder fast paths (ms_complex.h): the one-centre star
 * gathered without per-slot marks equals the general gather on every vertex of
 * random complexes (small and large stars, edges, duplicate triangles, keys in
 * any discovery order), a hand-built star has its exact canonical form, and a
 * cell's corner, refinement and coarsening agree with its key. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_complex.h"
#include "ms_quant.h"

#define P 8

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rnd(uint32_t below)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return (uint32_t)(rng_state % below);
}

/* A full-precision cell (level 3P) at grid point (x, y, z). */
static uint32_t add_point(ms_complex *cx, uint32_t x, uint32_t y, uint32_t z)
{
    uint32_t c[3] = {x, y, z};
    return ms_cx_add_vertex(cx, ms_quant_key(x, y, z, P), 3 * P, c);
}

static void star_equal(const ms_cx_star *a, const ms_cx_star *b)
{
    assert_int_equal(a->nn, b->nn);
    assert_int_equal(a->np, b->np);
    assert_int_equal(a->adj01, b->adj01);
    assert_int_equal(a->edge01, b->edge01);
    assert_memory_equal(a->nbr, b->nbr, a->nn * sizeof *a->nbr);
    assert_memory_equal(a->adj, b->adj, a->nn);
    assert_memory_equal(a->both, b->both, a->nn * sizeof *a->both);
    for (uint32_t p = 0; p < a->np; ++p) {
        assert_int_equal(a->pairs[p].i, b->pairs[p].i);
        assert_int_equal(a->pairs[p].j, b->pairs[p].j);
        assert_int_equal(a->pairs[p].t0, b->pairs[p].t0);
        assert_int_equal(a->pairs[p].t1, b->pairs[p].t1);
    }
    assert_memory_equal(a->adj_start, b->adj_start, (a->nn + 1) * sizeof *a->adj_start);
    assert_memory_equal(a->adj_list, b->adj_list, a->adj_start[a->nn] * sizeof *a->adj_list);
}

/* nv random points; every vertex gets about `degree` random triangles and a few
 * edges, some triangles repeated with the opposite orientation. */
static void random_complex(ms_complex *cx, uint32_t nv, uint32_t degree)
{
    ms_error err;
    uint32_t nt = nv * degree / 3 + 8, ne = nv + 8;
    assert_int_equal(ms_cx_init(cx, P, nv, nt, ne, &err), MS_OK);
    assert_int_equal(ms_cx_reserve(cx, nv, nt, ne, &err), MS_OK);
    for (uint32_t i = 0; i < nv; ++i) {
        /* distinct points: the index spread over the grid, shuffled */
        uint32_t x = (i * 37u) % 256, y = (i * 11u + 5) % 256, z = i / 256;
        add_point(cx, x, y, z);
    }
    for (uint32_t t = 0; t + 8 < nt; ++t) {
        uint32_t a = rnd(nv), b = rnd(nv), c = rnd(nv);
        if (a == b || b == c || a == c)
            continue;
        ms_cx_add_tri(cx, a, b, c);
        if (rnd(16) == 0 && t + 9 < nt) {
            ms_cx_add_tri(cx, a, c, b);
            ++t;
        }
    }
    for (uint32_t e = 0; e + 8 < ne; ++e) {
        uint32_t a = rnd(nv), b = rnd(nv);
        if (a != b && rnd(4) == 0)
            ms_cx_add_edge(cx, a, b);
    }
    assert_false(cx->nomem);
}

static void compare_all_stars(uint32_t nv, uint32_t degree, uint32_t *small_seen)
{
    ms_complex cx;
    random_complex(&cx, nv, degree);
    ms_cx_star fast = {0}, general = {0};
    ms_error err;
    for (uint32_t s = 0; s < cx.nv; ++s) {
        *small_seen += cx.v[s].n <= MS_CX_SMALL_STAR;
        assert_int_equal(ms_cx_gather(&cx, s, MS_CX_NONE, &fast, &err), MS_OK);
        assert_int_equal(ms_cx_gather_general(&cx, s, MS_CX_NONE, &general, &err), MS_OK);
        star_equal(&fast, &general);
    }
    ms_cx_star_free(&fast);
    ms_cx_star_free(&general);
    ms_cx_free(&cx);
}

static void test_fast_star_equals_general(void **state)
{
    (void)state;
    uint32_t small = 0;
    compare_all_stars(200, 6, &small);    /* every star small */
    assert_int_equal(small, 200);
    small = 0;
    compare_all_stars(60, 40, &small);    /* most stars past the small limit */
    assert_true(small < 30);
    small = 0;
    compare_all_stars(300, 20, &small);   /* both paths, around the limit */
    assert_true(small > 0 && small < 300);
}

/* Centre c with triangles (c,a,b), (c,d,b), an edge (c,e) and an isolated
 * neighbourhood elsewhere: neighbours sorted by key, pairs by local index. */
static void test_star_exact(void **state)
{
    (void)state;
    ms_complex cx;
    ms_error err;
    assert_int_equal(ms_cx_init(&cx, P, 8, 4, 4, &err), MS_OK);
    assert_int_equal(ms_cx_reserve(&cx, 8, 4, 4, &err), MS_OK);
    uint32_t a = add_point(&cx, 200, 0, 0);   /* largest key (x high bit) */
    uint32_t c = add_point(&cx, 10, 10, 10);
    uint32_t b = add_point(&cx, 0, 0, 1);     /* smallest key */
    uint32_t d = add_point(&cx, 0, 128, 0);
    uint32_t e = add_point(&cx, 0, 0, 64);
    uint32_t t0 = ms_cx_add_tri(&cx, c, a, b);
    uint32_t t1 = ms_cx_add_tri(&cx, c, d, b);
    ms_cx_add_edge(&cx, c, e);
    ms_cx_star st = {0};
    assert_int_equal(ms_cx_gather(&cx, c, MS_CX_NONE, &st, &err), MS_OK);
    /* keys: b (z bit 0) < e (z bit 6) < d (y bit 7) < a (x bit 7) */
    assert_int_equal(st.nn, 4);
    assert_int_equal(st.nbr[0], b);
    assert_int_equal(st.nbr[1], e);
    assert_int_equal(st.nbr[2], d);
    assert_int_equal(st.nbr[3], a);
    assert_int_equal(st.np, 2);
    assert_int_equal(st.pairs[0].i, 0); /* (b, d) */
    assert_int_equal(st.pairs[0].j, 2);
    assert_int_equal(st.pairs[0].t0, t1);
    assert_int_equal(st.pairs[1].i, 0); /* (b, a) */
    assert_int_equal(st.pairs[1].j, 3);
    assert_int_equal(st.pairs[1].t0, t0);
    assert_int_equal(st.pairs[1].t1, MS_CX_NONE);
    /* b's partners are d and a; e has none */
    assert_int_equal(st.adj_start[1] - st.adj_start[0], 2);
    assert_int_equal(st.adj_start[2] - st.adj_start[1], 0);
    assert_int_equal(st.adj_list[st.adj_start[0]], 2);
    assert_int_equal(st.adj_list[st.adj_start[0] + 1], 3);
    ms_cx_star_free(&st);
    ms_cx_free(&cx);
}

/* The root cell refined along x, y, z into halves and back: corner, centre and
 * level follow the key at every step. */
static void test_cell_refine_coarsen(void **state)
{
    (void)state;
    ms_complex cx;
    ms_error err;
    assert_int_equal(ms_cx_init(&cx, P, 2, 1, 1, &err), MS_OK);
    uint32_t zero[3] = {0, 0, 0};
    uint32_t s = ms_cx_add_vertex(&cx, 0, 0, zero);
    assert_int_equal(cx.cen[s][0], 256); /* twice the centre of [0, 256) */
    const int second[6] = {1, 0, 1, 1, 0, 0};
    uint32_t want[3] = {0, 0, 0};
    for (unsigned L = 0; L < 6; ++L) {
        ms_cx_refine_cell(&cx, s, L, second[L]);
        want[L % 3] += second[L] ? 256u >> (L / 3 + 1) : 0;
        uint32_t c[3];
        ms_cx_corner(&cx, s, c);
        assert_memory_equal(c, want, sizeof c);
        assert_int_equal(cx.v[s].level, L + 1);
        assert_int_equal(cx.cen[s][3], (int32_t)(L + 1));
        for (int a = 0; a < 3; ++a)
            assert_int_equal(cx.cen[s][a], (int32_t)(2 * want[a] + ms_cx_width(&cx, L + 1, a)));
    }
    for (unsigned L = 6; L-- > 0;)
        ms_cx_coarsen_cell(&cx, s, L, second[L]);
    uint32_t c[3];
    ms_cx_corner(&cx, s, c);
    assert_memory_equal(c, zero, sizeof c);
    assert_int_equal(cx.v[s].level, 0);
    assert_int_equal(cx.cen[s][2], 256);
    ms_cx_free(&cx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fast_star_equals_general),
        cmocka_unit_test(test_star_exact),
        cmocka_unit_test(test_cell_refine_coarsen),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
