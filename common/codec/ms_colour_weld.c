/* The colours of welded vertices (ms_colour_weld, ms_colour.h): the rounded
 * mean of the input vertices that share a grid point. */
#include "ms_colour.h"

#include <stdlib.h>
#include <string.h>

ms_status ms_colour_weld(const ms_mesh *mesh, const ms_qmesh *q, uint8_t **rgba, ms_error *err)
{
    *rgba = NULL;
    if (!mesh->colours)
        return ms_error_set(err, MS_ERR_ARG, "colour weld: the mesh has no colours");
    size_t V = q->vertex_count;
    uint64_t *keys = malloc((V ? V : 1) * sizeof *keys);
    uint64_t *sum = calloc(5 * (V ? V : 1), sizeof *sum); /* r g b a, count */
    if (!keys || !sum) {
        free(keys);
        free(sum);
        return ms_error_set(err, MS_ERR_NOMEM, "colour weld: out of memory");
    }
    for (size_t i = 0; i < V; ++i)
        keys[i] = ms_quant_key(q->coords[3 * i], q->coords[3 * i + 1], q->coords[3 * i + 2],
                               q->bits);
    ms_status st = MS_OK;
    for (size_t v = 0; v < mesh->vertex_count && st == MS_OK; ++v) {
        uint32_t c[3];
        for (int a = 0; a < 3; ++a)
            c[a] = ms_quantise(&q->box, q->bits, a, mesh->positions[3 * v + (unsigned)a]);
        uint64_t key = ms_quant_key(c[0], c[1], c[2], q->bits);
        size_t lo = 0, hi = V;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (keys[mid] < key)
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo == V || keys[lo] != key) {
            st = ms_error_set(err, MS_ERR_ARG, "colour weld: input vertex %zu is not a welded "
                              "vertex of the quantised mesh", v);
            break;
        }
        for (int k = 0; k < 4; ++k)
            sum[5 * lo + (unsigned)k] += mesh->colours[4 * v + (unsigned)k];
        sum[5 * lo + 4]++;
    }
    uint8_t *out = st == MS_OK ? malloc(4 * (V ? V : 1)) : NULL;
    if (st == MS_OK && !out)
        st = ms_error_set(err, MS_ERR_NOMEM, "colour weld: out of memory");
    for (size_t i = 0; st == MS_OK && i < V; ++i) {
        uint64_t n = sum[5 * i + 4];
        for (int k = 0; k < 4; ++k)
            out[4 * i + (unsigned)k] =
                n ? (uint8_t)((2 * sum[5 * i + (unsigned)k] + n) / (2 * n)) : 255;
    }
    free(keys);
    free(sum);
    if (st == MS_OK)
        *rgba = out;
    else
        free(out);
    return st;
}
