/* Codec encoder: merges the full complex back to p_min in exact reverse decode
 * order, recording each decision with the context the decoder will see, then
 * range-codes the recorded decisions in decode order, one chunk per bit. */
#include "ms_codec.h"
#include "ms_big_alloc.h"
#include "ms_codec_internal.h"
#include "ms_codec_model.h"
#include "ms_complex.h"
#include "ms_quant.h"
#include "ms_radix_sort.h"
#include "ms_rangecoder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct sym_buf {
    uint8_t *s; /* decisions (0/1), per group in decode order */
    size_t n, cap;
} sym_buf;

typedef struct enc {
    ms_complex cx;
    unsigned D;
    sym_buf sym;
    /* Each level's decisions, sym[level_first[L], level_end[L]), already in decode
     * order: the merge pass visits a level's cells in reverse decode order, so it
     * writes every cell's group reversed and then reverses the level once. */
    size_t level_first[3 * MS_CODEC_MAX_BITS + 1];
    size_t level_end[3 * MS_CODEC_MAX_BITS + 1];
    ms_cx_star star;
    uint8_t *code;   /* per neighbour of the star being recorded: its code */
    int32_t *vote;   /* per neighbour: orientation votes (star_votes) */
    size_t cap_code;
    int nomem;
} enc;

static void put(enc *e, int bit)
{
    if (e->sym.n == e->sym.cap) {
        size_t c = e->sym.cap ? e->sym.cap * 2 : 1 << 16;
        uint8_t *n = ms_big_realloc(e->sym.s, c * sizeof *n);
        if (!n) {
            e->nomem = 1;
            return;
        }
        e->sym.s = n;
        e->sym.cap = c;
    }
    e->sym.s[e->sym.n++] = (uint8_t)(bit != 0);
}

static void reverse_bytes(uint8_t *p, size_t n)
{
    for (size_t i = 0, j = n; i + 1 < j; ++i, --j) {
        uint8_t t = p[i];
        p[i] = p[j - 1];
        p[j - 1] = t;
    }
}

static int code_room(enc *e, size_t n)
{
    if (n <= e->cap_code)
        return 1;
    size_t c = e->cap_code ? e->cap_code : 256;
    while (c < n)
        c *= 2;
    uint8_t *a = realloc(e->code, c);
    if (!a)
        return 0;
    e->code = a;
    int32_t *v = realloc(e->vote, c * sizeof *v);
    if (!v)
        return 0;
    e->vote = v;
    e->cap_code = c;
    return 1;
}

/* Orientation votes around every neighbour x of the star of (c0, c1), as the
 * decoder counts them for a new triangle (c0, c1, x): each triangle of c0
 * holding x adds ms_cx_orient(t, c0, x), each of c1 subtracts
 * ms_cx_orient(t, c1, x), the triangles holding both centres left out; positive
 * predicts the cyclic order (c0, c1, x). One pass over both lists: counting
 * neighbour by neighbour would cost O(k^2) where k triangles share the edge
 * c0-c1. Reads the local indices that ms_cx_gather_general (two centres) left
 * in cx->mark. */
static void star_votes(const ms_complex *cx, const ms_cx_star *st, uint32_t c0, uint32_t c1,
                       int32_t *vote)
{
    memset(vote, 0, (size_t)st->nn * sizeof *vote);
    const uint32_t cs[2] = {c0, c1};
    for (int k = 0; k < 2; ++k) {
        const ms_cx_vert *v = &cx->v[cs[k]];
        const uint32_t *l = v->cap ? v->ext : v->inl;
        for (uint32_t i = 0; i < v->n; ++i) {
            if (l[i] & 1)
                continue;
            uint32_t t = l[i] >> 1;
            const uint32_t *tr = cx->tri[t];
            if (tr[0] == cs[1 - k] || tr[1] == cs[1 - k] || tr[2] == cs[1 - k])
                continue;
            for (int m = 0; m < 3; ++m) {
                uint32_t x = tr[m];
                if (x == cs[k])
                    continue;
                /* a neighbour with c0 -> x wants x -> c0 in the new one: (c0,c1,x) */
                int o = ms_cx_orient(cx, t, cs[k], x);
                vote[cx->mark[x]] += k == 0 ? o : -o;
            }
        }
    }
}

