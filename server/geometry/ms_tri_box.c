/* Triangle / cube overlap: the 13 separating axes (3 cube normals, the triangle
 * normal, and the 9 cross products of triangle edges with the cube axes). On an
 * edge's axis the edge's two corners project to the same value, so only two
 * projections are needed per edge axis. */
#include "ms_tri_box.h"

#include <math.h>

static inline float min_f(float a, float b) { return a < b ? a : b; }
static inline float max_f(float a, float b) { return a > b ? a : b; }

/* True when the interval of the two projections p, q misses [-r, r]. */
static inline bool apart(float p, float q, float r) { return min_f(p, q) > r || max_f(p, q) < -r; }

/* The three cube-axis cross products of edge e, tested with corners s and t (one
 * on the edge, the other off it). */
static inline bool edge_separates(const float e[3], const float s[3], const float t[3], float half)
{
    float ax = fabsf(e[0]), ay = fabsf(e[1]), az = fabsf(e[2]);
    /* x-axis x e = (0, -e.z, e.y) */
    if (apart(e[2] * s[1] - e[1] * s[2], e[2] * t[1] - e[1] * t[2], half * (az + ay)))
        return true;
    /* y-axis x e = (e.z, 0, -e.x) */
    if (apart(e[0] * s[2] - e[2] * s[0], e[0] * t[2] - e[2] * t[0], half * (az + ax)))
        return true;
    /* z-axis x e = (-e.y, e.x, 0) */
    return apart(e[1] * s[0] - e[0] * s[1], e[1] * t[0] - e[0] * t[1], half * (ay + ax));
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
    float e0[3], e1[3], e2[3];
    for (int k = 0; k < 3; ++k) {
        e0[k] = v1[k] - v0[k];
        e1[k] = v2[k] - v1[k];
        e2[k] = v0[k] - v2[k];
    }
    /* The triangle's plane. */
    float n[3] = {e0[1] * e1[2] - e0[2] * e1[1], e0[2] * e1[0] - e0[0] * e1[2], e0[0] * e1[1] - e0[1] * e1[0]};
    float d = n[0] * v0[0] + n[1] * v0[1] + n[2] * v0[2];
    if (fabsf(d) > half * (fabsf(n[0]) + fabsf(n[1]) + fabsf(n[2])))
        return false;
    /* Edge v0-v1 (v2 off it), edge v1-v2 (v0 off it), edge v2-v0 (v1 off it). */
    return !edge_separates(e0, v0, v2, half) && !edge_separates(e1, v1, v0, half) &&
           !edge_separates(e2, v2, v1, half);
}
