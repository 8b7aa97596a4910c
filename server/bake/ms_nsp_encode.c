/* Post-order parallel encoding of the nSP cells: see ms_nsp_encode.h. */
#include "ms_nsp_encode.h"
#include "ms_tri_unify.h"

#include <pthread.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif
#include <stdio.h>
#include <stdbool.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_build.h"
#include "ms_bake_apo_budget.h"
#include "ms_bake_colour.h"
#include "ms_codec.h"
#include "ms_nsp.h"
#include "ms_nsp_cell_state.h"
#include "ms_nsp_lone.h"
#include "ms_nsp_surface.h"
#include "ms_parallel.h"
#include "ms_progress.h"

typedef struct task {
    uint32_t pending;         /* children not yet done */
    uint32_t post;            /* post-order number (priority) */
    ms_codec_state *starts;   /* n^3 children's start states, once the first is done */
    ms_bake_apo_part *parts;  /* n^3 children's APO parts (this cell's M), likewise */
    ms_codec_truth truth;     /* its children's summaries (model grid steps), what its
                               * surface error is measured against; truth_cap points */
    size_t truth_cap;
} task;

typedef struct pool {
    const ms_nsp_build *b;
    const uint32_t *cell_of_node;
    ms_archive_writer *writer;
    const ms_nsp_encode_params *params;
    unsigned max_depth; /* of the tree's cells */
    task *tasks;
    uint32_t *heap; /* ready nodes, min-heap on post */
    uint32_t heap_n;
    uint32_t remaining, done;
    bool failed;
    ms_error err;
    ms_nsp_encode_stats stats;
    ms_bake_apo_budget_entry *chunks; /* every stored APO chunk, for the budget */
    size_t chunk_n;                   /* at most the internal cells (or all, every_cell) */
    pthread_mutex_t lock;
    pthread_cond_t wake;
} pool;

/* ---- ready heap ---------------------------------------------------------- */

static void heap_push(pool *p, uint32_t node)
{
    uint32_t i = p->heap_n++;
    p->heap[i] = node;
    while (i > 0) {
        uint32_t up = (i - 1) / 2;
        if (p->tasks[p->heap[up]].post <= p->tasks[p->heap[i]].post)
            break;
        uint32_t t = p->heap[up];
        p->heap[up] = p->heap[i];
        p->heap[i] = t;
        i = up;
    }
}

static uint32_t heap_pop(pool *p)
{
    uint32_t top = p->heap[0];
    p->heap[0] = p->heap[--p->heap_n];
    uint32_t i = 0;
    for (;;) {
        uint32_t l = 2 * i + 1, r = l + 1, m = i;
        if (l < p->heap_n && p->tasks[p->heap[l]].post < p->tasks[p->heap[m]].post)
            m = l;
        if (r < p->heap_n && p->tasks[p->heap[r]].post < p->tasks[p->heap[m]].post)
            m = r;
        if (m == i)
            break;
        uint32_t t = p->heap[m];
        p->heap[m] = p->heap[i];
        p->heap[i] = t;
        i = m;
    }
    return top;
}

/* ---- building a cell's complex ------------------------------------------- */

/* The levels a leaf's vertices freeze at (lone[v]: MS_CODEC_NO_FREEZE for its
 * own, the lone level, looked up in the owning leaf's segment, for a foreign
 * one); inside[v] says which are its own. *read grows by the segment bytes. */
static ms_status leaf_lone_levels(const ms_nsp_build *b, const ms_nsp_node *nd,
                                  const ms_codec_state *st, uint8_t *inside, uint8_t *lone,
                                  uint64_t *read, ms_error *err)
{
    size_t nk = st->vertex_count, foreign = 0;
    uint64_t *keys = malloc((nk ? nk : 1) * sizeof *keys);
    uint8_t *levels = malloc(nk ? nk : 1);
    if (!keys || !levels) {
        free(keys);
        free(levels);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory loading a leaf");
    }
    for (size_t v = 0; v < nk; ++v) {
        inside[v] = ms_nsp_prefix_inside(&b->params.shape, st->cells[v], st->level, nd->depth,
                                         nd->position);
        if (inside[v])
            lone[v] = MS_CODEC_NO_FREEZE;
        else
            keys[foreign++] = st->cells[v]; /* in key order */
    }
    ms_status s = ms_nsp_lone_lookup(b, keys, foreign, levels, read, err);
    for (size_t v = 0, f = 0; s == MS_OK && v < nk; ++v)
        if (!inside[v])
            lone[v] = levels[f++];
    free(keys);
    free(levels);
    return s;
}

