/* Meshes in an APO cube's frame (see ms_apo_local_mesh.h). */
#include "ms_apo_local_mesh.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Plain comparisons (fminf/fmaxf are library calls here); coordinates are
 * checked finite before they get here. */

void ms_apo_local_mesh_free(ms_apo_local_mesh *lm)
{
    free(lm->pos);
    free(lm->fnormal);
    free(lm->area);
    free(lm->vnormal);
    memset(lm, 0, sizeof *lm);
}

ms_status ms_apo_local_mesh_make(const ms_mesh *mesh, const double origin[3], double size, const char *name,
                                 ms_apo_local_mesh *lm, ms_error *err)
{
    memset(lm, 0, sizeof *lm);
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    if (nv > UINT32_MAX || nt > UINT32_MAX / 3)
        return ms_error_set(err, MS_ERR_ARG, "apo build: %s is too large", name);
    lm->vertex_count = nv;
    lm->triangle_count = nt;
    lm->tri = mesh->triangles;
    lm->pos = malloc((3 * nv + 1) * sizeof *lm->pos);
    lm->fnormal = malloc((3 * nt + 1) * sizeof *lm->fnormal);
    lm->area = malloc((nt + 1) * sizeof *lm->area);
    double *acc = calloc(3 * nv + 1, sizeof *acc); /* area-weighted vertex normal sums */
    lm->vnormal = malloc((3 * nv + 1) * sizeof *lm->vnormal);
    if (!lm->pos || !lm->fnormal || !lm->area || !lm->vnormal || !acc) {
        free(acc);
        ms_apo_local_mesh_free(lm);
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for %s", name);
    }
    lm->pos[3 * nv] = 0.0f; /* the padding Embree's 16-byte loads read past the last vertex */
    double inv = 1.0 / size;
    for (size_t i = 0; i < nv; ++i)
        for (int a = 0; a < 3; ++a) {
            double p = mesh->positions[3 * i + a];
            if (!isfinite(p)) {
                free(acc);
                ms_apo_local_mesh_free(lm);
                return ms_error_set(err, MS_ERR_RANGE, "apo build: %s vertex %zu is not finite", name, i);
            }
            lm->pos[3 * i + a] = (float)((p - origin[a]) * inv);
        }
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t *v = &mesh->triangles[3 * t];
        if (v[0] >= nv || v[1] >= nv || v[2] >= nv) {
            free(acc);
            ms_apo_local_mesh_free(lm);
            return ms_error_set(err, MS_ERR_ARG, "apo build: %s triangle %zu has a bad vertex index", name, t);
        }
        const float *p0 = &lm->pos[3 * v[0]], *p1 = &lm->pos[3 * v[1]], *p2 = &lm->pos[3 * v[2]];
        double e1[3], e2[3];
        for (int a = 0; a < 3; ++a) {
            e1[a] = (double)p1[a] - p0[a];
            e2[a] = (double)p2[a] - p0[a];
        }
        double c[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double len = sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
        lm->area[t] = (float)(0.5 * len);
        for (int a = 0; a < 3; ++a) {
            lm->fnormal[3 * t + a] = len > 0.0 ? (float)(c[a] / len) : 0.0f;
            for (int k = 0; k < 3; ++k)
                acc[3 * v[k] + a] += c[a]; /* area-weighted (|c| = 2 area) */
        }
    }
    for (size_t i = 0; i < nv; ++i) {
        double *s = &acc[3 * i];
        double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
        for (int a = 0; a < 3; ++a)
            lm->vnormal[3 * i + a] = len > 0.0 ? (float)(s[a] / len) : 0.0f;
    }
    free(acc);
    return MS_OK;
}


void ms_apo_local_mesh_normal_at(const ms_apo_local_mesh *lm, uint32_t t, float u, float v, double out[3])
{
    const uint32_t *i = &lm->tri[3 * t];
    double w0 = 1.0 - u - v, len2 = 0;
    for (int a = 0; a < 3; ++a) {
        out[a] = w0 * lm->vnormal[3 * i[0] + a] + u * lm->vnormal[3 * i[1] + a] + v * lm->vnormal[3 * i[2] + a];
        len2 += out[a] * out[a];
    }
    if (len2 > 1e-24) {
        double len = sqrt(len2);
        for (int a = 0; a < 3; ++a)
            out[a] /= len;
    } else {
        for (int a = 0; a < 3; ++a)
            out[a] = lm->fnormal[3 * t + a];
    }
}

double ms_apo_crowding(const ms_apo_local_mesh *big)
{
    double boxes = 0.0, area = 0.0;
    for (size_t t = 0; t < big->triangle_count; ++t) {
        const uint32_t *v = &big->tri[3 * t];
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            float p0 = big->pos[3 * v[0] + a], p1 = big->pos[3 * v[1] + a], p2 = big->pos[3 * v[2] + a];
            float lo = p0 < p1 ? p0 : p1, hi = p0 > p1 ? p0 : p1;
            lo = p2 < lo ? p2 : lo;
            hi = p2 > hi ? p2 : hi;
            d2 += ((double)hi - lo) * ((double)hi - lo);
        }
        boxes += d2;
        area += big->area[t];
    }
    return area > 0.0 ? boxes / area : 0.0;
}
