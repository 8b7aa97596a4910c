/* Ray casts on a stitched cut: see ms_web_cast.h. */
#include "ms_web_cast.h"

#include <math.h>

#include "ms_ray.h"
#include "ms_section.h"

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
        if (ms_section_cuts_away(planes, count, x))
            continue;
        best = fabs(t - t_near);
        *t_out = t;
        *triangle = i;
        found = true;
    }
    return found;
}
