/* The APO builder: an adaptive octree around a surface m, sampled from the
 * original mesh M (docs/APO.md, "Building").
 *
 * 1. Octree. The cube is the root. A node keeps the m-triangles and the
 *    M-triangles that touch its cell (closed cells, exact separating-axis test).
 *    A node is split while depth < init_depth (unconditionally), or while
 *    depth < max_depth, it touches at least one M-triangle and the variation of
 *    M's normals over those triangles exceeds `tolerance`. Only children that
 *    touch m are kept. The tree is built level by level, in parallel.
 * 2. Sampling. Every leaf casts, for each of the (at most
 *    MS_APO_SAMPLES_PER_LEAF, ms_apo_sample.h) m-triangles it touches whose
 *    closest point to its centre is nearest, a ray from its centre along m's
 *    interpolated vertex normal at that closest point, both ways, over [-s, s]; the nearest hit on M (Embree) wins
 *    and contributes M's interpolated vertex normal there. Without a hit, the
 *    closest point of M within s of the centre is used (Embree point query);
 *    without that either, m's own normal (counted as unsampled; +z for a
 *    degenerate m-triangle that has no normal, which casts no ray). The leaf normal
 *    is the normalised sum of its samples. The search half-length is
 *        s = 2 h + (sqrt(3)/2) w
 *    where w is the leaf's width and h estimates m's distance to M (the largest
 *    distance from m's vertices and face centroids to M, or the caller's bound),
 *    unless the options fix s. Internal nodes get the normalised mean of their children's normals.
 *    Where M is crowded (slivers: ms_apo_crowding above 64) every node keeps a
 *    capped list of the M-triangles near it and the leaves answer from it,
 *    never from Embree (ms_apo_sample.h, docs/APO.md "Sampling"), so that the
 *    work stays linear in M on a fan.
 * 3. Correction (options.correction): the texels m's smooth normal already
 *    gives are dropped (ms_apo_correct.h).
 *
 * Determinism: the output depends only on the inputs and options, never on the
 * thread count (work is split into blocks fixed by the work size; every block
 * writes its own outputs; Embree returns the nearest hit, and ties on a shared
 * edge interpolate the same vertex normals).
 *
 * Units: mesh positions in the meshes' own units; the cube is given in the same
 * units; the tolerance per measure (below); distances in the options and the
 * statistics are in cube units (the cube has width 1).
 *
 * Ownership and threads: an ms_apo_builder owns one Embree device (no global
 * state); one build at a time per builder; distinct builders are independent.
 */
#ifndef MS_APO_BUILD_H
#define MS_APO_BUILD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_apo_chunk.h"
#include "ms_apo_tree.h"
#include "ms_error.h"
#include "ms_mesh.h"

typedef enum ms_apo_measure {
    /* Area-weighted angular spread, in radians: sqrt(2 (1 - |sum a_i n_i| /
     * sum a_i)), the RMS chord between M's unit face normals n_i (areas a_i) and
     * their mean direction (equal to the RMS angle for small spreads). It does
     * not change when the same surface is tessellated more finely. Default. */
    MS_APO_MEASURE_SPREAD = 0,
    /* The published measure: sum_i |n_i - n_mean|^2 over the M-triangles of the
     * cell, n_mean the (not renormalised) mean of the unit normals; no area
     * weights, so it grows with the triangle count: tolerances are not
     * comparable between meshes of different density. */
    MS_APO_MEASURE_CLASSIC = 1
} ms_apo_measure;

