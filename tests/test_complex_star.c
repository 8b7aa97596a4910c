/* The codec complex's decoder fast paths (ms_complex.h): the one-centre star
 * gathered without per-slot marks equals the general gather on every vertex of
 * random complexes (small and large stars, edges, duplicate triangles, keys in
 * any discovery order), a hand-built star has its exact canonical form, a
 * cell's corner, refinement and coarsening agree with its key, and the in-place
 * compaction keeps the complex while renumbering around freed slots. */
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
#include "ms_test.h"

#define P 8

static uint64_t rng_state = 0x9E3779B97F4A7C15ull;

static uint32_t rnd(uint32_t below)
{
    return (uint32_t)(ms_test_random(&rng_state) % below);
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

/* Stars of points clustered within 2^k grid steps of a base at 16 bits: the
 * small gather sorts their neighbours from the bits where their centres differ
 * when those fit in ten positions, from full keys otherwise; both must order
 * as the cells' keys do (the general gather), and both must occur here. The
 * clusters straddle the boundary: 2^9 and 2^10 steps stay within ten bit
 * positions of the doubled centres, 2^11 and 2^16 mostly do not. */
static void test_fast_star_key_widths(void **state)
{
    (void)state;
    const unsigned bits = 16;
    uint32_t narrow = 0, wide = 0;
    for (unsigned k = 9; k <= 16; ++k) {
        if (k > 11 && k < 16)
            continue;
        const uint32_t nv = 400, nt = 900;
        ms_complex cx;
        ms_error err;
        assert_int_equal(ms_cx_init(&cx, bits, nv, nt, 8, &err), MS_OK);
        assert_int_equal(ms_cx_reserve(&cx, nv, nt, 0, &err), MS_OK);
        uint32_t base = k < 16 ? (1 + rnd(8)) << 12 : 0; /* aligned: no carries */
        for (uint32_t i = 0; i < nv; ++i) {
            /* distinct cells (z = base + i, i < 2^9), x and y anywhere in the cube */
            uint32_t c[3] = {base + rnd(1u << k), base + rnd(1u << k), base + i};
            ms_cx_add_vertex(&cx, ms_quant_key(c[0], c[1], c[2], bits), 3 * bits, c);
        }
        for (uint32_t t = 0; t < nt; ++t) {
            uint32_t a = rnd(nv), b = rnd(nv), c = rnd(nv);
            if (a != b && b != c && a != c)
                ms_cx_add_tri(&cx, a, b, c);
        }
        ms_cx_star fast = {0}, general = {0};
        for (uint32_t s = 0; s < nv; ++s) {
            if (cx.v[s].n > MS_CX_SMALL_STAR)
                continue;
            assert_int_equal(ms_cx_gather(&cx, s, MS_CX_NONE, &fast, &err), MS_OK);
            assert_int_equal(ms_cx_gather_general(&cx, s, MS_CX_NONE, &general, &err), MS_OK);
            star_equal(&fast, &general);
            uint32_t differ = 0;
            for (uint32_t i = 1; i < fast.nn; ++i)
                for (int a = 0; a < 3; ++a)
                    differ |= (uint32_t)(cx.cen[fast.nbr[i]][a] ^ cx.cen[fast.nbr[0]][a]);
            unsigned low = differ ? (unsigned)__builtin_ctz(differ) : 0;
            if ((differ >> low) < 1024)
                narrow++;
            else
                wide++;
        }
        ms_cx_star_free(&fast);
        ms_cx_star_free(&general);
        ms_cx_free(&cx);
    }
    assert_true(narrow > 200);
    assert_true(wide > 200);
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
        assert_int_equal(ms_cx_level(&cx, s), L + 1);
        assert_int_equal(cx.cen[s][3], (int32_t)(L + 1));
        for (int a = 0; a < 3; ++a)
            assert_int_equal(cx.cen[s][a], (int32_t)(2 * want[a] + ms_cx_width(&cx, L + 1, a)));
    }
    for (unsigned L = 6; L-- > 0;)
        ms_cx_coarsen_cell(&cx, s, L, second[L]);
    uint32_t c[3];
    ms_cx_corner(&cx, s, c);
    assert_memory_equal(c, zero, sizeof c);
    assert_int_equal(ms_cx_level(&cx, s), 0);
    assert_int_equal(cx.cen[s][2], 256);
    ms_cx_free(&cx);
}

/* The complex as sorted key triples (triangles, in their cyclic order starting
 * at the smallest key) and key pairs (edges): independent of slot numbers. */
