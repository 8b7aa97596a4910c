/* APO chunk encoding, validating loader and decoding (see ms_apo_chunk.h). */
#include "ms_apo_chunk.h"

#include <stdlib.h>
#include <string.h>

void ms_apo_chunk_free(ms_apo_chunk *chunk)
{
    if (!chunk)
        return;
    free(chunk->texels);
    memset(chunk, 0, sizeof *chunk);
}

void ms_apo_chunk_adopt(ms_apo_chunk *chunk, uint32_t *words, size_t count, uint32_t level_count,
                        const uint32_t *level_texels)
{
    memset(chunk, 0, sizeof *chunk);
    chunk->texels = words;
    chunk->texel_count = count;
    chunk->level_count = level_count;
    memcpy(chunk->level_texels, level_texels, level_count * sizeof *level_texels);
}

ms_status ms_apo_chunk_encode(const ms_apo_tree *tree, ms_apo_chunk *chunk, ms_error *err)
{
    ms_status st = ms_apo_tree_check(tree, err);
    if (st != MS_OK)
        return st;
    memset(chunk, 0, sizeof *chunk);
    if (tree->node_count == 0)
        return MS_OK;
    /* Pass 1: the word index of every node, in breadth-first order. */
    uint64_t *word_index = malloc(tree->node_count * sizeof *word_index);
    if (!word_index)
        return ms_error_set(err, MS_ERR_NOMEM, "apo encode: no memory for %zu nodes", tree->node_count);
    uint64_t words = 0;
    for (uint32_t d = 0; d < tree->level_count; ++d) {
        uint64_t level_words = 0;
        for (size_t i = tree->level_start[d]; i < tree->level_start[d + 1]; ++i) {
            word_index[i] = words + level_words;
            level_words += ms_apo_node_words(tree->nodes[i].child_mask != 0);
        }
        words += level_words;
        if (words > MS_APO_MAX_TEXELS) {
            free(word_index);
            return ms_error_set(err, MS_ERR_RANGE, "apo encode: more than %u words", MS_APO_MAX_TEXELS);
        }
        chunk->level_texels[d] = (uint32_t)level_words;
    }
    chunk->texels = malloc((size_t)words * sizeof *chunk->texels);
    if (!chunk->texels) {
        free(word_index);
        return ms_error_set(err, MS_ERR_NOMEM, "apo encode: no memory for %llu words", (unsigned long long)words);
    }
    /* Pass 2: the words, now that every child's index is known. */
    for (size_t i = 0; i < tree->node_count; ++i) {
        const ms_apo_node *n = &tree->nodes[i];
        uint32_t code = n->child_mask && n->smooth ? MS_APO_NORMAL_SMOOTH : ms_apo_normal_encode(n->normal);
        uint64_t w = word_index[i];
        if (!n->child_mask) {
            chunk->texels[w] = ms_apo_leaf_word(code);
            continue;
        }
        uint64_t offset = word_index[n->first_child] - w;
        if (offset > MS_APO_MAX_OFFSET) {
            free(word_index);
            ms_apo_chunk_free(chunk);
            return ms_error_set(err, MS_ERR_RANGE, "apo encode: node %zu needs offset %llu (> 24 bits)", i,
                                (unsigned long long)offset);
        }
        uint32_t kind = 0, k = 0;
        for (uint32_t o = 0; o < 8; ++o)
            if (n->child_mask >> o & 1u)
                kind |= (uint32_t)(tree->nodes[n->first_child + k++].child_mask != 0) << o;
        chunk->texels[w] = ms_apo_header_word((uint32_t)offset, n->child_mask);
        chunk->texels[w + 1] = ms_apo_mean_word(kind, code);
    }
    free(word_index);
    chunk->texel_count = (size_t)words;
    chunk->level_count = tree->level_count;
    return MS_OK;
}

/* The level table's own rules (and the words received against it); *total:
 * the words the table holds. */
