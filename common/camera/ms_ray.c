/* A ray against a triangle: see ms_ray.h. */
#include "ms_ray.h"

#include <math.h>

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void cross3(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Moller-Trumbore: barycentric coordinates from the edges' cross products. */
bool ms_ray_triangle(const double o[3], const double d[3], const double p0[3], const double p1[3],
                     const double p2[3], double *t)
{
    double e1[3], e2[3], tv[3], pv[3], qv[3];
    for (int a = 0; a < 3; ++a)
        e1[a] = p1[a] - p0[a], e2[a] = p2[a] - p0[a], tv[a] = o[a] - p0[a];
    cross3(d, e2, pv);
    double det = dot3(e1, pv);
    if (det == 0 || !isfinite(det))
        return false;
    double inv = 1.0 / det, slack = 1e-12;
    double u = dot3(tv, pv) * inv;
    if (u < -slack || u > 1 + slack)
        return false;
    cross3(tv, e1, qv);
    double v = dot3(d, qv) * inv;
    if (v < -slack || u + v > 1 + slack)
        return false;
    *t = dot3(e2, qv) * inv;
    return isfinite(*t);
}
