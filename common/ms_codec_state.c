/* ms_codec_state helpers and the stream header (shared by encoder and decoder). */
#include "ms_codec.h"
#include "ms_codec_internal.h"
#include "ms_big_alloc.h"
#include "ms_radix_sort.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

void ms_codec_state_free(ms_codec_state *s)
{
    if (!s)
        return;
    free(s->cells);
    free(s->tris);
    free(s->edges);
    memset(s, 0, sizeof *s);
}

ms_status ms_codec_state_from_qmesh(const ms_qmesh *q, ms_codec_state *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (q->bits < 1 || q->bits > MS_CODEC_MAX_BITS)
        return ms_error_set(err, MS_ERR_ARG, "precision %u outside 1..%d", q->bits,
                            MS_CODEC_MAX_BITS);
    out->bits = q->bits;
    out->level = 3 * q->bits;
    out->vertex_count = q->vertex_count;
    out->tri_count = q->tri_count;
    out->cells = malloc((q->vertex_count ? q->vertex_count : 1) * sizeof *out->cells);
    out->tris = malloc((q->tri_count ? q->tri_count : 1) * 3 * sizeof *out->tris);
    out->edges = malloc(2 * sizeof *out->edges);
    if (!out->cells || !out->tris || !out->edges) {
        ms_codec_state_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory building a codec state");
    }
    for (size_t i = 0; i < q->vertex_count; ++i)
        out->cells[i] = ms_quant_key(q->coords[3 * i], q->coords[3 * i + 1],
                                     q->coords[3 * i + 2], q->bits);
    if (q->tri_count)
        memcpy(out->tris, q->tris, q->tri_count * 3 * sizeof *out->tris);
    return MS_OK;
}

/* Bits needed for the indices 0..n-1 (at least 1). */
static unsigned index_bits(size_t n)
{
    unsigned w = 1;
    while (w < 32 && ((size_t)1 << w) < n)
        ++w;
    return w;
}

ms_status ms_sort_index_tuples(uint32_t *x, size_t n, unsigned arity, size_t index_limit,
                               ms_error *err)
{
    if (n < 2)
        return MS_OK;
    unsigned w = index_bits(index_limit);
    uint64_t *key = ms_big_malloc(n * sizeof *key);
    uint32_t *perm = ms_big_malloc(n * sizeof *perm);
    uint32_t *copy = ms_big_malloc(n * arity * sizeof *copy);
    ms_status s = MS_OK;
    if (!key || !perm || !copy)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory sorting %zu simplices", n);
    for (size_t i = 0; s == MS_OK && i < n; ++i)
        perm[i] = (uint32_t)i;
    /* LSD over whole columns: one sort when the tuple fits a 64-bit key, else the
     * trailing columns first, then the leading one (the sort is stable). */
    unsigned first = arity * w <= 64 ? 0 : 1;
    for (int pass = 0; s == MS_OK && pass < 2; ++pass) {
        unsigned c0 = pass == 0 ? first : 0, c1 = pass == 0 ? arity : first;
        if (c0 == c1)
            continue;
        for (size_t i = 0; i < n; ++i) {
            uint64_t k = 0;
            for (unsigned c = c0; c < c1; ++c)
                k = k << w | x[(size_t)perm[i] * arity + c];
            key[i] = k;
        }
        s = ms_radix_sort_pairs(key, perm, n, (c1 - c0) * w, err);
    }
    if (s == MS_OK) {
        memcpy(copy, x, n * arity * sizeof *copy);
        for (size_t i = 0; i < n; ++i)
            memcpy(x + i * arity, copy + (size_t)perm[i] * arity, arity * sizeof *x);
    }
    free(key);
    free(perm);
    free(copy);
    return s;
}

