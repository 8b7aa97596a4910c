/* Stable LSD radix sort of 64-bit keys carrying a 32-bit value, for the baker's
 * per-cell indexing (vertex keys, triangle vertex sets) and the codec's canonical
 * ordering of complexes: linear in the count, where qsort's comparisons
 * dominated.
 *
 * Only the low key_bits bits of the keys are looked at (1..64; rounded up to a
 * multiple of 11, the sort's former digit width, so that the order never depends
 * on the digit width chosen). Equal keys keep their input order. Input already
 * in order returns at once. Memory: two scratch arrays of n entries, allocated
 * per call when the input is not in order.
 * Thread-safety: no shared state. */
#ifndef MS_RADIX_SORT_H
#define MS_RADIX_SORT_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

ms_status ms_radix_sort_pairs(uint64_t *keys, uint32_t *values, size_t n, unsigned key_bits,
                              ms_error *err);

#endif
