/* The APO byte budget applied to a bake's archive (docs/APO.md, "The byte
 * budget"): once every cell is encoded, when the chunks put into the writer
 * hold more than params->budget times the geometry bytes, they lose levels one
 * at a time in ms_apo_budget_next's order (the finest first), each cut made
 * from the stored chunk read back from the writer (ms_apo_budget_cut) and
 * counted at its real size, until the total is within the budget; then each cut
 * chunk is put in place of the stored one.
 *
 * Thread-safety: one call per writer, with no other call on it meanwhile.
 */
#ifndef MS_BAKE_APO_BUDGET_H
#define MS_BAKE_APO_BUDGET_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_budget.h"
#include "ms_archive_writer.h"
#include "ms_bake_apo.h"
#include "ms_error.h"

/* A stored chunk and what the report counted of it. */
typedef struct ms_bake_apo_budget_entry {
    ms_apo_budget_chunk chunk;       /* levels: as stored */
    uint64_t bytes;                  /* compressed, as stored */
    uint64_t internal_nodes, leaves;
} ms_bake_apo_budget_entry;

/* What the budget did (all zero when the chunks were within it). */
typedef struct ms_bake_apo_budget_report {
    uint64_t limit;          /* budget · geometry bytes, rounded down; 0 without a budget */
    uint64_t bytes_before;   /* the chunks as built */
    uint64_t bytes_after;
    uint32_t chunks_cut;     /* chunks that lost levels (those removed included) */
    uint32_t chunks_removed; /* chunks left without a texel */
    uint32_t levels_dropped; /* summed over the chunks */
    uint64_t texels_dropped; /* words */
    uint64_t internal_dropped, leaves_dropped;
    uint64_t level_texels_dropped[MS_APO_MAX_LEVELS]; /* words per depth */
} ms_bake_apo_budget_report;

/* Applies the budget to the `count` chunks in entries (updated in place to what
 * is stored afterwards: a removed chunk gets 0 levels). Nothing happens when
 * params->budget is 0 or the chunks fit. Errors: the writer's, the cut's. */
ms_status ms_bake_apo_budget_apply(ms_archive_writer *writer, const ms_bake_apo_params *params,
                                   uint64_t geometry_bytes, ms_bake_apo_budget_entry *entries, size_t count,
                                   ms_bake_apo_budget_report *report, ms_error *err);

#endif
