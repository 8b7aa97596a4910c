/* Lone levels of the baker's vertices: see ms_nsp_lone.h. */
#include "ms_nsp_lone.h"

#include <stdlib.h>

#include "ms_big_alloc.h"
#include "ms_quant.h"
#include "ms_radix_sort.h"

ms_status ms_nsp_lone_levels(const uint64_t *keys, size_t n, unsigned key_bits, uint8_t **out,
                             ms_error *err)
{
    *out = NULL;
    if (n > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "too many vertices (%zu) for lone levels", n);
    uint8_t *lone = malloc(n ? n : 1);
    uint64_t *sorted = ms_big_malloc((n ? n : 1) * sizeof *sorted);
    uint32_t *who = ms_big_malloc((n ? n : 1) * sizeof *who);
    ms_status s = MS_OK;
    if (!lone || !sorted || !who)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory finding lone levels");
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        sorted[i] = keys[i];
        who[i] = (uint32_t)i;
    }
    if (s == MS_OK)
        s = ms_radix_sort_pairs(sorted, who, n, key_bits, err);
    /* runs of one key; a run's level comes from the distinct keys around it */
    for (size_t i = 0; s == MS_OK && i < n;) {
        size_t j = i + 1;
        while (j < n && sorted[j] == sorted[i])
            ++j;
        unsigned level = 0, l;
        if (i > 0 && (l = ms_key_lcp(sorted[i - 1], sorted[i], key_bits) + 1) > level)
            level = l;
        if (j < n && (l = ms_key_lcp(sorted[i], sorted[j], key_bits) + 1) > level)
            level = l;
        for (size_t k = i; k < j; ++k)
            lone[who[k]] = (uint8_t)level;
        i = j;
    }
    free(sorted);
    free(who);
    if (s != MS_OK) {
        free(lone);
        return s;
    }
    *out = lone;
    return MS_OK;
}
