/* Filtered APO lookup: the CPU reference of the shader's filter (docs/APO.md,
 * "Filtering"), after the thesis's chapter 4.3.
 *
 * Minification: a pixel whose footprint on the surface is f (cell-local units,
 * the width of one pixel at the fragment's distance) does not descend past the
 * first depth whose cells are no wider than itself (the thesis's
 * p = ceil(log2(1 / f))): ms_apo_footprint_depth; the caller takes the smaller
 * of it and its depth cap.
 *
 * Magnification: 8-cell interpolation. The plain lookup (ms_apo_lookup_fixed
 * with the caller's rule) finds the centre node: depth d >= 1, width W = 2^(32-d)
 * in fixed point, lower corner L. Per axis, with the point clamped into that
 * node, r = u - L:
 *     side  = r >= W/2 (the nearer face is the upper one)
 *     dist  = side ? r - W/2 : W/2 - 1 - r           (0 .. W/2 - 1)
 *     t     = (dist + 0.5) / W                       (the neighbour's weight, < 0.5)
 *     q     = side ? L + W : L - 1                   (one unit past the nearer face)
 * The 7 neighbours are looked up at the point with q on the axes of each
 * combination (x the most significant bit, as octants), with the same depth cap
 * and the STOP rule: a neighbour that was not stored (or whose node says
 * MS_APO_NORMAL_SMOOTH) gives the caller's smooth normal at the point (the
 * missing-neighbour rule: a chunk is a correction of that normal, docs/APO.md),
 * and so does a centre without a texel (its depth and cell are then the absent
 * node's, so that the texels around it blend into it). Stepping one
 * fixed-point unit past the face reaches the immediate neighbour even when it is
 * deeper (smaller) than the centre, at the point of it nearest to u. An axis
 * whose q would leave the cube stays at u (clamp to edge: the neighbour across
 * the cube's face belongs to another chunk). The result is
 *     n = normalize(sum over k of s_k * prod_a (bit_a(k) ? t_a : 1 - t_a) * n_k)
 * summed in octant order k = 0..7 (n_0 the centre's normal), s_k = -1 where
 * n_k . n_0 < 0 (a neighbour facing away, from a scan wound inconsistently or
 * the other sheet of a thin part, is taken turned over), else 1; and the centre's
 * normal where that sum is shorter than 1e-6. A centre at depth 0 (the whole
 * cube) gives the plain lookup; an EMPTY chunk the smooth normal. The smooth
 * normal is the caller's (the GPU's interpolated vertex normal, or the flat one
 * when smooth shading is off); NULL reads as a zero vector.
 *
 * At a face between two equal cells the two sides give the same blend (t = 1/2
 * on both), so the normal is continuous there; between cells of different
 * depths it is continuous across the face only along the face's normal axis
 * (the thesis's remaining artefact, Fig. 4.8).
 *
 * Thread-safety: reads the view only.
 */
#ifndef MS_APO_FILTER_H
#define MS_APO_FILTER_H

#include <stdint.h>

#include "ms_apo_traverse.h"

/* The first depth d with 2^-d <= footprint: 1 - e where footprint = m * 2^e,
 * m in [0.5, 1) (frexp: exact); 0 for a footprint >= 1, UINT32_MAX (no limit)
 * for footprint <= 0 or NaN. */
uint32_t ms_apo_footprint_depth(float footprint);

typedef struct ms_apo_filter_result {
    float normal[3];              /* unit (the smooth normal's length where only it was blended) */
    ms_apo_lookup_result centre;  /* the plain lookup at the point */
    float weight[3];              /* t per axis (0 without neighbours) */
    uint32_t neighbour_depth[8];  /* depth of each corner k's node (k = 0: the centre) */
    uint32_t missing;             /* neighbours that stopped at a missing child */
    uint32_t smooth;              /* neighbours that gave the smooth normal (missing ones included) */
    uint32_t texels;              /* of the 8 corners, those that gave a texel; 0: normal = the smooth
                                     normal as given (not renormalised), as where no chunk exists */
    uint32_t lookups;             /* traversals made, the centre's included */
} ms_apo_filter_result;

/* The filtered normal at a fixed-point position (ms_apo_position_to_fixed). */
ms_apo_stop ms_apo_lookup_filtered_fixed(const ms_apo_view *view, const uint32_t fixed[3], uint32_t depth_cap,
                                         ms_apo_missing_rule rule, const float smooth[3],
                                         ms_apo_filter_result *result);

/* Same with a float cell-local position. */
ms_apo_stop ms_apo_lookup_filtered_smooth(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                                          ms_apo_missing_rule rule, const float smooth[3],
                                          ms_apo_filter_result *result);

/* The same without a smooth normal (a zero vector): where no corner has a
 * texel the normal is zero, elsewhere the texels' blend (for callers that
 * fall back to a normal of their own, as meshrender does). */
ms_apo_stop ms_apo_lookup_filtered(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                                   ms_apo_missing_rule rule, ms_apo_filter_result *result);

#endif
