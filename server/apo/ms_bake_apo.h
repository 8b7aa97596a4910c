/* Per-cell APO chunks of a bake (docs/APO.md, "Per-cell chunks"): for one nSP
 * cell, the octree of normals rooted at the cell's cube, built around m (the
 * cell's mesh as the decoder gives it at the cell's bits_max) from M (the surface
 * whose normals are sampled: a leaf's input triangles at full precision; for an
 * internal cell the union of its children's m, log2(n) bits finer than the
 * cell's own m, vertices at the means of the input vertices they stand for:
 * ms_bake_apo_part, ms_bake_apo_union, ms_bake_apo_smooth), encoded into texel
 * words and compressed as the archive stores them (ms_apo_stream.h).
 *
 * Depth rule: the cell's finest geometric precision, in octree levels of its own
 * cube, is g = bits_max - log2(n) * depth (its grid has 2^g steps per side); the
 * chunk goes down at most min(g + lead, max_depth) levels, splitting where M's
 * normals spread more than `tolerance` radians (the builder's spread measure).
 *
 * No chunk where the geometry renders M (ms_bake_apo_geometry_renders: every
 * leaf cell), unless params->every_cell. Inside a chunk, only corrections: the
 * texels where M's normal differs from m's smooth normal, what the client draws
 * without a texel, by more than `correction` (ms_apo_correct.h; crease 60
 * degrees, m's vertices up to half a grid cell's diagonal off), unless
 * params->full_normals; a chunk left without texels is no chunk.
 *
 * Units: meshes in world units (the archive box's); the cube is derived from the
 * box and the cell. Ownership: the result owns its bytes (ms_bake_apo_result_free).
 * Thread-safety: one builder per thread; distinct calls are independent.
 */
#ifndef MS_BAKE_APO_H
#define MS_BAKE_APO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_apo_build.h"
#include "ms_error.h"
#include "ms_mesh.h"
#include "ms_nsp.h"
#include "ms_quant.h"

#define MS_BAKE_APO_MAX_LEAD 16u      /* what the archive header can record */
#define MS_BAKE_APO_MAX_DEPTH 24u
#define MS_BAKE_APO_BUDGET 1.0        /* APO bytes over geometry bytes, at most (docs/APO.md) */
#define MS_BAKE_APO_MAX_BUDGET 1000.0

typedef struct ms_bake_apo_params {
    bool enabled;
    uint32_t lead;        /* levels below the finest geometric precision, <= 16 (default 1) */
    uint32_t max_depth;   /* cap on the chunk's depth, <= 24 (default 10) */
    uint32_t init_depth;  /* split unconditionally above this depth (default 0) */
    double tolerance;     /* spread of M's normals, radians (default 0.2) */
    double correction;    /* keep a texel where it differs from the smooth normal by more, radians (default 0.2, the tolerance) */
    /* The chunks together hold at most budget times the geometry bytes, the
     * finest levels dropped first where they hold more (ms_apo_budget.h,
     * docs/APO.md "The byte budget"); 0: no budget. Default MS_BAKE_APO_BUDGET. */
    double budget;
    int zlib_level;       /* 0..9 (default 6) */
    bool verify;          /* decode each stored chunk back and compare it with the built tree */
    /* Diagnostics, off by default. sample_leaves: an internal cell's M is every
     * full-precision leaf triangle below it (the former rule: memory grows with the
     * model, the root holds all of it). accuracy: measure each internal cell's
     * chunk against those full-precision triangles (ms_bake_apo_result.accuracy),
     * which costs the same memory. */
    bool sample_leaves;
    bool accuracy;
    /* every_cell: a chunk for every cell with triangles, also where the cell's
     * geometry already renders M (ms_bake_apo_geometry_renders); the former rule,
     * kept to measure the trade and to exercise the format on small models. */
    bool every_cell;
    /* full_normals: every node keeps its texel, also where m's smooth normal
     * already gives M's (the former rule, before chunks were corrections:
     * docs/APO.md "APO as a correction"); kept to measure the trade. */
    bool full_normals;
    /* Adaptive sampling (radians, ms_apo_build_options.sample_agreement): a
     * leaf whose two nearest samples agree within this angle takes no more;
     * 0: every sample (the former rule). Default MS_BAKE_APO_AGREEMENT. */
    double sample_agreement;
} ms_bake_apo_params;

