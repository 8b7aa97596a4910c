/* A ray against a triangle, for picking and measuring on decoded meshes
 * (meshview's ms_viewer_measure.h, the browser client's ms_web_cast.h).
 *
 * Pure function; thread-safe. */
#ifndef MS_RAY_H
#define MS_RAY_H

#include <stdbool.h>

/* The parameter t where the ray origin + t direction meets triangle (p0, p1,
 * p2), both sides, edges included (a slack of 1e-12 in the barycentric
 * coordinates); false when it misses, runs parallel or a number is not
 * finite. */
bool ms_ray_triangle(const double origin[3], const double direction[3], const double p0[3], const double p1[3],
                     const double p2[3], double *t);

#endif
