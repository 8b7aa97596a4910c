/* Geometry ahead of connectivity (docs/CODEC.md §4.1): a cell that runs ahead
 * knows which of its descendants h.ahead kd-levels down are occupied, coded that
 * many levels before its connectivity, and is drawn at their barycentre, which
 * always lies inside the cell. The decoder's refinement of such a cell reads its
 * split off the mask; these functions keep the masks and the drawn points. */
#include <math.h>

#include "ms_codec_decisions.h"
#include "ms_codec_internal.h"
#include "ms_codec_model.h"
#include "ms_complex.h"

/* Set bits of x, without the library call a build for the baseline x86-64
 * makes of __builtin_popcountll: a table for the masks of up to 3 levels
 * ahead (8 bits, the default), else in parallel. */
#define POP2(n) n, n + 1, n + 1, n + 2
#define POP4(n) POP2(n), POP2(n + 1), POP2(n + 1), POP2(n + 2)
#define POP6(n) POP4(n), POP4(n + 1), POP4(n + 1), POP4(n + 2)
static const uint8_t pop8[256] = {POP6(0), POP6(1), POP6(1), POP6(2)};

static inline unsigned popcount64(uint64_t x)
{
    if (x < 256)
        return pop8[x];
    x -= (x >> 1) & 0x5555555555555555ull;
    x = (x & 0x3333333333333333ull) + ((x >> 2) & 0x3333333333333333ull);
    x = (x + (x >> 4)) & 0x0F0F0F0F0F0F0F0Full;
    return (unsigned)((x * 0x0101010101010101ull) >> 56);
}

/* Bit q of a descendant's index is set for the descendants in this set (the
 * index's bits, lowest first). */
static const uint64_t index_bit_set[6] = {
    0xAAAAAAAAAAAAAAAAull, 0xCCCCCCCCCCCCCCCCull, 0xF0F0F0F0F0F0F0F0ull,
    0xFF00FF00FF00FF00ull, 0xFFFF0000FFFF0000ull, 0xFFFFFFFF00000000ull,
};

/* Twice the centre along `axis` of descendant i (`depth` kd bits below
 * `level`, the first split's bit highest) of cell s at `level`: its position
 * t among the 2^n slices the n splits along that axis make, from the centre. */
static int64_t descendant_centre2(const ms_complex *cx, uint32_t s, unsigned level, uint32_t i,
                                  unsigned depth, int axis)
{
    unsigned first = ((unsigned)axis + 3 - level % 3) % 3, n = 0;
    int64_t t = 0;
    for (unsigned j = first; j < depth; j += 3, ++n) /* the levels that halve along axis */
        t = 2 * t + ((i >> (depth - 1 - j)) & 1);
    return cx->cen[s][axis] + (2 * t + 1 - (1ll << n)) * ms_cx_width(cx, level + depth, axis);
}

void ms_ahead_update_rep(ms_complex *cx, uint32_t s, unsigned level, unsigned depth)
{
    uint64_t m = cx->ahead[s];
    if (m == 0 || depth == 0) {
        for (int a = 0; a < 4; ++a)
            cx->rep[s][a] = cx->cen[s][a];
        return;
    }
    if ((m & (m - 1)) == 0) { /* one descendant (most cells, deep down): its centre */
        uint32_t i = (uint32_t)__builtin_ctzll(m);
        int64_t t[3] = {0, 0, 0}, n[3] = {0, 0, 0};
        for (unsigned j = 0, a = level % 3; j < depth; ++j, a = a == 2 ? 0 : a + 1) {
            t[a] = 2 * t[a] + ((i >> (depth - 1 - j)) & 1);
            n[a]++;
        }
        for (int a = 0; a < 3; ++a)
            cx->rep[s][a] = cx->cen[s][a] + (int32_t)((2 * t[a] + 1 - (1ll << n[a])) *
                                                      ms_cx_width(cx, level + depth, a));
        cx->rep[s][3] = cx->cen[s][3];
        return;
    }
    /* per axis, the sum of the occupied descendants' slice positions t, one
     * popcount per index bit (weighted by its place in t) */
    int64_t n = popcount64(m), tsum[3] = {0, 0, 0};
    unsigned splits[3] = {0, 0, 0};
    for (unsigned j = 0; j < depth; ++j) {
        unsigned a = (level + j) % 3;
        splits[a]++;
        tsum[a] += (int64_t)popcount64(m & index_bit_set[depth - 1 - j])
                   << ((depth - 1 - j) / 3);
    }
    for (int a = 0; a < 3; ++a) {
        int64_t w = ms_cx_width(cx, level + depth, a);
        int64_t sum = n * cx->cen[s][a] + w * (2 * tsum[a] + n * (1 - (1ll << splits[a])));
        /* rounded to the nearest half grid unit; all positive */
        cx->rep[s][a] = (int32_t)((2 * sum + n) / (2 * n));
    }
    cx->rep[s][3] = cx->cen[s][3];
}