/* Records the connectivity decisions of the split that separates c0 and c1
 * (siblings at level L + 1), read off the current (pre-merge) complex, in the
 * order the decoder's split consumes them. Contexts are chosen later, in the
 * forward pass. */
static ms_status record_split(enc *e, uint32_t c0, uint32_t c1, ms_error *err)
{
    ms_complex *cx = &e->cx;
    ms_cx_star *st = &e->star;
    /* general (two centres anyway): star_votes reads the marks it leaves */
    ms_status s = ms_cx_gather_general(cx, c0, c1, st, err);
    if (s != MS_OK)
        return s;
    if (!code_room(e, st->nn + 1))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory coding a split");
    int e12 = st->adj01;
    put(e, e12);
    for (uint32_t i = 0; i < st->nn; ++i) {
        uint8_t c = st->adj[i] == 1 ? 1 : st->adj[i] == 2 ? 2 : st->both[i] != MS_CX_NONE ? 4 : 3;
        e->code[i] = c;
        put(e, c >= 3);
        if (c < 3)
            put(e, c == 2);
        else if (e12)
            put(e, c == 4);
    }
    for (uint32_t p = 0; p < st->np; ++p) {
        const ms_cx_pair *pr = &st->pairs[p];
        if (e->code[pr->i] < 3 || e->code[pr->j] < 3)
            continue; /* implied (pruning rule) */
        int t = (pr->t0 != MS_CX_NONE) + 2 * (pr->t1 != MS_CX_NONE);
        put(e, t == 3);
        if (t != 3)
            put(e, t == 2);
    }
    for (uint32_t p = 0; p < st->np; ++p) {
        const ms_cx_pair *pr = &st->pairs[p];
        if (pr->t0 == MS_CX_NONE || pr->t1 == MS_CX_NONE)
            continue;
        uint32_t xi = st->nbr[pr->i], xj = st->nbr[pr->j];
        int s0 = ms_cx_orient(cx, pr->t0, xi, xj), s1 = ms_cx_orient(cx, pr->t1, xi, xj);
        put(e, s0 == s1);
    }
    uint32_t n4 = 0;
    for (uint32_t i = 0; i < st->nn; ++i)
        n4 += e->code[i] == 4;
    if (n4)
        star_votes(cx, st, c0, c1, e->vote);
    for (uint32_t i = 0; i < st->nn; ++i) {
        if (e->code[i] != 4)
            continue;
        uint32_t t = st->both[i];
        int pred = e->vote[i] >= 0 ? 1 : -1;
        put(e, ms_cx_orient(cx, t, c0, c1) != pred);
    }
    return e->nomem ? ms_error_set(err, MS_ERR_NOMEM, "out of memory recording symbols") : MS_OK;
}

/* Validates the input complex (indices, repeated vertices, duplicates). */
static ms_status validate_full(const ms_codec_state *f, ms_error *err)
{
    if (f->bits < 1 || f->bits > MS_CODEC_MAX_BITS || f->level != 3 * f->bits)
        return ms_error_set(err, MS_ERR_ARG, "encoder input must be at full precision "
                            "(level %u, bits %u)", f->level, f->bits);
    if (f->vertex_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "empty mesh: nothing to encode");
    if (f->vertex_count > MS_CODEC_MAX_VERTICES || f->tri_count > MS_CODEC_MAX_TRIANGLES ||
        f->edge_count > MS_CODEC_MAX_EDGES)
        return ms_error_set(err, MS_ERR_RANGE, "complex too large for the codec");
    uint64_t lim = f->level >= 64 ? UINT64_MAX : (1ull << f->level);
    for (size_t i = 0; i < f->vertex_count; ++i)
        if (f->cells[i] >= lim)
            return ms_error_set(err, MS_ERR_ARG, "vertex %zu outside the key space", i);
    for (size_t t = 0; t < f->tri_count; ++t) {
        const uint32_t *x = &f->tris[3 * t];
        if (x[0] >= f->vertex_count || x[1] >= f->vertex_count || x[2] >= f->vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "triangle %zu index out of range", t);
        if (x[0] == x[1] || x[1] == x[2] || x[0] == x[2])
            return ms_error_set(err, MS_ERR_ARG, "triangle %zu repeats a vertex", t);
    }
    for (size_t k = 0; k < f->edge_count; ++k) {
        const uint32_t *x = &f->edges[2 * k];
        if (x[0] >= f->vertex_count || x[1] >= f->vertex_count || x[0] == x[1])
            return ms_error_set(err, MS_ERR_ARG, "edge %zu invalid", k);
    }
    return MS_OK;
}

