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
#include "ms_radix_sort.h"
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

typedef struct keyed {
    uint64_t key;
    uint32_t value;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    const keyed *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->value < y->value ? -1 : x->value > y->value; /* value = input position */
}

/* ms_radix_sort_pairs against a stable reference (qsort on key, then input
 * position), keys of key_bits bits drawn from `distinct` values so that many
 * repeat; `presorted` gives input already in order. */
static void check_pairs(size_t n, unsigned key_bits, uint64_t distinct, bool presorted)
{
    uint64_t *keys = malloc(n * sizeof *keys);
    uint32_t *values = malloc(n * sizeof *values);
    keyed *ref = malloc(n * sizeof *ref);
    assert_non_null(keys);
    assert_non_null(values);
    assert_non_null(ref);
    uint64_t top = key_bits >= 64 ? UINT64_MAX : ((uint64_t)1 << key_bits) - 1;
    uint64_t stride = top / distinct;
    for (size_t i = 0; i < n; ++i) {
        uint64_t pick = ms_test_random(&rng_state) % distinct;
        keys[i] = presorted ? (uint64_t)(i * distinct / n) * stride : pick * stride;
        values[i] = (uint32_t)i;
        ref[i].key = keys[i];
        ref[i].value = (uint32_t)i;
    }
    qsort(ref, n, sizeof *ref, cmp_keyed);
    ms_error err;
    assert_int_equal(ms_radix_sort_pairs(keys, values, n, key_bits, &err), MS_OK);
    for (size_t i = 0; i < n; ++i) {
        assert_true(keys[i] == ref[i].key);
        assert_int_equal(values[i], ref[i].value);
    }
    free(keys);
    free(values);
    free(ref);
}

/* Both digit widths (counts below and from 4,096), key widths that are and are
 * not whole digits, repeated keys (stability), and input already in order. */
static void test_radix_pairs_stable(void **state)
{
    (void)state;
    const size_t counts[] = {2, 3, 100, 4095, 4096, 20000};
    const unsigned widths[] = {5, 21, 33, 60, 64};
    for (size_t c = 0; c < sizeof counts / sizeof *counts; ++c)
        for (size_t w = 0; w < sizeof widths / sizeof *widths; ++w) {
            check_pairs(counts[c], widths[w], 1 + counts[c] / 4, false);
            check_pairs(counts[c], widths[w], 1 + counts[c] / 4, true);
        }
    check_pairs(5000, 64, 1, false); /* one key everywhere: every pass skipped */
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
        cmocka_unit_test(test_radix_pairs_stable),
        cmocka_unit_test(test_big_alloc_keeps_contents),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
