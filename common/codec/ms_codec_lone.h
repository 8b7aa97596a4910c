/* The decoder's fast path for a lone cell (internal, ms_codec_decode.c): a
 * cell that runs ahead (docs/CODEC.md §4.1) knowing one descendant, most
 * cells deep down. It cannot split: it moves to that descendant's half and
 * learns the level below it, exactly as refine_ahead and ms_ahead_deepen
 * would (same decisions, contexts and state), with what depends only on the
 * level computed once per level. Decode mode only: the encoder's forward
 * pass takes the general path. */
#ifndef MS_CODEC_LONE_H
#define MS_CODEC_LONE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_codec_internal.h"
#include "ms_codec_model.h"
#include "ms_complex.h"
#include "ms_rangecoder.h"

/* What refining a lone cell that runs ahead needs of its level, computed once
 * per level (refine_lone). */
typedef struct lone_level {
    unsigned L, depth, half, lam;
    bool deepen;            /* the refined cell learns one level deeper */
    int axis, lax_i;        /* L's axis, lam's axis */
    int32_t cw;             /* child width at L + 1 along L's axis */
    int32_t lcw;            /* width at lam + 1 along lam's axis */
    int64_t lwp;            /* width at lam along lam's axis */
    uint64_t bit;           /* L's key bit */
    unsigned run_fixed;     /* GEO_RUNS when the run is the cell's own */
    ms_rc_prob *both, *half_ctx; /* GEO_BOTH(lam, 0, 0), GEO_HALF(lam, 0, 0) */
} lone_level;

static inline void lone_level_init(ms_codec_decoder *d, unsigned L, lone_level *lv)
{
    ms_complex *cx = &d->cx;
    lv->L = L;
    lv->depth = ms_ahead_depth(d, L); /* >= 1: L < D */
    lv->half = 1u << (lv->depth - 1);
    lv->axis = (int)(L % 3);
    lv->cw = (int32_t)ms_cx_width(cx, L + 1, lv->axis);
    lv->bit = 1ull << (d->D - L - 1);
    unsigned dc = ms_ahead_depth(d, L + 1);
    lv->deepen = dc == lv->depth;
    /* ms_ahead_deepen(d, s, L + 1, dc) for a lone cell */
    unsigned cur = dc - 1;
    lv->lam = L + 1 + cur;
    lv->lax_i = (int)(lv->lam % 3);
    if (lv->deepen) {
        lv->lwp = ms_cx_width(cx, lv->lam, lv->lax_i);
        lv->lcw = (int32_t)ms_cx_width(cx, lv->lam + 1, lv->lax_i);
        lv->both = &d->model[GEO_BOTH(lv->lam, 0, 0)];
        lv->half_ctx = &d->model[GEO_HALF(lv->lam, 0, 0)];
    }
    lv->run_fixed = cur >= GEO_RUNS - 1 ? GEO_RUNS - 1 : GEO_RUNS;
}

/* refine_ahead for a cell with one known descendant (most cells, deep down):
 * it cannot split, moves to that descendant's half, and learns the next level
 * down (ms_ahead_deepen's lone case), with the level's constants at hand. */
static inline __attribute__((always_inline)) void
refine_lone(ms_codec_decoder *d, const lone_level *lv, uint32_t s, ms_cx_vert *v, uint64_t m)
{
    ms_complex *cx = &d->cx;
    uint32_t i = (uint32_t)__builtin_ctzll(m);
    uint32_t second = i >= lv->half;
    v->key |= lv->bit & (0 - (uint64_t)second);
    cx->cen[s][lv->axis] += second ? lv->cw : -lv->cw;
    cx->cen[s][3] = (int32_t)(lv->L + 1);
    i -= second ? lv->half : 0;
    if (!lv->deepen) {
        cx->ahead[s] = 1ull << i;
        return;
    }
    unsigned run = lv->run_fixed < GEO_RUNS ? lv->run_fixed : geo_run(lv->lam, v->birth);
    int both = ms_rc_decode(&d->rc, &lv->both[run * GEO_DEGS + geo_deg(v)]);
    uint64_t out;
    if (both) {
        out = 3ull << (2 * i);
    } else {
        /* the neighbours' centroid only when the half is coded */
        int64_t n;
        int64_t sum = geo_sum_col(cx, s, &cx->rep[0][lv->lax_i], &n);
        int32_t *p = &cx->rep[s][lv->lax_i];
        unsigned b = geo_bucket(sum, n, lv->lwp, *p);
        uint32_t h = (uint32_t)ms_rc_decode_unpredictable(&d->rc,
                                                         &lv->half_ctx[run * GEO_BUCKETS + b]);
        *p += h ? lv->lcw : -lv->lcw;
        out = 1ull << (2 * i + h);
    }
    cx->ahead[s] = out;
}

#endif
