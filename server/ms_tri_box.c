/* Triangle / cube overlap: the 13 separating axes (3 cube normals, the triangle
 * normal, and the 9 cross products of triangle edges with the cube axes). */
#include "ms_tri_box.h"

#include <math.h>

/* Plain comparisons (fminf/fmaxf are library calls here, and NaN never
 * reaches them: coordinates are checked finite first). */
static inline float min_f(float a, float b) { return a < b ? a : b; }
static inline float max_f(float a, float b) { return a > b ? a : b; }

static float dot3(const float a[3], const float b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

/* True when the projections of the triangle on `axis` miss [-r, r]. */
static bool separated(const float axis[3], float half, const float v0[3], const float v1[3], const float v2[3])
{
    float p0 = dot3(axis, v0), p1 = dot3(axis, v1), p2 = dot3(axis, v2);
    float lo = min_f(p0, min_f(p1, p2)), hi = max_f(p0, max_f(p1, p2));
    float r = half * (fabsf(axis[0]) + fabsf(axis[1]) + fabsf(axis[2]));
    return lo > r || hi < -r;
}

bool ms_tri_cube_overlap(const float centre[3], float half, const float a[3], const float b[3], const float c[3])
{
    float v0[3], v1[3], v2[3];
    for (int k = 0; k < 3; ++k) {
        v0[k] = a[k] - centre[k];
        v1[k] = b[k] - centre[k];
        v2[k] = c[k] - centre[k];
        float lo = min_f(v0[k], min_f(v1[k], v2[k])), hi = max_f(v0[k], max_f(v1[k], v2[k]));
        if (lo > half || hi < -half)
            return false;
    }
    float e[3][3];
    for (int k = 0; k < 3; ++k) {
        e[0][k] = v1[k] - v0[k];
        e[1][k] = v2[k] - v1[k];
        e[2][k] = v0[k] - v2[k];
    }
    float n[3] = {e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
                  e[0][0] * e[1][1] - e[0][1] * e[1][0]};
    if (separated(n, half, v0, v1, v2))
        return false;
    for (int i = 0; i < 3; ++i) {
        const float *d = e[i];
        float ax[3][3] = {{0.0f, d[2], -d[1]}, {-d[2], 0.0f, d[0]}, {d[1], -d[0], 0.0f}};
        for (int k = 0; k < 3; ++k)
            if (separated(ax[k], half, v0, v1, v2))
                return false;
    }
    return true;
}
