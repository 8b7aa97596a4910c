/* Codec decoder: incremental and reversible refinement of the complex. */
#include "ms_codec.h"
#include "ms_big_alloc.h"
#include "ms_codec_decisions.h"
#include "ms_codec_internal.h"
#include "ms_codec_lone.h"
#include "ms_codec_model.h"
#include "ms_codec_prior.h"
#include "ms_complex.h"
#include "ms_quant.h"
#include "ms_rangecoder.h"

#include <stdlib.h>
#include <string.h>

static ms_status corrupt(ms_codec_decoder *d, ms_error *err, const char *what)
{
    d->broken = true;
    return ms_error_set(err, MS_ERR_CORRUPT, "corrupted codec stream at kd-level %u: %s",
                        d->level, what);
}

static int push_birth(ms_codec_decoder *d, unsigned L, uint8_t b)
{
    birth_stack *s = &d->births[L];
    if (s->n == s->cap) {
        uint32_t c = s->cap ? s->cap * 2 : 64;
        uint8_t *n = realloc(s->b, c);
        if (!n)
            return 0;
        s->b = n;
        s->cap = c;
    }
    s->b[s->n++] = b;
    return 1;
}

static int order_room(ms_codec_decoder *d, uint32_t n)
{
    if (n <= d->cap_order)
        return 1;
    uint32_t c = d->cap_order ? d->cap_order : 64;
    while (c < n)
        c *= 2;
    uint32_t *a = ms_big_realloc(d->order, (size_t)c * sizeof *a);
    if (a)
        d->order = a;
    uint32_t *b = ms_big_realloc(d->order2, (size_t)c * sizeof *b);
    if (b)
        d->order2 = b;
    if (!a || !b)
        return 0;
    d->cap_order = c;
    return 1;
}

static int code_room(ms_codec_decoder *d, size_t n, size_t np)
{
    if (n > d->cap_code) {
        size_t c = d->cap_code ? d->cap_code : 256;
        while (c < n)
            c *= 2;
        uint8_t *a = realloc(d->code, c);
        if (a)
            d->code = a;
        uint8_t *b = realloc(d->side, c);
        if (b)
            d->side = b;
        uint8_t *cv = realloc(d->cov, c);
        if (cv)
            d->cov = cv;
        uint8_t *pf = realloc(d->partners, c);
        if (pf)
            d->partners = pf;
        int32_t *vt = realloc(d->vote, c * sizeof *vt);
        if (vt)
            d->vote = vt;
        uint32_t *pv = realloc(d->pivot, c * sizeof *pv);
        if (pv)
            d->pivot = pv;
        if (!a || !b || !cv || !pf || !vt || !pv)
            return 0;
        d->cap_code = c;
    }
    if (np > d->cap_tcode) {
        size_t c = d->cap_tcode ? d->cap_tcode : 256;
        while (c < np)
            c *= 2;
        uint8_t *a = realloc(d->tcode, c);
        if (!a)
            return 0;
        d->tcode = a;
        d->cap_tcode = c;
    }
    return 1;
}

/* Takes off s's list the triangles that no longer hold s (order kept). */
static void drop_moved_triangles(ms_complex *cx, uint32_t s)
{
    ms_cx_vert *v = &cx->v[s];
    uint32_t *l = ms_cx_list(v), w = 0;
    for (uint32_t i = 0; i < v->n; ++i) {
        bool keep = l[i] & 1;
        if (!keep) {
            const uint32_t *t = cx->tri[l[i] >> 1];
            keep = (t[0] == s) | (t[1] == s) | (t[2] == s); /* no short circuit */
        }
        l[w] = l[i]; /* kept or overwritten next: no branch on keep */
        w += keep;
    }
    v->n = w;
    ms_cx_list_reindex(v); /* positions moved */
}

/* The code of each of the star's neighbours, in key order (1: joined to s
 * only, 2: to s2 only, 3: to both, 4: to both through a triangle s s2 x), with
 * its side of the splitting plane and the codes of its partners decoded before
 * it as context; side, cov and vote start afresh, pivot lists the code-4
 * ones. Returns their count. */