/* Leaf: records at full precision -> complex; *lone_out (malloc'd, one per
 * vertex of st) receives each foreign vertex's lone level, MS_CODEC_NO_FREEZE for
 * the leaf's own vertices. */
static ms_status leaf_state(pool *p, uint32_t node, ms_codec_state *st, uint8_t **lone_out,
                            ms_error *err)
{
    *lone_out = NULL;
    const ms_nsp_build *b = p->b;
    const ms_nsp_node *nd = &b->nodes[node];
    uint64_t *rec;
    size_t n, removed = 0;
    uint64_t read = 0;
    ms_status s = ms_nsp_build_read_leaf(b, node, &rec, &n, &read, err);
    if (s != MS_OK)
        return s;
    s = ms_nsp_leaf_complex(rec, n, b->params.shape.bits, st, &removed, err);
    free(rec);
    if (s != MS_OK)
        return s;
    size_t nk = st->vertex_count, nt = st->tri_count;
    uint8_t *lone = malloc(nk ? nk : 1), *inside = malloc(nk ? nk : 1);
    if (!lone || !inside)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory loading a leaf");
    if (s == MS_OK)
        s = leaf_lone_levels(b, nd, st, inside, lone, &read, err);
    if (s != MS_OK) {
        free(lone);
        free(inside);
        ms_codec_state_free(st);
        return s;
    }
    /* Model-wide counts: each vertex counted in its own leaf, each triangle in the
     * leaf of its smallest key. */
    uint64_t own_v = 0, own_t = 0, iso = 0;
    for (size_t v = 0; v < nk; ++v)
        own_v += inside[v];
    uint8_t *has = calloc(nk ? nk : 1, 1);
    for (size_t t = 0; t < nt; ++t) {
        uint32_t s3[3];
        ms_tri_sort3(&st->tris[3 * t], s3);
        own_t += inside[s3[0]];
        if (has)
            has[s3[0]] = has[s3[1]] = has[s3[2]] = 1;
    }
    if (has)
        for (size_t v = 0; v < nk; ++v)
            iso += !has[v];
    free(has);
    free(inside);
    *lone_out = lone;
    pthread_mutex_lock(&p->lock);
    p->stats.welded_vertices += own_v;
    p->stats.welded_triangles += own_t;
    p->stats.leaf_triangles += nt;
    p->stats.leaf_duplicates += removed;
    p->stats.isolated_vertices += iso;
    p->stats.io.read_back += read;
    p->stats.depth_leaves[nd->depth]++;
    p->stats.depth_triangles[nd->depth] += nt;
    p->stats.depth_owned[nd->depth] += own_t;
    pthread_mutex_unlock(&p->lock);
    return MS_OK;
}

/* The client's split of st must give back every child's start state. */
static ms_status check_partition(pool *p, uint32_t node, const ms_codec_state *st, ms_error *err)
{
    const ms_nsp_build *b = p->b;
    const unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
    const ms_nsp_node *nd = &b->nodes[node];
    ms_codec_state *parts = calloc(nc, sizeof *parts);
    if (!parts)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory checking a split");
    const ms_codec_state *ch = p->tasks[node].starts;
    ms_status s = ms_nsp_partition_state(&b->params.shape, st, nd->depth, nd->position,
                                         st->bits, parts, err);
    for (unsigned k = 0; k < nc && s == MS_OK; ++k) {
        /* compared whole (both canonical), not by checksum: no hashing */
        bool same = parts[k].vertex_count == ch[k].vertex_count &&
                    (ch[k].vertex_count == 0 || ms_codec_state_equal(&parts[k], &ch[k], true));
        if (!same)
            s = ms_error_set(err, MS_ERR_CORRUPT, "cell %u: the start state derived from its "
                             "parent (%zu vertices, %zu triangles, %zu edges) differs from the "
                             "one it was encoded from (%zu, %zu, %zu)",
                             p->cell_of_node[nd->first_child + k], parts[k].vertex_count,
                             parts[k].tri_count, parts[k].edge_count, ch[k].vertex_count,
                             ch[k].tri_count, ch[k].edge_count);
    }
    for (unsigned k = 0; k < nc; ++k)
        ms_codec_state_free(&parts[k]);
    free(parts);
    return s;
}

/* ---- one cell ------------------------------------------------------------ */

