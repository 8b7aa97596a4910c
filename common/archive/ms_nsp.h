/* nSP-tree geometry shared by the baker and the view-dependent decoder.
 *
 * The nSP-tree (docs/ARCHIVE.md, reference 003 §4) cuts the quantisation cube of
 * side 2^p grid units into n^3 equal children per level, n = 2^s. A cell at depth
 * D is identified by its position (x, y, z) in cells of that depth, each < n^D;
 * its children are numbered x + n (y + n z) by their offset inside it. A kd-cell
 * at kd-level L (the top L bits of the 3p-bit interleaved key, ms_quant.h) lies
 * inside exactly one depth-D cell when L >= 3 D s: the top D s bits of each of its
 * coordinates are then known.
 *
 * Membership rule: a simplex belongs to every cell holding one of its vertices.
 * A parent's complex at its bits_max (kd-level 3 bits_max) therefore splits into
 * the start states of its children by ms_nsp_partition_state; the baker checks
 * that this split reproduces, for every child, the start state its encoder began
 * from, and the client uses the same function to start the children's decoders.
 *
 * Units: integer grid coordinates and kd prefixes. Errors: ms_status with a
 * one-line message. Thread-safety: pure functions, no shared state.
 */
#ifndef MS_NSP_H
#define MS_NSP_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_error.h"

/* The parameters of one tree. */
typedef struct ms_nsp_shape {
    unsigned bits;      /* p: bits per coordinate of the full grid */
    unsigned n;         /* children per axis, a power of two 2..8 */
    unsigned log2n;     /* s */
    unsigned root_bits; /* p_r, >= s */
} ms_nsp_shape;

/* Fills shape from p, n and p_r; MS_ERR_ARG (with the reason) when n is not 2, 4
 * or 8, p is outside MS_QUANT_MIN_BITS..MS_CODEC_MAX_BITS or p_r is not in
 * [log2 n, p]. */
ms_status ms_nsp_shape_init(ms_nsp_shape *shape, unsigned bits, unsigned n, unsigned root_bits,
                            ms_error *err);

/* Precision window of a cell at `depth` (docs/ARCHIVE.md). */
void ms_nsp_window(const ms_nsp_shape *shape, unsigned depth, bool leaf, unsigned *bits_min,
                   unsigned *bits_max);

/* True when a cell at `depth` may split: its window as an internal cell ends below p. */
bool ms_nsp_can_split(const ms_nsp_shape *shape, unsigned depth);

/* Offset (x + n (y + n z)) inside its depth-`depth` parent of the depth+1 cell holding
 * the full-grid point xyz. */
unsigned ms_nsp_child_offset(const ms_nsp_shape *shape, unsigned depth, const uint32_t xyz[3]);

/* Full-grid coordinates of the minimum corner of kd-cell `prefix` at kd-level `level`. */
void ms_nsp_prefix_corner(const ms_nsp_shape *shape, uint64_t prefix, unsigned level,
                          uint32_t xyz[3]);

/* True when the kd-cell (prefix, level) lies inside the depth-`depth` cell at
 * `position` (requires level >= 3 depth s to be possible). */
bool ms_nsp_prefix_inside(const ms_nsp_shape *shape, uint64_t prefix, unsigned level,
                          unsigned depth, const uint32_t position[3]);

/* Splits `parent` (a complex at kd-level parent->level, every vertex a kd-cell at
 * that level, level >= 3 (depth + 1) s) of the cell at `depth` / `position` into
 * the n^3 complexes of its children: child k receives every simplex with a vertex
 * inside child k (with its foreign vertices) and every isolated vertex inside it.
 * children[k] are canonical states with bits = child_bits (the key space the
 * child's stream uses) and the parent's level; the caller frees them. A child with
 * nothing gets vertex_count 0. MS_ERR_NOMEM on allocation failure. */
ms_status ms_nsp_partition_state(const ms_nsp_shape *shape, const ms_codec_state *parent,
                                 unsigned depth, const uint32_t position[3], unsigned child_bits,
                                 ms_codec_state *children, ms_error *err);

#endif
