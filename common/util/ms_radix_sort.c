/* Stable LSD radix sort: see ms_radix_sort.h. */
#include "ms_radix_sort.h"

#include "ms_big_alloc.h"

#include <stdlib.h>
#include <string.h>

/* Digit width by count: a pass costs its buckets (clearing, prefix sums) plus
 * its keys, and most of the baker's sorts are per cell, a few hundred to a few
 * thousand keys, where 2,048 buckets a pass cost more than the keys. */
#define WIDE_DIGIT_BITS 11
#define NARROW_DIGIT_BITS 8
#define NARROW_BELOW 4096

/* Whether the low key_bits bits of keys are already in non-decreasing order:
 * then the stable sort is the identity (about half of the baker's calls). */
static int already_sorted(const uint64_t *keys, size_t n, uint64_t mask)
{
    for (size_t i = 1; i < n; ++i)
        if ((keys[i] & mask) < (keys[i - 1] & mask))
            return 0;
    return 1;
}

ms_status ms_radix_sort_pairs(uint64_t *keys, uint32_t *values, size_t n, unsigned key_bits,
                              ms_error *err)
{
    if (n < 2)
        return MS_OK;
    /* The bits the sort orders by: key_bits rounded up to whole wide digits, as
     * when every sort used them, so that keys with bits above key_bits still
     * sort as they always did. */
    unsigned sort_bits = (key_bits + WIDE_DIGIT_BITS - 1) / WIDE_DIGIT_BITS * WIDE_DIGIT_BITS;
    uint64_t mask = sort_bits >= 64 ? UINT64_MAX : ((uint64_t)1 << sort_bits) - 1;
    if (already_sorted(keys, n, mask))
        return MS_OK;
    const unsigned digit_bits = n < NARROW_BELOW ? NARROW_DIGIT_BITS : WIDE_DIGIT_BITS;
    const size_t buckets = (size_t)1 << digit_bits;
    const unsigned passes = ((sort_bits < 64 ? sort_bits : 64) + digit_bits - 1) / digit_bits;
    uint64_t *k2 = ms_big_malloc(n * sizeof *k2);
    uint32_t *v2 = ms_big_malloc(n * sizeof *v2);
    size_t *count = calloc(passes * buckets, sizeof *count);
    if (!k2 || !v2 || !count) {
        free(k2);
        free(v2);
        free(count);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory sorting %zu keys", n);
    }
    /* every pass's histogram in one read of the keys (a digit's counts do not
     * depend on the order the earlier passes leave) */
    for (size_t i = 0; i < n; ++i)
        for (unsigned p = 0; p < passes; ++p)
            count[p * buckets + (((keys[i] & mask) >> (p * digit_bits)) & (buckets - 1))]++;
    uint64_t *ka = keys, *kb = k2;
    uint32_t *va = values, *vb = v2;
    for (unsigned p = 0; p < passes; ++p) {
        unsigned shift = p * digit_bits;
        size_t *c = count + p * buckets;
        if (c[((ka[0] & mask) >> shift) & (buckets - 1)] == n)
            continue; /* this digit is the same everywhere */
        size_t sum = 0;
        for (size_t b = 0; b < buckets; ++b) {
            size_t here = c[b];
            c[b] = sum;
            sum += here;
        }
        for (size_t i = 0; i < n; ++i) {
            size_t at = c[((ka[i] & mask) >> shift) & (buckets - 1)]++;
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