typedef struct cell_out {
    uint8_t *stream;
    size_t size;
    ms_codec_state start;
    uint32_t table[MS_CODEC_MAX_BITS + 1];
    uint32_t vertices, triangles;
    ms_bake_apo_result apo;
    double apo_seconds;
    ms_bake_apo_part part;    /* the APO m, averaged, kept for the parent's M */
    size_t sample_triangles;  /* M's triangles */
    uint8_t *colour;          /* the colour stream (ms_bake_colour.h), or NULL */
    size_t colour_size;
    uint32_t colour_table[MS_CODEC_MAX_BITS + 1];
    uint8_t error_table[MS_CODEC_MAX_BITS + 1]; /* ms_archive_writer_put_error */
    ms_codec_truth summary;   /* for the parent's surface error, model grid steps */
} cell_out;

/* ---- APO inputs ---------------------------------------------------------- */

/* Appends the triangle records of every leaf below (or at) node to *tri (keys,
 * 3 per triangle), leaves in node order. */
static ms_status gather_records(const ms_nsp_build *b, uint32_t node, uint64_t **tri, size_t *count,
                                size_t *cap, ms_error *err)
{
    const ms_nsp_node *nd = &b->nodes[node];
    if (nd->first_child != MS_NSP_NONE) {
        unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
        for (unsigned k = 0; k < nc; ++k) {
            ms_status s = gather_records(b, nd->first_child + k, tri, count, cap, err);
            if (s != MS_OK)
                return s;
        }
        return MS_OK;
    }
    uint64_t *rec;
    size_t n;
    ms_status s = ms_nsp_build_read_leaf(b, node, &rec, &n, NULL, err);
    if (s != MS_OK)
        return s;
    if (*count + n > *cap) {
        size_t want = (*count + n) * 2;
        uint64_t *grown = realloc(*tri, want * 3 * sizeof *grown);
        if (!grown) {
            free(rec);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory gathering a cell's triangles");
        }
        *tri = grown, *cap = want;
    }
    for (size_t i = 0; i < n; ++i)
        if (rec[3 * i] != rec[3 * i + 1])
            memcpy(*tri + 3 * (*count)++, rec + 3 * i, 3 * sizeof *rec);
    free(rec);
    return MS_OK;
}

/* M of a cell: its input triangles at full precision (see ms_nsp_encode.h). */
static ms_status full_precision_mesh(const ms_nsp_build *b, uint32_t node, ms_mesh *M, ms_error *err)
{
    memset(M, 0, sizeof *M);
    uint64_t *tri = NULL;
    size_t nt = 0, cap = 0;
    ms_status s = gather_records(b, node, &tri, &nt, &cap, err);
    uint64_t *ref = s == MS_OK ? malloc((3 * nt + 1) * sizeof *ref) : NULL;
    uint64_t *keys = s == MS_OK ? malloc((3 * nt + 1) * sizeof *keys) : NULL;
    uint32_t *rank = s == MS_OK ? malloc((3 * nt + 1) * sizeof *rank) : NULL;
    if (s == MS_OK && (!ref || !keys || !rank))
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory gathering a cell's triangles");
    const unsigned p = b->params.shape.bits;
    size_t nk = 0;
    if (s == MS_OK) {
        for (size_t i = 0; i < 3 * nt; ++i)
            ref[i] = tri[i];
        s = ms_nsp_index_keys(ref, 3 * nt, 3 * p, keys, &nk, rank, err);
    }
    /* keep the first of each group of equal vertex sets, in leaf order */
    if (s == MS_OK)
        s = ms_tri_unify(rank, &nt, NULL, NULL, err);
    if (s == MS_OK)
        s = ms_mesh_reserve(M, nk, nt, err);
    if (s == MS_OK) {
        if (nt) /* no triangle left: no array to copy into */
            memcpy(M->triangles, rank, 3 * nt * sizeof *rank);
        M->triangle_count = nt;
    }
    if (s == MS_OK) {
        for (size_t v = 0; v < nk; ++v) { /* grid cell centres */
            uint32_t q[3];
            ms_quant_unkey(keys[v], p, q);
            for (int a = 0; a < 3; ++a)
                M->positions[3 * v + (size_t)a] = ms_dequantise(&b->box, p, a, q[a]);
        }
        M->vertex_count = nk;
    }
    free(tri);
    free(ref);
    free(keys);
    free(rank);
    if (s != MS_OK)
        ms_mesh_free(M);
    return s;
}