static inline __attribute__((always_inline)) uint32_t
neighbour_codes(ms_codec_decoder *d, ms_rc_prob *m, int axis, int64_t plane2, int64_t wp, int e12)
{
    const ms_complex *cx = &d->cx;
    const uint32_t nn = d->star.nn, np = d->star.np;
    const uint32_t *restrict nbr = d->star.nbr;
    const ms_cx_pair *restrict pairs = d->star.pairs;
    uint8_t *restrict code = d->code, *restrict side = d->side, *restrict cov = d->cov;
    uint8_t *restrict partners = d->partners;
    int32_t *restrict vote = d->vote;
    uint32_t *restrict pivot = d->pivot;
    uint32_t n4 = 0;
    unsigned nboth = 0;
    /* pairs are sorted by their smaller index i: once x_i has its code, the
     * pairs from pp on with that i tell its later partners */
    uint32_t pp = 0;
    memset(partners, 0, nn);
    for (uint32_t i = 0; i < nn; ++i) {
        unsigned sd = conn_side(cx, nbr[i], axis, plane2, wp);
        unsigned af = partners[i];
        uint8_t c;
        if (dbit(d, &m[C_EA + ((sd * ADJS + af) * 2 + (unsigned)e12) * 3 +
                         (nboth < 2 ? nboth : 2)])) {
            c = 3;
            nboth++;
            if (e12 && dbit(d, &m[C_EC + sd * ADJS + af]))
                c = 4;
        } else {
            c = dbit(d, &m[C_EB + sd * ADJS + af]) ? 2 : 1;
        }
        side[i] = (uint8_t)sd;
        code[i] = c;
        cov[i] = 0;
        vote[i] = 0;
        pivot[n4] = i; /* kept when code 4 */
        n4 += c == 4;
        for (; pp < np && pairs[pp].i == i; ++pp)
            partners[pairs[pp].j] |= (uint8_t)partner_flag(c);
    }
    return n4;
}

/* The code of the triangle of each of the star's pairs (1: stays with s, 2:
 * goes to s2, 3: copied to both), from its neighbours' codes, and cov of each
 * neighbour (its triangles' codes or-ed); *n3_out: the copies. A triangle
 * between edges of different halves is a corrupt stream. */
static inline __attribute__((always_inline)) ms_status
triangle_codes(ms_codec_decoder *d, ms_rc_prob *m, uint32_t *n3_out, ms_error *err)
{
    const uint32_t np = d->star.np;
    const ms_cx_pair *restrict pairs = d->star.pairs;
    const uint8_t *restrict code = d->code, *restrict side = d->side;
    uint8_t *restrict cov = d->cov, *restrict tcode = d->tcode;
    uint32_t n3 = 0;
    for (uint32_t p = 0; p < np; ++p) {
        uint32_t pi = pairs[p].i, pj = pairs[p].j;
        uint8_t ci = code[pi], cj = code[pj];
        uint8_t t;
        if (ci < 3 || cj < 3) {
            if (ci < 3 && cj < 3 && ci != cj)
                return corrupt(d, err, "triangle between edges of different halves");
            t = ci < 3 ? ci : cj;
        } else {
            unsigned idx = (unsigned)((ci == 4) + (cj == 4)) * 4 + (side[pi] >= SIDES / 2) * 2 +
                           (side[pj] >= SIDES / 2);
            if (dbit(d, &m[C_TA + idx]))
                t = 3;
            else
                t = dbit(d, &m[C_TB + idx]) ? 2 : 1;
        }
        tcode[p] = t;
        n3 += t == 3;
        cov[pi] |= t;
        cov[pj] |= t;
    }
    *n3_out = n3;
    return MS_OK;
}

/* Takes the maximal edges off s (a split rebuilds them). */
static inline __attribute__((always_inline)) void drop_maximal_edges(ms_complex *cx, uint32_t s)
{
    ms_cx_vert *v = &cx->v[s];
    uint32_t *l = ms_cx_list(v);
    for (uint32_t i = 0; i < v->n;) {
        if (l[i] & 1) {
            ms_cx_del_edge(cx, l[i] >> 1);
            l = ms_cx_list(v);
            continue;
        }
        ++i;
    }
}

/* The maximal edges a split leaves: from s and s2 to each neighbour its code
 * joins to one that no triangle covers, and s-s2 when the two are joined
 * without a triangle. */
static inline __attribute__((always_inline)) void
add_split_edges(ms_codec_decoder *d, uint32_t s, uint32_t s2, int e12, uint32_t n4)
{
    ms_complex *cx = &d->cx;
    const uint32_t nn = d->star.nn;
    const uint32_t *restrict nbr = d->star.nbr;
    const uint8_t *restrict code = d->code, *restrict cov = d->cov;
    for (uint32_t i = 0; i < nn; ++i) {
        unsigned bare = code[i] & ~cov[i];
        if (bare & 3) { /* rare: most neighbours share a triangle with both */
            if (bare & 1)
                ms_cx_add_edge(cx, s, nbr[i]);
            if (bare & 2)
                ms_cx_add_edge(cx, s2, nbr[i]);
        }
    }
    if (e12 && n4 == 0)
        ms_cx_add_edge(cx, s, s2);
}