static ms_status check_level_table(const uint32_t *level_texels, uint32_t level_count,
                                   const uint32_t *texels, size_t received, uint64_t *total_out,
                                   ms_error *err)
{
    if (level_count > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_FORMAT, "apo chunk: %u levels (max %u)", level_count, MS_APO_MAX_LEVELS);
    uint64_t total = 0;
    for (uint32_t d = 0; d < level_count; ++d) {
        if (level_texels[d] == 0)
            return ms_error_set(err, MS_ERR_FORMAT, "apo chunk: level %u is empty", d);
        total += level_texels[d];
    }
    if (total > MS_APO_MAX_TEXELS)
        return ms_error_set(err, MS_ERR_FORMAT, "apo chunk: %llu words (max %u)", (unsigned long long)total,
                            MS_APO_MAX_TEXELS);
    if (level_count > 0 && level_texels[0] != 1 && level_texels[0] != 2)
        return ms_error_set(err, MS_ERR_FORMAT, "apo chunk: level 0 has %u words (1 or 2 expected)", level_texels[0]);
    if (received > total)
        return ms_error_set(err, MS_ERR_RANGE, "apo chunk: %zu words received, table holds %llu", received,
                            (unsigned long long)total);
    if (received > 0 && !texels)
        return ms_error_set(err, MS_ERR_ARG, "apo chunk: no word array");
    *total_out = total;
    return MS_OK;
}

ms_status ms_apo_view_init(ms_apo_view *view, const uint32_t *level_texels, uint32_t level_count,
                           const uint32_t *texels, size_t received, ms_error *err)
{
    memset(view, 0, sizeof *view);
    uint64_t total = 0; /* set on MS_OK; gcc -O2 cannot see it through the early returns */
    ms_status table = check_level_table(level_texels, level_count, texels, received, &total, err);
    if (table != MS_OK)
        return table;
    ms_apo_view v;
    memset(&v, 0, sizeof v);
    v.texels = texels;
    v.texel_count = received;
    v.total_texels = (size_t)total;
    v.level_count = level_count;
    v.root_words = level_count ? level_texels[0] : 0;
    for (uint32_t d = 0; d < level_count; ++d) {
        v.level_texels[d] = level_texels[d];
        v.level_start[d + 1] = v.level_start[d] + level_texels[d];
        if (v.level_start[d + 1] <= received)
            v.complete_levels = d + 1;
    }
    /* Walk the complete levels breadth-first. `kinds` lists the kind (1 =
     * internal) of every node of the level being checked, in order; it is
     * produced by the level above. */
    /* A level holds at most as many nodes as words. */
    size_t kinds_cap = 2;
    for (uint32_t d = 0; d < level_count; ++d)
        if (level_texels[d] > kinds_cap)
            kinds_cap = level_texels[d];
    uint8_t *kinds = malloc(kinds_cap), *next_kinds = malloc(kinds_cap);
    if (!kinds || !next_kinds) {
        free(kinds);
        free(next_kinds);
        return ms_error_set(err, MS_ERR_NOMEM, "apo chunk: no memory to validate");
    }
    size_t kind_count = 1;
    kinds[0] = v.root_words == 2;
    ms_status st = MS_OK;
    for (uint32_t d = 0; d < v.complete_levels && st == MS_OK; ++d) {
        size_t w = v.level_start[d], end = v.level_start[d + 1];
        size_t child_cursor = v.level_start[d + 1]; /* where the next child block must start */
        size_t next_count = 0;
        for (size_t k = 0; k < kind_count; ++k) {
            bool internal = kinds[k];
            if (w + ms_apo_node_words(internal) > end) {
                st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: level %u overflows its %u words", d,
                                  level_texels[d]);
                break;
            }
            if (!internal) {
                if (!ms_apo_normal_code_valid(texels[w]))
                    st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: word %zu is not a valid leaf", w);
                w += 1;
            } else {
                uint32_t exist = ms_apo_header_exist(texels[w]);
                uint32_t kind = ms_apo_mean_kind(texels[w + 1]);
                uint64_t offset = ms_apo_header_offset(texels[w]);
                if (exist == 0 || (kind & ~exist) != 0)
                    st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: word %zu has bad masks", w);
                else if (!ms_apo_normal_code_valid(ms_apo_word_normal(texels[w + 1])) &&
                         ms_apo_word_normal(texels[w + 1]) != MS_APO_NORMAL_SMOOTH)
                    st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: word %zu has a bad mean normal", w + 1);
                else if (d + 1 >= level_count)
                    st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: word %zu has children below the last level", w);
                else if (w + offset != child_cursor)
                    st = ms_error_set(err, MS_ERR_CORRUPT,
                                      "apo chunk: word %zu offset %llu points to %llu, expected %zu", w,
                                      (unsigned long long)offset, (unsigned long long)(w + offset), child_cursor);
                if (st != MS_OK)
                    break;
                for (uint32_t o = 0; o < 8 && st == MS_OK; ++o)
                    if (exist >> o & 1u) {
                        bool child_internal = kind >> o & 1u;
                        /* Children must fit in the next level (this also bounds
                         * next_kinds, as every child takes at least one word). */
                        if (child_cursor + ms_apo_node_words(child_internal) > v.level_start[d + 2]) {
                            st = ms_error_set(err, MS_ERR_CORRUPT,
                                              "apo chunk: word %zu has more children than level %u holds", w, d + 1);
                            break;
                        }
                        next_kinds[next_count++] = child_internal;
                        child_cursor += ms_apo_node_words(child_internal);
                    }
                if (st != MS_OK)
                    break;
                w += 2;
            }
            if (st != MS_OK)
                break;
        }
        if (st != MS_OK)
            break;
        if (w != end)
            st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: level %u has %zu words, table says %u", d,
                              w - v.level_start[d], level_texels[d]);
        else if (d + 1 < level_count && child_cursor != v.level_start[d + 2])
            st = ms_error_set(err, MS_ERR_CORRUPT, "apo chunk: level %u children take %zu words, table says %u", d,
                              child_cursor - v.level_start[d + 1], level_texels[d + 1]);
        uint8_t *t = kinds;
        kinds = next_kinds;
        next_kinds = t;
        kind_count = next_count;
    }
    free(kinds);
    free(next_kinds);
    if (st == MS_OK)
        *view = v;
    return st;
}

