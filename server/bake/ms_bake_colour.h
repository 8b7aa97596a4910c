/* Per-vertex colour for a bake (docs/ARCHIVE.md, "Colour streams";
 * docs/COLOUR.md): the welded vertices' colours looked up by key, and each
 * cell's colour stream.
 *
 * ms_bake_colours_read reads the input a second time (the tree's build has
 * fixed the quantisation box) and keeps, per distinct grid point, its key and
 * the rounded mean (halves up) of the colours of the input vertices welded
 * there, as ms_colour_weld does. Memory: 12 bytes per input vertex while
 * reading, 12 per welded vertex after: unlike the rest of a bake this is an
 * array per vertex (docs/ARCHIVE.md says so; the bounded-memory rule does not
 * hold for colour bakes yet).
 *
 * A cell's colours (ms_bake_colour_cell): each vertex of its complex at
 * bits_max is a kd-cell; it gets the colour of that kd-cell by the rule of
 * docs/COLOUR.md §1 over the whole model (a leaf's vertices at full precision:
 * the welded colour itself). A frozen foreign vertex of a leaf is coded at the
 * key the geometry decoder reports for it (its frozen kd-cell's first
 * descendant), with its own colour (the only vertex in that kd-cell).
 * Thread-safety: the table is read-only once built; any number of threads may
 * encode cells concurrently.
 */
#ifndef MS_BAKE_COLOUR_H
#define MS_BAKE_COLOUR_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_error.h"
#include "ms_quant.h"

typedef struct ms_bake_colours {
    unsigned bits;     /* p: keys are 3p-bit */
    bool alpha;        /* the input has alpha */
    size_t count;      /* welded vertices */
    uint64_t *keys;    /* ascending */
    uint32_t *rgba;    /* r | g << 8 | b << 16 | a << 24 per key */
} ms_bake_colours;

/* Reads path's vertex colours at `bits` in `box` into *out. *present is false
 * (and *out empty) for an input without colour. Reader errors as the reader
 * gives them; MS_ERR_NOMEM. */
ms_status ms_bake_colours_read(const char *path, const ms_quant_box *box, unsigned bits,
                               ms_bake_colours *out, bool *present, ms_error *err);
void ms_bake_colours_free(ms_bake_colours *c);

/* The colour (packed as in ms_bake_colours) of the kd-cell at kd-level `level`
 * whose prefix is `key` (`level` bits wide): the rule of docs/COLOUR.md §1 on
 * the channels reduced to colour_bits, given back shifted up to 8 bits (what
 * ms_colour_encode reduces again). MS_ERR_ARG when no vertex lies in it. */
ms_status ms_bake_colour_of(const ms_bake_colours *c, uint64_t key, unsigned level,
                            unsigned colour_bits, uint32_t *rgba, ms_error *err);

/* A cell of the tree as the colour of its vertices needs it: its cube (the
 * kd prefix `cube` at kd-level cube_level = 3 log2(n) depth; the root's: 0, 0)
 * and its window's first precision lo. */
typedef struct ms_bake_colour_cube {
    uint64_t cube;
    unsigned cube_level;
    unsigned lo;
} ms_bake_colour_cube;

/* The colour a cell's stream decodes for the kd-cell `key` of kd-level
 * `level` (3 bits_max of chain[0]) of its complex at bits_max, chain[0] the
 * cell, chain[1] its parent, ..., the root last (chain_n cells): a kd-cell
 * inside the cell's cube (or any of the root's) has its model-wide colour by
 * the rule; a foreign one the colour of its ancestor at the cell's first
 * level, which the cell's stream takes from its parent (docs/ARCHIVE.md,
 * "Colour streams"). Packed as ms_bake_colour_of gives it. */
ms_status ms_bake_colour_decoded(const ms_bake_colours *c, const ms_bake_colour_cube *chain,
                                 size_t chain_n, uint64_t key, unsigned level,
                                 unsigned colour_bits, uint32_t *rgba, ms_error *err);

/* A cell's colour stream: st is its complex at bits_max (= st->bits), freeze
 * (NULL: none) the kd-level each vertex freezes at or MS_CODEC_NO_FREEZE, and
 * chain its cube and its ancestors' (ms_bake_colour_decoded; chain[0].lo is
 * its window's first precision). A cell other than the root takes its base
 * colours from its parent's stream (base_given) when every cube starts no
 * finer than its cell's window (log2 n <= p_r); otherwise it codes them, and
 * every vertex gets its model-wide colour. On success *out (malloc'd) and
 * *size hold the stream and table[0 .. st->bits - lo] its prefix table
 * (docs/ARCHIVE.md). Empty complex: *size 0. */
ms_status ms_bake_colour_cell(const ms_bake_colours *c, const ms_codec_state *st,
                              const uint8_t *freeze, const ms_bake_colour_cube *chain,
                              size_t chain_n, unsigned colour_bits, uint8_t **out, size_t *size,
                              uint32_t *table, ms_error *err);

#endif
