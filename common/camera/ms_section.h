/* Section planes as text (docs/VIEWER.md, "Sections"): what meshview and
 * meshrender take with --section. A plane is a point and a normal in model
 * coordinates; the side the normal points to is cut away (p kept where
 * normal . (p - point) <= 0). The text is "AXIS=VALUE", AXIS one of x y z -x
 * -y -z (x=V cuts away x > V, -x=V cuts away x < V), or six numbers
 * "PX,PY,PZ,NX,NY,NZ" separated by commas, the normal not zero; every number
 * finite, in decimal (no spaces, hex, nan or inf), normal . point finite.
 *
 * Pure functions; thread-safe.
 */
#ifndef MS_SECTION_H
#define MS_SECTION_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_error.h"

/* Reads a text into point and normal; MS_ERR_FORMAT with one line (what is
 * wrong, the text's first 64 bytes) otherwise, point and normal undefined. */
ms_status ms_section_parse(const char *text, double point[3], double normal[3], ms_error *err);

/* The plane a b c d of point and normal: a b c the normal, d = -normal .
 * point; the side a x + b y + c z + d > 0 is cut away. */
void ms_section_plane(const double point[3], const double normal[3], double plane[4]);

/* Whether any of the count planes (a b c d each, as ms_section_plane makes
 * them) cuts p away: what no picture shows, so no pick or measure hits it. */
bool ms_section_cuts_away(const double (*planes)[4], size_t count, const double p[3]);

#endif
