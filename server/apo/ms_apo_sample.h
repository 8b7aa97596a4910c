/* Probing the original mesh M with Embree 3 for the APO builder: the leaf normal
 * rule (rays both ways along m's interpolated normal, nearest hit, closest-point
 * fallback, m's own normal last) and the m-to-M distance h. The rules are
 * documented in ms_apo_build.h and docs/APO.md.
 *
 * Ownership: a sampler owns one Embree scene over M (built on the caller's
 * device) and borrows M, which must outlive it. After init it is read-only: any
 * number of threads may sample with it at once.
 */
#ifndef MS_APO_SAMPLE_H
#define MS_APO_SAMPLE_H

#include <embree3/rtcore.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_apo_local_mesh.h"
#include "ms_error.h"

typedef struct ms_apo_sampler {
    RTCScene scene;
    const ms_apo_local_mesh *big;
} ms_apo_sampler;

typedef struct ms_apo_sample_counts {
    uint64_t samples;        /* (leaf, m-triangle) pairs sampled */
    uint64_t ray_hits;
    uint64_t closest_points;
    uint64_t unsampled;      /* fell back to m's normal (or +z) */
    uint64_t rays;           /* rtcIntersect1 calls (at most 2 per sample) */
    uint64_t point_queries;  /* rtcPointQuery calls (at most 1 per leaf) */
    uint64_t local_answers;  /* ray pairs and closest points settled by the leaf's own M-triangles */
    uint64_t triangle_tests; /* m- and M-triangles looked at one by one (not counting Embree's) */
    uint64_t leaves;         /* leaves sampled (counted by the caller) */
    uint64_t agreed;         /* leaves that stopped after two agreeing samples (agreement > 0) */
} ms_apo_sample_counts;

/* A leaf samples at most this many of the m-triangles it touches: those whose
 * closest point to its centre is nearest (ties: lower triangle index), so that a
 * leaf costs at most 2 * MS_APO_SAMPLES_PER_LEAF rays whatever m's valence or
 * triangle count there (a fan's hub). */
#define MS_APO_SAMPLES_PER_LEAF 8u

/* A leaf with an M list (crowded M) tests every listed triangle for each of
 * its samples: it samples at most MS_APO_LOCAL_TESTS / (list length) of its
 * m-triangles, at least one, so that a leaf at a fan's hub, whose list holds
 * every sliver, costs one pass over it rather than eight. */
#define MS_APO_LOCAL_TESTS 16384u

/* The samples a leaf takes, for its M list's length (0: no list, Embree). */
size_t ms_apo_leaf_samples(size_t big_count);

/* Builds the scene (a fast Morton BVH). MS_ERR_UNSUPPORTED / MS_ERR_NOMEM when
 * Embree fails. On error *sampler is zeroed. */
ms_status ms_apo_sampler_init(ms_apo_sampler *sampler, RTCDevice device, const ms_apo_local_mesh *big,
                              ms_error *err);
void ms_apo_sampler_release(ms_apo_sampler *sampler);

/* h: the largest distance from m's vertices and face centroids to M (cube
 * units; 0 when M is empty). Deterministic whatever the thread count. */
ms_status ms_apo_sampler_distance(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, unsigned threads,
                                  double *h, ms_error *err);

/* One leaf: its cube (centre, half its width) and the triangles touching it. */
typedef struct ms_apo_leaf_probe {
    float centre[3];
    float half_width;
    const uint32_t *m_tris;   /* m-triangles touching the leaf */
    size_t m_count;
    const uint32_t *big_tris; /* M-triangles touching the leaf (a superset is fine) */
    size_t big_count;
    /* The list is the leaf's answer (crowded M): Embree is never asked, a leaf
     * whose list holds nothing near takes m's own normal (unsampled). */
    bool listed;
    /* Adaptive sampling: > 0 (radians): the leaf samples its two nearest
     * m-triangles first and stops there when their normals lie within this
     * angle of each other; the others only where they disagree. <= 0: every
     * sample (at most ms_apo_leaf_samples). */
    float agreement;
} ms_apo_leaf_probe;

/* The normal of a leaf: one sample for each of the (at most
 * MS_APO_SAMPLES_PER_LEAF) m-triangles nearest to the centre, within half-length
 * `search`, normalised sum (the nearest triangle's sample where the sum
 * vanishes; +z for no sample).
 *
 * A leaf without a list (uncrowded M) asks Embree over all of M. A leaf with
 * one (leaf->listed: crowded M) answers from it alone: the nearest listed hit
 * (M's nearest when it lies inside the grown cube by a sixteenth of its
 * half-width: every nearer hit would too, so its triangle is listed), else
 * the list's closest point within `search`, else m's own normal (unsampled);
 * it samples at most ms_apo_leaf_samples(big_count) m-triangles. Embree's
 * boxes of a fan's slivers all hold its hub, so one of its queries there
 * visits a good part of M.
 * smooth (may be NULL): the prediction, the normalised sum of m's smooth
 * normals (ms_apo_local_mesh_smooth_at) at the same closest points, what the
 * client draws there without a texel (zero when they cancel or no sample).
 * Adds what happened to *counts. */
void ms_apo_sample_leaf(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, const ms_apo_leaf_probe *leaf,
                        float search, float normal[3], float smooth[3], ms_apo_sample_counts *counts);

#endif
