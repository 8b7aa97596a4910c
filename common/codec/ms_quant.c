#include "ms_quant.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

void ms_qmesh_free(ms_qmesh *q)
{
    if (!q)
        return;
    free(q->coords);
    free(q->tris);
    memset(q, 0, sizeof *q);
}

static uint32_t gather3(uint64_t x)
{
    x &= 0x1249249249249249ull;
    x = (x | (x >> 2)) & 0x10C30C30C30C30C3ull;
    x = (x | (x >> 4)) & 0x100F00F00F00F00Full;
    x = (x | (x >> 8)) & 0x001F0000FF0000FFull;
    x = (x | (x >> 16)) & 0x001F00000000FFFFull;
    x = (x | (x >> 32)) & 0x1FFFFFull;
    return (uint32_t)x;
}

void ms_quant_unkey(uint64_t key, unsigned bits, uint32_t xyz[3])
{
    (void)bits;
    xyz[0] = gather3(key >> 2);
    xyz[1] = gather3(key >> 1);
    xyz[2] = gather3(key);
}

ms_status ms_quant_fit_box(const ms_mesh *mesh, ms_quant_box *box, ms_error *err)
{
    if (!mesh || mesh->vertex_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "empty mesh: no vertex to quantise");
    double lo[3], hi[3];
    for (int a = 0; a < 3; ++a)
        lo[a] = hi[a] = mesh->positions[a];
    for (size_t i = 0; i < mesh->vertex_count; ++i) {
        for (int a = 0; a < 3; ++a) {
            double v = mesh->positions[3 * i + a];
            if (!isfinite(v))
                return ms_error_set(err, MS_ERR_RANGE,
                                    "vertex %zu has a non-finite coordinate", i);
            if (v < lo[a])
                lo[a] = v;
            if (v > hi[a])
                hi[a] = v;
        }
    }
    double size = 0;
    for (int a = 0; a < 3; ++a) {
        double ext = hi[a] - lo[a];
        if (!isfinite(ext))
            return ms_error_set(err, MS_ERR_RANGE, "bounding box extent overflows");
        if (ext > size)
            size = ext;
        box->origin[a] = lo[a];
    }
    if (!(size > 0))
        size = 1.0;
    box->size = size;
    return MS_OK;
}

double ms_dequantise(const ms_quant_box *box, unsigned bits, int axis, uint32_t q)
{
    return box->origin[axis] + ((double)q + 0.5) * (box->size / (double)(1u << bits));
}

uint32_t ms_quantise(const ms_quant_box *box, unsigned bits, int axis, double x)
{
    const double origin = box->origin[axis], size = box->size;
    double cells = (double)(1u << bits);
    double t = floor((x - origin) / size * cells);
    if (!(t >= 0))
        t = 0;
    if (t > cells - 1)
        t = cells - 1;
    return (uint32_t)t;
}

typedef struct key_index {
    uint64_t key;
    uint32_t index;
} key_index;

static int cmp_key_index(const void *a, const void *b)
{
    const key_index *x = a, *y = b;
    if (x->key != y->key)
        return x->key < y->key ? -1 : 1;
    return x->index < y->index ? -1 : (x->index > y->index);
}

typedef struct tri_sort {
    uint32_t s[3];  /* sorted vertex indices */
    uint32_t index; /* position in the input */
} tri_sort;

static int cmp_tri_sort(const void *a, const void *b)
{
    const tri_sort *x = a, *y = b;
    for (int i = 0; i < 3; ++i)
        if (x->s[i] != y->s[i])
            return x->s[i] < y->s[i] ? -1 : 1;
    return x->index < y->index ? -1 : (x->index > y->index);
}

