/* The measured surface error of each precision of a stream (docs/CODEC.md
 * §4.3), taken by the encoder's forward pass at every bit boundary: how far
 * the model's vertices a drawn point stands for lie from the surface drawn
 * through it, along that surface's normal. A cut's selection uses it in place
 * of the kd-cell's half-diagonal, which bounds how far a vertex slides along
 * the surface too, and that costs nothing on screen. The points measured
 * against are the stream's own vertices, or for a stream whose vertices are
 * not the model's (an internal nSP cell's) the summaries its children's
 * encodes gave (ms_codec_truth). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_codec_internal.h"
#include "ms_complex.h"
#include "ms_radix_sort.h"

/* Below this coherence (the length of the summed normals over the sum of
 * their lengths: 1 for a flat patch, 0 for the two sides of a thin sheet) a
 * cluster is no surface patch with one normal, and the whole distance of each
 * point from the drawn point counts. */
#define COHERENT_NORMALS 0.5
/* Below this coherence of its own faces' normals a vertex is sharp (a corner,
 * or on a crease that turns the surface by more than about 80 degrees: two
 * equal faces 83 degrees apart have 0.75): moved along any one of its
 * faces it leaves another, so its whole distance counts, and it carries a zero
 * normal to say so (a lone vertex, with no faces, is sharp too). */
#define SHARP_VERTEX 0.75

void ms_codec_truth_free(ms_codec_truth *t)
{
    free(t->positions);
    free(t->normals);
    memset(t, 0, sizeof *t);
}

static ms_status truth_alloc(ms_codec_truth *t, size_t n, ms_error *err)
{
    memset(t, 0, sizeof *t);
    t->positions = malloc(3 * (n ? n : 1) * sizeof *t->positions);
    t->normals = malloc(3 * (n ? n : 1) * sizeof *t->normals);
    if (!t->positions || !t->normals) {
        ms_codec_truth_free(t);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory measuring the surface error");
    }
    t->n = n;
    return MS_OK;
}

/* The vertices of a full-precision complex as points (their cells' centres)
 * with area-weighted normals (0 for a sharp vertex), in the complex's (sorted)
 * vertex order. */
static ms_status state_points(const ms_codec_state *full, ms_codec_truth *t, ms_error *err)
{
    size_t n = full->vertex_count;
    ms_status s = truth_alloc(t, n, err);
    double *acc = s == MS_OK ? calloc(4 * (n ? n : 1), sizeof *acc) : NULL; /* normal, lengths */
    if (s == MS_OK && !acc) {
        ms_codec_truth_free(t);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory measuring the surface error");
    }
    if (s != MS_OK)
        return s;
    for (size_t i = 0; i < n; ++i) {
        uint32_t c[3];
        ms_quant_unkey(full->cells[i], full->bits, c);
        for (int a = 0; a < 3; ++a)
            t->positions[3 * i + a] = c[a] + 0.5;
    }
    for (size_t k = 0; k < full->tri_count; ++k) {
        const uint32_t *tri = full->tris + 3 * k;
        const double *p0 = t->positions + 3 * tri[0], *p1 = t->positions + 3 * tri[1],
                     *p2 = t->positions + 3 * tri[2];
        double u[3], v[3];
        for (int a = 0; a < 3; ++a)
            u[a] = p1[a] - p0[a], v[a] = p2[a] - p0[a];
        /* twice the area times the unit normal: area-weighted */
        double cross[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double length = sqrt(cross[0] * cross[0] + cross[1] * cross[1] + cross[2] * cross[2]);
        for (int j = 0; j < 3; ++j) {
            for (int a = 0; a < 3; ++a)
                acc[4 * tri[j] + a] += cross[a];
            acc[4 * tri[j] + 3] += length;
        }
    }
    for (size_t i = 0; i < n; ++i) {
        const double *x = acc + 4 * i;
        bool sharp = !(sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) >= SHARP_VERTEX * x[3]) || x[3] == 0;
        for (int a = 0; a < 3; ++a)
            t->normals[3 * i + a] = sharp ? 0.0f : (float)x[a];
    }
    free(acc);
    return MS_OK;
}