/* Freeze levels in the canonical (key) order of `canon`, checked (ms_codec.h,
 * ms_codec_encode_params): *out = NULL when nothing freezes. */
static ms_status freeze_levels(const ms_codec_state *full, const ms_codec_state *canon,
                               const ms_codec_encode_params *params, uint8_t **out, ms_error *err)
{
    *out = NULL;
    if (!params->freeze_level)
        return MS_OK;
    if (!params->region)
        return ms_error_set(err, MS_ERR_ARG, "freeze levels need a region");
    size_t n = full->vertex_count;
    unsigned P = full->bits, D = 3 * P, Lmin = 3 * params->p_min;
    uint64_t *keys = malloc(n * sizeof *keys);
    uint32_t *pos = malloc(n * sizeof *pos);
    uint8_t *fl = malloc(n);
    ms_status s = MS_OK;
    if (!keys || !pos || !fl)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory reading freeze levels");
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        keys[i] = full->cells[i];
        pos[i] = (uint32_t)i;
    }
    if (s == MS_OK)
        s = ms_radix_sort_pairs(keys, pos, n, D, err);
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        uint8_t f = params->freeze_level[pos[i]];
        fl[i] = f;
        if (f == MS_CODEC_NO_FREEZE)
            continue;
        uint32_t c[3];
        ms_quant_unkey(canon->cells[i], P, c);
        if (f < Lmin || f >= D)
            s = ms_error_set(err, MS_ERR_ARG, "vertex %u: freeze level %u outside [%u, %u)",
                             pos[i], f, Lmin, D);
        else if (!ms_codec_outside(params->region, c))
            s = ms_error_set(err, MS_ERR_ARG, "vertex %u: only a foreign vertex freezes", pos[i]);
        else if ((i > 0 && ms_key_lcp(canon->cells[i - 1], canon->cells[i], D) >= f) ||
                 (i + 1 < n && ms_key_lcp(canon->cells[i], canon->cells[i + 1], D) >= f))
            s = ms_error_set(err, MS_ERR_ARG, "vertex %u: freezes at kd-level %u in a cell it "
                             "shares", pos[i], f);
    }
    free(keys);
    free(pos);
    if (s != MS_OK) {
        free(fl);
        return s;
    }
    *out = fl;
    return MS_OK;
}

