/* A frame's stitched mesh split by drawing cell (ms_render_internal.h).
 *
 * Triangles are grouped by triangle_cell with one stable radix sort per frame
 * (ms_radix_sort_pairs; arrays sized by the frame's triangles and drawing cells, never by the
 * model's cell count, which may be millions); each
 * cell's vertices are numbered in the order its triangles first use them, so the
 * same cell content always gives the same arrays and the same hash, and a cell
 * whose drawn triangles did not change is not uploaded again.
 *
 * Vertex normals are computed once per frame over the whole stitched mesh, so a
 * vertex on a cell border has the same normal in every cell that draws it; they
 * are part of a cell's hash, so a cell whose normals moved because a neighbour
 * refined (new triangles around a shared border vertex) is uploaded again. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_radix_sort.h"
#include "ms_render_internal.h"

void ms_render_split_init(ms_render_split *s, const ms_archive_header *header)
{
    memset(s, 0, sizeof *s);
    s->header = header;
    s->cell_count = header->cell_count;
}

void ms_render_split_free(ms_render_split *s)
{
    free(s->order);
    free(s->sort_keys);
    free(s->present);
    free(s->present_start);
    free(s->local);
    free(s->stamp);
    free(s->normal_sum);
    free(s->packed);
    free(s->vertices);
    free(s->normals);
    free(s->indices);
    memset(s, 0, sizeof *s);
}

/* Grows *array to hold at least need elements of size bytes (contents kept). */
static bool grow(void **array, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return true;
    size_t cap2 = *cap ? *cap : 64;
    while (cap2 < need)
        cap2 *= 2;
    void *p = realloc(*array, cap2 * size);
    if (!p)
        return false;
    *array = p;
    *cap = cap2;
    return true;
}

uint32_t ms_render_pack_normal(const double n[3])
{
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !isfinite(len))
        return 0;
    uint32_t word = 0;
    for (int a = 0; a < 3; ++a) {
        long q = lround(n[a] / len * 511.0);
        q = q < -511 ? -511 : (q > 511 ? 511 : q);
        word |= ((uint32_t)q & 0x3FFu) << (10 * a);
    }
    return word;
}

/* Area-weighted vertex normals of the whole mesh into s->packed. */
static ms_status vertex_normals(ms_render_split *s, const ms_view_mesh *mesh, ms_error *err)
{
    size_t nv = mesh->vertex_count;
    if (nv > s->normal_cap) {
        double *sum = realloc(s->normal_sum, 3 * nv * sizeof *sum);
        if (sum)
            s->normal_sum = sum;
        uint32_t *packed = sum ? realloc(s->packed, nv * sizeof *packed) : NULL;
        if (!packed)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu vertex normals", nv);
        s->packed = packed;
        s->normal_cap = nv;
    }
    if (nv == 0)
        return MS_OK;
    memset(s->normal_sum, 0, 3 * nv * sizeof *s->normal_sum);
    const double *p = mesh->positions;
    for (size_t t = 0; t < mesh->triangle_count; ++t) {
        const uint32_t *tri = &mesh->triangles[3 * t];
        const double *a = &p[3 * (size_t)tri[0]], *b = &p[3 * (size_t)tri[1]], *c = &p[3 * (size_t)tri[2]];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
        double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        /* twice the area times the unit normal: the weighting by area */
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        for (int k = 0; k < 3; ++k)
            for (int ax = 0; ax < 3; ++ax)
                s->normal_sum[3 * (size_t)tri[k] + (size_t)ax] += n[ax];
    }
    for (size_t v = 0; v < nv; ++v)
        s->packed[v] = ms_render_pack_normal(&s->normal_sum[3 * v]);
    return MS_OK;
}

ms_status ms_render_split_frame(ms_render_split *s, const ms_view_mesh *mesh, ms_error *err)
{
    s->mesh = NULL;
    s->present_count = 0;
    if (!mesh)
        return ms_error_set(err, MS_ERR_ARG, "render: no mesh");
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    if (nv >= UINT32_MAX || nt >= UINT32_MAX / 3)
        return ms_error_set(err, MS_ERR_ARG, "render: mesh of %zu vertices, %zu triangles too large", nv, nt);
    if ((nv && !mesh->positions) || (nt && (!mesh->triangles || !mesh->triangle_cell)))
        return ms_error_set(err, MS_ERR_ARG, "render: mesh arrays missing");
    for (size_t i = 0; i < 3 * nv; ++i)
        if (!isfinite(mesh->positions[i]))
            return ms_error_set(err, MS_ERR_ARG, "render: vertex %zu is not finite", i / 3);
    for (size_t t = 0; t < nt; ++t) {
        if (mesh->triangle_cell[t] >= s->cell_count)
            return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu drawn by cell %u of %u", t,
                                mesh->triangle_cell[t], s->cell_count);
        for (int k = 0; k < 3; ++k)
            if (mesh->triangles[3 * t + (size_t)k] >= nv)
                return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu uses vertex %u of %zu", t,
                                    mesh->triangles[3 * t + (size_t)k], nv);
    }
    size_t local_cap = s->vertex_cap, order_cap = s->order_cap;
    if (!grow((void **)&s->order, &order_cap, nt ? nt : 1, sizeof *s->order) ||
        (order_cap != s->order_cap &&
         !grow((void **)&s->sort_keys, &s->order_cap, order_cap, sizeof *s->sort_keys)) ||
        !grow((void **)&s->local, &local_cap, nv ? nv : 1, sizeof *s->local))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu triangles", nt);
    if (local_cap != s->vertex_cap) {
        uint32_t *stamp = realloc(s->stamp, local_cap * sizeof *stamp);
        if (!stamp)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu vertices", nv);
        memset(stamp + s->vertex_cap, 0, (local_cap - s->vertex_cap) * sizeof *stamp);
        s->stamp = stamp;
        s->vertex_cap = local_cap;
    }
    /* the triangles by cell, in their order within a cell (a stable radix sort on
     * as many bits as the model's largest cell id needs) */
    uint32_t *order = s->order;
    for (size_t t = 0; t < nt; ++t) {
        order[t] = (uint32_t)t;
        s->sort_keys[t] = mesh->triangle_cell[t];
    }
    unsigned key_bits = 1;
    while (key_bits < 32 && (s->cell_count - 1) >> key_bits)
        key_bits++;
    ms_status sorted = ms_radix_sort_pairs(s->sort_keys, order, nt, key_bits, err);
    if (sorted != MS_OK)
        return sorted;
    /* the runs of equal cells */
    for (size_t i = 0; i < nt; ++i) {
        uint32_t cell = mesh->triangle_cell[order[i]];
        if (i > 0 && cell == s->present[s->present_count - 1])
            continue;
        size_t cap = s->present_cap;
        if (!grow((void **)&s->present, &cap, (size_t)s->present_count + 2, sizeof *s->present) ||
            (cap != s->present_cap &&
             !grow((void **)&s->present_start, &s->present_cap, cap, sizeof *s->present_start)))
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the frame's cells");
        s->present_start[s->present_count] = (uint32_t)i;
        s->present[s->present_count++] = cell;
    }
    if (s->present_count)
        s->present_start[s->present_count] = (uint32_t)nt;
    ms_status st = vertex_normals(s, mesh, err);
    if (st != MS_OK)
        return st;
    s->mesh = mesh;
    return MS_OK;
}