/* The given points in key order at `bits` (positions outside the grid count at
 * its border), with their keys; equal keys keep their given order. */
static ms_status sorted_points(const ms_codec_truth *in, unsigned bits, ms_codec_truth *out,
                               uint64_t **keys, ms_error *err)
{
    size_t n = in->n;
    if (n > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%zu points to measure a surface error against", n);
    uint32_t *order = malloc((n ? n : 1) * sizeof *order);
    *keys = malloc((n ? n : 1) * sizeof **keys);
    ms_status s = order && *keys ? truth_alloc(out, n, err)
                                 : ms_error_set(err, MS_ERR_NOMEM, "out of memory measuring the surface error");
    double top = ldexp(1.0, (int)bits) - 1;
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        uint32_t c[3];
        for (int a = 0; a < 3; ++a) {
            double x = floor(in->positions[3 * i + a]);
            c[a] = (uint32_t)(x < 0 ? 0 : x > top ? top : x);
        }
        (*keys)[i] = ms_quant_key(c[0], c[1], c[2], bits);
        order[i] = (uint32_t)i;
    }
    if (s == MS_OK)
        s = ms_radix_sort_pairs(*keys, order, n, bits ? 3 * bits : 1, err);
    if (s != MS_OK) {
        if (order && *keys)
            ms_codec_truth_free(out);
        free(order);
        free(*keys);
        *keys = NULL;
        return s;
    }
    for (size_t i = 0; i < n; ++i) {
        memcpy(out->positions + 3 * i, in->positions + 3 * (size_t)order[i], 3 * sizeof *out->positions);
        memcpy(out->normals + 3 * i, in->normals + 3 * (size_t)order[i], 3 * sizeof *out->normals);
    }
    free(order);
    return MS_OK;
}

ms_status ms_surface_prepare(const ms_codec_state *canon, const ms_codec_truth *given,
                             ms_surface_truth *truth, ms_error *err)
{
    ms_codec_truth own;
    ms_status s = state_points(canon, &own, err);
    if (s != MS_OK)
        return s;
    truth->keys_owned = NULL;
    if (!given) {
        truth->points = own;
        truth->keys = canon->cells;
        return MS_OK;
    }
    ms_codec_truth_free(&own);
    s = sorted_points(given, canon->bits, &truth->points, &truth->keys_owned, err);
    truth->keys = truth->keys_owned;
    return s;
}

void ms_surface_release(ms_surface_truth *truth)
{
    ms_codec_truth_free(&truth->points);
    free(truth->keys_owned);
    truth->keys_owned = NULL;
}

/* The summed normal of points [first, end) and whether they form one patch. */
static bool cluster_normal(const float *normals, size_t first, size_t end, double sum[3], double *length)
{
    double lengths = 0;
    sum[0] = sum[1] = sum[2] = 0;
    for (size_t i = first; i < end; ++i) {
        const float *nv = normals + 3 * i;
        for (int a = 0; a < 3; ++a)
            sum[a] += nv[a];
        lengths += sqrt((double)nv[0] * nv[0] + (double)nv[1] * nv[1] + (double)nv[2] * nv[2]);
    }
    *length = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    return lengths > 0 && *length >= COHERENT_NORMALS * lengths;
}

static bool sharp_point(const float *normal)
{
    return normal[0] == 0 && normal[1] == 0 && normal[2] == 0;
}

/* The error of one cluster: points [first, end) drawn at `drawn` (grid units). */
static double cluster_error(const ms_codec_truth *t, size_t first, size_t end, const double drawn[3])
{
    double sum[3], length;
    bool patch = cluster_normal(t->normals, first, end, sum, &length);
    double worst = 0;
    for (size_t i = first; i < end; ++i) {
        const double *p = t->positions + 3 * i;
        double d[3];
        for (int a = 0; a < 3; ++a)
            d[a] = p[a] - drawn[a];
        double e = patch && !sharp_point(t->normals + 3 * i)
                       ? fabs(d[0] * sum[0] + d[1] * sum[1] + d[2] * sum[2]) / length
                       : sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        if (e > worst)
            worst = e;
    }
    return worst;
}