/* Exports the complex (all cells at one level) as a canonical state. */
static ms_status export_state(const ms_complex *cx, const uint32_t *order, uint32_t n,
                              unsigned level, const float *bound, ms_codec_state *out,
                              ms_error *err)
{
    memset(out, 0, sizeof *out);
    out->bits = cx->P;
    out->level = level;
    out->vertex_count = n;
    out->tri_count = cx->live_t;
    out->edge_count = cx->live_e;
    out->cells = malloc((n ? n : 1) * sizeof *out->cells);
    out->tris = malloc((cx->live_t ? cx->live_t : 1) * 3 * sizeof *out->tris);
    out->edges = malloc((cx->live_e ? cx->live_e : 1) * 2 * sizeof *out->edges);
    uint32_t *rank = malloc((cx->nv ? cx->nv : 1) * sizeof *rank);
    if (!out->cells || !out->tris || !out->edges || !rank) {
        free(rank);
        ms_codec_state_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory exporting a complex");
    }
    unsigned shift = cx->D - level;
    for (uint32_t i = 0; i < n; ++i) {
        rank[order[i]] = i;
        out->cells[i] = shift >= 64 ? 0 : cx->v[order[i]].key >> shift;
    }
    if (cx->rep && !(out->rep = malloc((n ? n : 1) * 3 * sizeof *out->rep))) {
        free(rank);
        ms_codec_state_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory exporting a complex");
    }
    for (uint32_t i = 0; cx->rep && i < n; ++i)
        ms_cx_rep_fraction(cx, order[i], &out->rep[3 * i]);
    if (bound) {
        if (!(out->bound = malloc((n ? n : 1) * sizeof *out->bound))) {
            free(rank);
            ms_codec_state_free(out);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory exporting a complex");
        }
        memcpy(out->bound, bound, n * sizeof *bound);
    }
    size_t w = 0;
    for (uint32_t t = 0; t < cx->nt; ++t) {
        if (cx->tri[t][0] == MS_CX_NONE)
            continue;
        for (int k = 0; k < 3; ++k)
            out->tris[3 * w + k] = rank[cx->tri[t][k]];
        w++;
    }
    w = 0;
    for (uint32_t k = 0; k < cx->ne; ++k) {
        if (cx->edge[k][0] == MS_CX_NONE)
            continue;
        out->edges[2 * w] = rank[cx->edge[k][0]];
        out->edges[2 * w + 1] = rank[cx->edge[k][1]];
        w++;
    }
    free(rank);
    return ms_codec_state_canonicalise(out, err);
}

ms_status ms_codec_export_complex(const ms_complex *cx, const uint32_t *order, uint32_t n,
                                  unsigned level, const float *bound, ms_codec_state *out,
                                  ms_error *err)
{
    return export_state(cx, order, n, level, bound, out, err);
}