/* Default adaptive-sampling angle, radians: half the default tolerance. On
 * the dragon it settles 94 % of the leaves with two samples (3.08 M rays down
 * to 1.0 M) and brings the chunks closer to M (docs/APO.md, "Sampling"). */
#define MS_BAKE_APO_AGREEMENT 0.1

/* Defaults as above, enabled. */
void ms_bake_apo_params_default(ms_bake_apo_params *params);

/* MS_ERR_ARG (with the reason) when a field is out of range. */
ms_status ms_bake_apo_params_check(const ms_bake_apo_params *params, ms_error *err);

/* The deepest level the chunk of a cell at nSP `depth` with window end bits_max may reach. */
uint32_t ms_bake_apo_depth(const ms_nsp_shape *shape, unsigned depth, unsigned bits_max,
                           const ms_bake_apo_params *params);

/* The cell's cube in world units. */
void ms_bake_apo_cube(const ms_nsp_shape *shape, const ms_quant_box *box, unsigned depth,
                      const uint32_t position[3], double origin[3], double *size);

/* Angles between the chunk's normal (CPU traversal, MS_APO_MISSING_NEAREST, no
 * depth cap) and a reference mesh's face normal at the reference's triangle
 * centroids, as a histogram of MS_BAKE_APO_ANGLE_BINS bins of 0.1 degree (the last
 * bin holds everything above). Degenerate reference triangles are skipped. */
#define MS_BAKE_APO_ANGLE_BINS 1800u
typedef struct ms_bake_apo_accuracy {
    uint64_t points;
    double sum_degrees;
    uint64_t bins[MS_BAKE_APO_ANGLE_BINS];
} ms_bake_apo_accuracy;

/* Adds b's points into a. */
void ms_bake_apo_accuracy_add(ms_bake_apo_accuracy *a, const ms_bake_apo_accuracy *b);

/* The angle (degrees, bin centre) below which a fraction q (0..1) of the points
 * lie; 0 without points. */
double ms_bake_apo_accuracy_quantile(const ms_bake_apo_accuracy *a, double q);

typedef struct ms_bake_apo_result {
    uint8_t *data;             /* compressed chunk, NULL when the chunk is empty */
    size_t size;
    uint32_t levels;           /* 0: no chunk (m does not touch the cube) */
    uint32_t level_table[2 * MS_APO_MAX_LEVELS]; /* as ms_apo_stream_compress gives it */
    uint32_t level_texels[MS_APO_MAX_LEVELS];    /* words per level */
    uint64_t texels;
    size_t internal_nodes, leaves;
    uint64_t rays, point_queries; /* the builder's sampling work (ms_apo_build_stats) */
    uint64_t triangle_visits;     /* the builder's own work: triangles looked at one by one */
    uint64_t samples;             /* (leaf, m-triangle) samples taken */
    uint64_t sampled_leaves;      /* leaves sampled (before the correction rule) */
    uint64_t agreed_leaves;       /* of which settled by two agreeing samples */
    size_t smooth_leaves;      /* leaves dropped: m's smooth normal gives M's there */
    ms_bake_apo_accuracy accuracy; /* filled when a reference mesh was given */
} ms_bake_apo_result;

void ms_bake_apo_result_free(ms_bake_apo_result *result);

/* True when the geometry the client shows at the cell's finest precision (m)
 * already renders M's normals: every M-triangle of non-zero area is an m-triangle
 * (the same three vertex positions, exactly, in any order), so the flat shading
 * of m gives M's face normals and a chunk could only replace them with coarser
 * ones. True for a leaf cell, whose m at bits_max is its input at full precision
 * (foreign triangles aside), hence for a small model that fits in one cell (a
 * cube). False when M has a triangle m lacks, or when memory runs out (the caller
 * then builds the chunk, which is always correct). */
