/* The public preview's rules on a model's index (docs/SECURITY.md, "APO under
 * a preview"; PROTOCOL.md section 8): what a reader limited to a preview of
 * the geometry may read of a cell's APO chunk. One function that the server's
 * permission check (server/serve/ms_access.h) and the client core share, so
 * that a client computes exactly what the server grants and never asks for
 * more. Pure; thread-safe. */
#ifndef MS_PREVIEW_H
#define MS_PREVIEW_H

#include "ms_archive.h"

/* How many levels of cell c's chunk (depths 0 .. result - 1) a reader limited
 * to geometry steps 0 .. permitted_geometry_steps - 1 (a preview of
 * P = permitted_geometry_steps - 1 bits) may read. A texel at depth d of a
 * cell at `level` is a cube of side box_side / 2^(log2(n) * level + d): the
 * grid step of the geometry at log2(n) * level + d bits. So the preview reads
 * the depths whose texels are no finer than its own grid step,
 * d <= P - log2(n) * level: P - log2(n) * level + 1 levels, 0 when negative,
 * and 0 for a cell whose window starts at or beyond the preview (bits_min >=
 * permitted_geometry_steps: its geometry is not shown at all). Not clamped to
 * the cell's own apo_levels. permitted_geometry_steps > h->bits (full
 * precision) limits nothing: MS_ARCHIVE_MAX_APO_LEVELS. */
unsigned ms_archive_preview_apo_levels(const ms_archive_header *h, const ms_archive_cell *c,
                                       unsigned permitted_geometry_steps);

#endif