static ms_status out_of_memory(ms_error *err)
{
    return ms_error_set(err, MS_ERR_NOMEM, "out of memory while encoding");
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* Whether two triangles of one group (same smallest vertex) share their other
 * two vertices, in either orientation. keys has room for the group. */
static bool group_repeats(const uint32_t *tris, size_t first, size_t end, uint64_t *keys)
{
    size_t k = end - first;
    for (size_t t = first; t < end; ++t) {
        uint32_t b = tris[3 * t + 1], c = tris[3 * t + 2];
        keys[t - first] = b < c ? (uint64_t)b << 32 | c : (uint64_t)c << 32 | b;
    }
    if (k <= 16) { /* the usual group: a vertex's few triangles */
        for (size_t i = 1; i < k; ++i)
            for (size_t j = 0; j < i; ++j)
                if (keys[i] == keys[j])
                    return true;
        return false;
    }
    qsort(keys, k, sizeof *keys, cmp_u64);
    for (size_t i = 1; i < k; ++i)
        if (keys[i] == keys[i - 1])
            return true;
    return false;
}

/* No two triangles on the same vertex set, no two equal edges (canon is
 * canonical: each triangle starts with its smallest vertex, triangles and edges
 * sorted, so triangles on one vertex set lie in the group of their smallest
 * vertex and only the groups need looking at). */
static ms_status check_duplicates(const ms_codec_state *canon, ms_error *err)
{
    size_t nt = canon->tri_count, widest = 0;
    for (size_t t = 0, first = 0; t < nt; ++t)
        if (t + 1 == nt || canon->tris[3 * (t + 1)] != canon->tris[3 * t]) {
            if (t + 1 - first > widest)
                widest = t + 1 - first;
            first = t + 1;
        }
    uint64_t *keys = malloc((widest ? widest : 1) * sizeof *keys);
    if (!keys)
        return out_of_memory(err);
    bool dup = false;
    for (size_t t = 0, first = 0; t < nt && !dup; ++t)
        if (t + 1 == nt || canon->tris[3 * (t + 1)] != canon->tris[3 * t]) {
            dup = t > first && group_repeats(canon->tris, first, t + 1, keys);
            first = t + 1;
        }
    free(keys);
    if (dup)
        return ms_error_set(err, MS_ERR_ARG, "duplicate triangle (same vertex set)");
    for (size_t k = 1; k < canon->edge_count; ++k)
        if (canon->edges[2 * k] == canon->edges[2 * k - 2] &&
            canon->edges[2 * k + 1] == canon->edges[2 * k - 1])
            return ms_error_set(err, MS_ERR_ARG, "duplicate edge");
    return MS_OK;
}

/* Canonical copy of full: vertices in key order, checked for duplicate
 * cells, triangles and edges. canon is the caller's to free, also on error. */
static ms_status canonical_copy(const ms_codec_state *full, ms_codec_state *canon, ms_error *err)
{
    uint32_t n = (uint32_t)full->vertex_count;
    canon->bits = full->bits;
    canon->level = full->level;
    canon->vertex_count = full->vertex_count;
    canon->tri_count = full->tri_count;
    canon->edge_count = full->edge_count;
    canon->cells = ms_big_malloc((size_t)n * sizeof *canon->cells);
    canon->tris = ms_big_malloc((full->tri_count ? full->tri_count : 1) * 3 * sizeof *canon->tris);
    canon->edges =
        ms_big_malloc((full->edge_count ? full->edge_count : 1) * 2 * sizeof *canon->edges);
    if (!canon->cells || !canon->tris || !canon->edges)
        return out_of_memory(err);
    memcpy(canon->cells, full->cells, (size_t)n * sizeof *canon->cells);
    if (full->tri_count)
        memcpy(canon->tris, full->tris, full->tri_count * 3 * sizeof *canon->tris);
    if (full->edge_count)
        memcpy(canon->edges, full->edges, full->edge_count * 2 * sizeof *canon->edges);
    ms_status s = ms_codec_state_canonicalise(canon, err);
    if (s != MS_OK)
        return s;
    for (uint32_t i = 1; i < n; ++i)
        if (canon->cells[i] == canon->cells[i - 1])
            return ms_error_set(err, MS_ERR_ARG, "two vertices share a grid cell (weld first)");
    return check_duplicates(canon, err);
}

/* The complex of the full state: every vertex (a frozen one at the level it
 * freezes at), triangle and edge; order[i] is canonical vertex i's index.
 * Edges must be maximal (not a face of a triangle). */
static ms_status build_complex(enc *e, const ms_codec_state *canon, const uint8_t *frozen_at,
                               uint32_t *order, ms_error *err)
{
    unsigned P = canon->bits, D = e->D;
    uint32_t n = (uint32_t)canon->vertex_count;
    uint32_t max_t = (uint32_t)canon->tri_count;
    uint32_t max_e = (uint32_t)(canon->edge_count + canon->tri_count);
    ms_status s = ms_cx_init(&e->cx, P, n, max_t, max_e, err);
    if (s != MS_OK || (s = ms_cx_reserve(&e->cx, n, max_t, (uint32_t)canon->edge_count, err)) !=
                          MS_OK)
        return s;
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t c[3];
        unsigned f = frozen_at ? frozen_at[i] : MS_CODEC_NO_FREEZE;
        if (f == MS_CODEC_NO_FREEZE) {
            ms_quant_unkey(canon->cells[i], P, c);
            order[i] = ms_cx_add_vertex(&e->cx, canon->cells[i], D, c);
        } else {
            /* a frozen cell enters at the level it freezes at: the merge pass
             * never refines it below that */
            uint64_t key = canon->cells[i] & ~((1ull << (D - f)) - 1);
            ms_quant_unkey(key, P, c);
            order[i] = ms_cx_add_vertex(&e->cx, key, f, c);
            e->cx.v[order[i]].frozen = 1;
        }
    }
    for (size_t t = 0; t < canon->tri_count; ++t)
        ms_cx_add_tri(&e->cx, canon->tris[3 * t], canon->tris[3 * t + 1], canon->tris[3 * t + 2]);
    for (size_t k = 0; k < canon->edge_count; ++k)
        ms_cx_add_edge(&e->cx, canon->edges[2 * k], canon->edges[2 * k + 1]);
    if (e->cx.nomem)
        return out_of_memory(err);
    for (size_t k = 0; k < canon->edge_count; ++k) {
        uint32_t a = canon->edges[2 * k], b = canon->edges[2 * k + 1];
        ms_cx_vert *v = &e->cx.v[a];
        uint32_t *l = ms_cx_list(v);
        for (uint32_t i = 0; i < v->n; ++i)
            if (!(l[i] & 1)) {
                const uint32_t *t = e->cx.tri[l[i] >> 1];
                if (t[0] == b || t[1] == b || t[2] == b)
                    return ms_error_set(err, MS_ERR_ARG, "edge %zu is a face of a triangle", k);
            }
    }
    return MS_OK;
}

