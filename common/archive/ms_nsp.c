/* nSP-tree geometry: see ms_nsp.h. */
#include "ms_nsp.h"

#include <stdlib.h>
#include <string.h>

#include "ms_quant.h"

ms_status ms_nsp_shape_init(ms_nsp_shape *shape, unsigned bits, unsigned n, unsigned root_bits,
                            ms_error *err)
{
    memset(shape, 0, sizeof *shape);
    unsigned s = n == 2 ? 1 : n == 4 ? 2 : n == 8 ? 3 : 0;
    if (s == 0)
        return ms_error_set(err, MS_ERR_ARG, "n must be 2, 4 or 8 (got %u)", n);
    if (bits < MS_QUANT_MIN_BITS || bits > MS_CODEC_MAX_BITS)
        return ms_error_set(err, MS_ERR_ARG, "bits must be in %d..%d (got %u)", MS_QUANT_MIN_BITS,
                            MS_CODEC_MAX_BITS, bits);
    if (root_bits < s || root_bits > bits)
        return ms_error_set(err, MS_ERR_ARG, "root bits must be in %u..%u for n = %u (got %u)", s,
                            bits, n, root_bits);
    shape->bits = bits;
    shape->n = n;
    shape->log2n = s;
    shape->root_bits = root_bits;
    return MS_OK;
}

void ms_nsp_window(const ms_nsp_shape *shape, unsigned depth, bool leaf, unsigned *bits_min,
                   unsigned *bits_max)
{
    unsigned lo = depth == 0 ? 0 : shape->root_bits + (depth - 1) * shape->log2n;
    unsigned hi = depth == 0 ? shape->root_bits : lo + shape->log2n;
    if (lo > shape->bits)
        lo = shape->bits;
    if (hi > shape->bits || leaf)
        hi = shape->bits;
    *bits_min = lo;
    *bits_max = hi;
}

bool ms_nsp_can_split(const ms_nsp_shape *shape, unsigned depth)
{
    unsigned lo, hi;
    ms_nsp_window(shape, depth, false, &lo, &hi);
    return hi < shape->bits;
}

unsigned ms_nsp_child_offset(const ms_nsp_shape *shape, unsigned depth, const uint32_t xyz[3])
{
    unsigned shift = shape->bits - (depth + 1) * shape->log2n;
    unsigned mask = shape->n - 1;
    unsigned x = (xyz[0] >> shift) & mask, y = (xyz[1] >> shift) & mask,
             z = (xyz[2] >> shift) & mask;
    return x + shape->n * (y + shape->n * z);
}

void ms_nsp_prefix_corner(const ms_nsp_shape *shape, uint64_t prefix, unsigned level,
                          uint32_t xyz[3])
{
    unsigned shift = 3 * shape->bits - level;
    uint64_t aligned = shift >= 64 ? 0 : prefix << shift;
    ms_quant_unkey(aligned, shape->bits, xyz);
}

bool ms_nsp_prefix_inside(const ms_nsp_shape *shape, uint64_t prefix, unsigned level,
                          unsigned depth, const uint32_t position[3])
{
    if (level < 3 * depth * shape->log2n)
        return false;
    uint32_t xyz[3];
    ms_nsp_prefix_corner(shape, prefix, level, xyz);
    unsigned shift = shape->bits - depth * shape->log2n;
    for (int a = 0; a < 3; ++a)
        if ((shift >= 32 ? 0 : xyz[a] >> shift) != position[a])
            return false;
    return true;
}

#define FOREIGN 0xFFFFu /* owner of a vertex outside the parent (n^3 <= 512 children) */

/* Per-child lists in compressed rows: start[k]..start[k+1] in items. */
typedef struct rows {
    uint32_t *start; /* children + 1 */
    uint32_t *items;
} rows;

static void rows_free(rows *r)
{
    free(r->start);
    free(r->items);
}

/* Counts, then fills, each simplex into the rows of the distinct children of
 * its vertices (owner: child offset or FOREIGN); a vertex of no simplex goes
 * to its own child's isolated row. used marks the vertices of a simplex. */
static void bucket_simplices(const ms_codec_state *parent, const uint16_t *owner, uint8_t *used,
                             unsigned nc, rows *tr_io, rows *ed_io, rows *iso_io)
{
    const size_t nv = parent->vertex_count, nt = parent->tri_count, ne = parent->edge_count;
    rows tr = *tr_io, ed = *ed_io, iso = *iso_io;
    for (int pass = 0; pass < 2; ++pass) {
        if (pass == 1) {
            for (unsigned k = 0; k < nc; ++k) {
                tr.start[k + 1] += tr.start[k];
                ed.start[k + 1] += ed.start[k];
                iso.start[k + 1] += iso.start[k];
            }
            /* shift right by one so that start[k] is the fill cursor of child k */
            memmove(tr.start + 1, tr.start, nc * sizeof(uint32_t));
            memmove(ed.start + 1, ed.start, nc * sizeof(uint32_t));
            memmove(iso.start + 1, iso.start, nc * sizeof(uint32_t));
            tr.start[0] = ed.start[0] = iso.start[0] = 0;
        }
        for (size_t t = 0; t < nt; ++t) {
            const uint32_t *x = &parent->tris[3 * t];
            unsigned seen[3];
            unsigned ns = 0;
            for (int i = 0; i < 3; ++i) {
                used[x[i]] = 1;
                unsigned o = owner[x[i]];
                if (o == FOREIGN || (ns > 0 && seen[0] == o) || (ns > 1 && seen[1] == o))
                    continue;
                seen[ns++] = o;
            }
            for (unsigned i = 0; i < ns; ++i) {
                if (pass == 0)
                    tr.start[seen[i] + 1]++;
                else
                    tr.items[tr.start[seen[i] + 1]++] = (uint32_t)t;
            }
        }
        for (size_t e = 0; e < ne; ++e) {
            const uint32_t *x = &parent->edges[2 * e];
            used[x[0]] = used[x[1]] = 1;
            unsigned o0 = owner[x[0]], o1 = owner[x[1]];
            for (int i = 0; i < 2; ++i) {
                unsigned o = i == 0 ? o0 : o1;
                if (o == FOREIGN || (i == 1 && o == o0))
                    continue;
                if (pass == 0)
                    ed.start[o + 1]++;
                else
                    ed.items[ed.start[o + 1]++] = (uint32_t)e;
            }
        }
        for (size_t v = 0; v < nv; ++v) {
            if (used[v] || owner[v] == FOREIGN)
                continue;
            if (pass == 0)
                iso.start[owner[v] + 1]++;
            else
                iso.items[iso.start[owner[v] + 1]++] = (uint32_t)v;
        }
    }
}

