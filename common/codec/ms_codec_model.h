/* Context modelling shared by the codec's encoder and decoder (internal).
 *
 * Every coded decision is a binary symbol with a context index into one array of
 * adaptive probabilities. The contexts are computed from state that both sides
 * hold identically (the complex before a split / after the matching merge, and
 * the symbols already coded in the same split), so the encoder can record
 * (context, bit) pairs while merging and code them later in decode order.
 *
 * Layout: per kd-level, GEO_PER_LEVEL geometry contexts; then the connectivity
 * contexts (shared by all levels).
 */
#ifndef MS_CODEC_MODEL_H
#define MS_CODEC_MODEL_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_complex.h"
#include "ms_rangecoder.h"

/* Geometry: "both halves?" by (run = levels since the lineage last split, capped);
 * "which half" by run and the side/distance bucket of the neighbours' centroid. */
#define GEO_RUNS 4
#define GEO_DIST 14
#define GEO_BUCKETS (GEO_DIST + 1)
#define GEO_BOTH(level, run, deg) ((level) * GEO_PER_LEVEL + (run) * GEO_DEGS + (deg))
#define GEO_HALF(level, run, bucket) \
    ((level) * GEO_PER_LEVEL + GEO_RUNS * GEO_DEGS + (run) * GEO_BUCKETS + (bucket))
#define GEO_PER_LEVEL (GEO_RUNS * GEO_DEGS + GEO_RUNS * GEO_BUCKETS)
#define GEO_DEGS 4

/* Degree bucket of a cell for the "both halves?" bit: its incident simplex count. */
static inline unsigned geo_deg(const ms_cx_vert *v)
{
    /* 0 (<= 4), 1 (<= 6), 2 (<= 8), 3: counted, not branched on */
    return (unsigned)(v->n > 4) + (v->n > 6) + (v->n > 8);
}

/* Connectivity, offsets from the connectivity base. */
#define SIDES 8
#define ADJS 8
#define C_E12 0                             /* 5: degree bucket */
#define C_EA (C_E12 + 5)                    /* edge 3/4 vs 1/2: side x adj x e12 x nboth */
#define C_EB (C_EA + SIDES * ADJS * 2 * 3)  /* edge 1 vs 2: side x adj */
#define C_EC (C_EB + SIDES * ADJS)          /* edge 4 vs 3: side x adj */
#define C_TA (C_EC + SIDES * ADJS)          /* triangle 3 vs 1/2: n4 x sides */
#define C_TB (C_TA + 12)                    /* triangle 1 vs 2 */
#define C_O3 (C_TB + 12)                    /* orientation of a duplicated copy */
#define C_O4 (C_O3 + 2)                     /* orientation of a created triangle */
#define C_TOTAL (C_O4 + 3)

/* "Frozen?" of a foreign cell (streams with an owned region, ms_codec.h): run x
 * precision bits into the window (0, 1, 2, 3+). After the connectivity block and
 * outside the prior (single streams, which the prior is trained on, have none):
 * they start at 1/2. */
#define FRZ_CONTEXTS (GEO_RUNS * 4)

static inline uint32_t ms_model_size(unsigned D)
{
    return D * GEO_PER_LEVEL + C_TOTAL + FRZ_CONTEXTS;
}

static inline uint32_t frz_ctx(unsigned D, unsigned run, unsigned bits_in)
{
    return D * GEO_PER_LEVEL + C_TOTAL + run * 4 + (bits_in < 3 ? bits_in : 3);
}

/* The prior's layout (ms_codec_prior.h): every kd-level a stream can reach, then
 * the connectivity contexts. A model index i of a stream with D kd-levels is
 * prior index i below D * GEO_PER_LEVEL (geometry is level-major and absolute),
 * else i shifted to the connectivity block. */
#define MS_PRIOR_LEVELS (3 * MS_CODEC_MAX_BITS)
#define MS_PRIOR_GEO (MS_PRIOR_LEVELS * GEO_PER_LEVEL)
#define MS_PRIOR_SIZE (MS_PRIOR_GEO + C_TOTAL)

static inline uint32_t ms_prior_index(uint32_t model_index, unsigned D)
{
    uint32_t geo = D * GEO_PER_LEVEL;
    return model_index < geo ? model_index : MS_PRIOR_GEO + (model_index - geo);
}

/* Whether a model index has an entry in the prior (the freeze contexts do not). */
static inline bool ms_prior_has(uint32_t model_index, unsigned D)
{
    return model_index < D * GEO_PER_LEVEL + C_TOTAL;
}