/* Room for the edges a split creates (within the declared sizes). A
 * neighbour needs a maximal edge to s when its code holds s (1, 3: bit 0)
 * and no triangle of s covers it (cov bit 0), to s2 likewise with bit 1 (2,
 * 3; code 4 has neither bit, its triangle covers both). */
static inline __attribute__((always_inline)) uint32_t split_edge_count(const ms_codec_decoder *d,
                                                                       int e12, uint32_t n4)
{
    const uint32_t nn = d->star.nn;
    const uint8_t *restrict code = d->code, *restrict cov = d->cov;
    uint32_t ne_new = e12 && n4 == 0;
    for (uint32_t i = 0; i < nn; ++i) {
        unsigned bare = code[i] & ~cov[i];
        ne_new += (bare & 1) + ((bare >> 1) & 1);
    }
    return ne_new;
}

/* The new cell s2, the upper half of s (level L) along axis, with s refined
 * to the lower half; both born at L + 1. */
static inline __attribute__((always_inline)) uint32_t add_half(ms_codec_decoder *d, uint32_t s,
                                                               unsigned L, int axis, int64_t wp)
{
    ms_complex *cx = &d->cx;
    uint32_t c2[3];
    ms_cx_corner(cx, s, c2);
    c2[axis] += (uint32_t)(wp / 2);
    uint64_t key2 = cx->v[s].key | (1ull << (d->D - L - 1));
    uint32_t s2 = ms_cx_add_vertex(cx, key2, L + 1, c2);
    ms_cx_refine_cell(cx, s, L, 0);
    cx->v[s].birth = (uint8_t)(L + 1);
    cx->v[s2].birth = (uint8_t)(L + 1);
    return s2;
}

/* Each pair's triangle after its code: kept by s, handed to s2, or copied
 * to both (its orientation decoded); with code-4 neighbours (n4), the votes
 * that predict their triangles' orientation. */
static inline __attribute__((always_inline)) void
hand_triangles(ms_codec_decoder *d, ms_rc_prob *m, uint32_t s, uint32_t s2, uint32_t n4)
{
    ms_complex *cx = &d->cx;
    const uint32_t np = d->star.np;
    const uint32_t *restrict nbr = d->star.nbr;
    const ms_cx_pair *restrict pairs = d->star.pairs;
    const uint8_t *restrict tcode = d->tcode;
    int32_t *restrict vote = d->vote;
    uint32_t moved = 0; /* triangles handed to s2, taken off s's list in one pass */
    for (uint32_t p = 0; p < np; ++p) {
        uint32_t pi = pairs[p].i, pj = pairs[p].j, t = pairs[p].t0;
        uint8_t tc = tcode[p];
        int same = tc == 3 ? dbit(d, &m[C_O3]) : 0;
        uint32_t *x = cx->tri[t];
        if (n4) {
            /* the votes this triangle and its copy will cast, as star_votes
             * would count them on the lists of s and s2 after the split: kept
             * on s +o, moved to s2 -o, duplicated with the same cyclic order 0
             * (the copies cancel), with the opposite one +2o. Cast for every
             * pair (only code-4 neighbours read them): cheaper than testing. */
            int w = tc == 1 ? 1 : tc == 2 ? -1 : same ? 0 : 2;
            int o = ms_cx_orient(cx, t, s, nbr[pi]); /* the other one: -o */
            vote[pi] += w * o;
            vote[pj] -= w * o;
        }
        /* handing a triangle to s2 (code 2) or not is a coin toss: renamed
         * and listed by selection, not by a branch */
        bool to_s2 = tc == 2;
        uint32_t to = to_s2 ? s2 : s;
        for (int k = 0; k < 3; ++k)
            x[k] = x[k] == s ? to : x[k];
        ms_cx_list_add_if(cx, s2, t << 1, to_s2);
        moved += to_s2;
        if (tc == 3) {
            uint32_t y[3] = {x[0], x[1], x[2]};
            for (int k = 0; k < 3; ++k)
                if (y[k] == s)
                    y[k] = s2;
            if (same)
                ms_cx_add_tri(cx, y[0], y[1], y[2]);
            else
                ms_cx_add_tri(cx, y[0], y[2], y[1]);
        }
    }
    if (moved)
        drop_moved_triangles(cx, s);
}

