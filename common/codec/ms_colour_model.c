/* The colour codec's coding of one kd-level and of the base colours, shared by
 * the encoder (encode mode) and the decoder (docs/COLOUR.md, "Symbols"). */
#include "ms_colour_internal.h"

#include <stdlib.h>
#include <string.h>

void cc_model_init(cc_model *m)
{
    ms_rc_prob *p = (ms_rc_prob *)m;
    for (size_t i = 0; i < sizeof *m / sizeof *p; ++i)
        p[i] = MS_RC_PROB_INIT;
}

ms_status cc_level_reserve(cc_level *l, size_t n, ms_error *err)
{
    if (n <= l->cap)
        return MS_OK;
    size_t cap = l->cap ? l->cap : 64;
    while (cap < n)
        cap *= 2;
    uint64_t *cells = realloc(l->cells, cap * sizeof *cells);
    if (cells)
        l->cells = cells;
    uint8_t *col = realloc(l->col, cap * 4);
    if (col)
        l->col = col;
    uint16_t *act = realloc(l->act, cap * CC_SLOTS * sizeof *act);
    if (act)
        l->act = act;
    uint32_t *par = realloc(l->par, cap * sizeof *par);
    if (par)
        l->par = par;
    if (!cells || !col || !act || !par)
        return ms_error_set(err, MS_ERR_NOMEM, "colour codec: out of memory for %zu cells", n);
    l->cap = cap;
    return MS_OK;
}

void cc_level_free(cc_level *l)
{
    free(l->cells);
    free(l->col);
    free(l->act);
    free(l->par);
    memset(l, 0, sizeof *l);
}

static inline int cc_bit(cc_coder *c, ms_rc_prob *p, int bit)
{
    if (c->encoding) {
        ms_rc_encode(&c->enc, p, bit);
        return bit;
    }
    return ms_rc_decode(&c->dec, p);
}

/* A signed residual, |v| < 2^CC_CLASSES: zero?, sign, class k = floor(log2 |v|)
 * in unary (at most CC_CLASSES - 1 bits), then the k bits under the leading
 * one. Returns v (decoded in decode mode). */
static int code_residual(cc_coder *c, cc_residual *r, ms_rc_prob (*low)[CC_CLASSES],
                         unsigned sign_ctx, int v)
{
    if (!cc_bit(c, &r->zero, v != 0))
        return 0;
    int neg = cc_bit(c, &r->sign[sign_ctx], v < 0);
    unsigned m = (unsigned)(v < 0 ? -v : v), k = 0;
    if (c->encoding)
        k = 31u - (unsigned)__builtin_clz(m);
    unsigned cls = 0;
    while (cls < CC_CLASSES - 1 && cc_bit(c, &r->cls[cls], cls < k))
        cls++;
    unsigned mag = 1;
    if (cls > 0) {
        mag = 2u | (unsigned)cc_bit(c, &r->top[cls], (int)((m >> (cls - 1)) & 1));
        for (unsigned i = cls - 1; i-- > 0;)
            mag = mag << 1 | (unsigned)cc_bit(c, &low[cls][i], (int)((m >> i) & 1));
    }
    return neg ? -(int)mag : (int)mag;
}

ms_status cc_code_base(cc_coder *c, cc_level *l, ms_error *err)
{
    (void)err;
    int prev[4];
    for (int k = 0; k < 4; ++k)
        prev[k] = 1 << (c->bits - 1);
    int top = (1 << c->bits) - 1;
    for (size_t i = 0; i < l->n; ++i) {
        uint8_t *col = l->col + 4 * i;
        for (unsigned k = 0; k < 4; ++k) {
            if (k == 3 && c->slots == 3) {
                col[3] = (uint8_t)top;
                continue;
            }
            int v = code_residual(c, &c->m->base[k], c->m->low[k], 0,
                                  c->encoding ? col[k] - prev[k] : 0);
            int x = prev[k] + v;
            if (x < 0 || x > top)
                return ms_error_set(err, MS_ERR_CORRUPT,
                                    "colour stream: base colour out of range (corrupted)");
            col[k] = (uint8_t)x;
            prev[k] = x;
        }
        memset(l->act + CC_SLOTS * i, 0, CC_SLOTS * sizeof *l->act);
    }
    return MS_OK;
}