ms_status ms_codec_state_canonicalise(ms_codec_state *s, ms_error *err)
{
    size_t n = s->vertex_count;
    uint32_t *pos = malloc((n ? n : 1) * sizeof *pos);
    uint32_t *remap = malloc((n ? n : 1) * sizeof *remap);
    if (!pos || !remap) {
        free(pos);
        free(remap);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory canonicalising a complex");
    }
    for (size_t i = 0; i < n; ++i)
        pos[i] = (uint32_t)i;
    /* every bit of the widest cell, so that even a hostile start state sorts
     * exactly; equal cells (invalid, refused by the callers) keep their order */
    uint64_t widest = 0;
    for (size_t i = 0; i < n; ++i)
        widest |= s->cells[i];
    unsigned key_bits = widest ? 64u - (unsigned)__builtin_clzll(widest) : 1u;
    ms_status st = ms_radix_sort_pairs(s->cells, pos, n, key_bits, err);
    for (size_t i = 0; st == MS_OK && i < n; ++i)
        remap[pos[i]] = (uint32_t)i;
    for (size_t t = 0; st == MS_OK && t < s->tri_count; ++t) {
        uint32_t *x = &s->tris[3 * t];
        uint32_t a = remap[x[0]], b = remap[x[1]], c = remap[x[2]];
        if (b < a && b < c) {
            x[0] = b, x[1] = c, x[2] = a;
        } else if (c < a && c < b) {
            x[0] = c, x[1] = a, x[2] = b;
        } else {
            x[0] = a, x[1] = b, x[2] = c;
        }
    }
    for (size_t e = 0; st == MS_OK && e < s->edge_count; ++e) {
        uint32_t a = remap[s->edges[2 * e]], b = remap[s->edges[2 * e + 1]];
        s->edges[2 * e] = a < b ? a : b;
        s->edges[2 * e + 1] = a < b ? b : a;
    }
    free(pos);
    free(remap);
    if (st == MS_OK)
        st = ms_sort_index_tuples(s->tris, s->tri_count, 3, n, err);
    if (st == MS_OK)
        st = ms_sort_index_tuples(s->edges, s->edge_count, 2, n, err);
    return st;
}

static void sort3(uint32_t *x)
{
    uint32_t t;
    if (x[0] > x[1]) t = x[0], x[0] = x[1], x[1] = t;
    if (x[1] > x[2]) t = x[1], x[1] = x[2], x[2] = t;
    if (x[0] > x[1]) t = x[0], x[0] = x[1], x[1] = t;
}

bool ms_codec_state_equal(const ms_codec_state *a, const ms_codec_state *b, bool oriented)
{
    if (a->level != b->level || a->vertex_count != b->vertex_count ||
        a->tri_count != b->tri_count || a->edge_count != b->edge_count)
        return false;
    if (a->vertex_count && memcmp(a->cells, b->cells, a->vertex_count * sizeof *a->cells))
        return false;
    if (a->edge_count && memcmp(a->edges, b->edges, a->edge_count * 2 * sizeof *a->edges))
        return false;
    if (oriented || a->tri_count == 0)
        return a->tri_count == 0 ||
               memcmp(a->tris, b->tris, a->tri_count * 3 * sizeof *a->tris) == 0;
    size_t n = a->tri_count * 3;
    uint32_t *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    bool eq = false;
    if (x && y) {
        memcpy(x, a->tris, n * sizeof *x);
        memcpy(y, b->tris, n * sizeof *y);
        for (size_t t = 0; t < a->tri_count; ++t) {
            sort3(&x[3 * t]);
            sort3(&y[3 * t]);
        }
        /* unoriented comparison: a sort failure (no memory) reports "different" */
        eq = ms_sort_index_tuples(x, a->tri_count, 3, a->vertex_count, NULL) == MS_OK &&
             ms_sort_index_tuples(y, a->tri_count, 3, a->vertex_count, NULL) == MS_OK &&
             memcmp(x, y, n * sizeof *x) == 0;
    }
    free(x);
    free(y);
    return eq;
}

static uint64_t fnv(uint64_t h, const void *p, size_t n)
{
    const uint8_t *b = p;
    for (size_t i = 0; i < n; ++i) {
        h ^= b[i];
        h *= 0x100000001b3ull;
    }
    return h;
}

uint64_t ms_codec_state_checksum(const ms_codec_state *s)
{
    uint64_t h = 0xcbf29ce484222325ull;
    uint64_t counts[4] = {s->level, s->vertex_count, s->tri_count, s->edge_count};
    h = fnv(h, counts, sizeof counts);
    for (size_t i = 0; i < s->vertex_count; ++i) {
        uint8_t b[8];
        for (int k = 0; k < 8; ++k)
            b[k] = (uint8_t)(s->cells[i] >> (8 * k));
        h = fnv(h, b, 8);
    }
    for (size_t i = 0; i < 3 * s->tri_count; ++i) {
        uint8_t b[4] = {(uint8_t)s->tris[i], (uint8_t)(s->tris[i] >> 8),
                        (uint8_t)(s->tris[i] >> 16), (uint8_t)(s->tris[i] >> 24)};
        h = fnv(h, b, 4);
    }
    for (size_t i = 0; i < 2 * s->edge_count; ++i) {
        uint8_t b[4] = {(uint8_t)s->edges[i], (uint8_t)(s->edges[i] >> 8),
                        (uint8_t)(s->edges[i] >> 16), (uint8_t)(s->edges[i] >> 24)};
        h = fnv(h, b, 4);
    }
    return h;
}