/* Gives freed heap memory back to the kernel once more of it is resident than
 * the budget allows (resident_free_max): an internal cell's APO work frees
 * tens to hundreds of MB that glibc keeps. Below that it stays, and the next
 * build reuses its pages without faulting them in again. */
static void give_back_memory(const pool *p)
{
#ifdef __GLIBC__
    if (mallinfo2().fordblks > p->params->resident_free_max)
        malloc_trim(0);
#else
    (void)p;
#endif
}

/* Frees the children's parts of node (its M has been built from them). */
static void free_child_parts(pool *p, uint32_t node)
{
    const unsigned nc = p->b->params.shape.n * p->b->params.shape.n * p->b->params.shape.n;
    if (!p->tasks[node].parts)
        return;
    for (unsigned k = 0; k < nc; ++k)
        ms_bake_apo_part_free(&p->tasks[node].parts[k]);
    free(p->tasks[node].parts);
    p->tasks[node].parts = NULL;
}

/* What a cell hands up for its parent's M (ms_bake_apo_part): a leaf's m as it
 * is, each vertex standing for itself; an internal cell's m averaged over M. m is
 * taken. */
static ms_status hand_up(pool *p, uint32_t node, unsigned hi, ms_mesh *m, const ms_mesh *M, const uint32_t *owned,
                         ms_bake_apo_part *out, ms_error *err)
{
    const ms_nsp_build *b = p->b;
    const ms_nsp_node *nd = &b->nodes[node];
    double origin[3], size;
    ms_bake_apo_cube(&b->params.shape, &b->box, nd->depth, nd->position, origin, &size);
    if (nd->first_child != MS_NSP_NONE)
        return ms_bake_apo_smooth(m, hi, &b->box, origin, size, M, owned, out, err);
    memset(out, 0, sizeof *out);
    out->weight = malloc((m->vertex_count + 1) * sizeof *out->weight);
    if (!out->weight)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory keeping a cell's mesh");
    for (size_t v = 0; v < m->vertex_count; ++v)
        out->weight[v] = 1;
    out->mesh = *m;
    memset(m, 0, sizeof *m);
    out->bits = hi;
    memcpy(out->origin, origin, sizeof origin);
    out->size = size;
    return MS_OK;
}

/* The cell's chunk: m from its stream decoded to bits_max; M from its own records
 * (a leaf) or from its children's parts (an internal cell, see ms_nsp_encode.h).
 * The part for the parent goes to out->part when the parent will need it. */
static ms_status apo_cell(pool *p, uint32_t node, unsigned hi, ms_apo_builder *builder,
                          ms_mesh *given_m, cell_out *out, ms_error *err)
{
    const ms_nsp_build *b = p->b;
    const ms_nsp_node *nd = &b->nodes[node];
    const ms_bake_apo_params *ap = p->params->apo;
    const unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
    bool leaf = nd->first_child == MS_NSP_NONE;
    double t0 = ms_now_seconds();
    ms_codec_decoder *d = NULL;
    ms_mesh m, M, reference;
    uint32_t *owned = NULL;
    memset(&m, 0, sizeof m);
    memset(&M, 0, sizeof M);
    memset(&reference, 0, sizeof reference);
    ms_status s = MS_OK;
    if (given_m) {
        m = *given_m; /* taken */
        memset(given_m, 0, sizeof *given_m);
    } else {
        ms_codec_decoder_options o = {.box = &b->box};
        s = ms_codec_decoder_create(out->stream, out->size, &out->start, &o, &d, err);
        if (s == MS_OK)
            s = ms_codec_decoder_set_level(d, 3 * hi, err);
        if (s == MS_OK)
            s = ms_codec_decoder_mesh(d, &m, err);
        ms_codec_decoder_destroy(d);
    }
    /* A leaf's m is its full-precision complex (ms_nsp_leaf_mesh), which renders M
     * by construction: no chunk, and no need to gather M to find that out,
     * unless a chunk is wanted anyway or --apo-verify asks for the check. */
    bool leaf_renders = leaf && !ap->every_cell && !ap->sample_leaves && !ap->verify;
    if (s == MS_OK && (leaf || ap->sample_leaves)) {
        if (!leaf_renders)
            s = full_precision_mesh(b, node, &M, err);
    } else if (s == MS_OK && p->tasks[node].parts)
        s = ms_bake_apo_union(p->tasks[node].parts, nc, &b->box, &M, &owned, err);
    /* the children's parts are in M now: free them before the build's peak */
    free_child_parts(p, node);
    if (!leaf)
        give_back_memory(p);
    bool measured = ap->accuracy && !leaf;
    if (s == MS_OK && measured && !ap->sample_leaves)
        s = full_precision_mesh(b, node, &reference, err);
    /* Leaves run one per thread; internal cells, few, large and last in
     * post-order (the root ends the bake alone), use every thread. */
    unsigned threads = leaf ? 1 : p->params->threads;
    if (s == MS_OK && !leaf_renders)
        s = ms_bake_apo_cell(builder, ap, &b->params.shape, &b->box, nd->depth, nd->position, hi, &m, &M,
                             !measured ? NULL : ap->sample_leaves ? &M : &reference, threads, &out->apo,
                             err);
    ms_mesh_free(&reference);
    if (s == MS_OK && nd->parent != MS_NSP_NONE && !ap->sample_leaves)
        s = hand_up(p, node, hi, &m, &M, owned, &out->part, err);
    if (s != MS_OK) {
        char why[sizeof err->text];
        snprintf(why, sizeof why, "%s", err->text);
        s = ms_error_set(err, s, "cell %u: APO: %s", p->cell_of_node[node], why);
    }
    out->sample_triangles = M.triangle_count;
    ms_mesh_free(&m);
    ms_mesh_free(&M);
    free(owned);
    out->apo_seconds = ms_now_seconds() - t0;
    return s;
}