/* 64-bit hash of a byte array whose size is a multiple of 4: two independent
 * multiply-xorshift lanes over 8-byte words (fast, well mixed; not
 * cryptographic: a collision only keeps a cell's previous mesh). */
#define HASH_MULTIPLIER 0x9E3779B97F4A7C15ull

static uint64_t hash_bytes(uint64_t h, const void *data, size_t size)
{
    const unsigned char *p = data;
    uint64_t a = h, b = h ^ 0x6A09E667F3BCC909ull;
    size_t i = 0;
    for (; i + 16 <= size; i += 16) {
        uint64_t x, y;
        memcpy(&x, p + i, 8);
        memcpy(&y, p + i + 8, 8);
        a = (a ^ x) * HASH_MULTIPLIER;
        a ^= a >> 29;
        b = (b ^ y) * HASH_MULTIPLIER;
        b ^= b >> 29;
    }
    for (; i + 4 <= size; i += 4) {
        uint32_t w;
        memcpy(&w, p + i, 4);
        a = (a ^ w) * HASH_MULTIPLIER;
        a ^= a >> 29;
    }
    a ^= (b << 31 | b >> 33) * HASH_MULTIPLIER;
    return a ^ a >> 32;
}

ms_status ms_render_split_cell(ms_render_split *s, uint32_t k, const ms_archive_cell *record,
                               ms_render_cell_mesh *out, ms_error *err)
{
    const ms_view_mesh *m = s->mesh;
    uint32_t cell = s->present[k];
    uint32_t first = s->present_start[k], end = s->present_start[k + 1];
    uint32_t tris = end - first;
    if (!grow((void **)&s->indices, &s->cell_triangle_cap, 3 * (size_t)tris, sizeof *s->indices))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
    if (++s->pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->stamp, 0, s->vertex_cap * sizeof *s->stamp);
        s->pass = 1;
    }
    double origin[3], side;
    ms_render_cell_cube(s->header, record, origin, &side);
    uint32_t verts = 0;
    for (uint32_t i = first; i < end; ++i) {
        const uint32_t *tri = &m->triangles[3 * (size_t)s->order[i]];
        for (int c = 0; c < 3; ++c) {
            uint32_t v = tri[c];
            if (s->stamp[v] != s->pass) {
                if (!grow((void **)&s->vertices, &s->cell_vertex_cap, 3 * ((size_t)verts + 1),
                          sizeof *s->vertices) ||
                    !grow((void **)&s->normals, &s->cell_normal_cap, (size_t)verts + 1, sizeof *s->normals))
                    return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
                s->stamp[v] = s->pass;
                s->local[v] = verts;
                for (int a = 0; a < 3; ++a)
                    s->vertices[3 * (size_t)verts + (size_t)a] =
                        (float)((m->positions[3 * (size_t)v + (size_t)a] - origin[a]) / side);
                s->normals[verts] = s->packed[v];
                verts++;
            }
            s->indices[3 * (size_t)(i - first) + (size_t)c] = s->local[v];
        }
    }
    uint32_t counts[2] = {verts, tris};
    uint64_t h = hash_bytes(0xCBF29CE484222325ull, counts, sizeof counts);
    h = hash_bytes(h, s->vertices, 3 * (size_t)verts * sizeof *s->vertices);
    h = hash_bytes(h, s->normals, (size_t)verts * sizeof *s->normals);
    h = hash_bytes(h, s->indices, 3 * (size_t)tris * sizeof *s->indices);
    out->cell = cell;
    out->vertex_count = verts;
    out->triangle_count = tris;
    out->vertices = s->vertices;
    out->normals = s->normals;
    out->indices = s->indices;
    out->hash = h;
    return MS_OK;
}
