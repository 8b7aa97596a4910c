/* Meshes in an APO cube's frame (see ms_apo_local_mesh.h). */
#include "ms_apo_local_mesh.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

/* Plain comparisons (fminf/fmaxf are library calls here); coordinates are
 * checked finite before they get here. */

void ms_apo_local_mesh_free(ms_apo_local_mesh *lm)
{
    free(lm->pos);
    free(lm->fnormal);
    free(lm->area);
    free(lm->box);
    free(lm->vnormal);
    free(lm->cnormal);
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
    lm->box = malloc((6 * nt + 1) * sizeof *lm->box);
    double *acc = calloc(3 * nv + 1, sizeof *acc); /* area-weighted vertex normal sums */
    lm->vnormal = malloc((3 * nv + 1) * sizeof *lm->vnormal);
    if (!lm->pos || !lm->fnormal || !lm->area || !lm->box || !lm->vnormal || !acc) {
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
        float *b = &lm->box[6 * t];
        for (int a = 0; a < 3; ++a) {
            e1[a] = (double)p1[a] - p0[a];
            e2[a] = (double)p2[a] - p0[a];
            float lo = p1[a] < p2[a] ? p1[a] : p2[a], hi = p1[a] > p2[a] ? p1[a] : p2[a];
            b[a] = p0[a] < lo ? p0[a] : lo;
            b[3 + a] = p0[a] > hi ? p0[a] : hi;
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

/* How far triangle t's normal may be off (radians) with corners up to e away. */
static double slack_of(const ms_apo_local_mesh *lm, uint32_t t, double e)
{
    if (!(e > 0.0))
        return 0.0;
    const uint32_t *v = &lm->tri[3 * t];
    double longest = 0.0;
    for (int k = 0; k < 3; ++k) {
        const float *a = &lm->pos[3 * v[k]], *b = &lm->pos[3 * v[(k + 1) % 3]];
        double d2 = 0.0;
        for (int c = 0; c < 3; ++c)
            d2 += ((double)a[c] - b[c]) * ((double)a[c] - b[c]);
        if (d2 > longest)
            longest = d2;
    }
    return atan2(e * sqrt(longest), 4.0 * (double)lm->area[t]); /* height = 2 area / longest */
}

#define MS_APO_CORNER_GROUPS 16

ms_status ms_apo_local_mesh_corner_normals(ms_apo_local_mesh *lm, double crease, double vertex_error, ms_error *err)
{
    size_t nv = lm->vertex_count, nt = lm->triangle_count;
    free(lm->cnormal);
    lm->cnormal = malloc((9 * nt + 1) * sizeof *lm->cnormal);
    uint32_t *start = calloc(nv + 2, sizeof *start);
    uint32_t *fan = malloc((3 * nt + 1) * sizeof *fan);
    double *slack = malloc((nt + 1) * sizeof *slack);
    if (!lm->cnormal || !start || !fan || !slack) {
        free(start);
        free(fan);
        free(slack);
        free(lm->cnormal);
        lm->cnormal = NULL;
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for m's corner normals");
    }
    for (size_t t = 0; t < nt; ++t) {
        slack[t] = slack_of(lm, (uint32_t)t, vertex_error);
        for (int k = 0; k < 3; ++k)
            start[lm->tri[3 * t + k] + 2]++;
    }
    for (size_t i = 0; i < nv; ++i)
        start[i + 2] += start[i + 1];
    for (size_t t = 0; t < nt; ++t)
        for (int k = 0; k < 3; ++k)
            fan[start[lm->tri[3 * t + k] + 1]++] = (uint32_t)(3 * t + (size_t)k); /* corners, by vertex */
    const double cos_crease = cos(crease);
    for (size_t i = 0; i < nv; ++i) {
        uint32_t rep[MS_APO_CORNER_GROUPS];
        double sum[MS_APO_CORNER_GROUPS][3];
        size_t groups = 0;
        for (uint32_t c = start[i]; c < start[i + 1]; ++c) {
            uint32_t corner = fan[c], t = corner / 3;
            if (!(lm->area[t] > 0.0f)) { /* no normal: joins group 0 below, adds nothing */
                lm->cnormal[3 * corner] = -1.0f;
                continue;
            }
            const float *n = &lm->fnormal[3 * t];
            double w = 2.0 * lm->area[t];
            size_t g = groups, nearest = 0;
            double sign = 1.0, best = -2.0;
            for (size_t k = 0; k < groups; ++k) {
                const float *r = &lm->fnormal[3 * rep[k]];
                double cosine = (double)n[0] * r[0] + (double)n[1] * r[1] + (double)n[2] * r[2];
                double limit = crease + slack[t] + slack[rep[k]];
                /* within the crease itself: within the limit (cos, correctly
                 * rounded, decreases on [0, pi]), without its cosine */
                if (limit >= M_PI || (fabs(cosine) >= cos_crease && limit >= crease) ||
                    fabs(cosine) >= cos(limit)) {
                    g = k;
                    sign = cosine < 0.0 ? -1.0 : 1.0;
                    break;
                }
                if (fabs(cosine) > best) {
                    best = fabs(cosine);
                    nearest = k;
                    sign = cosine < 0.0 ? -1.0 : 1.0;
                }
            }
            if (g == groups && groups == MS_APO_CORNER_GROUPS)
                g = nearest;
            else if (g == groups) {
                rep[groups] = t;
                sum[groups][0] = sum[groups][1] = sum[groups][2] = 0.0;
                sign = 1.0;
                ++groups;
            }
            for (int a = 0; a < 3; ++a)
                sum[g][a] += sign * w * n[a];
            /* remember the group and the side in the output slot for now */
            lm->cnormal[3 * corner] = (float)g;
            lm->cnormal[3 * corner + 1] = (float)sign;
        }
        for (uint32_t c = start[i]; c < start[i + 1]; ++c) {
            uint32_t corner = fan[c];
            if (lm->cnormal[3 * corner] < 0.0f && groups == 0) {
                lm->cnormal[3 * corner] = lm->cnormal[3 * corner + 1] = lm->cnormal[3 * corner + 2] = 0.0f;
                continue;
            }
            bool degenerate = lm->cnormal[3 * corner] < 0.0f;
            size_t g = degenerate ? 0 : (size_t)lm->cnormal[3 * corner];
            double sign = degenerate ? 1.0 : lm->cnormal[3 * corner + 1];
            double len = sqrt(sum[g][0] * sum[g][0] + sum[g][1] * sum[g][1] + sum[g][2] * sum[g][2]);
            for (int a = 0; a < 3; ++a)
                lm->cnormal[3 * corner + a] = len > 0.0 ? (float)(sign * sum[g][a] / len) : 0.0f;
        }
    }
    free(start);
    free(fan);
    free(slack);
    return MS_OK;
}

void ms_apo_local_mesh_smooth_at(const ms_apo_local_mesh *lm, uint32_t t, float u, float v, double out[3])
{
    if (!lm->cnormal) {
        ms_apo_local_mesh_normal_at(lm, t, u, v, out);
        return;
    }
    const float *c = &lm->cnormal[9 * (size_t)t];
    double w0 = 1.0 - u - v, len2 = 0;
    for (int a = 0; a < 3; ++a) {
        out[a] = w0 * c[a] + u * c[3 + a] + v * c[6 + a];
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
