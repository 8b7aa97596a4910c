/* Colour checks shared by the colour tests: the welded input colours of a
 * model in an archive's box, an independent level-by-level implementation of
 * the rule of docs/COLOUR.md §1, and a stitched mesh's colours against it. */
#ifndef MS_COLOUR_CHECK_H
#define MS_COLOUR_CHECK_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_view_decoder.h"

/* Per distinct key (sorted, 3 h->bits bits) the rounded mean (halves up) of
 * the input colours ms_colour_test_welded there. */
typedef struct ms_colour_test_welded {
    size_t n;
    uint64_t *keys;
    uint8_t *rgba;
    bool alpha;
} ms_colour_test_welded;

/* Loads path (which must have colour) and welds it in h's box (fails the test
 * otherwise). */
void ms_colour_test_weld(const char *path, const ms_archive_header *h, ms_colour_test_welded *w);
void ms_colour_test_welded_free(ms_colour_test_welded *w);
/* The rule's colour (c-bit channels) of the ms_colour_test_welded vertices [lo, hi), which
 * lie in one kd-cell of level L (p bits per coordinate). */
void ms_colour_test_rule(const ms_colour_test_welded *w, unsigned p, unsigned c, size_t lo, size_t hi, unsigned L,
              unsigned out[4]);
/* Fails the test unless every vertex of m has its kd-cell's rule colour at c
 * bits, widened (alpha 255 without alpha in the input). */
void ms_colour_test_check(const ms_view_mesh *m, const ms_colour_test_welded *w, unsigned p, unsigned c);

#endif
