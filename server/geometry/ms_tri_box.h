/* Exact-enough triangle / axis-aligned cube overlap by separating axes.
 *
 * Closed sets: a triangle that only touches the cube (on a face, edge or corner)
 * overlaps it. Single-precision arithmetic on coordinates relative to the cube's
 * centre; cubes in the APO builder have dyadic centres and half-widths, so the
 * translation is exact and rounding only affects near-touching cases. Pure
 * function, thread-safe.
 */
#ifndef MS_TRI_BOX_H
#define MS_TRI_BOX_H

#include <stdbool.h>

/* centre: cube centre; half: half its width; a, b, c: the triangle's corners. */
bool ms_tri_cube_overlap(const float centre[3], float half, const float a[3], const float b[3], const float c[3]);

#endif
