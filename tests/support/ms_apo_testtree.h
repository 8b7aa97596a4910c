/* Test helpers for APO trees: deterministic random trees, hand-shaped trees, and
 * a brute-force lookup in the unencoded tree (the independent oracle). */
#ifndef MS_APO_TESTTREE_H
#define MS_APO_TESTTREE_H

#include <stdint.h>

#include "ms_apo_build.h"
#include "ms_apo_traverse.h"
#include "ms_apo_tree.h"
#include "ms_mesh.h"

/* The built-in demo sculpture (ms_demo_build) at grid, seed 0, into *mesh
 * (zeroed first; the caller frees it). */
void ms_test_demo_mesh(uint32_t grid, ms_mesh *mesh);

/* The APO cube around a mesh (o->cube_origin, o->cube_size): centred on its
 * bounding box, its largest extent padded by 2 %. */
void ms_test_apo_cube_around(const ms_mesh *mesh, ms_apo_build_options *o);

/* xorshift64* generator. */
uint64_t ms_test_rand(uint64_t *state);
/* Uniform float in [0,1). */
float ms_test_randf(uint64_t *state);

/* A random tree: every node above max_depth is internal with probability
 * p_internal (the root always when max_depth > 0), with a random non-empty child
 * mask; random unit normals (leaves), means recomputed. Aborts the test on OOM. */
void ms_test_random_tree(uint64_t seed, uint32_t max_depth, double p_internal, ms_apo_tree *tree);

/* A chain: every internal node has all 8 children; exactly one of them,
 * octant path[d] at depth d, is internal, down to `depth`. */
void ms_test_chain_tree(uint32_t depth, const uint8_t *path, ms_apo_tree *tree);

/* Brute force: descends the unencoded tree by testing which child's cell
 * [lo, hi) contains the point, in doubles (point = fixed / 2^32). Same stop rules
 * as the traversal; for MS_APO_MISSING_NEAREST it recomputes the nearest child
 * by explicit distances to the children's cells. Returns the node index reached
 * and its stop reason. */
size_t ms_test_brute_lookup(const ms_apo_tree *tree, const uint32_t fixed[3], uint32_t depth_cap,
                            uint32_t complete_levels, ms_apo_missing_rule rule, ms_apo_stop *stop);

#endif
