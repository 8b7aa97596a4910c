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
} ms_apo_sample_counts;

/* A leaf samples at most this many of the m-triangles it touches: those whose
 * closest point to its centre is nearest (ties: lower triangle index), so that a
 * leaf costs at most 2 * MS_APO_SAMPLES_PER_LEAF rays whatever m's valence or
 * triangle count there (a fan's hub). */
#define MS_APO_SAMPLES_PER_LEAF 8u

/* Builds the scene (a fast Morton BVH). MS_ERR_UNSUPPORTED / MS_ERR_NOMEM when
 * Embree fails. On error *sampler is zeroed. */
ms_status ms_apo_sampler_init(ms_apo_sampler *sampler, RTCDevice device, const ms_apo_local_mesh *big,
                              ms_error *err);
void ms_apo_sampler_release(ms_apo_sampler *sampler);

/* h: the largest distance from m's vertices and face centroids to M (cube
 * units; 0 when M is empty). Deterministic whatever the thread count. */
ms_status ms_apo_sampler_distance(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, unsigned threads,
                                  double *h, ms_error *err);

/* The normal of a leaf with centre `centre` touching the m-triangles
 * m_tris[0..count): one sample for each of the (at most MS_APO_SAMPLES_PER_LEAF)
 * m-triangles nearest to the centre, within half-length `search`,
 * normalised sum (the nearest triangle's sample where the sum vanishes; +z for
 * no sample).
 * Adds what happened to *counts. */
void ms_apo_sample_leaf(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, const uint32_t *m_tris,
                        size_t count, const float centre[3], float search, float normal[3],
                        ms_apo_sample_counts *counts);

#endif
