/* Stable LSD radix sort: see ms_radix_sort.h. */
#include "ms_radix_sort.h"

#include "ms_big_alloc.h"

#include <stdlib.h>
#include <string.h>

#define DIGIT_BITS 11
#define BUCKETS (1u << DIGIT_BITS)

ms_status ms_radix_sort_pairs(uint64_t *keys, uint32_t *values, size_t n, unsigned key_bits,
                              ms_error *err)
{
    if (n < 2)
        return MS_OK;
    uint64_t *k2 = ms_big_malloc(n * sizeof *k2);
    uint32_t *v2 = ms_big_malloc(n * sizeof *v2);
    size_t *count = malloc(BUCKETS * sizeof *count);
    if (!k2 || !v2 || !count) {
        free(k2);
        free(v2);
        free(count);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory sorting %zu keys", n);
    }
    uint64_t *ka = keys, *kb = k2;
    uint32_t *va = values, *vb = v2;
    for (unsigned shift = 0; shift < key_bits; shift += DIGIT_BITS) {
        memset(count, 0, BUCKETS * sizeof *count);
        for (size_t i = 0; i < n; ++i)
            count[(ka[i] >> shift) & (BUCKETS - 1)]++;
        if (count[(ka[0] >> shift) & (BUCKETS - 1)] == n)
            continue; /* this digit is the same everywhere */
        size_t sum = 0;
        for (unsigned b = 0; b < BUCKETS; ++b) {
            size_t c = count[b];
            count[b] = sum;
            sum += c;
        }
        for (size_t i = 0; i < n; ++i) {
            size_t at = count[(ka[i] >> shift) & (BUCKETS - 1)]++;
            kb[at] = ka[i];
            vb[at] = va[i];
        }
        uint64_t *kt = ka;
        ka = kb, kb = kt;
        uint32_t *vt = va;
        va = vb, vb = vt;
    }
    if (ka != keys) {
        memcpy(keys, ka, n * sizeof *keys);
        memcpy(values, va, n * sizeof *values);
    }
    free(k2);
    free(v2);
    free(count);
    return MS_OK;
}
