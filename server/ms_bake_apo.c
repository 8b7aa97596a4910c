/* Per-cell APO chunks: see ms_bake_apo.h. */
#include "ms_bake_apo.h"

#include <stdlib.h>
#include <string.h>

#include "ms_apo_chunk.h"
#include "ms_apo_stream.h"

void ms_bake_apo_params_default(ms_bake_apo_params *p)
{
    memset(p, 0, sizeof *p);
    p->enabled = true;
    p->lead = 3;
    p->max_depth = 10;
    p->init_depth = 0;
    p->tolerance = 0.2;
    p->zlib_level = 6;
}

ms_status ms_bake_apo_params_check(const ms_bake_apo_params *p, ms_error *err)
{
    if (p->lead > MS_BAKE_APO_MAX_LEAD)
        return ms_error_set(err, MS_ERR_ARG, "--apo-lead must be at most %u", MS_BAKE_APO_MAX_LEAD);
    if (p->max_depth > MS_BAKE_APO_MAX_DEPTH)
        return ms_error_set(err, MS_ERR_ARG, "--apo-max-depth must be at most %u", MS_BAKE_APO_MAX_DEPTH);
    if (!(p->tolerance >= 0.0 && p->tolerance < 1e12))
        return ms_error_set(err, MS_ERR_ARG, "--apo-tol must be a number >= 0");
    if (p->zlib_level < 0 || p->zlib_level > 9)
        return ms_error_set(err, MS_ERR_ARG, "APO zlib level must be 0..9");
    return MS_OK;
}

uint32_t ms_bake_apo_depth(const ms_nsp_shape *shape, unsigned depth, unsigned bits_max,
                           const ms_bake_apo_params *p)
{
    unsigned above = shape->log2n * depth;
    uint32_t finest = bits_max > above ? bits_max - above : 0;
    uint32_t d = finest + p->lead;
    return d < p->max_depth ? d : p->max_depth;
}

void ms_bake_apo_cube(const ms_nsp_shape *shape, const ms_quant_box *box, unsigned depth,
                      const uint32_t position[3], double origin[3], double *size)
{
    /* box->size / n^depth is exact (a power of two), so is position * width. */
    double width = box->size / (double)(1ull << (shape->log2n * depth));
    for (int a = 0; a < 3; ++a)
        origin[a] = box->origin[a] + (double)position[a] * width;
    *size = width;
}

void ms_bake_apo_result_free(ms_bake_apo_result *r)
{
    free(r->data);
    memset(r, 0, sizeof *r);
}

bool ms_bake_apo_same_tree(const ms_apo_tree *a, const ms_apo_tree *b, size_t *node)
{
    *node = 0;
    if (a->node_count != b->node_count || a->level_count != b->level_count)
        return false;
    for (size_t i = 0; i < a->node_count; ++i) {
        const ms_apo_node *x = &a->nodes[i], *y = &b->nodes[i];
        *node = i;
        if (x->first_child != y->first_child || x->child_mask != y->child_mask || x->depth != y->depth ||
            memcmp(x->cell, y->cell, sizeof x->cell) != 0 ||
            ms_apo_normal_encode(x->normal) != ms_apo_normal_encode(y->normal))
            return false;
    }
    return true;
}

/* Inflate, load, decode: the stored bytes must give back the built tree. */
static ms_status verify_stored(const ms_apo_tree *built, const ms_bake_apo_result *r, ms_error *err)
{
    ms_apo_chunk back;
    ms_status st = ms_apo_stream_inflate(r->data, r->size, r->level_table, r->levels, &back, err);
    if (st != MS_OK)
        return st;
    ms_apo_view view;
    ms_apo_tree decoded;
    memset(&decoded, 0, sizeof decoded);
    st = ms_apo_view_of_chunk(&view, &back, err);
    if (st == MS_OK)
        st = ms_apo_view_decode(&view, &decoded, err);
    size_t node;
    if (st == MS_OK && !ms_bake_apo_same_tree(built, &decoded, &node))
        st = ms_error_set(err, MS_ERR_CORRUPT, "APO chunk does not decode to the built tree (node %zu)", node);
    ms_apo_tree_free(&decoded);
    ms_apo_chunk_free(&back);
    return st;
}

ms_status ms_bake_apo_cell(ms_apo_builder *builder, const ms_bake_apo_params *p, const ms_nsp_shape *shape,
                           const ms_quant_box *box, unsigned depth, const uint32_t position[3], unsigned bits_max,
                           const ms_mesh *m, const ms_mesh *M, unsigned threads, ms_bake_apo_result *out,
                           ms_error *err)
{
    memset(out, 0, sizeof *out);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_bake_apo_cube(shape, box, depth, position, o.cube_origin, &o.cube_size);
    o.max_depth = ms_bake_apo_depth(shape, depth, bits_max, p);
    o.init_depth = p->init_depth < o.max_depth ? p->init_depth : o.max_depth;
    o.tolerance = p->tolerance;
    o.measure = MS_APO_MEASURE_SPREAD;
    o.threads = threads ? threads : 1;
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    ms_status st = ms_apo_builder_build_tree(builder, m, M, &o, &tree, NULL, err);
    ms_apo_chunk chunk;
    memset(&chunk, 0, sizeof chunk);
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_chunk_encode(&tree, &chunk, err);
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_stream_compress(&chunk, p->zlib_level, &out->data, &out->size, out->level_table, err);
    if (st == MS_OK) {
        out->levels = chunk.level_count;
        memcpy(out->level_texels, chunk.level_texels, chunk.level_count * sizeof *chunk.level_texels);
        out->texels = chunk.texel_count;
        ms_apo_tree_counts(&tree, &out->internal_nodes, &out->leaves);
        if (p->verify && out->levels > 0)
            st = verify_stored(&tree, out, err);
    }
    ms_apo_chunk_free(&chunk);
    ms_apo_tree_free(&tree);
    if (st != MS_OK)
        ms_bake_apo_result_free(out);
    return st;
}
