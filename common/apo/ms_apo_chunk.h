/* APO chunks in memory: encoding a tree into texel words, the validating loader
 * (a read-only "view" over received words), and decoding back into a tree.
 *
 * A chunk is its level table (words per level of the complete chunk) plus the
 * words received so far, which may be any prefix. Only whole levels are used: a
 * level still in transit reads as absent. The loader checks, before anything can
 * follow an offset, that every word of every complete level is well formed and
 * that every offset is exactly the one breadth-first order implies, so a
 * corrupted offset can never lead a traversal outside the chunk (docs/APO.md,
 * "Validation").
 *
 * Ownership: ms_apo_chunk owns its texels (ms_apo_chunk_free); ms_apo_view
 * borrows them and must not outlive them. Views are immutable after
 * ms_apo_view_init and may be shared by any number of threads.
 */
#ifndef MS_APO_CHUNK_H
#define MS_APO_CHUNK_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_format.h"
#include "ms_apo_tree.h"
#include "ms_error.h"

typedef struct ms_apo_chunk {
    uint32_t *texels;                          /* texel_count words, owned */
    size_t texel_count;                        /* words held (a prefix or all) */
    uint32_t level_count;                      /* levels of the complete chunk; 0 = empty */
    uint32_t level_texels[MS_APO_MAX_LEVELS];  /* words per level of the complete chunk */
} ms_apo_chunk;

typedef struct ms_apo_view {
    const uint32_t *texels;                    /* borrowed */
    size_t texel_count;                        /* words received */
    size_t total_texels;                       /* words of the complete chunk */
    uint32_t level_count;                      /* levels of the complete chunk */
    uint32_t complete_levels;                  /* levels wholly inside the received words */
    uint32_t level_texels[MS_APO_MAX_LEVELS];
    size_t level_start[MS_APO_MAX_LEVELS + 1]; /* word index where each level starts */
    uint32_t root_words;                       /* 1 = the root is a leaf, 2 = internal */
} ms_apo_view;

void ms_apo_chunk_free(ms_apo_chunk *chunk);

/* Makes *chunk own `words` (malloc'd, count of them) under the given table of the
 * complete chunk (level_count <= MS_APO_MAX_LEVELS words per level). */
void ms_apo_chunk_adopt(ms_apo_chunk *chunk, uint32_t *words, size_t count, uint32_t level_count,
                        const uint32_t *level_texels);

/* Encodes a tree (checked with ms_apo_tree_check first). *chunk must be zeroed.
 * Errors: MS_ERR_CORRUPT for a malformed tree, MS_ERR_RANGE when a relative offset
 * does not fit in 24 bits or the chunk exceeds MS_APO_MAX_TEXELS, MS_ERR_NOMEM. */
ms_status ms_apo_chunk_encode(const ms_apo_tree *tree, ms_apo_chunk *chunk, ms_error *err);

/* The validating loader. level_texels[0..level_count) is the table of the
 * complete chunk; texels[0..received) the words received so far (received may be
 * anything from 0 to the table's total). Errors: MS_ERR_FORMAT for a bad table,
 * MS_ERR_RANGE when more words are received than the table holds, MS_ERR_CORRUPT
 * for any bad word (naming its index), MS_ERR_NOMEM. On error *view is zeroed. */
ms_status ms_apo_view_init(ms_apo_view *view, const uint32_t *level_texels, uint32_t level_count,
                           const uint32_t *texels, size_t received, ms_error *err);

/* Convenience: a view over a chunk's own words. */
ms_status ms_apo_view_of_chunk(ms_apo_view *view, const ms_apo_chunk *chunk, ms_error *err);

/* Rebuilds the tree of the complete levels of a validated view (normals are the
 * decoded codes, smooth set where a mean word holds MS_APO_NORMAL_SMOOTH; a node
 * of the last complete level whose children are missing becomes a leaf carrying
 * its mean, which may be smooth). *tree must be zeroed. */
ms_status ms_apo_view_decode(const ms_apo_view *view, ms_apo_tree *tree, ms_error *err);

#endif