/* Where a client draws d's vertices now, grid units, 3 per live cell in key
 * order (d->order): the smoothed points below truth->smooth_level (docs/CODEC.md
 * §4.4, as ms_codec_state_smooth gives them from the exported state), else the
 * representative points (twice-points, geometry ahead) or the centres. */
static ms_status drawn_points(const ms_codec_decoder *d, const ms_surface_truth *truth, double *out,
                              ms_error *err)
{
    const ms_complex *cx = &d->cx;
    if (!truth->smooth_rounds || d->level >= truth->smooth_level) {
        int32_t (*at)[4] = cx->rep ? cx->rep : cx->cen;
        for (uint32_t k = 0; k < d->norder; ++k)
            for (int a = 0; a < 3; ++a)
                out[3 * k + a] = 0.5 * at[d->order[k]][a];
        return MS_OK;
    }
    ms_codec_state st;
    ms_status s = ms_codec_decoder_state(d, &st, err);
    if (s == MS_OK)
        s = ms_codec_state_smooth(&st, truth->smooth_rounds, err);
    if (s != MS_OK) {
        ms_codec_state_free(&st);
        return s;
    }
    /* the export keeps d->order's key order: vertex k is live cell order[k] */
    unsigned shift = 3 * st.bits - st.level;
    for (size_t k = 0; k < st.vertex_count && s == MS_OK; ++k)
        if (k >= d->norder || cx->v[d->order[k]].key >> shift != st.cells[k])
            s = ms_error_set(err, MS_ERR_CORRUPT, "surface error: the exported state's vertex %zu is not "
                             "the decoder's", k);
    if (s == MS_OK && st.vertex_count != d->norder)
        s = ms_error_set(err, MS_ERR_CORRUPT, "surface error: %zu exported vertices for %u live cells",
                         st.vertex_count, d->norder);
    for (size_t k = 0; k < st.vertex_count && s == MS_OK; ++k) {
        uint32_t xyz[3];
        ms_quant_unkey(shift >= 64 ? 0 : st.cells[k] << shift, st.bits, xyz);
        for (int a = 0; a < 3; ++a) {
            double width = (double)(1u << (st.bits - (st.level + 2u - (unsigned)a) / 3u));
            out[3 * k + a] = xyz[a] + st.rep[3 * k + a] / 65536.0 * width;
        }
    }
    ms_codec_state_free(&st);
    return s;
}

ms_status ms_surface_error(const ms_codec_decoder *d, const ms_surface_truth *truth, double *error,
                           ms_error *err)
{
    const ms_complex *cx = &d->cx;
    const ms_codec_region *region = d->h.has_region ? &d->h.region : NULL;
    double *drawn = malloc(3 * (d->norder ? d->norder : 1) * sizeof *drawn);
    if (!drawn)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory measuring the surface error");
    ms_status st = drawn_points(d, truth, drawn, err);
    if (st != MS_OK) {
        free(drawn);
        return st;
    }
    unsigned D = 3 * cx->P;
    size_t n = truth->points.n, i = 0;
    double worst = 0;
    /* the live cells (d->order) and the points are both in key order: each
     * cell's points are the run of keys under its prefix */
    for (uint32_t k = 0; k < d->norder && i < n; ++k) {
        uint32_t s = d->order[k];
        unsigned shift = D - ms_cx_level(cx, s);
        uint64_t prefix = shift >= 64 ? 0 : cx->v[s].key >> shift;
        while (i < n && (shift >= 64 ? 0 : truth->keys[i] >> shift) < prefix)
            ++i;
        size_t first = i;
        while (i < n && (shift >= 64 ? 0 : truth->keys[i] >> shift) == prefix)
            ++i;
        if (first == i || (region && cell_outside(cx, region, s)))
            continue; /* a foreign cell is drawn at its owner's point */
        double e = cluster_error(&truth->points, first, i, drawn + 3 * k);
        if (e > worst)
            worst = e;
    }
    free(drawn);
    *error = worst;
    return MS_OK;
}

