/* The codec's canonical ordering after the move to radix sorting
 * (ms_sort_index_tuples, ms_codec_state_canonicalise) and the large-array
 * allocator (ms_big_alloc.h): results equal a qsort reference on both the
 * one-key path (tuples that fit 64 bits) and the two-pass path (triples of
 * indices over 2^21), hostile wide cells still sort exactly, and huge-page
 * hinted blocks keep their contents through realloc. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_big_alloc.h"
#include "ms_codec.h"
#include "ms_codec_internal.h"
#include "ms_test.h"

static uint64_t rng_state = 88172645463325252ull;

static uint32_t rnd(uint32_t below)
{
    return (uint32_t)(ms_test_random(&rng_state) % below);
}

static unsigned cmp_arity;

static int cmp_tuple(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (unsigned i = 0; i < cmp_arity; ++i)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}

static void check_against_qsort(unsigned arity, size_t n, uint32_t limit)
{
    uint32_t *x = malloc(n * arity * sizeof *x), *ref = malloc(n * arity * sizeof *ref);
    assert_non_null(x);
    assert_non_null(ref);
    for (size_t i = 0; i < n * arity; ++i)
        x[i] = rnd(limit);
    /* repeated tuples too */
    memcpy(x + arity * (n / 2), x, arity * sizeof *x);
    memcpy(ref, x, n * arity * sizeof *ref);
    cmp_arity = arity;
    qsort(ref, n, arity * sizeof *ref, cmp_tuple);
    ms_error err;
    assert_int_equal(ms_sort_index_tuples(x, n, arity, limit, &err), MS_OK);
    assert_memory_equal(x, ref, n * arity * sizeof *x);
    free(x);
    free(ref);
}

static void test_tuples_one_key(void **state)
{
    (void)state;
    check_against_qsort(3, 5000, 1000);      /* 3 x 10 bits */
    check_against_qsort(3, 3000, 1u << 21);  /* 3 x 21 bits: exactly one 63-bit key */
    check_against_qsort(2, 5000, 1u << 31);  /* 2 x 31 bits */
    check_against_qsort(3, 1, 7);
    check_against_qsort(3, 2, 2);
}

static void test_tuples_two_pass(void **state)
{
    (void)state;
    check_against_qsort(3, 4000, (1u << 21) + 1); /* 3 x 22 bits > 64 */
    check_against_qsort(3, 4000, 1u << 26);       /* the codec's vertex cap */
    check_against_qsort(3, 100, UINT32_MAX);
}

static void test_canonicalise_wide_cells(void **state)
{
    (void)state;
    /* A hostile start state may carry cells above 2^level: they still sort by
     * their whole value (the caller then refuses them). */
    uint64_t cells[4] = {1ull << 59, 3, 1ull << 40, 2};
    uint32_t tris[6] = {0, 1, 2, 3, 2, 1};
    uint32_t edges[2] = {2, 0};
    ms_codec_state s = {.bits = 4, .level = 12, .vertex_count = 4, .tri_count = 2,
                        .edge_count = 1, .cells = cells, .tris = tris, .edges = edges};
    ms_error err;
    assert_int_equal(ms_codec_state_canonicalise(&s, &err), MS_OK);
    const uint64_t want_cells[4] = {2, 3, 1ull << 40, 1ull << 59};
    assert_memory_equal(cells, want_cells, sizeof cells);
    /* old 0,1,2,3 -> new 3,1,2,0: (3,1,2) -> (1,2,3); (0,2,1) -> (0,2,1) */
    const uint32_t want_tris[6] = {0, 2, 1, 1, 2, 3};
    assert_memory_equal(tris, want_tris, sizeof tris);
    const uint32_t want_edges[2] = {2, 3};
    assert_memory_equal(edges, want_edges, sizeof edges);
}

static void test_big_alloc_keeps_contents(void **state)
{
    (void)state;
    size_t n = (MS_BIG_ALLOC_HINT + 12345) / sizeof(uint32_t);
    uint32_t *p = ms_big_malloc(n * sizeof *p);
    assert_non_null(p);
    for (size_t i = 0; i < n; ++i)
        p[i] = (uint32_t)(i * 2654435761u);
    uint32_t *q = ms_big_realloc(p, 3 * n * sizeof *q);
    assert_non_null(q);
    for (size_t i = 0; i < n; ++i)
        assert_true(q[i] == (uint32_t)(i * 2654435761u));
    q[3 * n - 1] = 7; /* the grown part is writable */
    uint32_t *r = ms_big_realloc(q, 16);
    assert_non_null(r);
    assert_int_equal(r[3], (uint32_t)(3u * 2654435761u));
    free(r);
    free(ms_big_malloc(0));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tuples_one_key),
        cmocka_unit_test(test_tuples_two_pass),
        cmocka_unit_test(test_canonicalise_wide_cells),
        cmocka_unit_test(test_big_alloc_keeps_contents),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