ms_status ms_quantise_mesh(const ms_mesh *mesh, unsigned bits, ms_qmesh *out,
                           ms_weld_report *report, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (bits < MS_QUANT_MIN_BITS || bits > MS_QUANT_MAX_BITS)
        return ms_error_set(err, MS_ERR_ARG, "precision %u bits outside %d..%d", bits,
                            MS_QUANT_MIN_BITS, MS_QUANT_MAX_BITS);
    if (!mesh || mesh->vertex_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "empty mesh: no vertex to quantise");
    if (mesh->vertex_count > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "too many vertices (%zu)", mesh->vertex_count);
    ms_quant_box box;
    ms_status st = ms_quant_fit_box(mesh, &box, err);
    if (st != MS_OK)
        return st;
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    for (size_t t = 0; t < 3 * nt; ++t)
        if (mesh->triangles[t] >= nv)
            return ms_error_set(err, MS_ERR_RANGE, "triangle %zu uses vertex %u of %zu", t / 3,
                                mesh->triangles[t], nv);

    key_index *ki = malloc(nv * sizeof *ki);
    uint32_t *remap = malloc(nv * sizeof *remap);
    tri_sort *ts = malloc((nt ? nt : 1) * sizeof *ts);
    if (!ki || !remap || !ts) {
        free(ki), free(remap), free(ts);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory quantising %zu vertices", nv);
    }
    for (size_t i = 0; i < nv; ++i) {
        uint32_t q[3];
        for (int a = 0; a < 3; ++a)
            q[a] = ms_quantise(&box, bits, a, mesh->positions[3 * i + a]);
        ki[i].key = ms_quant_key(q[0], q[1], q[2], bits);
        ki[i].index = (uint32_t)i;
    }
    qsort(ki, nv, sizeof *ki, cmp_key_index);
    size_t unique = 0;
    for (size_t i = 0; i < nv; ++i) {
        if (i == 0 || ki[i].key != ki[i - 1].key)
            ki[unique++] = (key_index){ki[i].key, ki[i].index};
        remap[ki[i].index] = (uint32_t)(unique - 1);
    }
    out->coords = malloc(3 * unique * sizeof *out->coords);
    if (!out->coords)
        goto nomem;
    for (size_t i = 0; i < unique; ++i)
        ms_quant_unkey(ki[i].key, bits, &out->coords[3 * i]);

    size_t kept = 0, degenerate = 0;
    for (size_t t = 0; t < nt; ++t) {
        uint32_t a = remap[mesh->triangles[3 * t]], b = remap[mesh->triangles[3 * t + 1]],
                 c = remap[mesh->triangles[3 * t + 2]];
        if (a == b || b == c || a == c) {
            degenerate++;
            continue;
        }
        uint32_t s0 = a, s1 = b, s2 = c, tmp;
        if (s0 > s1) tmp = s0, s0 = s1, s1 = tmp;
        if (s1 > s2) tmp = s1, s1 = s2, s2 = tmp;
        if (s0 > s1) tmp = s0, s0 = s1, s1 = tmp;
        ts[kept].s[0] = s0, ts[kept].s[1] = s1, ts[kept].s[2] = s2;
        ts[kept].index = (uint32_t)t;
        kept++;
    }
    qsort(ts, kept, sizeof *ts, cmp_tri_sort);
    /* Mark the first occurrence of each vertex set, then keep input order. */
    uint8_t *keep = calloc(nt ? nt : 1, 1);
    if (!keep)
        goto nomem;
    size_t dup = 0, final = 0;
    for (size_t i = 0; i < kept; ++i) {
        if (i > 0 && memcmp(ts[i].s, ts[i - 1].s, sizeof ts[i].s) == 0) {
            dup++;
            continue;
        }
        keep[ts[i].index] = 1;
        final++;
    }
    out->tris = malloc((final ? final : 1) * 3 * sizeof *out->tris);
    uint8_t *used = calloc(unique, 1);
    if (!out->tris || !used) {
        free(keep), free(used);
        goto nomem;
    }
    size_t w = 0;
    for (size_t t = 0; t < nt; ++t) {
        if (!keep[t])
            continue;
        for (int k = 0; k < 3; ++k) {
            uint32_t v = remap[mesh->triangles[3 * t + k]];
            out->tris[3 * w + k] = v;
            used[v] = 1;
        }
        w++;
    }
    size_t isolated = 0;
    for (size_t i = 0; i < unique; ++i)
        isolated += !used[i];
    free(keep), free(used), free(ki), free(remap), free(ts);
    out->bits = bits;
    out->box = box;
    out->vertex_count = unique;
    out->tri_count = w;
    if (report) {
        report->input_vertices = nv;
        report->input_triangles = nt;
        report->welded_vertices = nv - unique;
        report->degenerate_triangles = degenerate;
        report->duplicate_triangles = dup;
        report->isolated_vertices = isolated;
    }
    return MS_OK;

nomem:
    free(ki), free(remap), free(ts);
    ms_qmesh_free(out);
    return ms_error_set(err, MS_ERR_NOMEM, "out of memory welding %zu vertices", nv);
}
