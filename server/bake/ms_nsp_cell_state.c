/* The complexes the baker encodes cells from (ms_nsp_cell_state.h). */
#include "ms_nsp_cell_state.h"

#include <stdlib.h>
#include <string.h>

#include "ms_radix_sort.h"
#include "ms_tri_unify.h"

/* The plain way: every reference sorted, equal neighbours merged. */
static ms_status index_by_sorting(uint64_t *ref, size_t n, unsigned key_bits, uint64_t *cells,
                                  size_t *ncells, uint32_t *rank, ms_error *err)
{
    uint32_t *pos = malloc((n ? n : 1) * sizeof *pos);
    if (!pos)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory indexing a cell");
    for (size_t i = 0; i < n; ++i)
        pos[i] = (uint32_t)i;
    ms_status s = ms_radix_sort_pairs(ref, pos, n, key_bits, err);
    size_t w = 0;
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        if (w == 0 || ref[i] != cells[w - 1])
            cells[w++] = ref[i];
        rank[pos[i]] = (uint32_t)(w - 1);
    }
    free(pos);
    *ncells = w;
    return s;
}

#define NO_SLOT UINT32_MAX

/* A leaf's references name each vertex about six times (once per triangle of
 * its star): the distinct keys are found by hashing and only they are sorted,
 * a sixth of the sorting, with the same result as sorting every reference. */
ms_status ms_nsp_index_keys(uint64_t *ref, size_t n, unsigned key_bits, uint64_t *cells,
                            size_t *ncells, uint32_t *rank, ms_error *err)
{
    uint64_t wide = 0;
    for (size_t i = 0; i < n; ++i)
        wide |= ref[i];
    /* keys with bits above key_bits sort by part of them only: keep that order */
    if (n < 2 || (key_bits < 64 && (wide >> key_bits) != 0))
        return index_by_sorting(ref, n, key_bits, cells, ncells, rank, err);
    unsigned log2_slots = 4;
    while (((size_t)1 << log2_slots) < 2 * n)
        ++log2_slots;
    size_t slots = (size_t)1 << log2_slots;
    uint32_t *slot = malloc(slots * sizeof *slot);
    uint32_t *id = malloc(n * sizeof *id);
    if (!slot || !id) {
        free(slot);
        free(id);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory indexing a cell");
    }
    memset(slot, 0xFF, slots * sizeof *slot); /* NO_SLOT everywhere */
    size_t distinct = 0;
    for (size_t i = 0; i < n; ++i) { /* rank[i]: first-seen number of ref[i]'s key */
        uint64_t k = ref[i];
        size_t h = (size_t)((k * 0x9E3779B97F4A7C15ull) >> (64 - log2_slots));
        while (slot[h] != NO_SLOT && cells[slot[h]] != k)
            h = (h + 1) & (slots - 1);
        if (slot[h] == NO_SLOT) {
            slot[h] = (uint32_t)distinct;
            cells[distinct++] = k;
        }
        rank[i] = slot[h];
    }
    for (size_t d = 0; d < distinct; ++d)
        id[d] = (uint32_t)d;
    ms_status s = ms_radix_sort_pairs(cells, id, distinct, key_bits, err);
    if (s == MS_OK) {
        uint32_t *order_of = slot; /* first-seen number -> rank in key order */
        for (size_t d = 0; d < distinct; ++d)
            order_of[id[d]] = (uint32_t)d;
        for (size_t i = 0; i < n; ++i)
            rank[i] = order_of[rank[i]];
    }
    *ncells = s == MS_OK ? distinct : 0;
    free(slot);
    free(id);
    return s;
}

ms_status ms_nsp_leaf_complex(const uint64_t *rec, size_t n, unsigned bits, ms_codec_state *st,
                              size_t *removed, ms_error *err)
{
    memset(st, 0, sizeof *st);
    st->bits = bits;
    st->level = 3 * bits;
    st->cells = malloc((3 * n + 1) * sizeof *st->cells);
    st->tris = malloc((3 * n + 1) * sizeof *st->tris);
    st->edges = malloc(sizeof *st->edges);
    /* Vertex references: three per triangle record, one per point record. */
    uint64_t *ref = malloc((3 * n + 1) * sizeof *ref);
    uint32_t *rank = malloc((3 * n + 1) * sizeof *rank);
    ms_status s = MS_OK;
    if (!st->cells || !st->tris || !st->edges || !ref || !rank)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory loading a leaf");
    size_t nr = 0;
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        const uint64_t *r = rec + 3 * i;
        int verts = r[0] == r[1] ? 1 : 3;
        for (int j = 0; j < verts; ++j)
            ref[nr++] = r[j];
    }
    size_t nk = 0;
    if (s == MS_OK)
        s = ms_nsp_index_keys(ref, nr, 3 * bits, st->cells, &nk, rank, err);
    st->vertex_count = nk;
    size_t nt = 0;
    nr = 0;
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        const uint64_t *r = rec + 3 * i;
        if (r[0] == r[1]) {
            nr++;
            continue;
        }
        for (int j = 0; j < 3; ++j)
            st->tris[3 * nt + (size_t)j] = rank[nr++];
        nt++;
    }
    free(ref);
    free(rank);
    *removed = 0;
    if (s == MS_OK)
        s = ms_tri_unify(st->tris, &nt, NULL, removed, err);
    st->tri_count = nt;
    if (s != MS_OK)
        ms_codec_state_free(st);
    return s;
}