static ms_status encode_cell(pool *p, uint32_t node, ms_apo_builder **builder, cell_out *out, ms_error *err)
{
    const ms_nsp_build *b = p->b;
    const ms_nsp_node *nd = &b->nodes[node];
    bool leaf = nd->first_child == MS_NSP_NONE;
    unsigned lo, hi;
    ms_nsp_window(&b->params.shape, nd->depth, leaf, &lo, &hi);
    memset(out, 0, sizeof *out);
    ms_codec_state st;
    uint8_t *freeze = NULL;
    ms_status s = leaf ? leaf_state(p, node, &st, &freeze, err)
                       : ms_nsp_merge_states(p->tasks[node].starts,
                                              b->params.shape.n * b->params.shape.n * b->params.shape.n,
                                              hi, p->cell_of_node[node], &st, err);
    if (s != MS_OK)
        return s;
    if (!leaf)
        s = check_partition(p, node, &st, err);
    ms_codec_region region;
    bool freezing = leaf && ms_nsp_leaf_freezing(&b->params.shape, p->max_depth, nd->depth, nd->position, lo,
                                                      freeze, st.vertex_count, &region);
    bool apo = p->params->apo && p->params->apo->enabled;
    ms_mesh m_leaf; /* the cell's APO m: a leaf's full-precision complex, an internal cell's decoded stream */
    memset(&m_leaf, 0, sizeof m_leaf);
    bool m_given = apo && (leaf || st.bits == hi);
    double leaf_mesh_seconds = ms_now_seconds(); /* a leaf's mesh for its parent's M: APO's work */
    if (s == MS_OK && apo && leaf && st.vertex_count > 0)
        s = ms_nsp_leaf_mesh(&st, &b->box, &m_leaf, err);
    leaf_mesh_seconds = ms_now_seconds() - leaf_mesh_seconds;
    if (s == MS_OK && st.vertex_count > 0) {
        ms_codec_encode_params ep = {
            .p_min = lo, .box = b->box, .compact_header = true, .ahead = p->params->ahead,
            .ahead_until = p->params->ahead_until,
            .smooth_rounds = p->params->smooth_rounds, .smooth_level = p->params->smooth_level};
        if (freezing) {
            ep.region = &region;
            ep.freeze_level = freeze;
        }
        /* An internal cell's APO m is its stream decoded to bits_max: the
         * encoder's forward pass ends in that state, no second decode. */
        if (m_given && !leaf)
            ep.mesh = &m_leaf;
        /* the surface error: a leaf against its own vertices, an internal
         * cell against its children's summaries (in its stream's steps) */
        double surface[MS_CODEC_MAX_BITS + 1];
        ms_codec_truth *given = leaf ? NULL : &p->tasks[node].truth;
        int to_stream = (int)st.bits - (int)b->params.shape.bits;
        if (given)
            ms_nsp_truth_scale(given, to_stream);
        ep.surface_error = surface;
        ep.truth = given;
        if (nd->parent != MS_NSP_NONE)
            ep.summary = &out->summary;
        s = ms_codec_encode(&st, &ep, &out->stream, &out->size, &out->start, err);
        if (given)
            ms_codec_truth_free(given);
        if (s == MS_OK) {
            ms_nsp_error_table(b->params.shape.bits, st.bits, lo, hi, surface, out->error_table);
            ms_nsp_truth_scale(&out->summary, -to_stream);
        }
        if (s == MS_OK && out->size > UINT32_MAX)
            s = ms_error_set(err, MS_ERR_RANGE, "cell %u: payload over 4 GiB",
                             p->cell_of_node[node]);
        ms_codec_header h;
        if (s == MS_OK)
            s = ms_codec_read_header(out->stream, out->size, &h, err);
        if (s == MS_OK) {
            out->table[0] = (uint32_t)h.header_size;
            for (unsigned k = 1; k <= hi - lo; ++k)
                out->table[k] = (uint32_t)(h.header_size + h.chunk_end[k - 1]);
        }
        out->vertices = (uint32_t)st.vertex_count;
        out->triangles = (uint32_t)st.tri_count;
    }
    if (s == MS_OK && p->params->colours) {
        ms_bake_colour_cube chain[MS_NSP_MAX_DEPTH + 1];
        size_t chain_n = 0;
        for (uint32_t x = node; x != MS_NSP_NONE; x = b->nodes[x].parent) {
            const ms_nsp_node *xn = &b->nodes[x];
            unsigned xlo, xhi;
            ms_nsp_window(&b->params.shape, xn->depth, xn->first_child == MS_NSP_NONE, &xlo, &xhi);
            chain[chain_n++] = (ms_bake_colour_cube){
                ms_quant_key(xn->position[0], xn->position[1], xn->position[2], 0),
                3u * b->params.shape.log2n * xn->depth, xlo};
        }
        s = ms_bake_colour_cell(p->params->colours, &st, freezing ? freeze : NULL, chain, chain_n,
                                p->params->colour_bits, &out->colour, &out->colour_size,
                                out->colour_table, err);
    }
    ms_codec_state_free(&st);
    free(freeze);
    if (s == MS_OK && apo && out->size > 0 && !*builder)
        s = ms_apo_builder_create(builder, err);
    if (s == MS_OK && apo && out->size > 0)
        s = apo_cell(p, node, hi, *builder, m_given ? &m_leaf : NULL, out, err);
    out->apo_seconds += apo ? leaf_mesh_seconds : 0.0;
    ms_mesh_free(&m_leaf);
    if (s != MS_OK) {
        free(out->stream);
        free(out->colour);
        ms_codec_state_free(&out->start);
        ms_bake_apo_result_free(&out->apo);
        ms_bake_apo_part_free(&out->part);
        ms_codec_truth_free(&out->summary);
        memset(out, 0, sizeof *out);
    }
    return s;
}