/* The triangle s s2 x of each code-4 neighbour x, its orientation decoded
 * against the votes' prediction. */
static inline __attribute__((always_inline)) void
add_code4_triangles(ms_codec_decoder *d, ms_rc_prob *m, uint32_t s, uint32_t s2, uint32_t n4)
{
    ms_complex *cx = &d->cx;
    const uint32_t *restrict nbr = d->star.nbr;
    const int32_t *restrict vote = d->vote;
    const uint32_t *restrict pivot = d->pivot;
    for (uint32_t k = 0; k < n4; ++k) {
        uint32_t i = pivot[k];
        int pred = vote[i] >= 0 ? 1 : -1;
        int flip = dbit(d, &m[o4_ctx(vote[i])]);
        if ((flip ? -pred : pred) > 0)
            ms_cx_add_tri(cx, s, s2, nbr[i]);
        else
            ms_cx_add_tri(cx, s2, s, nbr[i]);
    }
}

/* Splits cell s (level L) in two after a "both" symbol. The steps read the
 * per-neighbour and per-triangle arrays through restrict locals: they are
 * distinct allocations, and without that every byte store would make the
 * compiler reload every bound and base pointer. */
static ms_status split(ms_codec_decoder *d, uint32_t s, unsigned L, uint32_t *out2, ms_error *err)
{
    ms_complex *cx = &d->cx;
    ms_cx_star *st = &d->star;
    ms_rc_prob *m = d->model + d->D * GEO_PER_LEVEL;
    ms_status r = ms_cx_gather(cx, s, MS_CX_NONE, st, err);
    if (r != MS_OK)
        return r;
    if (!code_room(d, st->nn + 1, st->np + 1))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory decoding a split");
    int axis = (int)(L % 3);
    int64_t wp = ms_cx_width(cx, L, axis);
    int64_t plane2 = cx->cen[s][axis]; /* s is at level L: its centre is the plane */
    int e12 = dbit(d, &m[e12_ctx(st->nn)]);
    uint32_t n4 = neighbour_codes(d, m, axis, plane2, wp, e12);
    uint32_t n3 = 0;
    if ((r = triangle_codes(d, m, &n3, err)) != MS_OK)
        return r;
    drop_maximal_edges(cx, s); /* rebuilt below */
    if ((r = ms_cx_reserve(cx, 1, n3 + n4, split_edge_count(d, e12, n4), err)) != MS_OK) {
        d->broken = true;
        return r;
    }
    if (!push_birth(d, L, cx->v[s].birth))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory decoding a split");
    uint32_t s2 = add_half(d, s, L, axis, wp);
    hand_triangles(d, m, s, s2, n4);
    add_code4_triangles(d, m, s, s2, n4);
    add_split_edges(d, s, s2, e12, n4);
    if (cx->nomem)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory decoding a split");
    *out2 = s2;
    return MS_OK;
}

static ms_status enter_chunk(ms_codec_decoder *d, unsigned c, ms_error *err)
{
    if (d->enc) {
        d->rc_chunk = c;
        return MS_OK;
    }
    size_t a = c ? d->h.chunk_end[c - 1] : 0, b = d->h.chunk_end[c];
    if (b > d->body_avail) {
        return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated: precision bit %u "
                            "is not complete", d->h.p_min + c + 1);
    }
    if (!d->skip_crc && !d->crc_ok[c]) {
        if (ms_codec_crc(d->body + a, b - a) != d->h.chunk_crc[c])
            return corrupt(d, err, "chunk checksum mismatch");
        d->crc_ok[c] = 1;
    }
    if (!d->snap_valid[c]) {
        memcpy(d->snap + (size_t)c * d->nmodel, d->model, (size_t)d->nmodel * sizeof *d->model);
        d->snap_valid[c] = 1;
    } else {
        memcpy(d->model, d->snap + (size_t)c * d->nmodel, (size_t)d->nmodel * sizeof *d->model);
    }
    ms_rc_decoder_init(&d->rc, d->body + a, b - a);
    d->rc_chunk = c;
    return MS_OK;
}

/* Refines cell s (level L) that runs ahead: its split is read off its mask,
 * its connectivity decoded as usual; then each resulting cell learns its
 * descendants one level deeper (unless the window's end is that close). */
