/* Ray casts on a stitched cut: see ms_web_cast.h. */
#include "ms_web_cast.h"

#include <math.h>

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* The ray's parameter where it meets the triangle (barycentric coordinates
 * from the edge cross products), both sides, edges included; false when it
 * misses or runs parallel. */
static bool meets(const double o[3], const double d[3], const double *p0, const double *p1, const double *p2,
                  double *t)
{
    double e1[3], e2[3], s[3], p[3], q[3];
    for (int a = 0; a < 3; ++a)
        e1[a] = p1[a] - p0[a], e2[a] = p2[a] - p0[a], s[a] = o[a] - p0[a];
    cross3(d, e2, p);
    double det = dot3(e1, p);
    if (det == 0 || !isfinite(det))
        return false;
    double inv = 1.0 / det, slack = 1e-12;
    double u = dot3(s, p) * inv;
    if (u < -slack || u > 1 + slack)
        return false;
    cross3(s, e1, q);
    double v = dot3(d, q) * inv;
    if (v < -slack || u + v > 1 + slack)
        return false;
    *t = dot3(e2, q) * inv;
    return isfinite(*t);
}

static bool cut_away(const double x[3], const double (*planes)[4], size_t count)
{
    for (size_t k = 0; k < count; ++k)
        if (planes[k][0] * x[0] + planes[k][1] * x[1] + planes[k][2] * x[2] + planes[k][3] > 0)
            return true;
    return false;
}

bool ms_web_cast(const ms_view_mesh *m, const double origin[3], const double direction[3], double t_min,
                 double t_near, const double (*planes)[4], size_t count, double *t_out, size_t *triangle)
{
    double best = INFINITY;
    bool found = false;
    for (size_t i = 0; i < m->triangle_count; ++i) {
        const uint32_t *c = &m->triangles[3 * i];
        if (c[0] >= m->vertex_count || c[1] >= m->vertex_count || c[2] >= m->vertex_count)
            continue;
        double t;
        if (!meets(origin, direction, &m->positions[3 * c[0]], &m->positions[3 * c[1]], &m->positions[3 * c[2]],
                   &t) ||
            t < t_min || !(fabs(t - t_near) < best))
            continue;
        double x[3] = {origin[0] + t * direction[0], origin[1] + t * direction[1], origin[2] + t * direction[2]};
        if (cut_away(x, planes, count))
            continue;
        best = fabs(t - t_near);
        *t_out = t;
        *triangle = i;
        found = true;
    }
    return found;
}