/* One group of level L (cell `last`, with its sibling `first` or MS_CX_NONE)
 * merged into its parent cell, its decisions recorded (in reverse); the
 * kept cell's index is returned in *keep. */
static ms_status merge_group(enc *e, const ms_codec_encode_params *params, unsigned L,
                             uint32_t first, uint32_t last, uint32_t *keep, ms_error *err)
{
    uint64_t child_bit = 1ull << (e->D - L - 1);
    size_t group = e->sym.n;
    bool foreign = params->region && cell_outside(&e->cx, params->region, last);
    if (foreign)
        put(e, 0); /* not frozen at L */
    /* a cell that runs ahead codes its geometry from the keys (forward pass),
     * until the level where geometry ahead stops */
    bool geometry = foreign || params->ahead == 0 || (params->ahead_until && L >= 3 * params->ahead_until);
    *keep = first != MS_CX_NONE ? first : last;
    if (first != MS_CX_NONE) {
        if (geometry)
            put(e, 1);
        ms_status s = record_split(e, first, last, err);
        if (s != MS_OK || (s = ms_cx_merge(&e->cx, first, last, err)) != MS_OK)
            return s;
    } else if (geometry) {
        put(e, 0);
    }
    ms_cx_vert *v = &e->cx.v[*keep];
    int second = (v->key & child_bit) != 0;
    v->key &= ~child_bit;
    ms_cx_coarsen_cell(&e->cx, *keep, L, second);
    if (first == MS_CX_NONE && geometry)
        put(e, second);
    if (e->nomem)
        return out_of_memory(err);
    reverse_bytes(e->sym.s + group, e->sym.n - group);
    return MS_OK;
}

/* Merges level by level, deepest first, decreasing key within a level,
 * down to Lmin; order (and scratch order2) hold the live cells, *norder of
 * them at the end. */
static ms_status merge_levels(enc *e, const ms_codec_encode_params *params, unsigned Lmin,
                              uint32_t *order, uint32_t *order2, uint32_t *norder, ms_error *err)
{
    unsigned D = e->D;
    for (unsigned L = D; L-- > Lmin;) {
        e->level_first[L] = e->sym.n;
        unsigned shift = D - L; /* bits below the parent's prefix */
        uint32_t w = 0;
        for (uint32_t k = *norder; k > 0;) {
            uint32_t last = order[--k];
            ms_cx_vert *lv = &e->cx.v[last];
            if (lv->frozen) {
                /* frozen at f <= L: nothing below f; at f, the "frozen" decision */
                if (ms_cx_level(&e->cx, last) == L) {
                    put(e, 1);
                    lv->frozen = 0;
                }
                order2[w++] = last;
                continue;
            }
            uint32_t first = MS_CX_NONE;
            if (k > 0 && (e->cx.v[order[k - 1]].key >> shift) == (e->cx.v[last].key >> shift))
                first = order[--k];
            ms_status s = merge_group(e, params, L, first, last, &order2[w++], err);
            if (s != MS_OK)
                return s;
        }
        reverse_bytes(e->sym.s + e->level_first[L], e->sym.n - e->level_first[L]);
        for (uint32_t k = 0; k < w; ++k)
            order[k] = order2[w - 1 - k];
        *norder = w;
        e->level_end[L] = e->sym.n;
    }
    return MS_OK;
}

/* The decisions in decode order (levels upwards), in a new buffer of *count
 * bytes; the encoder's symbol buffer is released. NULL when out of memory. */