static unsigned act_bucket(unsigned a)
{
    if (a == 0)
        return 0;
    unsigned b = 32u - (unsigned)__builtin_clz(a); /* 1 for 1, 2 for 2..3, ... */
    return b < CC_ACT - 1 ? b : CC_ACT - 1;
}

static void copy_cell(cc_level *next, size_t j, uint64_t cell, const cc_level *cur, size_t i)
{
    next->cells[j] = cell;
    memcpy(next->col + 4 * j, cur->col + 4 * i, 4);
    memcpy(next->act + CC_SLOTS * j, cur->act + CC_SLOTS * i, CC_SLOTS * sizeof *next->act);
}

/* The detail d (r g b) predicted from the neighbours of the two children j
 * (lower) and j + 1 of a split in g: the difference of their neighbours' mean
 * colours, each neighbour at its colour so far (refined when before j in key
 * order, else its parent's). False when a child has no other neighbour. */
static bool nb_predict(const cc_graph *g, const cc_level *cur, const cc_level *next, size_t j,
                       int top, int pd[3])
{
    int64_t sum[2][3] = {{0, 0, 0}, {0, 0, 0}}, cnt[2] = {0, 0};
    for (size_t h = 0; h < 2; ++h) {
        size_t x = j + h, other = j + 1 - h;
        for (uint32_t e = g->off[x]; e < g->off[x] + g->deg[x]; ++e) {
            size_t y = g->adj[e];
            if (y == other)
                continue;
            const uint8_t *col = y < j ? next->col + 4 * y : cur->col + 4 * (size_t)next->par[y];
            for (int k = 0; k < 3; ++k)
                sum[h][k] += col[k];
            cnt[h]++;
        }
    }
    if (!cnt[0] || !cnt[1])
        return false;
    int64_t den = cnt[0] * cnt[1];
    for (int k = 0; k < 3; ++k) {
        int64_t num = sum[0][k] * cnt[1] - sum[1][k] * cnt[0];
        int64_t q = num >= 0 ? (2 * num + den) / (2 * den) : -((-2 * num + den) / (2 * den));
        pd[k] = (int)(q > top ? top : q < -top ? -top : q);
    }
    return true;
}

/* The lossless YCoCg-R transform of a detail (r g b) and its inverse. */
static void to_ycocg(const int d[3], int s[3])
{
    int co = d[0] - d[2];
    int t = d[2] + cc_floor_half(co);
    int cg = d[1] - t;
    s[0] = t + cc_floor_half(cg);
    s[1] = co;
    s[2] = cg;
}

static void from_ycocg(const int s[3], int d[3])
{
    int t = s[0] - cc_floor_half(s[2]);
    d[1] = s[2] + t;
    d[2] = t - cc_floor_half(s[1]);
    d[0] = d[2] + s[1];
}

/* Codes the slots (Y Co Cg of the detail, then alpha's) of the split of cur's
 * cell into next's cells j and j + 1; s holds them (encode mode) or receives
 * them. Each is coded against the neighbours' prediction, in a context of the
 * activity around it. */
static void code_split(cc_coder *c, const cc_level *cur, size_t i, const cc_graph *g,
                       const cc_level *next, size_t j, unsigned prev[CC_SLOTS], int s[CC_SLOTS])
{
    int pd[3], pred[CC_SLOTS] = {0, 0, 0, 0};
    if (g && nb_predict(g, cur, next, j, (1 << c->bits) - 1, pd))
        to_ycocg(pd, pred);
    const uint16_t *act = cur->act + CC_SLOTS * i;
    for (unsigned k = 0; k < c->slots; ++k) {
        unsigned ctx = act_bucket(act[k] + prev[k] + (unsigned)abs(pred[k]));
        unsigned sign = pred[k] > 0 ? 1 : pred[k] < 0 ? 2 : 0;
        int r = code_residual(c, &c->m->slot[k][ctx], c->m->low[k], sign,
                              c->encoding ? s[k] - pred[k] : 0);
        s[k] = r + pred[k];
        prev[k] = (unsigned)abs(s[k]);
    }
    if (c->slots == 3)
        s[3] = 0;
}