/* Level at which the lineage of descendant i (depth `depth` below cell s at
 * `level`, mask m) last split in two: the deepest ancestor whose sibling is
 * occupied, else the cell's own; only the last GEO_RUNS - 1 levels matter
 * (geo_run caps the run). */
static unsigned descendant_birth(const ms_complex *cx, uint32_t s, unsigned level, uint64_t m,
                                 uint32_t i, unsigned depth)
{
    for (unsigned j = depth; j >= 1 && depth - j < GEO_RUNS - 1; --j) {
        uint32_t sibling = (i >> (depth - j)) ^ 1u;
        unsigned span = depth - j; /* the sibling covers 2^span descendants */
        uint64_t range = ((1ull << (1u << span)) - 1) << (sibling << span);
        if (m & range)
            return level + j;
    }
    return depth >= GEO_RUNS - 1 ? level + depth - (GEO_RUNS - 1) : cx->v[s].birth;
}

/* Encode mode: whether a vertex key lies in [lo, hi). */
static bool occupied(const ms_codec_decoder *d, uint64_t lo, uint64_t hi)
{
    size_t a = 0, b = d->nokeys;
    while (a < b) {
        size_t mid = a + (b - a) / 2;
        if (d->okeys[mid] < lo)
            a = mid + 1;
        else
            b = mid;
    }
    return a < d->nokeys && d->okeys[a] < hi;
}

void ms_ahead_deepen(ms_codec_decoder *d, uint32_t s, unsigned level, unsigned depth)
{
    ms_complex *cx = &d->cx;
    unsigned cur = depth - 1, lam = level + cur; /* the descendants split now are at lam */
    int axis = (int)(lam % 3);
    int64_t wp = ms_cx_width(cx, lam, axis);
    int64_t n = -1, sum = 0; /* the neighbours' centroid, taken at the first half coded */
    unsigned deg = geo_deg(&cx->v[s]);
    unsigned shift = d->D - lam; /* key bits below a descendant's prefix, >= 1 */
    uint64_t m = cx->ahead[s], out = 0;
    bool lone = (m & (m - 1)) == 0; /* one descendant: the cell's point is its centre */
    for (uint64_t b = m; b; b &= b - 1) {
        uint32_t i = (uint32_t)__builtin_ctzll(b);
        /* a lone descendant's lineage has not split within the mask */
        unsigned birth = !lone               ? descendant_birth(cx, s, level, m, i, cur)
                         : cur >= GEO_RUNS - 1 ? lam - (GEO_RUNS - 1)
                                               : cx->v[s].birth;
        unsigned run = geo_run(lam, birth);
        ms_rc_prob *pboth = &d->model[GEO_BOTH(lam, run, deg)];
        int both, second = 0;
        if (d->enc) {
            uint64_t k = cx->v[s].key | ((uint64_t)i << shift), half = 1ull << (shift - 1);
            bool lo = occupied(d, k, k + half), hi = occupied(d, k + half, k + 2 * half);
            both = dbit_code(d, pboth, lo && hi);
            second = !lo;
        } else {
            both = ms_rc_decode(&d->rc, pboth);
        }
        if (!both) {
            if (n < 0)
                sum = geo_sum_col(cx, s, &cx->rep[0][axis], &n);
            int64_t plane2 = lone ? cx->rep[s][axis] : descendant_centre2(cx, s, level, i, cur, axis);
            ms_rc_prob *phalf = &d->model[GEO_HALF(lam, run, geo_bucket(sum, n, wp, plane2))];
            second = d->enc ? dbit_code(d, phalf, second)
                            : ms_rc_decode_unpredictable(&d->rc, phalf);
            if (lone) /* the one descendant's half: the point moves by its width */
                cx->rep[s][axis] += (int32_t)(second ? 1 : -1) * ms_cx_width(cx, lam + 1, axis);
        }
        /* (a lone descendant in both halves keeps the point: their barycentre) */
        out |= (both ? 3ull : 1ull << second) << (2 * i);
    }
    cx->ahead[s] = out;
    if (!lone)
        ms_ahead_update_rep(cx, s, level, depth);
}