static int cmp_edge(const void *x, const void *y)
{
    const uint32_t *a = x, *b = y;
    if (a[0] != b[0])
        return a[0] < b[0] ? -1 : 1;
    return a[1] < b[1] ? -1 : (a[1] > b[1]);
}

ms_status ms_nsp_merge_states(const ms_codec_state *ch, unsigned nc, unsigned bits_max,
                              uint32_t cell, ms_codec_state *st, ms_error *err)
{
    size_t nv = 0, nt = 0, ne = 0;
    for (unsigned k = 0; k < nc; ++k) {
        nv += ch[k].vertex_count;
        nt += ch[k].tri_count;
        ne += ch[k].edge_count;
    }
    memset(st, 0, sizeof *st);
    st->bits = bits_max;
    st->level = 3 * bits_max;
    st->cells = malloc((nv + 1) * sizeof *st->cells);
    st->tris = malloc((3 * nt + 1) * sizeof *st->tris);
    st->edges = malloc((2 * ne + 1) * sizeof *st->edges);
    if (!st->cells || !st->tris || !st->edges) {
        ms_codec_state_free(st);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory merging children");
    }
    uint64_t *ref = malloc((nv + 1) * sizeof *ref);
    uint32_t *rank = malloc((nv + 1) * sizeof *rank);
    if (!ref || !rank) {
        free(ref);
        free(rank);
        ms_codec_state_free(st);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory merging children");
    }
    size_t w = 0;
    for (unsigned k = 0; k < nc; ++k)
        for (size_t i = 0; i < ch[k].vertex_count; ++i)
            ref[w++] = ch[k].cells[i];
    ms_status s = ms_nsp_index_keys(ref, w, 3 * bits_max, st->cells, &nv, rank, err);
    st->vertex_count = nv;
    size_t wt = 0, we = 0, base = 0;
    for (unsigned k = 0; k < nc; ++k) {
        const ms_codec_state *c = &ch[k];
        for (size_t t = 0; t < 3 * c->tri_count; ++t)
            st->tris[wt++] = rank[base + c->tris[t]];
        for (size_t e = 0; e < c->edge_count; ++e) {
            uint32_t x = rank[base + c->edges[2 * e]], y = rank[base + c->edges[2 * e + 1]];
            st->edges[we++] = x < y ? x : y;
            st->edges[we++] = x < y ? y : x;
        }
        base += c->vertex_count;
    }
    free(ref);
    free(rank);
    nt = wt / 3;
    size_t removed = 0;
    bool conflict = false;
    if (s == MS_OK)
        s = ms_tri_unify(st->tris, &nt, &conflict, &removed, err);
    st->tri_count = nt;
    if (s == MS_OK && conflict)
        s = ms_error_set(err, MS_ERR_CORRUPT, "cell %u: children disagree on a triangle's "
                         "orientation", cell);
    ne = we / 2;
    qsort(st->edges, ne, 8, cmp_edge);
    size_t u = 0;
    for (size_t e = 0; e < ne; ++e)
        if (u == 0 || cmp_edge(&st->edges[2 * e], &st->edges[2 * (u - 1)]) != 0) {
            st->edges[2 * u] = st->edges[2 * e];
            st->edges[2 * u + 1] = st->edges[2 * e + 1];
            u++;
        }
    st->edge_count = u;
    /* vertices are already in key order; the codec canonicalises the rest */
    if (s != MS_OK)
        ms_codec_state_free(st);
    return s;
}

ms_status ms_nsp_leaf_mesh(const ms_codec_state *st, const ms_quant_box *box, ms_mesh *m, ms_error *err)
{
    ms_status s = ms_mesh_reserve(m, st->vertex_count, st->tri_count, err);
    if (s != MS_OK)
        return s;
    double scale = box->size / (double)(1u << st->bits);
    for (size_t i = 0; i < st->vertex_count; ++i) {
        uint32_t c[3];
        ms_quant_unkey(st->cells[i], st->bits, c);
        for (int a = 0; a < 3; ++a)
            m->positions[3 * i + (size_t)a] = box->origin[a] + 0.5 * (2.0 * c[a] + 1.0) * scale;
    }
    if (st->tri_count) /* an empty cell may have no triangle array at all */
        memcpy(m->triangles, st->tris, 3 * st->tri_count * sizeof *m->triangles);
    m->vertex_count = st->vertex_count;
    m->triangle_count = st->tri_count;
    return MS_OK;
}

bool ms_nsp_leaf_freezing(const ms_nsp_shape *sh, unsigned max_depth, unsigned depth, const uint32_t position[3],
                          unsigned lo, uint8_t *lone, size_t n, ms_codec_region *region)
{
    unsigned depth_bits = depth * sh->log2n;
    if (depth == 0 || depth_bits > lo)
        return false;
    region->log2_side = sh->bits - depth_bits;
    for (int a = 0; a < 3; ++a)
        region->min[a] = position[a] << region->log2_side;
    unsigned Lmin = 3 * lo, D = 3 * sh->bits;
    if (Lmin < 3 * sh->log2n * max_depth)
        Lmin = 3 * sh->log2n * max_depth;
    for (size_t v = 0; v < n; ++v) {
        if (lone[v] == MS_CODEC_NO_FREEZE)
            continue;
        unsigned f = lone[v] < Lmin ? Lmin : lone[v];
        lone[v] = f < D ? (uint8_t)f : MS_CODEC_NO_FREEZE;
    }
    return true;
}