typedef struct ms_apo_build_options {
    double cube_origin[3];   /* lowest corner of the cube, mesh units */
    double cube_size;        /* its width, mesh units (> 0) */
    uint32_t init_depth;     /* split unconditionally above this depth (published: 5) */
    uint32_t max_depth;      /* deepest level, <= MS_APO_MAX_DEPTH (published: 13) */
    double tolerance;        /* on the chosen measure */
    ms_apo_measure measure;
    double search_distance;  /* fixed s in cube units; <= 0: the automatic rule */
    /* h for the automatic rule, cube units: > 0 uses this bound instead of
     * measuring m's distance to M (a point query per vertex and face of m, whose
     * cost grows with M's valence: Embree's boxes of a fan's slivers all hold its
     * hub); <= 0 measures it. */
    double distance_bound;
    unsigned threads;        /* 0 = all cores */
    /* APO as a correction (ms_apo_correct.h, docs/APO.md): keep only the texels
     * whose normal differs from m's smooth normal (what the client draws without
     * a texel) by more than correction_tolerance radians. m's smooth normals
     * follow the client's rule (ms_apo_local_mesh_corner_normals) with
     * crease_angle (radians) and vertex_error (cube units: how far m's vertices
     * may be from where they stand for, the renderer's slack). Off by default:
     * every node is kept, as before. */
    bool correction;
    double correction_tolerance;
    double crease_angle;     /* default 60 degrees, the client's default */
    double vertex_error;
    /* Adaptive sampling (radians): > 0, a leaf samples its two nearest
     * m-triangles first and takes the others (up to MS_APO_SAMPLES_PER_LEAF)
     * only where those two normals differ by more than this angle
     * (ms_apo_leaf_probe.agreement); <= 0 (default): every sample. */
    double sample_agreement;
} ms_apo_build_options;

/* Defaults: unit cube at the origin, init 0, max 12, spread tolerance 0.05 rad,
 * automatic search distance, all cores. */
void ms_apo_build_options_default(ms_apo_build_options *options);

typedef struct ms_apo_build_stats {
    size_t internal_nodes;
    size_t leaves;
    uint32_t levels;
    uint64_t samples;          /* (leaf, m-triangle) pairs sampled */
    uint64_t ray_hits;         /* samples answered by a ray */
    uint64_t closest_points;   /* samples answered by the closest-point query */
    uint64_t unsampled;        /* samples that fell back to m's normal */
    uint64_t rays;             /* rays cast while sampling (<= 2 * MS_APO_SAMPLES_PER_LEAF per leaf) */
    uint64_t point_queries;    /* closest-point queries while sampling (<= 1 per leaf; h's not counted) */
    uint64_t local_answers;    /* ray pairs and closest points answered from a leaf's own M-triangles */
    size_t sampled_leaves;     /* leaves sampled (before the correction rule drops any) */
    size_t agreed_leaves;      /* of which stopped after two agreeing samples (sample_agreement) */
    double crowding;           /* ms_apo_crowding of M; above 64 the leaves keep M lists */
    size_t smooth_leaves;      /* leaves dropped by the correction rule (m's smooth normal suffices) */
    /* The build's own work, one per triangle looked at: list entries made by
     * the splits, m- and M-triangles tested by the leaves (Embree's queries,
     * counted in rays and point_queries, not included). */
    uint64_t triangle_visits;
    double m_to_M_distance;    /* h, cube units */
    double seconds_prepare;    /* transforms, normals, root lists, Embree scene, h */
    double seconds_scene;      /* of which: Embree's BVH over M */
    double seconds_distance;   /* of which: h */
    double seconds_octree;
    double seconds_sample;
} ms_apo_build_stats;

typedef struct ms_apo_builder ms_apo_builder;

/* Creates a builder with its own Embree device. MS_ERR_NOMEM / MS_ERR_UNSUPPORTED
 * (Embree refused) with err set. */
ms_status ms_apo_builder_create(ms_apo_builder **builder, ms_error *err);
void ms_apo_builder_destroy(ms_apo_builder *builder);

/* Builds the tree for surface m and original M. *tree must be zeroed. An m that
 * does not touch the cube gives an empty tree (0 levels), not an error. Errors:
 * MS_ERR_ARG (bad options, bad triangle indices), MS_ERR_RANGE (non-finite
 * coordinates), MS_ERR_NOMEM, MS_ERR_UNSUPPORTED (Embree). stats may be NULL. */
ms_status ms_apo_builder_build_tree(ms_apo_builder *builder, const ms_mesh *m, const ms_mesh *M,
                                    const ms_apo_build_options *options, ms_apo_tree *tree,
                                    ms_apo_build_stats *stats, ms_error *err);

/* The same, encoded: *chunk must be zeroed. Also fails with MS_ERR_RANGE when an
 * offset does not fit in 24 bits. */
ms_status ms_apo_builder_build_chunk(ms_apo_builder *builder, const ms_mesh *m, const ms_mesh *M,
                                     const ms_apo_build_options *options, ms_apo_chunk *chunk,
                                     ms_apo_build_stats *stats, ms_error *err);

#endif
