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
 * positions (each < 2^36 units) stays far inside 64 bits. */
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

/* One Jacobi step of weight w / 256 from pos into next, clamped to each cell. */
static void smooth_step(const ms_codec_state *s, const uint32_t *start, const uint32_t *items,
                        const int64_t *pos, const int64_t *cell, int w, int64_t *next)
{
    for (size_t i = 0; i < s->vertex_count; ++i) {
        uint32_t deg = start[i + 1] - start[i];
        for (int a = 0; a < 3; ++a) {
            int64_t x = pos[3 * i + a];
            if (deg > 0 && deg <= MAX_NEIGHBOURS) {
                int64_t sum = 0;
                for (uint32_t k = start[i]; k < start[i + 1]; ++k)
                    sum += pos[3 * items[k] + a];
                int64_t mean = floor_div(2 * sum + deg, 2 * (int64_t)deg); /* rounded */
                x += floor_div((mean - x) * w, 256);
                int64_t lo = cell[3 * i + a] * CELL_UNITS;
                x = x < lo ? lo : x > lo + CELL_UNITS - 1 ? lo + CELL_UNITS - 1 : x;
            }
            next[3 * i + a] = x;
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
    int64_t *pos = malloc(3 * n * sizeof *pos), *next = malloc(3 * n * sizeof *next);
    int64_t *cell = malloc(3 * n * sizeof *cell);
    uint16_t *rep = s->rep ? s->rep : malloc(3 * n * sizeof *rep);
    if (!pos || !next || !cell || !rep) {
        free(start), free(items), free(pos), free(next), free(cell);
        if (rep != s->rep)
            free(rep);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory smoothing a state");
    }
    /* each point in units of its cell's width: its cell's index along the axis
     * (every vertex of a state shares its level, so the widths are equal) */
    unsigned shift = 3 * s->bits - s->level;
    for (size_t i = 0; i < n; ++i) {
        uint32_t xyz[3];
        ms_quant_unkey(shift >= 64 ? 0 : s->cells[i] << shift, s->bits, xyz);
        for (int a = 0; a < 3; ++a) {
            unsigned cut = (s->level + 2u - (unsigned)a) / 3u; /* times axis a is halved */
            cell[3 * i + a] = xyz[a] >> (s->bits - cut);
            pos[3 * i + a] = cell[3 * i + a] * CELL_UNITS + (s->rep ? s->rep[3 * i + a] : CELL_UNITS / 2);
        }
    }
    for (unsigned r = 0; r < rounds; ++r) {
        smooth_step(s, start, items, pos, cell, LAMBDA, next);
        smooth_step(s, start, items, next, cell, MU, pos);
    }
    for (size_t i = 0; i < 3 * n; ++i)
        rep[i] = (uint16_t)(pos[i] - cell[i] * CELL_UNITS);
    s->rep = rep;
    free(start), free(items), free(pos), free(next), free(cell);
    return MS_OK;
}
