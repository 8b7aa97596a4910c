/* The bake's side of the surface error: see ms_nsp_surface.h. */
#include "ms_nsp_surface.h"

#include <math.h>
#include <string.h>

#include "ms_archive.h"
#include "ms_grow.h"

void ms_nsp_error_table(unsigned model_bits, unsigned bits, unsigned lo, unsigned hi, const double *surface,
                        uint8_t *table)
{
    double step = ldexp(1.0, (int)model_bits - (int)bits); /* model steps per stream step */
    double worst = 0; /* model steps, the most of this bit's and every finer one's */
    for (unsigned k = hi - lo + 1; k-- > 0;) {
        unsigned b = lo + k;
        double half_diagonal = 0.5 * sqrt(3.0) * ldexp(1.0, (int)model_bits - (int)b);
        double least = b < model_bits ? MS_NSP_SURFACE_ERROR_FLOOR * half_diagonal : 0;
        if (surface[k] * step > worst)
            worst = surface[k] * step;
        if (least > worst)
            worst = least;
        /* the drawn point and the model's both lie in the kd-cell: the share
         * is at most its diagonal, rounding aside */
        double share = ceil(worst / half_diagonal * MS_ARCHIVE_ERROR_SCALE);
        table[k] = (uint8_t)(share < MS_ARCHIVE_ERROR_MAX ? share : MS_ARCHIVE_ERROR_MAX);
    }
}

void ms_nsp_truth_scale(ms_codec_truth *t, int shift)
{
    for (size_t i = 0; i < 3 * t->n; ++i)
        t->positions[i] = ldexp(t->positions[i], shift);
}

bool ms_nsp_truth_append(ms_codec_truth *points, size_t *cap, const ms_codec_truth *summary)
{
    if (summary->n == 0)
        return true;
    size_t need = points->n + summary->n, cap_positions = *cap, cap_normals = *cap;
    if (!ms_grow((void **)&points->positions, &cap_positions, need, 3 * sizeof *points->positions) ||
        !ms_grow((void **)&points->normals, &cap_normals, need, 3 * sizeof *points->normals))
        return false;
    *cap = cap_positions < cap_normals ? cap_positions : cap_normals;
    memcpy(points->positions + 3 * points->n, summary->positions, 3 * summary->n * sizeof *summary->positions);
    memcpy(points->normals + 3 * points->n, summary->normals, 3 * summary->n * sizeof *summary->normals);
    points->n = need;
    return true;
}
