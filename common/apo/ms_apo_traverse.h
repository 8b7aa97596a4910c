/* The CPU reference traversal of an APO chunk: the oracle the GPU shader is tested
 * against. It does, step for step, what the shader does (docs/APO.md, "Traversal").
 *
 * Position rule: a cell-local coordinate p (float, nominally in [0,1]) becomes a
 * 32-bit fixed-point integer once per axis:
 *     u = 0                 if p <= 0 or p is NaN
 *     u = 2^32 - 1          if p >= 1   (1.0 stays inside: the last cell)
 *     u = uint(p * 2^32)    otherwise   (exact: p*2^32 only shifts the exponent)
 * At depth d the child side on each axis is bit (31 - d) of u: 1 = upper half, so
 * a point exactly on a mid-plane goes to the upper child. Child octant =
 * 4*bx + 2*by + bz. The same bits drive the octant choice and the cell, so they
 * can never disagree. Depths up to MS_APO_MAX_DEPTH (30) are exact.
 *
 * Child address = node word + offset + popcount(exist & below) +
 * popcount(exist & kind & below), below = (1 << octant) - 1.
 *
 * Stopping: at a leaf (its normal); at depth_cap or at the last complete level of
 * the received prefix (the node's mean normal, or "smooth" where the mean word
 * holds MS_APO_NORMAL_SMOOTH); at a missing child, by rule:
 *   MS_APO_MISSING_STOP     no texel: "smooth" (the chunk is a correction of the
 *       client's smooth normal, which a missing node leaves as it is); the
 *       result's depth and cell are the absent child's;
 *   MS_APO_MISSING_NEAREST  descend into the existing child nearest to the point
 *       (L-infinity distance to the child's cell, computed exactly in integers;
 *       ties: fewer differing axes, then the lower octant), and replace the point
 *       by its closest point in that child (on each flipped axis: the child's
 *       nearest face), so deeper levels stay consistent. Kept for measurements:
 *       since chunks are corrections (docs/APO.md), it paints a neighbour's
 *       correction where the chunk says "smooth".
 * A "smooth" result (also EMPTY) has smooth = true, code MS_APO_NORMAL_SMOOTH and
 * a zero normal: the caller uses its own smooth normal there.
 *
 * Thread-safety: reads the view only; any number of threads may call it.
 */
#ifndef MS_APO_TRAVERSE_H
#define MS_APO_TRAVERSE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_apo_chunk.h"

typedef enum ms_apo_missing_rule {
    MS_APO_MISSING_STOP = 0,
    MS_APO_MISSING_NEAREST = 1
} ms_apo_missing_rule;

typedef enum ms_apo_stop {
    MS_APO_STOP_LEAF = 0,    /* reached a leaf */
    MS_APO_STOP_CAP = 1,     /* an internal node at depth_cap */
    MS_APO_STOP_PREFIX = 2,  /* an internal node on the last complete received level */
    MS_APO_STOP_MISSING = 3, /* the child was absent (MS_APO_MISSING_STOP): smooth */
    MS_APO_STOP_EMPTY = 4    /* no complete level: nothing to read, smooth */
} ms_apo_stop;

typedef struct ms_apo_lookup_result {
    float normal[3];        /* decoded unit normal; (0,0,0) where smooth */
    uint32_t code;          /* its 24-bit normal code; MS_APO_NORMAL_SMOOTH where smooth */
    bool smooth;            /* no texel here: the caller's smooth normal */
    uint32_t word;          /* index of the node's first word (MISSING: the parent's) */
    uint32_t depth;         /* depth of the node whose normal was returned (MISSING: the absent child's) */
    uint32_t cell[3];       /* that node's integer cell coordinates */
    uint32_t substitutions; /* missing children replaced by a neighbour */
    ms_apo_stop stop;
} ms_apo_lookup_result;

/* The fixed-point conversion described above. */
void ms_apo_position_to_fixed(const float position[3], uint32_t fixed[3]);

/* Looks up the normal at a fixed-point position (see above). */
ms_apo_stop ms_apo_lookup_fixed(const ms_apo_view *view, const uint32_t fixed[3], uint32_t depth_cap,
                                ms_apo_missing_rule rule, ms_apo_lookup_result *result);

/* Same with a float cell-local position. */
ms_apo_stop ms_apo_lookup(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                          ms_apo_missing_rule rule, ms_apo_lookup_result *result);

#endif
