/* The unencoded APO octree: what the builder produces and the encoder consumes.
 *
 * Nodes are stored breadth-first: level d occupies nodes[level_start[d] ..
 * level_start[d+1]), and the children of a node are contiguous, in increasing
 * octant order, starting at first_child. A node's cell is given by its depth and
 * integer coordinates cell[3] in [0, 2^depth): it covers
 * [cell*2^-depth, (cell+1)*2^-depth) on each axis of the chunk's unit cube.
 * Octant i of a node = 4*[x upper] + 2*[y upper] + [z upper].
 *
 * The tree owns its node array (ms_apo_tree_free). Not thread-safe per object.
 */
#ifndef MS_APO_TREE_H
#define MS_APO_TREE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_format.h"
#include "ms_error.h"

typedef struct ms_apo_node {
    uint32_t first_child;  /* index in nodes of the first stored child (0 for a leaf) */
    uint32_t cell[3];      /* integer cell coordinates at `depth` */
    uint8_t child_mask;    /* bit i: octant i stored; 0 for a leaf */
    uint8_t depth;         /* 0 = root */
    uint8_t smooth;        /* internal nodes: 1 = no correction here, the client's smooth
                              normal (encoded MS_APO_NORMAL_SMOOTH; normal ignored) */
    float normal[3];       /* unit normal: sampled (leaf) or normalised mean (internal) */
} ms_apo_node;

typedef struct ms_apo_tree {
    ms_apo_node *nodes;
    size_t node_count;
    uint32_t level_count;                       /* 0 for an empty tree */
    size_t level_start[MS_APO_MAX_LEVELS + 1];  /* level_start[level_count] == node_count */
} ms_apo_tree;

void ms_apo_tree_free(ms_apo_tree *tree);

/* Checks every structural promise above (BFS levels, contiguous children in octant
 * order, consistent cells and depths, no child of a leaf). MS_ERR_CORRUPT with a
 * message naming the first faulty node. */
ms_status ms_apo_tree_check(const ms_apo_tree *tree, ms_error *err);

/* Sets every internal node's normal to the normalised mean of its children's
 * normals, bottom-up. A zero sum keeps the first child's normal. */
void ms_apo_tree_average_normals(ms_apo_tree *tree);

/* Keeps only the nodes with keep[i] set (a kept node's parent must be kept, the
 * root's flag decides whether anything is left): the tree is rebuilt in place,
 * breadth-first, children masks and first_child renumbered; a kept internal
 * node none of whose children is kept becomes a leaf. MS_ERR_NOMEM (the tree is
 * then unchanged), MS_ERR_ARG when a kept node's parent is not kept. */
ms_status ms_apo_tree_prune(ms_apo_tree *tree, const uint8_t *keep, ms_error *err);

/* Counts of internal nodes and leaves. */
void ms_apo_tree_counts(const ms_apo_tree *tree, size_t *internal_nodes, size_t *leaves);

#endif