ms_status cc_step(cc_coder *c, const cc_level *cur, unsigned level, const uint64_t *next_cells,
                  size_t n, const cc_graph *g, cc_level *next, ms_error *err)
{
    ms_status st = cc_level_reserve(next, n, err);
    if (st != MS_OK)
        return st;
    if (g && g->n != n)
        return ms_error_set(err, MS_ERR_ARG, "colour codec: graph of %zu cells for %zu", g->n, n);
    for (size_t x = 0, i = 0; x < n; ++x) {
        while (i < cur->n && cur->cells[i] < next_cells[x] >> 1)
            ++i;
        next->par[x] = (uint32_t)(i < cur->n ? i : 0); /* checked in the loop below */
    }
    int top = (1 << c->bits) - 1;
    unsigned prev[CC_SLOTS] = {0};
    size_t j = 0;
    for (size_t i = 0; i < cur->n; ++i) {
        uint64_t p = cur->cells[i];
        if (j >= n || next_cells[j] >> 1 != p)
            return ms_error_set(err, MS_ERR_ARG,
                                "colour decoder: the cells at kd-level %u do not refine the "
                                "colour stream's cells", level + 1);
        bool two = !(next_cells[j] & 1) && j + 1 < n && next_cells[j + 1] == 2 * p + 1;
        if (!two) {
            copy_cell(next, j, next_cells[j], cur, i);
            j++;
            continue;
        }
        int s[CC_SLOTS] = {0}, d[4];
        if (c->encoding) {
            if (c->src_at >= c->src_n)
                return ms_error_set(err, MS_ERR_ARG, "colour encoder: split count mismatch");
            const int16_t *src = c->src + 4 * c->src_at++;
            for (int k = 0; k < 4; ++k)
                d[k] = src[k];
            to_ycocg(d, s);
            s[3] = d[3];
        }
        code_split(c, cur, i, g, next, j, prev, s);
        from_ycocg(s, d);
        d[3] = s[3];
        const uint8_t *pc = cur->col + 4 * i;
        uint8_t *ca = next->col + 4 * j, *cb = ca + 4;
        for (int k = 0; k < 4; ++k) {
            int a = pc[k] + cc_floor_half(d[k] + 1), b = a - d[k];
            if (a < 0 || a > top || b < 0 || b > top)
                return ms_error_set(err, MS_ERR_CORRUPT,
                                    "colour stream: detail out of range at kd-level %u "
                                    "(corrupted)", level);
            ca[k] = (uint8_t)a;
            cb[k] = (uint8_t)b;
        }
        for (int h = 0; h < 2; ++h) {
            size_t x = j + (size_t)h;
            next->cells[x] = next_cells[x];
            for (int k = 0; k < CC_SLOTS; ++k)
                next->act[CC_SLOTS * x + (unsigned)k] = (uint16_t)abs(s[k]);
        }
        j += 2;
    }
    if (j != n)
        return ms_error_set(err, MS_ERR_ARG,
                            "colour decoder: the cells at kd-level %u do not refine the colour "
                            "stream's cells", level + 1);
    next->n = n;
    return MS_OK;
}

ms_status cc_coarsen(const cc_level *l, cc_level *out, ms_error *err)
{
    ms_status st = cc_level_reserve(out, l->n, err);
    if (st != MS_OK)
        return st;
    size_t m = 0;
    for (size_t i = 0; i < l->n; ++i) {
        uint64_t p = l->cells[i] >> 1;
        const uint8_t *a = l->col + 4 * i;
        if (i + 1 < l->n && l->cells[i + 1] >> 1 == p) {
            const uint8_t *b = a + 4;
            for (int k = 0; k < 4; ++k)
                out->col[4 * m + (unsigned)k] = (uint8_t)((a[k] + b[k]) >> 1);
            ++i;
        } else {
            memcpy(out->col + 4 * m, a, 4);
        }
        out->cells[m++] = p;
    }
    out->n = m;
    return MS_OK;
}
