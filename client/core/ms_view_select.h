/* Which nSP cells a camera needs, and at what precision: the per-frame cell
 * selection of a client (DESIGN.md section 4, step 3), on a model's index
 * (ms_archive_open_index). From the root down, a cell is kept when its cube
 * meets the frustum (with a margin); its precision is the screen-space need
 * (ms_archive_bits_needed: its measured surface error at the nearest point
 * of its cube) clamped to its window; when the need exceeds the window and the cell has children, the
 * children are visited too (the parent stays selected at its full window, as
 * the fallback a client draws until they arrive).
 *
 * Pure function of its inputs; thread-safe.
 */
#ifndef MS_VIEW_SELECT_H
#define MS_VIEW_SELECT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"

typedef struct ms_view_cell {
    uint32_t cell;
    uint8_t bits;      /* precision wanted, in [bits_min, bits_max] */
    bool refined;      /* its children are selected too */
    double distance;   /* camera to the cube, world units */
} ms_view_cell;

/* Writes up to capacity cells to out, parents before children; returns how
 * many cells are selected in all (may exceed capacity: then call again with
 * more room). tolerance_px > 0. */
size_t ms_view_select_cells(const ms_archive *index, const ms_camera *camera, double tolerance_px,
                      ms_view_cell *out, size_t capacity);

#endif
