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
    free(s->rep);
    free(s->bound);
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

/* Whether the tuples are already in lexicographic order (then sorting is the
 * identity: the common case of a state canonicalised twice). */
static bool tuples_sorted(const uint32_t *x, size_t n, unsigned arity)
{
    for (size_t i = 1; i < n; ++i) {
        const uint32_t *a = x + (i - 1) * arity, *b = x + i * arity;
        unsigned c = 0;
        while (c < arity && a[c] == b[c])
            ++c;
        if (c < arity && a[c] > b[c])
            return false;
    }
    return true;
}

ms_status ms_sort_index_tuples(uint32_t *x, size_t n, unsigned arity, size_t index_limit,
                               ms_error *err)
{
    if (n < 2 || tuples_sorted(x, n, arity))
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
    if (st == MS_OK && s->rep) { /* the drawn points follow their cells */
        uint16_t *rep = malloc((n ? n : 1) * 3 * sizeof *rep);
        if (!rep)
            st = ms_error_set(err, MS_ERR_NOMEM, "out of memory canonicalising a complex");
        for (size_t i = 0; rep && i < n; ++i)
            memcpy(&rep[3 * i], &s->rep[3 * (size_t)pos[i]], 3 * sizeof *rep);
        if (rep) {
            free(s->rep);
            s->rep = rep;
        }
    }
    if (st == MS_OK && s->bound) { /* and their error bounds */
        float *bound = malloc((n ? n : 1) * sizeof *bound);
        if (!bound)
            st = ms_error_set(err, MS_ERR_NOMEM, "out of memory canonicalising a complex");
        for (size_t i = 0; bound && i < n; ++i)
            bound[i] = s->bound[pos[i]];
        if (bound) {
            free(s->bound);
            s->bound = bound;
        }
    }
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

uint32_t ms_codec_crc(const uint8_t *p, size_t n)
{
    return (uint32_t)crc32(0L, p, (uInt)n);
}
