/* Ray casts on a stitched cut for the browser client's measuring
 * (docs/BROWSER.md, "Measuring"): the ray against every triangle of an
 * ms_view_mesh, in doubles, both faces, edges included, the points on the
 * cut-away side of the section planes skipped (what the page does not draw).
 * meshview casts the same way on its core's frame (ms_viewer_measure_cast),
 * with the same ray-triangle test (ms_ray.h).
 *
 * Pure function; thread-safe. */
#ifndef MS_WEB_CAST_H
#define MS_WEB_CAST_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_view_decoder.h"

/* Of the hits with t >= t_min whose point no plane cuts away (a b c d: a x +
 * b y + c z + d > 0 cut away; planes may be NULL when count is 0), the one
 * whose t is nearest t_near: *t, and the index of its triangle. The
 * direction need not be unit (t in its units). False when nothing is hit. */
bool ms_web_cast(const ms_view_mesh *mesh, const double origin[3], const double direction[3], double t_min,
                 double t_near, const double (*planes)[4], size_t count, double *t, size_t *triangle);

#endif
