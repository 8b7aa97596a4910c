/* A picture of an APO chunk without any mesh: an orthographic view along -z of
 * the chunk's cube, found by marching the octree itself. For debugging and for a
 * first look at a bake (apoclassic --png).
 *
 * Each pixel (column i, row j, top row first) looks down from z = 1 at
 * x = (i + 1/2) / width, y = 1 - (j + 1/2) / height, with the same fixed-point
 * positions as ms_apo_lookup. The march descends with the STOP rule; where the
 * child on the way is missing, it jumps below that child's whole cell (its
 * lower z face, exactly, in fixed point); the first node that is not a missing
 * child (a leaf, or the depth cap / received prefix) is the surface, shaded by
 * Lambert's law with its normal, light from (0.3, 0.4, 1). Background: 0.
 *
 * Pure function of its inputs; the caller owns `grey` (width * height bytes).
 */
#ifndef MS_APO_RENDER_H
#define MS_APO_RENDER_H

#include <stdint.h>

#include "ms_apo_chunk.h"

/* Returns the number of pixels that found the surface. */
uint64_t ms_apo_render_top_view(const ms_apo_view *view, uint32_t depth_cap, uint32_t width, uint32_t height,
                                uint8_t *grey);

#endif
