/* The APO byte budget: see ms_apo_budget.h. */
#include "ms_apo_budget.h"

#include <stdlib.h>
#include <string.h>

#include "ms_apo_chunk.h"
#include "ms_apo_stream.h"
#include "ms_apo_tree.h"

size_t ms_apo_budget_next(const ms_apo_budget_chunk *chunks, size_t count)
{
    size_t best = count;
    for (size_t i = 0; i < count; ++i) {
        const ms_apo_budget_chunk *c = &chunks[i];
        if (c->levels == 0)
            continue;
        if (best == count) {
            best = i;
            continue;
        }
        const ms_apo_budget_chunk *b = &chunks[best];
        uint64_t fine = (uint64_t)c->scale + c->levels, fine_best = (uint64_t)b->scale + b->levels;
        if (fine > fine_best || (fine == fine_best && c->cell >= b->cell))
            best = i;
    }
    return best;
}

/* Keeps a node when it, or a node below it, holds a correction: bottom-up, a
 * leaf when it is not smooth, an internal node when a child is kept or its own
 * mean is a correction (then it becomes a leaf if no child is kept). */
static void mark_corrections(const ms_apo_tree *tree, uint8_t *keep)
{
    for (size_t i = tree->node_count; i-- > 0;) {
        const ms_apo_node *nd = &tree->nodes[i];
        bool child_kept = false;
        if (nd->child_mask) {
            unsigned children = (unsigned)__builtin_popcount(nd->child_mask);
            for (unsigned k = 0; k < children; ++k)
                child_kept |= keep[nd->first_child + k] != 0;
        }
        keep[i] = child_kept || !nd->smooth;
    }
}

ms_status ms_apo_budget_cut(const uint8_t *data, size_t size, const uint32_t *level_table, uint32_t levels,
                            uint32_t keep, int zlib_level, ms_bake_apo_result *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (keep == 0 || keep > levels || levels > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_ARG, "APO budget: cannot keep %u of %u levels", keep, levels);
    size_t prefix = level_table[2 * (keep - 1)];
    if (prefix > size)
        return ms_error_set(err, MS_ERR_FORMAT, "APO budget: level table beyond the chunk's %zu bytes", size);
    ms_apo_chunk part, cut;
    memset(&part, 0, sizeof part);
    memset(&cut, 0, sizeof cut);
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    ms_apo_view view;
    uint8_t *flags = NULL;
    ms_status st = ms_apo_stream_inflate(data, prefix, level_table, levels, &part, err);
    if (st == MS_OK)
        st = ms_apo_view_of_chunk(&view, &part, err);
    if (st == MS_OK && view.complete_levels != keep)
        st = ms_error_set(err, MS_ERR_CORRUPT, "APO budget: %u complete levels where %u were cut",
                          view.complete_levels, keep);
    if (st == MS_OK)
        st = ms_apo_view_decode(&view, &tree, err);
    if (st == MS_OK && tree.node_count > 0) {
        flags = malloc(tree.node_count);
        if (!flags)
            st = ms_error_set(err, MS_ERR_NOMEM, "out of memory cutting an APO chunk");
    }
    if (st == MS_OK && tree.node_count > 0) {
        mark_corrections(&tree, flags);
        if (flags[0])
            st = ms_apo_tree_prune(&tree, flags, err);
        else
            ms_apo_tree_free(&tree);
    }
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_chunk_encode(&tree, &cut, err);
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_stream_compress(&cut, zlib_level, &out->data, &out->size, out->level_table, err);
    if (st == MS_OK && tree.level_count > 0) {
        out->levels = cut.level_count;
        memcpy(out->level_texels, cut.level_texels, cut.level_count * sizeof *cut.level_texels);
        out->texels = cut.texel_count;
        ms_apo_tree_counts(&tree, &out->internal_nodes, &out->leaves);
    }
    free(flags);
    ms_apo_tree_free(&tree);
    ms_apo_chunk_free(&cut);
    ms_apo_chunk_free(&part);
    if (st != MS_OK)
        ms_bake_apo_result_free(out);
    return st;
}
