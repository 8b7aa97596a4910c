/* APO as a correction (docs/APO.md, "APO as a correction"): of a built tree,
 * keep only the texels where M's normal differs from what the client already
 * draws there, m's smooth normal, by more than a tolerance.
 *
 * Input: the tree with its normals (leaves sampled, internal nodes the
 * normalised means of their children: ms_apo_tree_average_normals) and, per
 * node, the prediction: for a leaf, m's smooth normal at the leaf's samples
 * (ms_apo_sample_leaf), for an internal node the normalised sum of its
 * children's (computed here). The deviation of a node is the angle between its
 * normal and its prediction, taken unsigned (acos |n . p|: the client turns a
 * normal facing away from its triangle over, so a texel wound the other way
 * shades as its reverse). Rule:
 *   - a leaf is kept when its deviation exceeds `tolerance` (radians);
 *   - an internal node is kept when a child is kept; its mean is stored as
 *     MS_APO_NORMAL_SMOOTH (smooth = 1) unless its own deviation exceeds the
 *     tolerance (what a lookup stopped there, by depth cap, footprint or a
 *     prefix, then draws: the mean only where it improves on the smooth normal
 *     by that much over the whole node);
 *   - everything else is dropped: where the chunk holds no node the client
 *     draws its smooth normal. A tree with no kept leaf becomes empty.
 * A prediction of zero length (no sample) keeps the node (nothing to compare).
 *
 * Thread-safety: works on the caller's objects only.
 */
#ifndef MS_APO_CORRECT_H
#define MS_APO_CORRECT_H

#include <stddef.h>

#include "ms_apo_tree.h"
#include "ms_error.h"

/* Applies the rule above to *tree in place. predicted: 3 floats per node,
 * leaves filled, internal nodes overwritten here. dropped_leaves (may be NULL):
 * leaves dropped. MS_ERR_NOMEM (tree unchanged). */
ms_status ms_apo_correct(ms_apo_tree *tree, float *predicted, double tolerance, size_t *dropped_leaves,
                         ms_error *err);

/* acos |a . b| / (|a| |b|) in radians; -1 when either has zero length. */
double ms_apo_unsigned_angle(const float a[3], const float b[3]);

#endif
