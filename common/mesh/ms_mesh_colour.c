/* Distinct vertex colours: the colours as 32-bit keys, radix-sorted, runs counted. */
#include "ms_mesh_colour.h"
#include "ms_radix_sort.h"

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
            if (cap > SIZE_MAX / (2 * sizeof *t->keys))
                return ms_error_set(err, MS_ERR_NOMEM, "too many colours to count");
            cap *= 2;
        }
        uint64_t *grown = realloc(t->keys, cap * sizeof *grown);
        if (!grown)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory counting %zu colours", cap);
        t->keys = grown;
        t->capacity = cap;
    }
    uint64_t *out = t->keys + t->count;
    for (size_t i = 0; i < count; ++i, rgba += 4)
        out[i] = (uint64_t)rgba[0] << 24 | (uint64_t)rgba[1] << 16 | (uint64_t)rgba[2] << 8 |
                 rgba[3];
    t->count += count;
    return MS_OK;
}

ms_status ms_colour_tally_distinct(ms_colour_tally *t, uint64_t *distinct, ms_error *err)
{
    *distinct = 0;
    if (t->count == 0)
        return MS_OK;
    uint32_t *values = calloc(t->count, sizeof *values); /* the sort carries a value */
    if (!values)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory counting %zu colours", t->count);
    ms_status st = ms_radix_sort_pairs(t->keys, values, t->count, 32, err);
    free(values);
    if (st != MS_OK)
        return st;
    uint64_t n = 1;
    for (size_t i = 1; i < t->count; ++i)
        n += t->keys[i] != t->keys[i - 1];
    *distinct = n;
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
