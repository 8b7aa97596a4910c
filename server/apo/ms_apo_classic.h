/* Whole-model APO ("classic" mode), for comparison with the published results:
 * simplify M to N triangles with quadric decimation, fit one cube around the
 * whole model (its bounding box's lowest corner, width = the largest extent),
 * build one APO around the simplified mesh with the published settings (initial
 * depth 5, maximum depth 13, the published variation measure), encode it, and
 * report sizes and the seconds spent in each phase.
 *
 * Ownership: the caller owns M; chunk (optional) receives the encoded chunk and
 * must be zeroed. Errors: those of ms_simplify, ms_apo_builder_*, and
 * ms_apo_chunk_encode. Thread-safety: independent calls may run concurrently.
 */
#ifndef MS_APO_CLASSIC_H
#define MS_APO_CLASSIC_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_build.h"
#include "ms_apo_chunk.h"
#include "ms_error.h"
#include "ms_mesh.h"

typedef struct ms_apo_classic_options {
    size_t simplify_triangles;  /* N > 0 */
    double tolerance;           /* default 0.05 */
    uint32_t init_depth;        /* default 5 */
    uint32_t max_depth;         /* default 13 */
    ms_apo_measure measure;     /* default MS_APO_MEASURE_CLASSIC */
    double search_distance;     /* cube units; <= 0: automatic (default) */
    unsigned threads;           /* 0 = all cores */
    int zlib_level;             /* for the compressed size; default 6 */
    const ms_mesh *simplified;  /* borrowed: use this m instead of simplifying (NULL) */
    ms_mesh *keep_simplified;   /* if non-NULL (zeroed), receives m; caller frees it */
} ms_apo_classic_options;

void ms_apo_classic_options_default(ms_apo_classic_options *options);

typedef struct ms_apo_classic_report {
    size_t input_triangles;
    size_t simplified_triangles;
    size_t refused_faces;          /* faces OpenMesh would not take */
    size_t internal_nodes;
    size_t leaves;
    size_t texels;                 /* 32-bit words */
    size_t bytes;                  /* 4 * texels */
    size_t stored_bytes;           /* the stored chunk (zlib + header) */
    uint32_t levels;
    uint32_t level_texels[MS_APO_MAX_LEVELS];
    double cube_origin[3];         /* the cube around the model, mesh units */
    double cube_size;
    uint32_t texture_width;        /* the published 2D layout, for comparison */
    uint32_t texture_height;
    ms_apo_build_stats build;
    double seconds_simplify;
    double seconds_prepare;        /* transforms, normals, Embree scene, m-to-M distance */
    double seconds_octree;
    double seconds_sample;
    double seconds_encode;         /* texel words */
    double seconds_store;          /* zlib + CRC */
    double seconds_apo;            /* prepare + octree + sample + encode */
    double seconds_total;          /* everything above */
} ms_apo_classic_report;

ms_status ms_apo_classic_run(const ms_mesh *M, const ms_apo_classic_options *options, ms_apo_chunk *chunk,
                             ms_apo_classic_report *report, ms_error *err);

#endif
