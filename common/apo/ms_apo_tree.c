/* Checks and bottom-up averaging on the unencoded APO octree. */
#include "ms_apo_tree.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void ms_apo_tree_free(ms_apo_tree *tree)
{
    if (!tree)
        return;
    free(tree->nodes);
    memset(tree, 0, sizeof *tree);
}

ms_status ms_apo_tree_check(const ms_apo_tree *tree, ms_error *err)
{
    if (tree->level_count > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: %u levels (max %u)", tree->level_count,
                            MS_APO_MAX_LEVELS);
    if (tree->level_count == 0)
        return tree->node_count == 0 ? MS_OK
                                     : ms_error_set(err, MS_ERR_CORRUPT, "apo tree: nodes but no levels");
    if (tree->level_start[0] != 0 || tree->level_start[1] != 1 ||
        tree->level_start[tree->level_count] != tree->node_count)
        return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: bad level table");
    const ms_apo_node *root = &tree->nodes[0];
    if (root->depth != 0 || root->cell[0] || root->cell[1] || root->cell[2])
        return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: bad root");
    for (uint32_t d = 0; d < tree->level_count; ++d) {
        size_t next = tree->level_start[d + 1];
        if (tree->level_start[d] >= next)
            return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: empty level %u", d);
        for (size_t i = tree->level_start[d]; i < tree->level_start[d + 1]; ++i) {
            const ms_apo_node *n = &tree->nodes[i];
            if (n->depth != d)
                return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: node %zu has depth %u on level %u", i,
                                    n->depth, d);
            if (!n->child_mask)
                continue;
            if (d + 1 >= tree->level_count || n->first_child != next)
                return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: node %zu children not where expected", i);
            for (uint32_t o = 0; o < 8; ++o) {
                if (!(n->child_mask >> o & 1u))
                    continue;
                if (next >= tree->level_start[d + 2])
                    return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: level %u overflows", d + 1);
                const ms_apo_node *c = &tree->nodes[next];
                uint32_t want[3] = {2 * n->cell[0] + (o >> 2 & 1u), 2 * n->cell[1] + (o >> 1 & 1u),
                                    2 * n->cell[2] + (o & 1u)};
                if (c->depth != d + 1 || memcmp(c->cell, want, sizeof want) != 0)
                    return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: node %zu octant %u has a wrong cell", i, o);
                ++next;
            }
        }
        if (d + 1 < tree->level_count && next != tree->level_start[d + 2])
            return ms_error_set(err, MS_ERR_CORRUPT, "apo tree: level %u children do not fill level %u", d, d + 1);
    }
    return MS_OK;
}

void ms_apo_tree_average_normals(ms_apo_tree *tree)
{
    for (size_t i = tree->node_count; i-- > 0;) {
        ms_apo_node *n = &tree->nodes[i];
        if (!n->child_mask)
            continue;
        double s[3] = {0, 0, 0};
        uint32_t count = ms_apo_popcount8(n->child_mask);
        for (uint32_t k = 0; k < count; ++k)
            for (int a = 0; a < 3; ++a)
                s[a] += tree->nodes[n->first_child + k].normal[a];
        double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        if (len > 1e-12)
            for (int a = 0; a < 3; ++a)
                n->normal[a] = (float)(s[a] / len);
        else
            memcpy(n->normal, tree->nodes[n->first_child].normal, sizeof n->normal);
    }
}

ms_status ms_apo_tree_prune(ms_apo_tree *tree, const uint8_t *keep, ms_error *err)
{
    if (tree->node_count == 0)
        return MS_OK;
    for (size_t i = 0; i < tree->node_count; ++i) {
        const ms_apo_node *n = &tree->nodes[i];
        uint32_t count = ms_apo_popcount8(n->child_mask);
        for (uint32_t k = 0; k < count; ++k)
            if (keep[n->first_child + k] && !keep[i])
                return ms_error_set(err, MS_ERR_ARG, "apo prune: node %zu kept under a dropped parent",
                                    (size_t)n->first_child + k);
    }
    if (!keep[0]) {
        ms_apo_tree_free(tree);
        return MS_OK;
    }
    uint32_t *new_index = malloc(tree->node_count * sizeof *new_index);
    if (!new_index)
        return ms_error_set(err, MS_ERR_NOMEM, "apo prune: no memory for %zu nodes", tree->node_count);
    /* Breadth-first order is kept by keeping the nodes in their order: the
     * children of a kept node stay contiguous and in octant order. */
    size_t kept = 0;
    for (size_t i = 0; i < tree->node_count; ++i)
        new_index[i] = keep[i] ? (uint32_t)kept++ : UINT32_MAX;
    size_t at = 0;
    uint32_t levels = 0;
    size_t level_start[MS_APO_MAX_LEVELS + 1];
    for (size_t i = 0; i < tree->node_count; ++i) {
        if (!keep[i])
            continue;
        ms_apo_node n = tree->nodes[i];
        uint32_t first = UINT32_MAX;
        uint8_t mask = 0;
        for (uint32_t o = 0, k = 0; o < 8; ++o) {
            if (!(n.child_mask >> o & 1u))
                continue;
            uint32_t c = n.first_child + k++;
            if (keep[c]) {
                mask |= (uint8_t)(1u << o);
                if (first == UINT32_MAX)
                    first = new_index[c];
            }
        }
        n.child_mask = mask;
        n.first_child = mask ? first : 0;
        if (!mask)
            n.smooth = 0; /* a leaf holds its normal */
        while (levels <= n.depth)
            level_start[levels++] = at;
        tree->nodes[at++] = n;
    }
    free(new_index);
    level_start[levels] = at;
    tree->node_count = at;
    tree->level_count = levels;
    memcpy(tree->level_start, level_start, (levels + 1) * sizeof *level_start);
    return MS_OK;
}

void ms_apo_tree_counts(const ms_apo_tree *tree, size_t *internal_nodes, size_t *leaves)
{
    size_t in = 0;
    for (size_t i = 0; i < tree->node_count; ++i)
        in += tree->nodes[i].child_mask != 0;
    if (internal_nodes)
        *internal_nodes = in;
    if (leaves)
        *leaves = tree->node_count - in;
}