/* Under the lock: hands the result to the writer and to the parent. */
static ms_status finish_cell(pool *p, uint32_t node, cell_out *out, ms_error *err)
{
    const ms_nsp_build *b = p->b;
    const ms_nsp_node *nd = &b->nodes[node];
    ms_status s = ms_archive_writer_put_geometry(p->writer, p->cell_of_node[node], out->stream,
                                                 (uint32_t)out->size, out->table, out->vertices,
                                                 out->triangles, err);
    if (s == MS_OK) /* an empty cell draws nothing: no error */
        s = ms_archive_writer_put_error(p->writer, p->cell_of_node[node], out->error_table, err);
    p->stats.geometry_bytes += out->size;
    p->stats.empty_cells += out->size == 0;
    free(out->stream);
    out->stream = NULL;
    if (s == MS_OK && out->colour_size > 0)
        s = ms_archive_writer_put_colour(p->writer, p->cell_of_node[node], out->colour,
                                         (uint32_t)out->colour_size, out->colour_table, err);
    p->stats.colour_bytes += out->colour_size;
    free(out->colour);
    out->colour = NULL;
    const ms_bake_apo_result *a = &out->apo;
    if (s == MS_OK) { /* the sampling work, also of a chunk left without texels */
        p->stats.apo_rays += a->rays;
        p->stats.apo_point_queries += a->point_queries;
        p->stats.apo_triangle_visits += a->triangle_visits;
        p->stats.apo_smooth_leaves += a->smooth_leaves;
        p->stats.apo_samples += a->samples;
        p->stats.apo_sampled_leaves += a->sampled_leaves;
        p->stats.apo_agreed_leaves += a->agreed_leaves;
    }
    if (s == MS_OK && a->levels > 0) {
        s = ms_archive_writer_put_apo(p->writer, p->cell_of_node[node], a->data, (uint32_t)a->size,
                                      (uint32_t)(4 * a->texels), a->level_table, (uint8_t)a->levels, err);
        ms_bake_apo_budget_entry *e = &p->chunks[p->chunk_n++];
        *e = (ms_bake_apo_budget_entry){.chunk = {.cell = p->cell_of_node[node], .levels = a->levels,
                                                  .scale = b->params.shape.log2n * nd->depth},
                                        .bytes = a->size, .internal_nodes = a->internal_nodes, .leaves = a->leaves};
        p->stats.apo_bytes += a->size;
        p->stats.apo_raw_bytes += 4 * a->texels;
        p->stats.apo_chunks++;
        p->stats.apo_internal_nodes += a->internal_nodes;
        p->stats.apo_leaves += a->leaves;
        for (uint32_t d = 0; d < a->levels; ++d)
            p->stats.apo_level_texels[d] += a->level_texels[d];
        if (a->levels > p->stats.apo_levels)
            p->stats.apo_levels = a->levels;
        ms_bake_apo_accuracy_add(&p->stats.apo_accuracy, &a->accuracy);
    }
    if (nd->first_child != MS_NSP_NONE) {
        p->stats.apo_sample_triangles += out->sample_triangles;
        if (out->sample_triangles > p->stats.apo_sample_triangles_max)
            p->stats.apo_sample_triangles_max = out->sample_triangles;
    }
    p->stats.apo_thread_seconds += out->apo_seconds;
    ms_bake_apo_result_free(&out->apo);
    if (s != MS_OK || nd->parent == MS_NSP_NONE) {
        ms_codec_state_free(&out->start);
        ms_bake_apo_part_free(&out->part);
        ms_codec_truth_free(&out->summary);
        return s;
    }
    task *parent = &p->tasks[nd->parent];
    unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
    if (!parent->starts)
        parent->starts = calloc(nc, sizeof *parent->starts);
    if (!parent->parts)
        parent->parts = calloc(nc, sizeof *parent->parts);
    if (!parent->starts || !parent->parts) {
        ms_codec_state_free(&out->start);
        ms_bake_apo_part_free(&out->part);
        ms_codec_truth_free(&out->summary);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    }
    unsigned k = node - b->nodes[nd->parent].first_child;
    bool appended = ms_nsp_truth_append(&parent->truth, &parent->truth_cap, &out->summary);
    ms_codec_truth_free(&out->summary);
    if (!appended) {
        ms_codec_state_free(&out->start);
        ms_bake_apo_part_free(&out->part);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    }
    parent->starts[k] = out->start;
    parent->parts[k] = out->part;
    memset(&out->start, 0, sizeof out->start);
    memset(&out->part, 0, sizeof out->part);
    if (--parent->pending == 0)
        heap_push(p, nd->parent);
    return MS_OK;
}

