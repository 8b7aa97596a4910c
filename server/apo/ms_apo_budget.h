/* The APO byte budget of a bake (docs/APO.md, "The byte budget"): a model's
 * chunks together hold at most R times its geometry bytes. Where the chunks as
 * built hold more, the finest texels go first: whole levels are dropped from
 * the chunks, the level whose texels are smallest in world units first (a
 * chunk of a cell at nSP depth t with a level d: texels 2^-(log2(n)·t + d) of
 * the root cube), ties taken from the chunk of the larger cell number first, so
 * the result depends only on the chunks and the budget.
 *
 * A chunk cut to its first k levels is built again from them: the nodes of
 * level k - 1 become leaves holding their mean normal, and those whose mean is
 * "smooth" (no correction there, MS_APO_NORMAL_SMOOTH) are dropped with every
 * ancestor left without a kept child and without a correction of its own; a
 * chunk left without a texel is no chunk. So a cut chunk is a valid chunk of
 * at most k levels whose first k - 1 levels hold the stored chunk's nodes but
 * for those dropped. Under the correction rule most internal means are smooth,
 * so a cut loses most of level k - 1 too.
 *
 * Ownership: a cut's result owns its bytes
 * (ms_bake_apo_result_free). Thread-safety: pure functions.
 */
#ifndef MS_APO_BUDGET_H
#define MS_APO_BUDGET_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_format.h"
#include "ms_bake_apo.h"
#include "ms_error.h"

/* One stored chunk, as the planner sees it. */
typedef struct ms_apo_budget_chunk {
    uint32_t cell;                       /* archive cell number (tie-break: larger first) */
    uint32_t scale;                      /* log2(n) · the cell's nSP depth */
    uint32_t levels;                     /* levels kept so far, 0..MS_APO_MAX_LEVELS */
} ms_apo_budget_chunk;

/* The chunk that loses a level next, in the order above: the largest scale +
 * levels - 1 among those with a level left, the larger cell number on a tie
 * (then the larger index); count when none has a level left. The caller cuts it
 * (ms_apo_budget_cut), lowers its levels, and asks again while the cut chunks'
 * real bytes exceed the budget: a cut chunk loses more than its last level's
 * bytes (its smooth nodes on the level above go too), so planning from the level
 * table's prefixes would drop more than needed. */
size_t ms_apo_budget_next(const ms_apo_budget_chunk *chunks, size_t count);

/* The chunk stored as data[0..size) with its level table (2 · levels words, as
 * ms_apo_stream_compress gives it) cut to its first `keep` levels (1 <= keep <=
 * levels) and compressed again at zlib_level, into *out (zeroed first; levels 0
 * when nothing is left). Errors: those of ms_apo_stream_inflate, the loader, the
 * encoder and the compressor; MS_ERR_ARG for keep out of range. */
ms_status ms_apo_budget_cut(const uint8_t *data, size_t size, const uint32_t *level_table, uint32_t levels,
                            uint32_t keep, int zlib_level, ms_bake_apo_result *out, ms_error *err);

#endif
