/* The smoothed point of a coarse vertex (docs/CODEC.md §4.4): at a precision
 * where a kd-cell stands for several of the model's vertices, its centre (or
 * geometry ahead's barycentre) is a grid point, and the coarse surface is a
 * staircase. A few rounds of Taubin's lambda|mu smoothing over the state's own
 * triangles, each point kept inside its kd-cell, put the points back on a
 * smooth surface through the cells, at no cost in bytes. Integer arithmetic
 * throughout: the encoder measures the error of exactly the points a client
 * draws, whatever order either holds the vertices in. */
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_quant.h"

/* One round: a step towards the neighbours' mean by LAMBDA / 256, then one
 * away from it by MU / 256 (Taubin: lambda 0.63, mu -0.67; the pair keeps a
 * curved surface from shrinking). */
#define LAMBDA 161
#define MU (-172)
/* Units of a point along an axis: 1/65536 of a kd-cell's width (rep's unit). */
#define CELL_UNITS 65536
/* A vertex with more neighbour entries than this keeps its point: its sum of
 * positions (each < 2^37 units) stays far inside 64 bits. */
#define MAX_NEIGHBOURS (1u << 24)

static int64_t floor_div(int64_t v, int64_t d)
{
    int64_t q = v / d;
    return (v % d != 0 && (v < 0) != (d < 0)) ? q - 1 : q;
}

/* The neighbours of every vertex through the triangles, in compressed rows:
 * (*start)[i] .. (*start)[i + 1] in *items; an interior edge counts twice. */
static ms_status neighbour_rows(const ms_codec_state *s, uint32_t **start, uint32_t **items, ms_error *err)
{
    size_t n = s->vertex_count;
    *start = calloc(n + 1, sizeof **start);
    *items = malloc((6 * s->tri_count + 1) * sizeof **items);
    uint32_t *fill = calloc(n + 1, sizeof *fill);
    if (!*start || !*items || !fill) {
        free(*start), free(*items), free(fill);
        *start = *items = NULL;
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory smoothing a state");
    }
    for (size_t t = 0; t < 3 * s->tri_count; ++t)
        (*start)[s->tris[t] + 1] += 2;
    for (size_t i = 0; i < n; ++i)
        (*start)[i + 1] += (*start)[i];
    for (size_t t = 0; t < s->tri_count; ++t)
        for (int j = 0; j < 3; ++j) {
            uint32_t v = s->tris[3 * t + j];
            (*items)[(*start)[v] + fill[v]++] = s->tris[3 * t + (j + 1) % 3];
            (*items)[(*start)[v] + fill[v]++] = s->tris[3 * t + (j + 2) % 3];
        }
    free(fill);
    return MS_OK;
}

/* The smoothing's arrays, per vertex: its cell's index along each axis, the
 * sum of its neighbour entries' cell indices (fixed while the points move),
 * and its point's offset inside its cell, now and after the step. A point is
 * cell * CELL_UNITS + offset; the offsets are all a step reads of the
 * neighbours (6 bytes each rather than 24: the step waits on these loads). */
typedef struct smooth_arrays {
    const uint32_t *start, *items;
    uint32_t *cell;    /* below 2^21 */
    int64_t *cell_sum;
    uint16_t *off, *next;
} smooth_arrays;

/* One Jacobi step of weight w / 256 from a->off into a->next, each point
 * clamped to its cell. The rounded mean of the neighbours is exact: every
 * point is >= 0, and a sum stays below 2^62 (at most 2^24 entries of points
 * below 2^37). */