/* One encoding thread: takes ready cells until every cell is done (or one
 * failed). Run as one block per thread of ms_parallel_for. */
static void worker(void *arg, size_t block)
{
    (void)block;
    pool *p = arg;
    const ms_nsp_build *b = p->b;
    ms_apo_builder *builder = NULL; /* created on this thread's first APO chunk */
    pthread_mutex_lock(&p->lock);
    for (;;) {
        while (!p->failed && p->remaining > 0 && p->heap_n == 0)
            pthread_cond_wait(&p->wake, &p->lock);
        if (p->failed || p->remaining == 0)
            break;
        uint32_t node = heap_pop(p);
        pthread_mutex_unlock(&p->lock);
        cell_out out;
        ms_error err;
        ms_error_clear(&err);
        ms_status s = encode_cell(p, node, &builder, &out, &err);
        /* the children's states are no longer needed */
        if (p->tasks[node].starts) {
            unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
            for (unsigned k = 0; k < nc; ++k)
                ms_codec_state_free(&p->tasks[node].starts[k]);
            free(p->tasks[node].starts);
            p->tasks[node].starts = NULL;
        }
        free_child_parts(p, node);
        if (b->nodes[node].first_child != MS_NSP_NONE && p->params->apo && p->params->apo->enabled)
            give_back_memory(p);
        pthread_mutex_lock(&p->lock);
        if (s == MS_OK)
            s = finish_cell(p, node, &out, &err);
        else
            ms_bake_apo_result_free(&out.apo);
        if (s != MS_OK) {
            if (!p->failed)
                p->err = err;
            p->failed = true;
        } else {
            p->remaining--;
            p->done++;
            if (p->params->progress)
                p->params->progress(p->params->progress_context, "encoding",
                                    (double)p->done / (double)b->node_count);
        }
        pthread_cond_broadcast(&p->wake);
    }
    pthread_mutex_unlock(&p->lock);
    ms_apo_builder_destroy(builder);
}