static ms_status refine_ahead(ms_codec_decoder *d, uint32_t s, unsigned L, uint32_t *w,
                              ms_error *err)
{
    ms_complex *cx = &d->cx;
    unsigned depth = ms_ahead_depth(d, L); /* >= 1: L < D */
    unsigned half = 1u << (depth - 1);
    uint64_t m = cx->ahead[s], lo = m & ((1ull << half) - 1), hi = m >> half;
    uint32_t out[2] = {s, MS_CX_NONE};
    if (lo && hi) {
        ms_status r = split(d, s, L, &out[1], err);
        if (r != MS_OK) {
            d->broken = true;
            return r;
        }
        cx->ahead[s] = lo;
        cx->ahead[out[1]] = hi;
    } else {
        int second = lo == 0;
        cx->v[s].key |= second ? 1ull << (d->D - L - 1) : 0;
        ms_cx_refine_cell(cx, s, L, second);
        cx->ahead[s] = second ? hi : lo;
    }
    /* a cell that did not split keeps its descendants, hence its point; the
     * halves of a split have theirs */
    unsigned dc = ms_ahead_depth(d, L + 1);
    for (int k = 0; k < 2 && out[k] != MS_CX_NONE; ++k) {
        d->order2[(*w)++] = out[k];
        uint64_t mk = cx->ahead[out[k]];
        bool deepen = dc == depth, several = (mk & (mk - 1)) != 0;
        /* (a half that deepens with several descendants gets its point
         * recomputed there, and its own point is no term of its centroid) */
        if (out[1] != MS_CX_NONE && !(deepen && several))
            ms_ahead_update_rep(cx, out[k], L + 1, depth - 1);
        if (deepen)
            ms_ahead_deepen(d, out[k], L + 1, dc);
    }
    return MS_OK;
}

