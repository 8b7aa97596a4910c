/* Indexing a cell's vertex references (ms_nsp_index_keys, server/bake/
 * ms_nsp_cell_state.h): the distinct keys in order and every reference's rank
 * equal a sort-and-merge reference, for references that repeat as a leaf's do
 * (each key several times, in any order), for keys using every bit, for keys
 * above key_bits (the sorting path), and for 0, 1 and 2 references. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_nsp_cell_state.h"
#include "ms_test.h"

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* n references drawn from `distinct` random keys of key_bits bits (plus
 * `above`, ORed into every key, to reach past key_bits). */
static void check_index(size_t n, size_t distinct, unsigned key_bits, uint64_t above,
                        uint64_t *rng)
{
    uint64_t *pool = malloc((distinct + 1) * sizeof *pool);
    uint64_t *ref = malloc((n + 1) * sizeof *ref), *keep = malloc((n + 1) * sizeof *keep);
    uint64_t *cells = malloc((n + 1) * sizeof *cells), *want = malloc((n + 1) * sizeof *want);
    uint32_t *rank = malloc((n + 1) * sizeof *rank);
    assert_true(pool && ref && keep && cells && want && rank);
    uint64_t mask = key_bits >= 64 ? UINT64_MAX : ((uint64_t)1 << key_bits) - 1;
    for (size_t d = 0; d < distinct; ++d)
        pool[d] = (ms_test_random(rng) & mask) | above;
    for (size_t i = 0; i < n; ++i)
        keep[i] = ref[i] = pool[ms_test_random(rng) % distinct];
    /* the reference: sorted, equal keys merged */
    memcpy(want, keep, n * sizeof *want);
    qsort(want, n, sizeof *want, cmp_u64);
    size_t nwant = 0;
    for (size_t i = 0; i < n; ++i)
        if (nwant == 0 || want[i] != want[nwant - 1])
            want[nwant++] = want[i];
    size_t got = 12345;
    ms_error err;
    assert_int_equal(ms_nsp_index_keys(ref, n, key_bits, cells, &got, rank, &err), MS_OK);
    assert_int_equal(got, nwant);
    for (size_t d = 0; d < nwant; ++d)
        assert_true(cells[d] == want[d]);
    for (size_t i = 0; i < n; ++i) {
        assert_true(rank[i] < nwant);
        assert_true(cells[rank[i]] == keep[i]);
    }
    free(pool);
    free(ref);
    free(keep);
    free(cells);
    free(want);
    free(rank);
}

static void test_index_matches_sorting(void **state)
{
    (void)state;
    uint64_t rng = 0x2545F4914F6CDD1Dull;
    check_index(3900, 650, 48, 0, &rng);    /* a leaf: each key about six times */
    check_index(20000, 20000, 48, 0, &rng); /* mostly distinct */
    check_index(5000, 7, 48, 0, &rng);      /* a few keys, long probe runs */
    check_index(4000, 900, 64, 0, &rng);    /* every bit used */
    check_index(4000, 900, 30, 1ull << 40, &rng); /* above key_bits: the sorting path */
    check_index(2, 2, 48, 0, &rng);
    check_index(1, 1, 48, 0, &rng);
    check_index(0, 1, 48, 0, &rng);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_index_matches_sorting),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