ms_status ms_nsp_encode_all(ms_nsp_build *build, const uint32_t *cell_of_node,
                            ms_archive_writer *writer, const ms_nsp_encode_params *params,
                            ms_nsp_encode_stats *stats, ms_error *err)
{
    double t0 = ms_now_seconds();
    memset(stats, 0, sizeof *stats);
    const ms_nsp_build *b = build;
    pool p;
    memset(&p, 0, sizeof p);
    p.b = b;
    p.cell_of_node = cell_of_node;
    p.writer = writer;
    p.params = params;
    uint32_t n = b->node_count;
    const unsigned nc = b->params.shape.n * b->params.shape.n * b->params.shape.n;
    for (uint32_t v = 0; v < n; ++v)
        if (b->nodes[v].depth > p.max_depth)
            p.max_depth = b->nodes[v].depth;
    const ms_bake_apo_params *ap = params->apo && params->apo->enabled ? params->apo : NULL;
    size_t may_chunk = 1; /* cells that may get a chunk */
    for (uint32_t v = 0; ap && v < n; ++v)
        may_chunk += ap->every_cell || b->nodes[v].first_child != MS_NSP_NONE;
    p.tasks = calloc(n, sizeof *p.tasks);
    p.heap = malloc(n * sizeof *p.heap);
    p.chunks = ap ? malloc(may_chunk * sizeof *p.chunks) : NULL;
    uint32_t *stack = malloc(n * sizeof *stack);
    uint8_t *visited = calloc(n, 1);
    if (!p.tasks || !p.heap || !stack || !visited || (ap && !p.chunks)) {
        free(p.chunks);
        free(p.tasks);
        free(p.heap);
        free(stack);
        free(visited);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory scheduling cells");
    }
    /* Post-order numbers (children in offset order), iteratively. */
    uint32_t sp = 0, post = 0;
    stack[sp++] = 0;
    while (sp > 0) {
        uint32_t v = stack[sp - 1];
        const ms_nsp_node *nd = &b->nodes[v];
        if (nd->first_child != MS_NSP_NONE && !visited[v]) {
            visited[v] = 1;
            for (unsigned k = nc; k-- > 0;)
                stack[sp++] = nd->first_child + k;
            continue;
        }
        sp--;
        p.tasks[v].post = post++;
        p.tasks[v].pending = nd->first_child != MS_NSP_NONE ? nc : 0;
    }
    free(stack);
    free(visited);
    for (uint32_t v = 0; v < n; ++v)
        if (p.tasks[v].pending == 0)
            heap_push(&p, v);
    p.remaining = n;
    pthread_mutex_init(&p.lock, NULL);
    pthread_cond_init(&p.wake, NULL);
    unsigned threads = params->threads ? params->threads : 1;
    /* the work completes even where no helper thread could start */
    ms_error no_threads;
    (void)ms_parallel_for(threads, threads, worker, &p, &no_threads);
    ms_status s = MS_OK;
    if (p.failed) {
        *err = p.err;
        s = err->code != MS_OK ? err->code : MS_ERR_IO;
    }
    for (uint32_t v = 0; v < n; ++v) {
        if (p.tasks[v].starts) {
            for (unsigned k = 0; k < nc; ++k)
                ms_codec_state_free(&p.tasks[v].starts[k]);
            free(p.tasks[v].starts);
        }
        ms_codec_truth_free(&p.tasks[v].truth);
        free_child_parts(&p, v);
    }
    if (s == MS_OK && ap) { /* the byte budget, on the whole archive's chunks */
        double t1 = ms_now_seconds();
        s = ms_bake_apo_budget_apply(writer, ap, p.stats.geometry_bytes, p.chunks, p.chunk_n,
                                     &p.stats.apo_budget, err);
        p.stats.apo_thread_seconds += (ms_now_seconds() - t1) * threads; /* the others wait */
    }
    free(p.chunks);
    pthread_mutex_destroy(&p.lock);
    pthread_cond_destroy(&p.wake);
    free(p.tasks);
    free(p.heap);
    p.stats.seconds = ms_now_seconds() - t0;
    *stats = p.stats;
    return s;
}