static uint8_t *decisions_in_decode_order(enc *e, unsigned Lmin, size_t *count)
{
    uint8_t *dec = ms_big_malloc(e->sym.n ? e->sym.n : 1);
    if (!dec)
        return NULL;
    size_t nd = 0;
    for (unsigned L = Lmin; L < e->D; ++L) {
        size_t n = e->level_end[L] - e->level_first[L]; /* none at all: sym.s is NULL */
        if (n)
            memcpy(dec + nd, e->sym.s + e->level_first[L], n);
        nd += n;
    }
    free(e->sym.s);
    e->sym.s = NULL;
    *count = nd;
    return dec;
}

static void fill_header(ms_codec_header *h, const ms_codec_encode_params *params, unsigned pmin,
                        unsigned P, const ms_codec_state *start, const ms_codec_state *end)
{
    memset(h, 0, sizeof *h);
    h->version = MS_CODEC_VERSION;
    h->p_min = pmin;
    h->p_max = P;
    h->box = params->box;
    h->compact = params->compact_header;
    h->ahead = params->ahead;
    h->ahead_until = params->ahead_until;
    if (params->region) {
        h->has_region = true;
        h->region = *params->region;
    }
    h->start_vertices = (uint32_t)start->vertex_count;
    h->start_tris = (uint32_t)start->tri_count;
    h->start_edges = (uint32_t)start->edge_count;
    h->start_checksum = ms_codec_state_checksum(start);
    h->end_vertices = (uint32_t)end->vertex_count;
    h->end_tris = (uint32_t)end->tri_count;
    h->end_edges = (uint32_t)end->edge_count;
}

/* The header and the range coder's bytes as one stream (malloc'd), checked
 * to be accepted by the decoder (e.g. the plausibility caps). */
static ms_status write_stream(const ms_codec_header *h, const ms_rc_encoder *rc, uint8_t **out,
                              size_t *out_size, ms_error *err)
{
    size_t hs = ms_codec_write_header(NULL, h);
    uint8_t *buf = malloc(hs + rc->size + 1);
    if (!buf)
        return out_of_memory(err);
    ms_codec_write_header(buf, h);
    if (rc->size)
        memcpy(buf + hs, rc->buf, rc->size);
    ms_codec_header check;
    ms_status s = ms_codec_read_header(buf, hs + rc->size, &check, err);
    if (s != MS_OK) {
        free(buf);
        return s;
    }
    *out = buf;
    *out_size = hs + rc->size;
    return MS_OK;
}

static ms_status check_params(const ms_codec_state *full, const ms_codec_encode_params *params,
                              ms_error *err)
{
    ms_status s = validate_full(full, err);
    if (s != MS_OK)
        return s;
    if (params->ahead > MS_CODEC_MAX_AHEAD)
        return ms_error_set(err, MS_ERR_ARG, "geometry ahead by %u kd-levels (at most %u)",
                            params->ahead, MS_CODEC_MAX_AHEAD);
    if (params->ahead_until > MS_CODEC_MAX_AHEAD_UNTIL)
        return ms_error_set(err, MS_ERR_ARG, "geometry ahead stopping at %u bits (at most %u)",
                            params->ahead_until, MS_CODEC_MAX_AHEAD_UNTIL);
    if (params->p_min > full->bits)
        return ms_error_set(err, MS_ERR_ARG, "p_min %u above the precision %u", params->p_min,
                            full->bits);
    if (!isfinite(params->box.size) || !(params->box.size > 0) ||
        !isfinite(params->box.origin[0]) || !isfinite(params->box.origin[1]) ||
        !isfinite(params->box.origin[2]))
        return ms_error_set(err, MS_ERR_ARG, "encoder box must be finite with a positive size");
    if (params->smooth_rounds > MS_CODEC_SMOOTH_ROUNDS_MAX)
        return ms_error_set(err, MS_ERR_ARG, "encoder: %u smoothing rounds, at most %u", params->smooth_rounds,
                            MS_CODEC_SMOOTH_ROUNDS_MAX);
    return MS_OK;
}

/* The parameters with geometry ahead's stop where the header states it: none
 * past the window (the window's end stops it first), no geometry ahead at all
 * in a window that starts at or past it. */
