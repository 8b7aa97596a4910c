/* Per-vertex colour of the mesh readers: the conversions of the input's colour
 * types to 8 bits per channel, and the count of distinct colours that
 * `meshbake --info` reports. docs/INPUT.md states the rules.
 *
 * Reentrant; no global state.
 */
#ifndef MS_MESH_COLOUR_H
#define MS_MESH_COLOUR_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* A 16-bit channel to 8 bits: v * 255 / 65535 rounded to nearest, which is
 * round(v / 257); never a tie, as 257 is odd. 0 -> 0, 65535 -> 255. */
static inline uint8_t ms_colour_from_u16(uint32_t v)
{
    return (uint8_t)((v + 128) / 257);
}

/* A channel in 0..1 to 8 bits: v * 255 rounded to nearest (halves up). False,
 * *out untouched, for NaN and values outside 0..1. */
static inline bool ms_colour_from_unit(double v, uint8_t *out)
{
    if (!(v >= 0.0 && v <= 1.0))
        return false;
    *out = (uint8_t)(v * 255.0 + 0.5);
    return true;
}

/* Colours gathered chunk by chunk (a mesh reader's sink) to count the distinct
 * ones: 8 bytes per colour while gathering, 16 more while counting (the radix
 * sort of common/util/ms_radix_sort.h). Zero it to start; ms_colour_tally_free
 * releases it. */
typedef struct ms_colour_tally {
    uint64_t *keys; /* r g b a packed in the low 32 bits, r most significant */
    size_t count, capacity;
} ms_colour_tally;

/* Appends rgba[0 .. 4 * count). MS_ERR_NOMEM. */
ms_status ms_colour_tally_add(ms_colour_tally *tally, const uint8_t *rgba, size_t count,
                              ms_error *err);

/* Number of distinct r g b a quadruples gathered into *distinct (0 for none).
 * Linear time: a radix sort of the keys (which it leaves sorted). MS_ERR_NOMEM. */
ms_status ms_colour_tally_distinct(ms_colour_tally *tally, uint64_t *distinct, ms_error *err);

void ms_colour_tally_free(ms_colour_tally *tally);

/* The same for rgba[0 .. 4 * count) in one call. */
ms_status ms_colour_count_distinct(const uint8_t *rgba, size_t count, uint64_t *distinct,
                                   ms_error *err);

#endif