/* Refines every cell of the current level by one kd-level. */
static ms_status refine_level(ms_codec_decoder *d, ms_error *err)
{
    unsigned L = d->level;
    unsigned c = (L - d->Lmin) / 3;
    ms_status r;
    if ((L - d->Lmin) % 3 == 0 || d->rc_chunk != c) {
        if ((L - d->Lmin) % 3 != 0)
            return ms_error_set(err, MS_ERR_ARG, "decoder state lost mid-chunk");
        if ((r = enter_chunk(d, c, err)) != MS_OK)
            return r;
        if (L == d->Lmin && d->h.ahead && (r = ms_ahead_prelude(d, err)) != MS_OK)
            return r;
    }
    ms_complex *cx = &d->cx;
    int axis = (int)(L % 3);
    uint64_t bit = 1ull << (d->D - L - 1);
    int64_t width = ms_cx_width(cx, L, axis);                 /* of the cells at L */
    int32_t child_width = (int32_t)ms_cx_width(cx, L + 1, axis);
    if (!order_room(d, 2 * d->norder))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory decoding a level");
    uint32_t w = 0;
    const ms_codec_region *region = d->h.has_region ? &d->h.region : NULL;
    unsigned bits_in = (L - d->Lmin) / 3;
    lone_level lv = {0};
    /* past where geometry ahead stops, every cell codes its geometry inline */
    bool ahead_here = cx->ahead && ms_ahead_depth(d, L) > 0;
    bool fast = ahead_here && !d->enc;
    if (fast)
        lone_level_init(d, L, &lv);
    for (uint32_t k = 0; k < d->norder; ++k) {
        uint32_t s = d->order[k];
        ms_cx_vert *v = &cx->v[s];
        if (v->frozen) {
            d->order2[w++] = s;
            continue;
        }
        if (fast) {
            uint64_t m = cx->ahead[s];
            if (m != 0 && (m & (m - 1)) == 0) {
                refine_lone(d, &lv, s, v, m);
                d->order2[w++] = s;
                continue;
            }
        }
        if (ahead_here && cx->ahead[s]) {
            if ((r = refine_ahead(d, s, L, &w, err)) != MS_OK)
                return r;
            continue;
        }
        unsigned run = geo_run(L, v->birth);
        if (region && cell_outside(cx, region, s) &&
            dbit(d, &d->model[frz_ctx(d->D, run, bits_in)])) {
            v->frozen = 1; /* stays at kd-level L */
            d->frozen++;
            d->order2[w++] = s;
            continue;
        }
        if (dbit(d, &d->model[GEO_BOTH(L, run, geo_deg(v))])) {
            uint32_t s2 = 0;
            if ((r = split(d, s, L, &s2, err)) != MS_OK) {
                d->broken = true;
                return r;
            }
            ms_cx_rep_follow(cx, s); /* s2 follows from its birth */
            if (cx->ahead) /* past the stop, an own cell's half stays own (mask 1) */
                cx->ahead[s2] = cx->ahead[s];
            d->order2[w++] = s;
            d->order2[w++] = s2;
        } else {
            int64_t n;
            int64_t sum = geo_sum(cx, s, axis, &n);
            unsigned b = geo_bucket(sum, n, width, cx->cen[s][axis]);
            int second = dbit_coin(d, &d->model[GEO_HALF(L, run, b)]);
            v->key |= bit & (0 - (uint64_t)second); /* no branch: a coin toss, nearly */
            ms_cx_refine_cell_by(cx, s, L, axis, child_width, second);
            ms_cx_rep_follow(cx, s);
            d->order2[w++] = s;
        }
    }
    /* Checked once per level: past the end, the decisions read as zeros and
     * the work stays bounded by the declared counts until here. */
    if (d->rc.overrun)
        return corrupt(d, err, "read past the end of a chunk");
    if (d->enc && d->src_pos > d->src_n)
        return ms_error_set(err, MS_ERR_ARG, "encoder: decision stream too short");
    uint32_t *t = d->order;
    d->order = d->order2;
    d->order2 = t;
    d->norder = w;
    d->level = L + 1;
    /* Keep slots in key order (memory locality) once half as many cells are new. */
    if (w >= 4096 && cx->nv - d->compact_nv > w / 2) {
        if ((r = ms_cx_compact(cx, d->order, w, err)) != MS_OK) {
            d->broken = true;
            return r;
        }
        d->compact_nv = cx->nv;
    }
    if ((d->level - d->Lmin) % 3 == 0) {
        if (d->enc) {
            size_t start = c ? d->enc_h->chunk_end[c - 1] : 0;
            ms_rc_encoder_flush(d->enc);
            if (d->enc->failed || d->enc->size > (1u << 31))
                return ms_error_set(err, MS_ERR_NOMEM, "coded stream too large");
            d->enc_h->chunk_end[c] = (uint32_t)d->enc->size;
            d->enc_h->chunk_crc[c] = ms_codec_crc(d->enc->buf + start, d->enc->size - start);
        } else if (!ms_rc_decoder_clean_end(&d->rc))
            return corrupt(d, err, "chunk not consumed exactly");
        d->rc_chunk = UINT32_MAX;
        if (d->level == d->D && (cx->live_v != d->h.end_vertices ||
                                 cx->live_t != d->h.end_tris || cx->live_e != d->h.end_edges))
            return corrupt(d, err, "final complex differs from the declared counts");
    }
    return MS_OK;
}

/* Undoes the refinement of level L = level - 1. */
static ms_status coarsen_level(ms_codec_decoder *d, ms_error *err)
{
    unsigned L = d->level - 1;
    ms_complex *cx = &d->cx;
    unsigned shift = d->D - L;
    uint64_t child_bit = 1ull << (shift - 1);
    birth_stack *bs = &d->births[L];
    uint32_t w = 0;
    for (uint32_t k = d->norder; k > 0;) {
        uint32_t last = d->order[--k];
        ms_cx_vert *lv = &cx->v[last];
        if (lv->frozen && ms_cx_level(cx, last) <= L) {
            /* frozen at L: refining L decided it, coarsening undoes it */
            if (ms_cx_level(cx, last) == L) {
                lv->frozen = 0;
                d->frozen--;
            }
            d->order2[w++] = last;
            continue;
        }
        uint32_t first = MS_CX_NONE;
        /* a frozen cell never shares its parent (it is alone in its kd-cell) */
        if (k > 0 && (cx->v[d->order[k - 1]].key >> shift) == (lv->key >> shift))
            first = d->order[--k];
        uint32_t keep = last;
        uint64_t mask_first = 0, mask_last = cx->ahead ? cx->ahead[last] : 0;
        if (first != MS_CX_NONE) {
            mask_first = cx->ahead ? cx->ahead[first] : 0;
            ms_status r = ms_cx_merge(cx, first, last, err);
            if (r != MS_OK) {
                d->broken = true;
                return r;
            }
            keep = first;
            if (bs->n == 0) {
                d->broken = true;
                return ms_error_set(err, MS_ERR_ARG, "coarsening without history");
            }
            cx->v[keep].birth = bs->b[--bs->n];
        }
        ms_cx_vert *v = &cx->v[keep];
        int second = (v->key & child_bit) != 0;
        v->key &= ~child_bit;
        ms_cx_coarsen_cell(cx, keep, L, second);
        if (mask_last) /* runs ahead: the mask one level up, then its point */
            ms_ahead_merged(d, keep, L, first != MS_CX_NONE ? mask_first : second ? 0 : mask_last,
                            first != MS_CX_NONE || second ? mask_last : 0);
        else
            ms_cx_rep_follow(cx, keep);
        d->order2[w++] = keep;
    }
    for (uint32_t k = 0; k < w; ++k)
        d->order[k] = d->order2[w - 1 - k];
    d->norder = w;
    d->level = L;
    d->rc_chunk = UINT32_MAX;
    if (L == d->Lmin && cx->ahead) /* the prelude belongs to the first chunk: undone */
        ms_ahead_forget(d);
    return MS_OK;
}

