/* Distinct vertex colours, by a radix sort of the colours as 32-bit keys. */
#include "ms_mesh_colour.h"

#include <stdlib.h>
#include <string.h>

ms_status ms_colour_tally_add(ms_colour_tally *t, const uint8_t *rgba, size_t count,
                              ms_error *err)
{
    if (count == 0)
        return MS_OK;
    if (count > t->capacity - t->count) {
        size_t cap = t->capacity ? t->capacity : 4096;
        while (cap - t->count < count) {
            if (cap > SIZE_MAX / (2 * 2 * sizeof *t->keys))
                return ms_error_set(err, MS_ERR_NOMEM, "too many colours to count");
            cap *= 2;
        }
        uint32_t *grown = realloc(t->keys, cap * sizeof *grown);
        if (!grown)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory counting %zu colours", cap);
        t->keys = grown;
        t->capacity = cap;
    }
    uint32_t *out = t->keys + t->count;
    for (size_t i = 0; i < count; ++i, rgba += 4)
        out[i] = (uint32_t)rgba[0] << 24 | (uint32_t)rgba[1] << 16 | (uint32_t)rgba[2] << 8 |
                 rgba[3];
    t->count += count;
    return MS_OK;
}

ms_status ms_colour_tally_distinct(ms_colour_tally *t, uint64_t *distinct, ms_error *err)
{
    *distinct = 0;
    const size_t count = t->count;
    if (count == 0)
        return MS_OK;
    uint32_t *scratch = malloc(count * sizeof *scratch);
    if (!scratch)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory counting %zu colours", count);
    uint32_t *keys = t->keys, *other = scratch;
    /* Least significant byte first: four stable counting passes sort the keys; after
     * an even number of passes they are back in t->keys. */
    for (unsigned shift = 0; shift < 32; shift += 8) {
        size_t start[257];
        memset(start, 0, sizeof start);
        for (size_t i = 0; i < count; ++i)
            ++start[(keys[i] >> shift & 255) + 1];
        for (int b = 0; b < 256; ++b)
            start[b + 1] += start[b];
        for (size_t i = 0; i < count; ++i)
            other[start[keys[i] >> shift & 255]++] = keys[i];
        uint32_t *swap = keys;
        keys = other;
        other = swap;
    }
    uint64_t n = 1;
    for (size_t i = 1; i < count; ++i)
        n += keys[i] != keys[i - 1];
    *distinct = n;
    free(scratch);
    return MS_OK;
}

void ms_colour_tally_free(ms_colour_tally *t)
{
    free(t->keys);
    memset(t, 0, sizeof *t);
}

ms_status ms_colour_count_distinct(const uint8_t *rgba, size_t count, uint64_t *distinct,
                                   ms_error *err)
{
    ms_colour_tally t = {0};
    ms_status st = ms_colour_tally_add(&t, rgba, count, err);
    if (st == MS_OK)
        st = ms_colour_tally_distinct(&t, distinct, err);
    else
        *distinct = 0;
    ms_colour_tally_free(&t);
    return st;
}
