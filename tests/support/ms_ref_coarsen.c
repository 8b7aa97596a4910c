/* Reference coarsener for the codec tests, written independently of the codec:
 * map each vertex to its kd-cell prefix, map simplices, dedupe, keep maximal. */
#include <stdlib.h>
#include <string.h>
#include "ms_ref_coarsen.h"

#include <stdio.h>

static void *xmalloc(size_t n)
{
    void *p = malloc(n);
    if (!p) {
        fprintf(stderr, "ms_ref_coarsen: out of memory\n");
        abort();
    }
    return p;
}
static int rc_cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y);
}
static int rc_cmp3(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int i = 0; i < 3; ++i)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}
static int rc_cmp2(const void *a, const void *b)
{
    const uint32_t *x = a, *y = b;
    for (int i = 0; i < 2; ++i)
        if (x[i] != y[i])
            return x[i] < y[i] ? -1 : 1;
    return 0;
}
static uint32_t rc_find(const uint64_t *cells, size_t n, uint64_t k)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t m = (lo + hi) / 2;
        if (cells[m] < k) lo = m + 1; else hi = m;
    }
    return (uint32_t)lo;
}
void ms_ref_coarsen(const ms_codec_state *full, unsigned L, ms_codec_state *out)
{
    unsigned shift = full->level - L;
    size_t n = full->vertex_count;
    uint64_t *cells = xmalloc((n + 1) * sizeof *cells);
    for (size_t i = 0; i < n; ++i)
        cells[i] = shift >= 64 ? 0 : full->cells[i] >> shift;
    qsort(cells, n, sizeof *cells, rc_cmp_u64);
    size_t u = 0;
    for (size_t i = 0; i < n; ++i)
        if (u == 0 || cells[i] != cells[u - 1]) cells[u++] = cells[i];
    uint32_t *map = xmalloc((n + 1) * sizeof *map);
    for (size_t i = 0; i < n; ++i)
        map[i] = rc_find(cells, u, shift >= 64 ? 0 : full->cells[i] >> shift);
    size_t nt = full->tri_count, ne = full->edge_count;
    uint32_t *tris = xmalloc((nt + 1) * 3 * sizeof *tris);
    uint32_t *edges = xmalloc((3 * nt + ne + 1) * 2 * sizeof *edges);
    size_t wt = 0, we = 0;
    for (size_t t = 0; t < nt; ++t) {
        uint32_t x[3] = {map[full->tris[3*t]], map[full->tris[3*t+1]], map[full->tris[3*t+2]]};
        uint32_t tmp;
        if (x[0] > x[1]) tmp = x[0], x[0] = x[1], x[1] = tmp;
        if (x[1] > x[2]) tmp = x[1], x[1] = x[2], x[2] = tmp;
        if (x[0] > x[1]) tmp = x[0], x[0] = x[1], x[1] = tmp;
        if (x[0] != x[1] && x[1] != x[2]) {
            memcpy(&tris[3 * wt++], x, sizeof x);
        } else if (x[0] != x[2]) {
            edges[2 * we] = x[0]; edges[2 * we + 1] = x[2]; we++;
        }
    }
    for (size_t e = 0; e < ne; ++e) {
        uint32_t a = map[full->edges[2*e]], b = map[full->edges[2*e+1]];
        if (a == b) continue;
        edges[2 * we] = a < b ? a : b; edges[2 * we + 1] = a < b ? b : a; we++;
    }
    qsort(tris, wt, 3 * sizeof *tris, rc_cmp3);
    size_t ut = 0;
    for (size_t t = 0; t < wt; ++t)
        if (ut == 0 || rc_cmp3(&tris[3 * t], &tris[3 * (ut - 1)]) != 0)
            memmove(&tris[3 * ut++], &tris[3 * t], 3 * sizeof *tris);
    /* faces of triangles */
    uint32_t *faces = xmalloc((3 * ut + 1) * 2 * sizeof *faces);
    for (size_t t = 0; t < ut; ++t) {
        uint32_t *x = &tris[3 * t];
        faces[6*t] = x[0]; faces[6*t+1] = x[1];
        faces[6*t+2] = x[1]; faces[6*t+3] = x[2];
        faces[6*t+4] = x[0]; faces[6*t+5] = x[2];
    }
    qsort(faces, 3 * ut, 2 * sizeof *faces, rc_cmp2);
    qsort(edges, we, 2 * sizeof *edges, rc_cmp2);
    size_t ue = 0;
    for (size_t e = 0; e < we; ++e) {
        if (ue > 0 && rc_cmp2(&edges[2 * e], &edges[2 * (ue - 1)]) == 0) continue;
        if (bsearch(&edges[2 * e], faces, 3 * ut, 2 * sizeof *faces, rc_cmp2)) continue;
        memmove(&edges[2 * ue++], &edges[2 * e], 2 * sizeof *edges);
    }
    free(faces);
    free(map);
    memset(out, 0, sizeof *out);
    out->bits = full->bits;
    out->level = L;
    out->vertex_count = u;
    out->tri_count = ut;
    out->edge_count = ue;
    out->cells = cells;
    out->tris = tris;
    out->edges = edges;
}
