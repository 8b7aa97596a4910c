/* Ray casts on a stitched cut: see ms_web_cast.h. */
#include "ms_web_cast.h"

#include <math.h>

#include "ms_ray.h"

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
        if (!ms_ray_triangle(origin, direction, &m->positions[3 * c[0]], &m->positions[3 * c[1]], &m->positions[3 * c[2]],
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