bool ms_bake_apo_geometry_renders(const ms_mesh *m, const ms_mesh *M);

/* Builds, encodes and compresses one cell's chunk into *out (zeroed first), the
 * builder running on `threads` threads (the output does not depend on it). With
 * params->verify, also inflates the stored bytes, loads them (ms_apo_view_init),
 * decodes them into a tree and fails with MS_ERR_CORRUPT unless it has exactly the
 * built tree's nodes and normal codes. reference may be NULL; otherwise the chunk
 * is measured against it into out->accuracy (nothing else depends on it). Errors:
 * those of the builder, the encoder, the compressor. */
ms_status ms_bake_apo_cell(ms_apo_builder *builder, const ms_bake_apo_params *params,
                           const ms_nsp_shape *shape, const ms_quant_box *box, unsigned depth,
                           const uint32_t position[3], unsigned bits_max, const ms_mesh *m,
                           const ms_mesh *M, const ms_mesh *reference, unsigned threads,
                           ms_bake_apo_result *out, ms_error *err);

/* What a cell hands its parent for the parent's M: its m (decoded at its
 * bits_max) with every vertex moved from its grid cell's centre to the mean of the
 * full-precision input vertices that cell stands for (found level by level: a
 * leaf's vertices are themselves, weight 1; see ms_bake_apo_smooth). Centres at
 * 9 bits make a staircase whose face normals spread everywhere; the means give
 * the surface back its shape at the same size. */
typedef struct ms_bake_apo_part {
    ms_mesh mesh;
    uint32_t *weight;       /* per vertex: input vertices its position averages (>= 1) */
    unsigned bits;          /* the cell's bits_max: each vertex lies in one grid cell of it */
    double origin[3], size; /* the cell's cube: vertices inside it are its own */
} ms_bake_apo_part;

void ms_bake_apo_part_free(ms_bake_apo_part *part);

/* M of an internal cell: the union of the `count` parts (its children; empty ones
 * allowed) into *M (zeroed first; caller frees with ms_mesh_free) and *owned
 * (malloc'd, one per M vertex, caller frees): the vertex's weight when it lies in
 * the cube of the part it comes from, else 0. Vertices are one per (bits, grid
 * cell): siblings share their border vertices, and a vertex held by several parts
 * takes the position of its owner (the part whose cube holds it, which saw all of
 * its input vertices), else of the heaviest copy, else the first; they are
 * ordered by (bits, cell). Triangles are then kept once per set of three
 * vertices, the first in part order, in part order. The output depends only on
 * the input. box: the archive's. Errors: MS_ERR_NOMEM, MS_ERR_RANGE (2^32 vertices
 * or more). */
ms_status ms_bake_apo_union(const ms_bake_apo_part *parts, size_t count, const ms_quant_box *box, ms_mesh *M,
                            uint32_t **owned, ms_error *err);

/* The part an internal cell hands up: its m (bits_max `bits`, vertices at grid
 * cell centres) with each vertex at the weighted mean of M's owned vertices in
 * its grid cell (owned from ms_bake_apo_union); a cell without any takes the plain
 * mean of M's vertices there, else keeps its centre. *out takes m's arrays (m is
 * left zeroed). cube: the cell's. Errors: MS_ERR_NOMEM (m is then left as given). */
ms_status ms_bake_apo_smooth(ms_mesh *m, unsigned bits, const ms_quant_box *box, const double origin[3],
                             double size, const ms_mesh *M, const uint32_t *owned, ms_bake_apo_part *out,
                             ms_error *err);


/* True when two trees have the same nodes (depth, cell, children) and the same
 * normal codes; on a difference, writes the first differing node into *node. */
bool ms_bake_apo_same_tree(const ms_apo_tree *a, const ms_apo_tree *b, size_t *node);

#endif