ms_status ms_apo_view_of_chunk(ms_apo_view *view, const ms_apo_chunk *chunk, ms_error *err)
{
    return ms_apo_view_init(view, chunk->level_texels, chunk->level_count, chunk->texels, chunk->texel_count, err);
}

ms_status ms_apo_view_decode(const ms_apo_view *view, ms_apo_tree *tree, ms_error *err)
{
    memset(tree, 0, sizeof *tree);
    if (view->complete_levels == 0)
        return MS_OK;
    /* Breadth-first walk with a queue of (word index, kind); each node takes at
     * least one word, so the word count bounds the node count. */
    size_t cap = view->level_start[view->complete_levels];
    tree->nodes = calloc(cap ? cap : 1, sizeof *tree->nodes);
    uint64_t *word_of = malloc((cap ? cap : 1) * sizeof *word_of);
    uint8_t *internal_of = malloc(cap ? cap : 1);
    if (!tree->nodes || !word_of || !internal_of) {
        free(word_of);
        free(internal_of);
        ms_apo_tree_free(tree);
        return ms_error_set(err, MS_ERR_NOMEM, "apo decode: no memory");
    }
    size_t count = 1;
    word_of[0] = 0;
    internal_of[0] = view->root_words == 2;
    tree->level_start[0] = 0;
    tree->level_start[1] = 1;
    uint32_t levels = 1;
    for (size_t i = 0; i < count; ++i) {
        ms_apo_node *n = &tree->nodes[i];
        uint64_t w = word_of[i];
        uint32_t depth = n->depth;
        if (depth + 1 > levels) {
            tree->level_start[depth] = i;
            levels = depth + 1;
        }
        if (!internal_of[i]) {
            ms_apo_normal_decode(ms_apo_word_normal(view->texels[w]), n->normal);
            continue;
        }
        uint32_t mean = ms_apo_word_normal(view->texels[w + 1]);
        n->smooth = mean == MS_APO_NORMAL_SMOOTH;
        if (!n->smooth)
            ms_apo_normal_decode(mean, n->normal);
        if (depth + 1 >= view->complete_levels)
            continue; /* children not received: a leaf with its mean normal (or smooth) */
        uint32_t exist = ms_apo_header_exist(view->texels[w]);
        uint32_t kind = ms_apo_mean_kind(view->texels[w + 1]);
        uint64_t child_word = w + ms_apo_header_offset(view->texels[w]);
        n->child_mask = (uint8_t)exist;
        n->first_child = (uint32_t)count;
        for (uint32_t o = 0; o < 8; ++o) {
            if (!(exist >> o & 1u))
                continue;
            ms_apo_node *c = &tree->nodes[count];
            c->depth = (uint8_t)(depth + 1);
            c->cell[0] = 2 * n->cell[0] + (o >> 2 & 1u);
            c->cell[1] = 2 * n->cell[1] + (o >> 1 & 1u);
            c->cell[2] = 2 * n->cell[2] + (o & 1u);
            word_of[count] = child_word;
            internal_of[count] = kind >> o & 1u;
            child_word += ms_apo_node_words(internal_of[count]);
            ++count;
        }
    }
    tree->node_count = count;
    tree->level_count = levels;
    tree->level_start[levels] = count;
    free(word_of);
    free(internal_of);
    return ms_apo_tree_check(tree, err);
}
