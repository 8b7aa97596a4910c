/* Per-cell APO chunks of a bake (docs/APO.md, "Per-cell chunks"): for one nSP
 * cell, the octree of normals rooted at the cell's cube, built around m (the
 * cell's mesh as the decoder gives it at the cell's bits_max) from M (the input's
 * triangles of the cell at full precision), encoded into texel words and
 * compressed as the archive stores them (ms_apo_stream.h).
 *
 * Depth rule: the cell's finest geometric precision, in octree levels of its own
 * cube, is g = bits_max - log2(n) * depth (its grid has 2^g steps per side); the
 * chunk goes down at most min(g + lead, max_depth) levels, splitting where M's
 * normals spread more than `tolerance` radians (the builder's spread measure).
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

typedef struct ms_bake_apo_params {
    bool enabled;
    uint32_t lead;        /* levels below the finest geometric precision, <= 16 (default 3) */
    uint32_t max_depth;   /* cap on the chunk's depth, <= 24 (default 10) */
    uint32_t init_depth;  /* split unconditionally above this depth (default 0) */
    double tolerance;     /* spread of M's normals, radians (default 0.2) */
    int zlib_level;       /* 0..9 (default 6) */
    bool verify;          /* decode each stored chunk back and compare it with the built tree */
} ms_bake_apo_params;

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

typedef struct ms_bake_apo_result {
    uint8_t *data;             /* compressed chunk, NULL when the chunk is empty */
    size_t size;
    uint32_t levels;           /* 0: no chunk (m does not touch the cube) */
    uint32_t level_table[2 * MS_APO_MAX_LEVELS]; /* as ms_apo_stream_compress gives it */
    uint32_t level_texels[MS_APO_MAX_LEVELS];    /* words per level */
    uint64_t texels;
    size_t internal_nodes, leaves;
} ms_bake_apo_result;

void ms_bake_apo_result_free(ms_bake_apo_result *result);

/* Builds, encodes and compresses one cell's chunk into *out (zeroed first), the
 * builder running on `threads` threads (the output does not depend on it). With
 * params->verify, also inflates the stored bytes, loads them (ms_apo_view_init),
 * decodes them into a tree and fails with MS_ERR_CORRUPT unless it has exactly the
 * built tree's nodes and normal codes. Errors: those of the builder, the encoder,
 * the compressor. */
ms_status ms_bake_apo_cell(ms_apo_builder *builder, const ms_bake_apo_params *params,
                           const ms_nsp_shape *shape, const ms_quant_box *box, unsigned depth,
                           const uint32_t position[3], unsigned bits_max, const ms_mesh *m,
                           const ms_mesh *M, unsigned threads, ms_bake_apo_result *out,
                           ms_error *err);

/* True when two trees have the same nodes (depth, cell, children) and the same
 * normal codes; on a difference, writes the first differing node into *node. */
bool ms_bake_apo_same_tree(const ms_apo_tree *a, const ms_apo_tree *b, size_t *node);

#endif