static void smooth_step(size_t n, const smooth_arrays *a, int w)
{
    for (size_t i = 0; i < n; ++i) {
        uint32_t first = a->start[i], deg = a->start[i + 1] - first;
        const uint16_t *p = &a->off[3 * i];
        uint16_t *q = &a->next[3 * i];
        if (deg == 0 || deg > MAX_NEIGHBOURS) {
            q[0] = p[0], q[1] = p[1], q[2] = p[2];
            continue;
        }
        uint64_t sum[3] = {0, 0, 0};
        for (uint32_t k = first; k < first + deg; ++k) {
            const uint16_t *y = &a->off[3 * (size_t)a->items[k]];
            sum[0] += y[0];
            sum[1] += y[1];
            sum[2] += y[2];
        }
        for (int c = 0; c < 3; ++c) {
            uint64_t total = (uint64_t)a->cell_sum[3 * i + c] * CELL_UNITS + sum[c];
            int64_t mean = (int64_t)((2 * total + deg) / (2 * (uint64_t)deg)); /* rounded */
            int64_t lo = (int64_t)a->cell[3 * i + c] * CELL_UNITS, x = lo + p[c];
            x += floor_div((mean - x) * w, 256);
            q[c] = (uint16_t)(x < lo ? 0 : x > lo + CELL_UNITS - 1 ? CELL_UNITS - 1 : x - lo);
        }
    }
}

ms_status ms_codec_state_smooth(ms_codec_state *s, unsigned rounds, ms_error *err)
{
    size_t n = s->vertex_count;
    if (rounds == 0 || n == 0)
        return MS_OK;
    if (rounds > MS_CODEC_SMOOTH_ROUNDS_MAX || s->bits > 21 || s->level > 3 * s->bits)
        return ms_error_set(err, MS_ERR_ARG, "smoothing: %u rounds, kd-level %u of %u bits (at most "
                            "%u rounds, 21 bits)", rounds, s->level, s->bits, MS_CODEC_SMOOTH_ROUNDS_MAX);
    if (s->tri_count > UINT32_MAX / 6 || n > UINT32_MAX)
        return ms_error_set(err, MS_ERR_ARG, "smoothing: %zu triangles, %zu vertices", s->tri_count, n);
    for (size_t t = 0; t < 3 * s->tri_count; ++t)
        if (s->tris[t] >= n)
            return ms_error_set(err, MS_ERR_CORRUPT, "smoothing: a triangle names vertex %u of %zu",
                                s->tris[t], n);
    uint32_t *start, *items;
    ms_status st = neighbour_rows(s, &start, &items, err);
    if (st != MS_OK)
        return st;
    smooth_arrays a = {.start = start, .items = items};
    a.cell = malloc(3 * n * sizeof *a.cell);
    a.cell_sum = calloc(3 * n, sizeof *a.cell_sum);
    a.off = malloc(3 * n * sizeof *a.off);
    a.next = malloc(3 * n * sizeof *a.next);
    if (!a.cell || !a.cell_sum || !a.off || !a.next) {
        free(start), free(items), free(a.cell), free(a.cell_sum), free(a.off), free(a.next);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory smoothing a state");
    }
    /* each point in units of its cell's width: its cell's index along the axis
     * (every vertex of a state shares its level, so the widths are equal) */
    unsigned shift = 3 * s->bits - s->level;
    for (size_t i = 0; i < n; ++i) {
        uint32_t xyz[3];
        ms_quant_unkey(shift >= 64 ? 0 : s->cells[i] << shift, s->bits, xyz);
        for (int c = 0; c < 3; ++c) {
            unsigned cut = (s->level + 2u - (unsigned)c) / 3u; /* times axis c is halved */
            a.cell[3 * i + c] = xyz[c] >> (s->bits - cut);
            a.off[3 * i + c] = s->rep ? s->rep[3 * i + c] : CELL_UNITS / 2;
        }
    }
    for (size_t i = 0; i < n; ++i)
        for (uint32_t k = start[i]; k < start[i + 1]; ++k)
            for (int c = 0; c < 3; ++c)
                a.cell_sum[3 * i + c] += a.cell[3 * (size_t)items[k] + c];
    for (unsigned r = 0; r < rounds; ++r) {
        smooth_step(n, &a, LAMBDA);
        uint16_t *t = a.off;
        a.off = a.next, a.next = t;
        smooth_step(n, &a, MU);
        t = a.off;
        a.off = a.next, a.next = t;
    }
    free(s->rep);
    s->rep = a.off;
    free(start), free(items), free(a.cell), free(a.cell_sum), free(a.next);
    return MS_OK;
}
