/* Whole-model APO with the published settings (see ms_apo_classic.h). */
#include "ms_apo_classic.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_blob.h"
#include "ms_progress.h"
#include "ms_simplify.h"

void ms_apo_classic_options_default(ms_apo_classic_options *o)
{
    memset(o, 0, sizeof *o);
    o->simplify_triangles = 3000;
    o->tolerance = 0.05;
    o->init_depth = 5;
    o->max_depth = 13;
    o->measure = MS_APO_MEASURE_CLASSIC;
    o->zlib_level = 6;
}

/* Smallest power-of-two width whose square holds the words; rows that would be
 * empty are dropped. */
static void texture_layout(size_t texels, uint32_t *width, uint32_t *height)
{
    uint64_t w = 1;
    while (w * w < texels)
        w *= 2;
    *width = (uint32_t)w;
    *height = (uint32_t)((texels + w - 1) / w);
}

ms_status ms_apo_classic_run(const ms_mesh *M, const ms_apo_classic_options *o, ms_apo_chunk *chunk_out,
                             ms_apo_classic_report *r, ms_error *err)
{
    memset(r, 0, sizeof *r);
    if (chunk_out)
        memset(chunk_out, 0, sizeof *chunk_out);
    r->input_triangles = M->triangle_count;
    if (M->vertex_count == 0 || M->triangle_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "apo classic: the mesh has no triangle");
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t i = 0; i < M->vertex_count; ++i)
        for (int a = 0; a < 3; ++a) {
            double p = M->positions[3 * i + a];
            if (!isfinite(p))
                return ms_error_set(err, MS_ERR_RANGE, "apo classic: vertex %zu is not finite", i);
            lo[a] = fmin(lo[a], p);
            hi[a] = fmax(hi[a], p);
        }
    double size = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    if (!(size > 0.0))
        return ms_error_set(err, MS_ERR_RANGE, "apo classic: the mesh has no extent");

    memcpy(r->cube_origin, lo, sizeof lo);
    r->cube_size = size;
    double t0 = ms_now_seconds();
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_status st = MS_OK;
    const ms_mesh *surface = o->simplified;
    if (!surface) {
        ms_simplify_report sr;
        st = ms_simplify(M, o->simplify_triangles, &m, &sr, err);
        if (st != MS_OK)
            return st;
        r->refused_faces = sr.refused_faces;
        surface = &m;
    }
    r->simplified_triangles = surface->triangle_count;
    double t1 = ms_now_seconds();
    r->seconds_simplify = t1 - t0;

    ms_apo_build_options bo;
    ms_apo_build_options_default(&bo);
    memcpy(bo.cube_origin, lo, sizeof lo);
    bo.cube_size = size;
    bo.init_depth = o->init_depth;
    bo.max_depth = o->max_depth;
    bo.tolerance = o->tolerance;
    bo.measure = o->measure;
    bo.search_distance = o->search_distance;
    bo.threads = o->threads;
    ms_apo_builder *builder = NULL;
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    st = ms_apo_builder_create(&builder, err);
    if (st == MS_OK)
        st = ms_apo_builder_build_tree(builder, surface, M, &bo, &tree, &r->build, err);
    ms_apo_builder_destroy(builder);
    if (o->keep_simplified && !o->simplified && st == MS_OK)
        *o->keep_simplified = m;
    else
        ms_mesh_free(&m);
    if (st != MS_OK)
        return st;
    r->seconds_prepare = r->build.seconds_prepare;
    r->seconds_octree = r->build.seconds_octree;
    r->seconds_sample = r->build.seconds_sample;

    double t2 = ms_now_seconds();
    ms_apo_chunk chunk;
    st = ms_apo_chunk_encode(&tree, &chunk, err);
    ms_apo_tree_free(&tree);
    if (st != MS_OK)
        return st;
    double t3 = ms_now_seconds();
    r->seconds_encode = t3 - t2;
    uint8_t *blob = NULL;
    size_t blob_size = 0;
    st = ms_apo_blob_write(&chunk, o->zlib_level, &blob, &blob_size, err);
    free(blob);
    r->seconds_store = ms_now_seconds() - t3;
    if (st != MS_OK) {
        ms_apo_chunk_free(&chunk);
        return st;
    }
    r->internal_nodes = r->build.internal_nodes;
    r->leaves = r->build.leaves;
    r->texels = chunk.texel_count;
    r->bytes = 4 * chunk.texel_count;
    r->stored_bytes = blob_size;
    r->levels = chunk.level_count;
    memcpy(r->level_texels, chunk.level_texels, sizeof r->level_texels);
    texture_layout(r->texels, &r->texture_width, &r->texture_height);
    r->seconds_apo = r->seconds_prepare + r->seconds_octree + r->seconds_sample + r->seconds_encode;
    r->seconds_total = r->seconds_simplify + r->seconds_apo + r->seconds_store;
    if (chunk_out)
        *chunk_out = chunk;
    else
        ms_apo_chunk_free(&chunk);
    return MS_OK;
}
