/* APO chunks for the browser client (docs/BROWSER.md, "APO"): which levels of
 * which cells' chunks the page fetches, by the client core's rule (docs/
 * CLIENT.md, "APO fetched by footprint": a visible shown cell with a chunk,
 * not about to split, down to the first level whose texel projects to the
 * tolerance, at most max_levels and, under a public preview, no level finer
 * than the preview, ms_archive_preview_apo_levels), and the check of what
 * came (ms_apo_view_init, the native loader) before a word reaches the GPU.
 * Inflating is the caller's (the page's DecompressionStream: the module has
 * no zlib); fetching too. Not thread-safe: the web view's caller. */
#ifndef MS_WEB_APO_H
#define MS_WEB_APO_H

#include <stdint.h>

#include "ms_error.h"
#include "ms_web_view.h"

typedef struct ms_web_apo ms_web_apo;

/* APO state over a web view (which must outlive it); NULL when out of
 * memory. */
ms_web_apo *ms_web_apo_new(ms_web_view *view);
void ms_web_apo_free(ms_web_apo *apo);

/* The geometry under APO, as the client core chooses it (meshview with APO:
 * its --tolerance is the core's apo_geometry_tolerance_px, the detail
 * tolerance its tolerance_px, 1 px): with APO drawn (on) on a model that
 * has it, the cells that carry a chunk refine to the view's tolerance and
 * the others, which only their triangles shade, to detail_tolerance_px
 * (ms_view_select_params.chunkless_tolerance_scale); off, or a model
 * without APO: every cell to the view's tolerance. Call after each
 * ms_web_view_camera (the scale is relative to its tolerance). */
void ms_web_apo_geometry(ms_web_apo *apo, int on, double detail_tolerance_px);

/* After a plan of the view (its targets current): lists the shown cells
 * whose chunk needs levels not held, by the footprint rule at the view's
 * camera and detail_tolerance_px, at most max_levels levels a cell
 * (meshview's --apo-levels, 16 by default). Returns the count listed; 0
 * without a camera. */
uint32_t ms_web_apo_plan(ms_web_apo *apo, unsigned max_levels, double detail_tolerance_px);
/* The k-th listed cell, the levels wanted (levels 0 .. levels - 1) and the
 * byte length of the stored chunk's prefix that holds them
 * (ms_archive_apo_prefix: GET /models/NAME/cells/ID/apo?levels=LEVELS). */
uint32_t ms_web_apo_plan_cell(const ms_web_apo *apo, uint32_t k);
uint32_t ms_web_apo_plan_levels(const ms_web_apo *apo, uint32_t k);
uint32_t ms_web_apo_plan_bytes(const ms_web_apo *apo, uint32_t k);

/* Levels of the cell's chunk held (0: none) and its words per level in the
 * complete chunk (0 past its levels). */
uint32_t ms_web_apo_held(const ms_web_apo *apo, uint32_t cell);
uint32_t ms_web_apo_level_texels(const ms_web_apo *apo, uint32_t cell, uint32_t level);

/* The inflated words of levels 0 .. levels - 1 of the cell's chunk (count
 * of them, exactly those levels' words): checked by the native loader
 * against the index's level table; then held. MS_ERR_ARG for a cell
 * without a chunk or a count that is not those levels' words,
 * MS_ERR_CORRUPT (the loader's line) for a bad word; the message in
 * ms_web_view_error. */
ms_status ms_web_apo_give(ms_web_apo *apo, uint32_t cell, uint32_t levels, const uint32_t *words,
                          uint32_t count);

#endif
