/* The browser view's memory budget (ms_web_view_budget, docs/BROWSER.md
 * "Memory"): what a view holds of its cells' received streams, and the cells
 * it forgets once that passes the budget. The page keeps every byte it
 * receives otherwise, so a long visit over a large model would grow the tab
 * without end. Internal to client/web (ms_web_view.c).
 *
 * Thread-safety: none; the caller owns the view. */
#ifndef MS_WEB_BUDGET_H
#define MS_WEB_BUDGET_H

#include <stdint.h>

#include "ms_archive.h"
#include "ms_error.h"
#include "ms_view_decoder.h"

/* A known cell's cube in model units: origin x y z and side (out[4]).
 * false for a cell with no record. */
bool ms_web_cell_cube(const ms_archive *index, uint32_t cell, double out[4]);

/* Forgets (ms_view_forget: bytes, colour and decoder) the HIDDEN cells the
 * last selection does not target, farthest first (the distance from eye to
 * the cell's cube's centre; equal distances by cell id), until the view
 * holds at most `budget` bytes of geometry and colour streams (over its
 * known cells) or none of them is left: the cells shown or targeted are never
 * forgotten, so a cut that alone needs more keeps what it needs. budget 0: no
 * limit. Adds the cells and bytes forgotten to *cells and *bytes.
 * MS_ERR_NOMEM (nothing forgotten). */
ms_status ms_web_budget_apply(ms_view *view, const ms_archive *index, const double eye[3], uint64_t budget,
                              uint64_t *cells, uint64_t *bytes, ms_error *err);

#endif