static inline unsigned geo_run(unsigned level, unsigned birth)
{
    unsigned r = level - birth;
    return r < GEO_RUNS ? r : GEO_RUNS - 1;
}

/* Sum of the doubled positions (one column of cen or rep, stride 4) of cell s's
 * neighbours, each counted once per incident simplex; *count receives the
 * number of terms. (The hottest loop of the decoder: cell s's own term taken
 * out once.) */
static inline int64_t geo_sum_col(const ms_complex *cx, uint32_t s, const int32_t *col,
                                  int64_t *count)
{
    const ms_cx_vert *v = &cx->v[s];
    const uint32_t *l = v->cap ? v->ext : v->inl; /* col: position of slot x at col[4 * x] */
    const uint32_t(*tri)[3] = (const uint32_t(*)[3])cx->tri;
    int64_t sum = 0;
    uint32_t edges = 0;
    for (uint32_t i = 0; i < v->n; ++i) {
        uint32_t id = l[i] >> 1;
        if (l[i] & 1) {
            const uint32_t *e = cx->edge[id];
            sum += col[4 * (size_t)(e[0] == s ? e[1] : e[0])];
            edges++;
        } else {
            const uint32_t *t = tri[id];
            sum += col[4 * (size_t)t[0]] + col[4 * (size_t)t[1]] + col[4 * (size_t)t[2]];
        }
    }
    uint32_t tris = v->n - edges;
    sum -= (int64_t)tris * col[4 * (size_t)s];
    *count = 2 * (int64_t)tris + edges;
    return sum;
}

/* geo_sum_col over the neighbours' cell centres along axis. */
static inline int64_t geo_sum(const ms_complex *cx, uint32_t s, int axis, int64_t *count)
{
    return geo_sum_col(cx, s, &cx->cen[0][axis], count);
}

/* Context of the "which half" bit of a cell (width wp along the level's axis,
 * doubled centre plane2 along it: the split plane) from its neighbours'
 * centroid (sum, n): side and distance from the split plane in units of the
 * child cell. */
static inline unsigned geo_bucket(int64_t sum, int64_t n, int64_t wp, int64_t plane2)
{
    if (n == 0)
        return GEO_DIST;
    int64_t diff = sum - n * plane2;
    int64_t unit = n * wp;
    uint64_t a = 8 * (uint64_t)(diff < 0 ? -diff : diff), u = (uint64_t)unit;
    /* m = number of thresholds u * {1, 2, 4, 8, 16, 32} that a reaches: with
     * r = floor(log2(a / u)) from the leading bits, m = min(r + 1, 6) */
    unsigned m = 0;
    if (a >= u) {
        unsigned r = (unsigned)(__builtin_clzll(u) - __builtin_clzll(a));
        r -= a < (u << r);
        m = r < 5 ? r + 1 : 6;
    }
    return diff < 0 ? 6 - m : 7 + m;
}

/* Side of neighbour x relative to the split plane, in 8 buckets. */
static inline unsigned conn_side(const ms_complex *cx, uint32_t x, int axis, int64_t plane2,
                                 int64_t wp)
{
    int64_t d = 2 * (ms_cx_centre2(cx, x, axis) - plane2);
    /* below: 0 (<= -4 wp), 1 (<= -2 wp), 2 (<= -wp), 3; above: 4 (< wp), 5
     * (< 2 wp), 6 (< 4 wp), 7; thresholds counted, not branched on */
    unsigned below = 3 - (unsigned)((d <= -wp) + (d <= -2 * wp) + (d <= -4 * wp));
    unsigned above = 4 + (unsigned)((d >= wp) + (d >= 2 * wp) + (d >= 4 * wp));
    return d < 0 ? below : above;
}

static inline unsigned e12_ctx(uint32_t nn)
{
    return C_E12 + (nn == 0 ? 0 : nn <= 2 ? 1 : nn <= 5 ? 2 : nn <= 8 ? 3 : 4);
}

/* Edge code contexts: the codes already decoded of the partners of x (the
 * neighbours sharing a triangle with it), one flag per kind: 1 (code 1), 2
 * (code 2), 4 (code 3 or 4); ADJS combinations. */
static inline unsigned partner_flag(uint8_t code)
{
    return code == 1 ? 1u : code == 2 ? 2u : 4u;
}

static inline unsigned o4_ctx(int vote)
{
    int a = vote < 0 ? -vote : vote;
    return C_O4 + (a == 0 ? 0 : a == 1 ? 1 : 2);
}

#endif