static size_t complex_keys(const ms_complex *cx, uint64_t *out)
{
    size_t w = 0;
    for (uint32_t t = 0; t < cx->nt; ++t) {
        if (cx->tri[t][0] == MS_CX_NONE)
            continue;
        uint64_t k[3];
        for (int m = 0; m < 3; ++m)
            k[m] = cx->v[cx->tri[t][m]].key;
        int r = k[0] < k[1] ? (k[0] < k[2] ? 0 : 2) : (k[1] < k[2] ? 1 : 2);
        for (int m = 0; m < 3; ++m)
            out[w++] = k[(r + m) % 3];
    }
    for (uint32_t e = 0; e < cx->ne; ++e) {
        if (cx->edge[e][0] == MS_CX_NONE)
            continue;
        uint64_t a = cx->v[cx->edge[e][0]].key, b = cx->v[cx->edge[e][1]].key;
        out[w++] = a < b ? a : b;
        out[w++] = a < b ? b : a;
        out[w++] = UINT64_MAX; /* edge marker */
    }
    return w;
}

static int cmp_triple(const void *a, const void *b)
{
    const uint64_t *x = a, *y = b;
    for (int m = 0; m < 3; ++m)
        if (x[m] != y[m])
            return x[m] < y[m] ? -1 : 1;
    return 0;
}

static void test_compact_in_place(void **state)
{
    (void)state;
    ms_complex cx;
    ms_error err;
    random_complex(&cx, 500, 8);
    /* free some triangles and, with their simplices, some vertices */
    for (uint32_t t = 0; t < cx.nt; t += 7)
        if (cx.tri[t][0] != MS_CX_NONE)
            ms_cx_del_tri(&cx, t);
    uint32_t freed = 0;
    for (uint32_t s = 0; s < cx.nv; s += 11) {
        ms_cx_vert *v = &cx.v[s];
        while (v->n > 0) {
            uint32_t x = ms_cx_list(v)[0];
            if (x & 1)
                ms_cx_del_edge(&cx, x >> 1);
            else
                ms_cx_del_tri(&cx, x >> 1);
        }
        ms_cx_free_vertex(&cx, s);
        freed++;
    }
    assert_int_equal(cx.live_v, 500 - freed);
    uint64_t *before = malloc(3 * (cx.nt + cx.ne) * sizeof *before);
    uint64_t *after = malloc(3 * (cx.nt + cx.ne) * sizeof *after);
    assert_non_null(before);
    assert_non_null(after);
    size_t nb = complex_keys(&cx, before);
    uint32_t live_t = cx.live_t;
    /* live slots in a shuffled order */
    uint32_t *order = malloc(cx.live_v * sizeof *order), n = 0;
    assert_non_null(order);
    for (uint32_t s = 0; s < cx.nv; ++s)
        if (cx.v[s].alive)
            order[n++] = s;
    for (uint32_t i = n; i > 1; --i) {
        uint32_t j = rnd(i), tmp = order[i - 1];
        order[i - 1] = order[j];
        order[j] = tmp;
    }
    uint64_t *want_keys = malloc(n * sizeof *want_keys);
    assert_non_null(want_keys);
    for (uint32_t i = 0; i < n; ++i)
        want_keys[i] = cx.v[order[i]].key;
    assert_int_equal(ms_cx_compact(&cx, order, n, &err), MS_OK);
    assert_int_equal(cx.nv, n);
    assert_int_equal(cx.nt, live_t);
    for (uint32_t i = 0; i < n; ++i) {
        assert_int_equal(order[i], i);
        assert_true(cx.v[i].alive);
        assert_true(cx.v[i].key == want_keys[i]);
    }
    /* every list entry points at a simplex holding the vertex */
    for (uint32_t s = 0; s < n; ++s) {
        const uint32_t *l = ms_cx_list(&cx.v[s]);
        for (uint32_t k = 0; k < cx.v[s].n; ++k) {
            const uint32_t *x = l[k] & 1 ? cx.edge[l[k] >> 1] : cx.tri[l[k] >> 1];
            int arity = l[k] & 1 ? 2 : 3, found = 0;
            for (int m = 0; m < arity; ++m)
                found |= x[m] == s;
            assert_true(found);
        }
    }
    size_t na = complex_keys(&cx, after);
    assert_int_equal(na, nb);
    qsort(before, nb / 3, 3 * sizeof *before, cmp_triple);
    qsort(after, na / 3, 3 * sizeof *after, cmp_triple);
    assert_memory_equal(before, after, nb * sizeof *before);
    free(before);
    free(after);
    free(order);
    free(want_keys);
    ms_cx_free(&cx);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_fast_star_equals_general),
        cmocka_unit_test(test_fast_star_key_widths),
        cmocka_unit_test(test_star_exact),
        cmocka_unit_test(test_cell_refine_coarsen),
        cmocka_unit_test(test_compact_in_place),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