/* ---- header ---- */

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void put64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get64(const uint8_t *p)
{
    return (uint64_t)get32(p) | (uint64_t)get32(p + 4) << 32;
}

static uint64_t dbits(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    return u;
}

static double bitsd(uint64_t u)
{
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

size_t ms_codec_header_size(unsigned nchunks, bool has_region)
{
    return MS_CODEC_FIXED_HEADER + (has_region ? MS_CODEC_REGION_BYTES : 0) +
           8 * (size_t)nchunks + 4;
}

void ms_codec_write_header(uint8_t *p, const ms_codec_header *h)
{
    unsigned nchunks = h->p_max - h->p_min;
    memcpy(p, MS_CODEC_MAGIC, 4);
    p[4] = (uint8_t)h->version;
    p[5] = (uint8_t)h->p_max;
    p[6] = (uint8_t)h->p_min;
    p[7] = h->has_region ? 1 : 0;
    for (int a = 0; a < 3; ++a)
        put64(p + 8 + 8 * a, dbits(h->box.origin[a]));
    put64(p + 32, dbits(h->box.size));
    put32(p + 40, h->start_vertices);
    put32(p + 44, h->start_tris);
    put32(p + 48, h->start_edges);
    put64(p + 52, h->start_checksum);
    put32(p + 60, h->end_vertices);
    put32(p + 64, h->end_tris);
    put32(p + 68, h->end_edges);
    uint8_t *q = p + MS_CODEC_FIXED_HEADER;
    if (h->has_region) {
        for (int a = 0; a < 3; ++a)
            put32(q + 4 * a, h->region.min[a]);
        memset(q + 12, 0, 4);
        q[12] = (uint8_t)h->region.log2_side;
        q += MS_CODEC_REGION_BYTES;
    }
    for (unsigned i = 0; i < nchunks; ++i) {
        put32(q + 8 * i, h->chunk_end[i]);
        put32(q + 8 * i + 4, h->chunk_crc[i]);
    }
    size_t n = ms_codec_header_size(nchunks, h->has_region) - 4;
    put32(p + n, (uint32_t)crc32(0L, p, (uInt)n));
}

ms_status ms_codec_region_check(const uint8_t *q, unsigned p_min, unsigned p_max,
                                ms_codec_region *out, ms_error *err)
{
    ms_codec_region r;
    for (int a = 0; a < 3; ++a)
        r.min[a] = get32(q + 4 * a);
    r.log2_side = q[12];
    if (q[13] || q[14] || q[15])
        return ms_error_set(err, MS_ERR_FORMAT, "codec region: reserved bytes not zero");
    if (r.log2_side > p_max || 3 * (p_max - r.log2_side) > 3 * p_min)
        return ms_error_set(err, MS_ERR_FORMAT, "codec region of side 2^%u does not fit the "
                            "window [%u, %u]", r.log2_side, p_min, p_max);
    uint64_t side = 1ull << r.log2_side, grid = 1ull << p_max;
    for (int a = 0; a < 3; ++a)
        if (r.min[a] % side != 0 || r.min[a] + side > grid)
            return ms_error_set(err, MS_ERR_FORMAT, "codec region not aligned inside the grid");
    *out = r;
    return MS_OK;
}

ms_status ms_codec_read_header(const uint8_t *data, size_t size, ms_codec_header *h,
                               ms_error *err)
{
    return ms_codec_parse_header(data, size, h, true, err);
}

ms_status ms_codec_parse_header(const uint8_t *data, size_t size, ms_codec_header *h,
                                bool verify_crc, ms_error *err)
{
    memset(h, 0, sizeof *h);
    if (size < MS_CODEC_FIXED_HEADER)
        return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated in its header (%zu bytes)",
                            size);
    if (memcmp(data, MS_CODEC_MAGIC, 4) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "not a meshstream codec stream (bad magic)");
    h->version = data[4];
    if (h->version != MS_CODEC_VERSION && h->version != MS_CODEC_VERSION_FLAT)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "codec stream version %u not supported",
                            h->version);
    h->p_max = data[5];
    h->p_min = data[6];
    if (h->p_max < 1 || h->p_max > MS_CODEC_MAX_BITS || h->p_min > h->p_max || (data[7] & ~1u) ||
        (data[7] && h->version == MS_CODEC_VERSION_FLAT))
        return ms_error_set(err, MS_ERR_FORMAT, "bad precision window [%u, %u] or flags",
                            h->p_min, h->p_max);
    h->has_region = data[7] & 1;
    unsigned nchunks = h->p_max - h->p_min;
    size_t hs = ms_codec_header_size(nchunks, h->has_region);
    if (size < hs)
        return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated in its header (%zu of %zu "
                            "bytes)", size, hs);
    if (verify_crc && get32(data + hs - 4) != (uint32_t)crc32(0L, data, (uInt)(hs - 4)))
        return ms_error_set(err, MS_ERR_CORRUPT, "codec header checksum mismatch");
    for (int a = 0; a < 3; ++a)
        h->box.origin[a] = bitsd(get64(data + 8 + 8 * a));
    h->box.size = bitsd(get64(data + 32));
    for (int a = 0; a < 3; ++a)
        if (!isfinite(h->box.origin[a]))
            return ms_error_set(err, MS_ERR_FORMAT, "box origin is not finite");
    if (!isfinite(h->box.size) || !(h->box.size > 0))
        return ms_error_set(err, MS_ERR_FORMAT, "box size is not a positive number");
    h->start_vertices = get32(data + 40);
    h->start_tris = get32(data + 44);
    h->start_edges = get32(data + 48);
    h->start_checksum = get64(data + 52);
    h->end_vertices = get32(data + 60);
    h->end_tris = get32(data + 64);
    h->end_edges = get32(data + 68);
    if (h->end_vertices < 1 || h->end_vertices > MS_CODEC_MAX_VERTICES ||
        h->end_tris > MS_CODEC_MAX_TRIANGLES || h->end_edges > MS_CODEC_MAX_EDGES)
        return ms_error_set(err, MS_ERR_NOMEM, "declared complex too large or empty (%u vertices, "
                            "%u triangles, %u edges)", h->end_vertices, h->end_tris, h->end_edges);
    if (h->p_max < 9 && h->end_vertices > (1u << (3 * h->p_max)))
        return ms_error_set(err, MS_ERR_FORMAT, "more vertices (%u) than grid cells",
                            h->end_vertices);
    if (h->start_vertices < 1 || h->start_vertices > h->end_vertices ||
        h->start_tris > h->end_tris ||
        (uint64_t)h->start_edges > (uint64_t)h->end_edges + h->end_tris)
        return ms_error_set(err, MS_ERR_FORMAT, "start state larger than the final complex");
    if (h->p_min == 0 && (h->start_vertices != 1 || h->start_tris || h->start_edges))
        return ms_error_set(err, MS_ERR_FORMAT, "a stream from precision 0 starts at one vertex");
    size_t table = MS_CODEC_FIXED_HEADER;
    if (h->has_region) {
        const uint8_t *q = data + MS_CODEC_FIXED_HEADER;
        ms_status r = ms_codec_region_check(q, h->p_min, h->p_max, &h->region, err);
        if (r != MS_OK)
            return r;
        table += MS_CODEC_REGION_BYTES;
    }
    uint32_t prev = 0;
    for (unsigned i = 0; i < nchunks; ++i) {
        const uint8_t *q = data + table + 8 * i;
        h->chunk_end[i] = get32(q);
        h->chunk_crc[i] = get32(q + 4);
        if (h->chunk_end[i] < prev + 4 || h->chunk_end[i] > (1u << 31))
            return ms_error_set(err, MS_ERR_FORMAT, "bad chunk offset table (entry %u)", i);
        prev = h->chunk_end[i];
    }
    /* Plausibility: even a perfectly regular complex costs more than 1/32 bit
     * per new vertex; this bounds what a short hostile stream can make the
     * decoder allocate. */
    uint64_t room = 256ull * ((uint64_t)prev + 16);
    if ((uint64_t)h->end_vertices > h->start_vertices + room ||
        (uint64_t)h->end_tris > h->start_tris + 2 * room ||
        (uint64_t)h->end_edges > (uint64_t)h->start_edges + 2 * room)
        return ms_error_set(err, MS_ERR_FORMAT, "declared complex (%u vertices, %u triangles) "
                            "implausibly large for a %u-byte body", h->end_vertices,
                            h->end_tris, prev);
    h->header_size = hs;
    h->body_size = prev;
    return MS_OK;
}

uint32_t ms_codec_crc(const uint8_t *p, size_t n)
{
    return (uint32_t)crc32(0L, p, (uInt)n);
}