void ms_ahead_forget(ms_codec_decoder *d)
{
    ms_complex *cx = &d->cx;
    for (uint32_t k = 0; k < d->norder; ++k) {
        uint32_t s = d->order[k];
        if (cx->ahead[s])
            cx->ahead[s] = 1;
        ms_ahead_update_rep(cx, s, d->level, 0);
    }
}

ms_status ms_ahead_prelude(ms_codec_decoder *d, ms_error *err)
{
    (void)err;
    ms_complex *cx = &d->cx;
    unsigned L = d->Lmin, depth = ms_ahead_depth(d, L);
    ms_ahead_forget(d);
    /* level by level, so that every cell's context sees its neighbours' points
     * one level finer each round */
    for (unsigned j = 1; j <= depth; ++j) {
        for (uint32_t k = 0; k < d->norder; ++k)
            if (cx->ahead[d->order[k]])
                ms_ahead_deepen(d, d->order[k], L, j);
    }
    return MS_OK;
}

/* A mask of `depth` with each pair of sibling descendants merged (depth - 1). */
static uint64_t coarser_mask(uint64_t m, unsigned depth)
{
    uint64_t out = 0;
    for (unsigned i = 0; i < (1u << (depth - 1)); ++i)
        out |= (uint64_t)(((m >> (2 * i)) & 3) != 0) << i;
    return out;
}

uint64_t ms_ahead_parent_mask(uint64_t lo, uint64_t hi, unsigned d, unsigned dc)
{
    /* the children's descendants lie at L + 1 + dc, the parent's at L + d: one
     * level deeper unless the window's end stopped the children short */
    if (dc + 1 > d) {
        lo = coarser_mask(lo, dc);
        hi = coarser_mask(hi, dc);
    }
    return lo | hi << (1u << (d - 1));
}

void ms_ahead_merged(ms_codec_decoder *d, uint32_t keep, unsigned level, uint64_t lo, uint64_t hi)
{
    ms_complex *cx = &d->cx;
    unsigned depth = ms_ahead_depth(d, level);
    cx->ahead[keep] = depth == 0 ? 1 : ms_ahead_parent_mask(lo, hi, depth, ms_ahead_depth(d, level + 1));
    ms_ahead_update_rep(cx, keep, level, depth);
}

unsigned ms_ahead_state_depth(const ms_codec_decoder *d)
{
    /* at the window's first level every cell knows only itself (the prelude
     * belongs to refining it) */
    return d->h.ahead && d->level > d->Lmin ? ms_ahead_depth(d, d->level) : 0;
}

double ms_ahead_cell_bound(const ms_complex *cx, uint32_t s, unsigned depth)
{
    unsigned level = ms_cx_level(cx, s);
    /* the drawn point, in doubled grid units, exactly where a renderer puts it
     * from ms_codec_state.rep: its cell's minimum corner plus the 16-bit
     * fraction of its width (dyadic: exact in a double) */
    double p[3];
    uint16_t f[3] = {32768, 32768, 32768};
    if (cx->rep)
        ms_cx_rep_fraction(cx, s, f);
    for (int a = 0; a < 3; ++a) {
        double w = (double)ms_cx_width(cx, level, a);
        p[a] = ((double)cx->cen[s][a] - w) + (double)f[a] * w / 32768.0;
    }
    uint64_t m = cx->ahead ? cx->ahead[s] : 0;
    /* no mask (a foreign cell, no geometry ahead) or none of this depth: the
     * whole cell, descendant 0 at depth 0 */
    if (m == 0 || depth > MS_CODEC_MAX_AHEAD || (depth < 6 && (m >> (1u << depth)) != 0))
        m = 1, depth = 0;
    double worst = 0;
    for (uint64_t b = m; b; b &= b - 1) {
        uint32_t i = (uint32_t)__builtin_ctzll(b);
        double d2 = 0;
        for (int a = 0; a < 3; ++a) {
            double c = (double)descendant_centre2(cx, s, level, i, depth, a);
            double hw = (double)ms_cx_width(cx, level + depth, a); /* doubled half width */
            double e = fmax(fabs(p[a] - (c - hw)), fabs(p[a] - (c + hw)));
            d2 += e * e;
        }
        if (d2 > worst)
            worst = d2;
    }
    /* halved back to grid units; the squares and the root round by a few
     * ulps at most: 2^-40 more covers them */
    return 0.5 * sqrt(worst) * (1.0 + 0x1p-40);
}