ms_status ms_codec_decoder_set_level(ms_codec_decoder *d, unsigned level, ms_error *err)
{
    if (d->broken)
        return ms_error_set(err, MS_ERR_CORRUPT, "decoder stopped after a corrupted stream");
    if (level < d->Lmin || level > d->D)
        return ms_error_set(err, MS_ERR_ARG, "kd-level %u outside the stream window [%u, %u]",
                            level, d->Lmin, d->D);
    if (level < d->level) {
        unsigned boundary = d->Lmin + (level - d->Lmin) / 3 * 3;
        while (d->level > boundary) {
            ms_status r = coarsen_level(d, err);
            if (r != MS_OK)
                return r;
        }
    }
    while (d->level < level) {
        if (d->level + 1 > d->avail_level)
            return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated: kd-level %u not "
                                "available (stream holds %u)", level, d->avail_level);
        ms_status r = refine_level(d, err);
        if (r != MS_OK)
            return r;
    }
    return MS_OK;
}

/* Highest kd-level the held body bytes allow (complete chunks only). */
static unsigned available_level(const ms_codec_decoder *d)
{
    unsigned level = d->Lmin, nchunks = d->h.p_max - d->h.p_min;
    for (unsigned c = 0; c < nchunks && (d->enc || d->h.chunk_end[c] <= d->body_avail); ++c)
        level = d->Lmin + 3 * (c + 1);
    return level;
}

/* Allocates the decoder around d->h (already validated) and loads the start state. */
static ms_status decoder_init(ms_codec_decoder *d, const ms_codec_state *start, ms_error *err)
{
    ms_status r;
    d->D = 3 * d->h.p_max;
    d->Lmin = 3 * d->h.p_min;
    d->level = d->Lmin;
    d->rc_chunk = UINT32_MAX;
    unsigned nchunks = d->h.p_max - d->h.p_min;
    d->avail_level = available_level(d);
    d->nmodel = ms_model_size(d->D);
    d->model = malloc((size_t)d->nmodel * sizeof *d->model);
    d->snap = malloc((size_t)(nchunks ? nchunks : 1) * d->nmodel * sizeof *d->snap);
    d->snap_valid = calloc(nchunks + 1, 1);
    d->crc_ok = calloc(nchunks + 1, 1);
    uint32_t max_e = d->h.end_edges + d->h.end_tris;
    if (!d->model || !d->snap || !d->snap_valid || !d->crc_ok ||
        !order_room(d, d->h.start_vertices))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a decoder");
    ms_codec_model_init(d->model, d->D);
    if ((r = ms_cx_init(&d->cx, d->h.p_max, d->h.end_vertices, d->h.end_tris, max_e, err)) !=
        MS_OK)
        return r;
    d->cx.with_ahead = d->h.ahead > 0;
    /* Reserve the declared final size up front (no regrowth copies), as far as
     * the body makes it plausible: real streams hold under 4 vertices per byte. */
    uint64_t room = 16 * (uint64_t)(d->enc ? d->h.end_vertices : d->body_avail) + 1024;
    uint32_t rv = d->h.end_vertices < room ? d->h.end_vertices : (uint32_t)room;
    uint32_t rt = d->h.end_tris < 2 * room ? d->h.end_tris : (uint32_t)(2 * room);
    uint32_t re = d->h.end_edges < room ? d->h.end_edges : (uint32_t)room;
    if ((r = ms_cx_reserve(&d->cx, rv, rt, re, err)) != MS_OK)
        return r;
    if (!order_room(d, rv))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a decoder");
    if ((r = ms_codec_decoder_load_start(d, start, err)) != MS_OK)
        return r;
    /* the cells that run ahead: all but the foreign ones, each knowing only
     * itself until the first chunk's prelude */
    const ms_codec_region *region = d->h.has_region ? &d->h.region : NULL;
    for (uint32_t k = 0; d->h.ahead && k < d->norder; ++k)
        d->cx.ahead[d->order[k]] = !region || !cell_outside(&d->cx, region, d->order[k]);
    return MS_OK;
}

