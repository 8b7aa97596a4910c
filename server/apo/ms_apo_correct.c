/* APO as a correction of the smooth normal (rules in ms_apo_correct.h). */
#include "ms_apo_correct.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>

double ms_apo_unsigned_angle(const float a[3], const float b[3])
{
    double aa = 0, bb = 0, ab = 0;
    for (int k = 0; k < 3; ++k) {
        aa += (double)a[k] * a[k];
        bb += (double)b[k] * b[k];
        ab += (double)a[k] * b[k];
    }
    if (!(aa > 0.0) || !(bb > 0.0))
        return -1.0;
    double c = fabs(ab) / sqrt(aa * bb);
    return acos(c > 1.0 ? 1.0 : c);
}

ms_status ms_apo_correct(ms_apo_tree *tree, float *predicted, double tolerance, size_t *dropped_leaves,
                         ms_error *err)
{
    if (dropped_leaves)
        *dropped_leaves = 0;
    if (tree->node_count == 0)
        return MS_OK;
    uint8_t *keep = calloc(tree->node_count, 1);
    if (!keep)
        return ms_error_set(err, MS_ERR_NOMEM, "apo correction: no memory for %zu nodes", tree->node_count);
    /* Bottom-up (children follow their parents in breadth-first order). */
    size_t dropped = 0;
    for (size_t i = tree->node_count; i-- > 0;) {
        ms_apo_node *n = &tree->nodes[i];
        float *p = &predicted[3 * i];
        if (n->child_mask) {
            double s[3] = {0, 0, 0};
            uint32_t count = ms_apo_popcount8(n->child_mask);
            for (uint32_t k = 0; k < count; ++k) {
                keep[i] |= keep[n->first_child + k];
                for (int a = 0; a < 3; ++a)
                    s[a] += predicted[3 * (n->first_child + k) + a];
            }
            double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
            for (int a = 0; a < 3; ++a)
                p[a] = len > 1e-12 ? (float)(s[a] / len) : 0.0f;
        }
        double dev = ms_apo_unsigned_angle(n->normal, p);
        bool corrects = dev < 0.0 || dev > tolerance;
        if (!n->child_mask) {
            keep[i] = corrects;
            dropped += !corrects;
        } else {
            n->smooth = !corrects;
        }
    }
    ms_status st = ms_apo_tree_prune(tree, keep, err);
    free(keep);
    if (st == MS_OK && dropped_leaves)
        *dropped_leaves = dropped;
    return st;
}