static ms_codec_encode_params window_params(const ms_codec_encode_params *params, unsigned P)
{
    ms_codec_encode_params w = *params;
    if (w.ahead == 0 || w.ahead_until >= P)
        w.ahead_until = 0;
    else if (w.ahead_until != 0 && w.ahead_until <= w.p_min)
        w.ahead = 0, w.ahead_until = 0;
    return w;
}

ms_status ms_codec_encode(const ms_codec_state *full, const ms_codec_encode_params *given,
                          uint8_t **out, size_t *out_size, ms_codec_state *start_out,
                          ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    if (start_out)
        memset(start_out, 0, sizeof *start_out);
    ms_status s = check_params(full, given, err);
    if (s != MS_OK)
        return s;
    const ms_codec_encode_params window = window_params(given, full->bits), *params = &window;
    unsigned P = full->bits, D = 3 * P, pmin = params->p_min, Lmin = 3 * pmin;
    enc e;
    memset(&e, 0, sizeof e);
    e.D = D;
    uint32_t n = (uint32_t)full->vertex_count;
    uint32_t *order = NULL, *order2 = NULL;
    uint8_t *frozen_at = NULL; /* per canonical vertex, or NULL */
    ms_codec_state canon = {0};
    ms_codec_state start = {0};
    ms_rc_encoder rc;
    ms_rc_encoder_init(&rc);
    uint8_t *dec = NULL;
    ms_surface_truth truth = {0}; /* with params->surface_error or summary */

    if ((s = canonical_copy(full, &canon, err)) != MS_OK)
        goto done;
    if (params->region && (s = ms_codec_region_check(params->region, pmin, P, err)) != MS_OK) {
        s = ms_error_set(err, MS_ERR_ARG, "encoder region invalid: %s", err->text);
        goto done;
    }
    if ((s = freeze_levels(full, &canon, params, &frozen_at, err)) != MS_OK)
        goto done;
    order = ms_big_malloc((size_t)n * sizeof *order);
    order2 = ms_big_malloc((size_t)n * sizeof *order2);
    if (!order || !order2) {
        s = out_of_memory(err);
        goto done;
    }
    uint32_t norder = n;
    if ((s = build_complex(&e, &canon, frozen_at, order, err)) != MS_OK ||
        (s = merge_levels(&e, params, Lmin, order, order2, &norder, err)) != MS_OK ||
        (s = export_state(&e.cx, order, norder, Lmin, NULL, &start, err)) != MS_OK)
        goto done;
    size_t nd;
    if (!(dec = decisions_in_decode_order(&e, Lmin, &nd))) {
        s = out_of_memory(err);
        goto done;
    }
    ms_codec_header h;
    fill_header(&h, params, pmin, P, &start, &canon);
    /* Forward pass: the decoder itself chooses every context. */
    ms_cx_free(&e.cx);
    bool measured = params->surface_error || params->summary;
    if (measured && (s = ms_surface_prepare(&canon, params->truth, &truth, err)) != MS_OK)
        goto done;
    truth.error = params->surface_error;
    truth.smooth_rounds = params->smooth_rounds;
    truth.smooth_level = params->smooth_level;
    s = ms_codec_run_encoder(&h, pmin == 0 ? NULL : &start, dec, nd, canon.cells, canon.vertex_count,
                             &rc, params->context_counts, params->mesh,
                             params->surface_error ? &truth : NULL, err);
    if (s == MS_OK && params->summary)
        s = ms_surface_summary(&truth, &start, params->summary, err);
    if (s == MS_OK && rc.failed)
        s = out_of_memory(err);
    if (s == MS_OK)
        s = write_stream(&h, &rc, out, out_size, err);
    if (s == MS_OK && start_out) {
        *start_out = start;
        memset(&start, 0, sizeof start);
    }
done:
    free(dec);
    ms_surface_release(&truth);
    ms_rc_encoder_free(&rc);
    ms_codec_state_free(&start);
    ms_codec_state_free(&canon);
    ms_cx_free(&e.cx);
    ms_cx_star_free(&e.star);
    free(e.sym.s);
    free(e.code);
    free(e.vote);
    free(order);
    free(order2);
    free(frozen_at);
    return s;
}