ms_status ms_codec_decoder_create(const uint8_t *data, size_t size, const ms_codec_state *start,
                                  const ms_codec_decoder_options *options,
                                  ms_codec_decoder **out, ms_error *err)
{
    *out = NULL;
    ms_codec_decoder *d = calloc(1, sizeof *d);
    if (!d)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a decoder");
    ms_status r = ms_codec_parse_header(data, size, &d->h, !(options && options->skip_crc), err);
    if (r != MS_OK) {
        free(d);
        return r;
    }
    size_t hs = d->h.header_size;
    size_t body_avail = size - hs < d->h.body_size ? size - hs : d->h.body_size;
    d->data = malloc(hs + body_avail + 1);
    if (!d->data) {
        free(d);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a decoder");
    }
    memcpy(d->data, data, hs + body_avail);
    d->size = hs + body_avail;
    d->body = d->data + hs;
    d->body_avail = body_avail;
    d->skip_crc = options && options->skip_crc;
    if (d->h.compact && options && options->box) {
        d->h.box = *options->box;
        d->has_box = true;
    }
    d->has_box |= !d->h.compact;
    if ((r = decoder_init(d, start, err)) != MS_OK) {
        ms_codec_decoder_destroy(d);
        return r;
    }
    *out = d;
    return MS_OK;
}

ms_status ms_codec_decoder_extend(ms_codec_decoder *d, const uint8_t *data, size_t size,
                                  ms_error *err)
{
    if (d->broken)
        return ms_error_set(err, MS_ERR_CORRUPT, "decoder stopped after a corrupted stream");
    size_t hs = d->h.header_size;
    if (size < d->size || memcmp(data, d->data, hs) != 0)
        return ms_error_set(err, MS_ERR_ARG, "extending a decoder with bytes that do not "
                            "continue its stream");
    size_t body_avail = size - hs < d->h.body_size ? size - hs : d->h.body_size;
    if (body_avail == d->body_avail)
        return MS_OK;
    uint8_t *b = realloc(d->data, hs + body_avail + 1);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory extending a decoder");
    memcpy(b + d->size, data + d->size, hs + body_avail - d->size);
    /* The range decoder may sit inside a chunk: keep it on the moved bytes. */
    if (d->rc_chunk != UINT32_MAX)
        d->rc.data = b + hs + (d->rc.data - d->body);
    d->data = b;
    d->body = b + hs;
    d->size = hs + body_avail;
    d->body_avail = body_avail;
    d->avail_level = available_level(d);
    return MS_OK;
}

ms_status ms_codec_run_encoder(ms_codec_header *h, const ms_codec_state *start,
                               const uint8_t *decisions, size_t n, const uint64_t *keys,
                               size_t nkeys, ms_rc_encoder *enc, uint64_t *context_counts,
                               ms_mesh *mesh, const ms_surface_truth *truth, ms_error *err)
{
    ms_codec_decoder *d = calloc(1, sizeof *d);
    if (!d)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory encoding");
    d->h = *h;
    d->enc = enc, d->enc_h = h;
    d->src = decisions, d->src_n = n;
    d->train = context_counts;
    d->okeys = keys, d->nokeys = nkeys;
    ms_status r = decoder_init(d, start, err);
    if (r == MS_OK && truth) /* bit by bit, the surface error of each */
        r = ms_surface_measure(d, truth, err);
    if (r == MS_OK)
        r = ms_codec_decoder_set_level(d, d->D, err);
    if (r == MS_OK && d->src_pos != n)
        r = ms_error_set(err, MS_ERR_ARG, "encoder: %zu of %zu decisions used", d->src_pos, n);
    if (r == MS_OK && mesh)
        r = ms_codec_decoder_mesh(d, mesh, err);
    ms_codec_decoder_destroy(d);
    return r;
}
