/* Three-component double vectors (positions, directions, normals) as plain
 * arrays: the products and the normalisation the camera, the renderers and the
 * study share. Pure functions; thread-safe. */
#ifndef MS_VEC3_H
#define MS_VEC3_H

#include <math.h>
#include <stdbool.h>

static inline double ms_vec3_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* out = a x b (out must not alias a or b). */
static inline void ms_vec3_cross(const double a[3], const double b[3], double out[3])
{
    out[0] = a[1] * b[2] - a[2] * b[1];
    out[1] = a[2] * b[0] - a[0] * b[2];
    out[2] = a[0] * b[1] - a[1] * b[0];
}

/* Scales v to unit length in place; false (v unchanged) when its length is not a
 * finite number above 1e-300. */
static inline bool ms_vec3_normalise(double v[3])
{
    double len = sqrt(ms_vec3_dot(v, v));
    if (!(len > 1e-300) || !isfinite(len))
        return false;
    for (int i = 0; i < 3; ++i)
        v[i] /= len;
    return true;
}

#endif