ms_status ms_nsp_partition_state(const ms_nsp_shape *shape, const ms_codec_state *parent,
                                 unsigned depth, const uint32_t position[3], unsigned child_bits,
                                 ms_codec_state *children, ms_error *err)
{
    const unsigned nc = shape->n * shape->n * shape->n;
    for (unsigned k = 0; k < nc; ++k)
        memset(&children[k], 0, sizeof children[k]);
    const size_t nv = parent->vertex_count, nt = parent->tri_count, ne = parent->edge_count;
    uint16_t *owner = malloc((nv ? nv : 1) * sizeof *owner); /* child offset, or FOREIGN */
    uint8_t *used = calloc(nv ? nv : 1, 1);  /* vertex has a simplex */
    uint32_t *local = malloc((nv ? nv : 1) * sizeof *local);
    uint32_t *stamp = malloc((nv ? nv : 1) * sizeof *stamp);
    rows tr = {calloc(nc + 1, sizeof(uint32_t)), malloc((3 * nt + 1) * sizeof(uint32_t))};
    rows ed = {calloc(nc + 1, sizeof(uint32_t)), malloc((2 * ne + 1) * sizeof(uint32_t))};
    rows iso = {calloc(nc + 1, sizeof(uint32_t)), malloc((nv + 1) * sizeof(uint32_t))};
    ms_status s = MS_OK;
    if (!owner || !used || !local || !stamp || !tr.start || !tr.items || !ed.start || !ed.items ||
        !iso.start || !iso.items) {
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory splitting a cell's complex");
        goto done;
    }
    const unsigned child_depth = depth + 1;
    for (size_t v = 0; v < nv; ++v) {
        owner[v] = FOREIGN;
        stamp[v] = UINT32_MAX;
        if (ms_nsp_prefix_inside(shape, parent->cells[v], parent->level, depth, position)) {
            uint32_t xyz[3];
            ms_nsp_prefix_corner(shape, parent->cells[v], parent->level, xyz);
            if (parent->level >= 3 * child_depth * shape->log2n)
                owner[v] = (uint16_t)ms_nsp_child_offset(shape, depth, xyz);
        }
    }
    bucket_simplices(parent, owner, used, nc, &tr, &ed, &iso);
    for (unsigned k = 0; k < nc; ++k) {
        ms_codec_state *c = &children[k];
        c->bits = child_bits;
        c->level = parent->level;
        uint32_t t0 = tr.start[k], t1 = tr.start[k + 1];
        uint32_t e0 = ed.start[k], e1 = ed.start[k + 1];
        uint32_t i0 = iso.start[k], i1 = iso.start[k + 1];
        if (t0 == t1 && e0 == e1 && i0 == i1)
            continue;
        size_t cap_v = 3 * (size_t)(t1 - t0) + 2 * (size_t)(e1 - e0) + (i1 - i0);
        c->cells = malloc(cap_v * sizeof *c->cells);
        c->tris = malloc(((size_t)(t1 - t0) * 3 + 1) * sizeof *c->tris);
        c->edges = malloc(((size_t)(e1 - e0) * 2 + 1) * sizeof *c->edges);
        if (!c->cells || !c->tris || !c->edges) {
            s = ms_error_set(err, MS_ERR_NOMEM, "out of memory splitting a cell's complex");
            goto done;
        }
        size_t w = 0;
#define LOCAL_OF(v)                                                                                \
    (stamp[v] == k ? local[v] : (stamp[v] = k, c->cells[w] = parent->cells[v], local[v] = (uint32_t)w++))
        for (uint32_t i = t0; i < t1; ++i) {
            const uint32_t *x = &parent->tris[3 * (size_t)tr.items[i]];
            for (int j = 0; j < 3; ++j)
                c->tris[3 * c->tri_count + (size_t)j] = LOCAL_OF(x[j]);
            c->tri_count++;
        }
        for (uint32_t i = e0; i < e1; ++i) {
            const uint32_t *x = &parent->edges[2 * (size_t)ed.items[i]];
            for (int j = 0; j < 2; ++j)
                c->edges[2 * c->edge_count + (size_t)j] = LOCAL_OF(x[j]);
            c->edge_count++;
        }
        for (uint32_t i = i0; i < i1; ++i) {
            uint32_t v = iso.items[i];
            (void)LOCAL_OF(v);
        }
#undef LOCAL_OF
        c->vertex_count = w;
        if ((s = ms_codec_state_canonicalise(c, err)) != MS_OK)
            goto done;
    }
done:
    if (s != MS_OK)
        for (unsigned k = 0; k < nc; ++k)
            ms_codec_state_free(&children[k]);
    free(owner);
    free(used);
    free(local);
    free(stamp);
    rows_free(&tr);
    rows_free(&ed);
    rows_free(&iso);
    return s;
}