ms_status ms_surface_measure(ms_codec_decoder *d, const ms_surface_truth *truth, ms_error *err)
{
    for (unsigned L = d->Lmin; L <= d->D; L += 3) {
        ms_status s = ms_codec_decoder_set_level(d, L, err);
        if (s != MS_OK)
            return s;
        s = ms_surface_error(d, truth, &truth->error[(L - d->Lmin) / 3], err);
        if (s != MS_OK)
            return s;
    }
    return MS_OK;
}

/* The points of [first, end) (only the sharp ones, or every one) lowest and
 * highest along dir, into pick: how many (0 when there is none, 1 when they
 * are the same point). */
static int extremes(const ms_codec_truth *t, size_t first, size_t end, const double dir[3], bool sharp_only,
                    size_t pick[2])
{
    size_t lo = end, hi = end;
    double lo_v = INFINITY, hi_v = -INFINITY;
    for (size_t j = first; j < end; ++j) {
        if (sharp_only && !sharp_point(t->normals + 3 * j))
            continue;
        const double *p = t->positions + 3 * j;
        double v = p[0] * dir[0] + p[1] * dir[1] + p[2] * dir[2];
        if (v < lo_v)
            lo_v = v, lo = j;
        if (v > hi_v)
            hi_v = v, hi = j;
    }
    if (lo == end)
        return 0;
    pick[0] = lo, pick[1] = hi;
    return lo == hi ? 1 : 2;
}

ms_status ms_surface_summary(const ms_surface_truth *truth, const ms_codec_state *start, ms_codec_truth *out,
                             ms_error *err)
{
    ms_status s = truth_alloc(out, 4 * start->vertex_count, err);
    if (s != MS_OK)
        return s;
    const ms_codec_truth *t = &truth->points;
    unsigned shift = 3 * start->bits - start->level;
    size_t i = 0, w = 0;
    for (size_t k = 0; k < start->vertex_count; ++k) {
        uint64_t prefix = shift >= 64 ? 0 : start->cells[k];
        while (i < t->n && (shift >= 64 ? 0 : truth->keys[i] >> shift) < prefix)
            ++i;
        size_t first = i;
        while (i < t->n && (shift >= 64 ? 0 : truth->keys[i] >> shift) == prefix)
            ++i;
        if (first == i)
            continue;
        double sum[3], length;
        bool patch = cluster_normal(t->normals, first, i, sum, &length);
        /* the extremes along the summed normal (along x for the two sides of a
         * sheet), sharing it */
        double dir[3] = {1, 0, 0};
        if (patch)
            for (int a = 0; a < 3; ++a)
                dir[a] = sum[a] / length;
        size_t pick[4];
        int picked = extremes(t, first, i, dir, false, pick);
        for (int m = 0; m < picked; ++m, ++w) {
            memcpy(out->positions + 3 * w, t->positions + 3 * pick[m], 3 * sizeof *out->positions);
            for (int a = 0; a < 3; ++a)
                out->normals[3 * w + a] = (float)(sum[a] / picked);
        }
        /* and its sharp points' extremes along their widest axis, sharp still */
        double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
        for (size_t j = first; j < i; ++j)
            for (int a = 0; a < 3 && sharp_point(t->normals + 3 * j); ++a)
                lo[a] = fmin(lo[a], t->positions[3 * j + a]), hi[a] = fmax(hi[a], t->positions[3 * j + a]);
        int axis = hi[1] - lo[1] > hi[0] - lo[0] ? 1 : 0;
        axis = hi[2] - lo[2] > hi[axis] - lo[axis] ? 2 : axis;
        double along[3] = {axis == 0, axis == 1, axis == 2};
        picked = extremes(t, first, i, along, true, pick);
        for (int m = 0; m < picked; ++m, ++w) {
            memcpy(out->positions + 3 * w, t->positions + 3 * pick[m], 3 * sizeof *out->positions);
            memset(out->normals + 3 * w, 0, 3 * sizeof *out->normals);
        }
    }
    out->n = w;
    return MS_OK;
}
