/* The browser client's decoding core (docs/BROWSER.md): the small C interface
 * that web/ compiles to WebAssembly with the same view decoder as the native
 * client (common/archive/ms_view_decoder.h). It is also built natively, into
 * the room's library, so that its tests run under the sanitizers.
 *
 * A web view holds one model's index and a view over it: the whole index (the
 * index blob of GET /models/NAME), or its head (GET /models/NAME/head) and
 * the subtrees its plans ask for (GET /models/NAME/subtrees/ID), read by the
 * native client's own reader (common/archive's ms_archive_open_head and
 * ms_archive_add_subtree; docs/ARCHIVE.md, "Subtrees"). The caller (the
 * page's Web Worker) loops:
 *   ms_web_view_camera     sets the camera and the screen tolerance;
 *   ms_web_view_plan       selects and applies: the cut moves as far as the
 *                          bytes held allow, and the cells still short of
 *                          bytes are listed with the prefix they need;
 *   ms_web_view_give       hands over the bytes fetched for one of them,
 *   ms_web_view_give_subtree  and the subtrees the plan lists;
 * until the plan lists nothing, then ms_web_view_stitch builds the mesh to
 * draw (float positions, 32-bit triangle corners). Fetching is the caller's:
 * the C side never does I/O.
 *
 * Every function that can fail returns ms_status and leaves a one-line
 * message in ms_web_view_error. Not thread-safe: one caller (its helper
 * threads, ms_web_view_threads, are its own). */
#ifndef MS_WEB_VIEW_H
#define MS_WEB_VIEW_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_web_view ms_web_view;

/* A view over the index blob (copied; name is used in errors). On failure
 * *out is NULL and err says why. */
ms_status ms_web_view_new(const uint8_t *blob, size_t size, const char *name, ms_web_view **out,
                          ms_error *err);
void ms_web_view_free(ms_web_view *view);

/* A view over the index head (copied): its header and root subtree, checked
 * as the native client checks them; the other subtrees come as plans ask
 * (ms_web_view_plan_subtree). */
ms_status ms_web_view_new_head(const uint8_t *head, size_t size, const char *name, ms_web_view **out,
                               ms_error *err);

/* Hands over subtree id's stored bytes (its whole zlib stream): checked
 * against the records held, then its cells are known to the plans. MS_OK for
 * one held already; MS_ERR_RANGE for a subtree whose parent cell is not held,
 * MS_ERR_FORMAT / MS_ERR_CORRUPT for bytes that disagree (the line names the
 * subtree; nothing changes); MS_ERR_ARG on a view of the whole index. */
ms_status ms_web_view_give_subtree(ms_web_view *view, uint32_t id, const uint8_t *data, uint32_t length);

/* Subtrees held (every one with the whole index) and their raw bytes. */
uint32_t ms_web_view_subtrees_held(const ms_web_view *view);
uint64_t ms_web_view_index_bytes_held(const ms_web_view *view);

/* The last error's message ("" when none). */
const char *ms_web_view_error(const ms_web_view *view);

/* The model's box: origin x y z and side (4 doubles). */
void ms_web_view_box(const ms_web_view *view, double out[4]);
uint32_t ms_web_view_cell_count(const ms_web_view *view);

/* The box of the model's vertices as the root cell's bytes held show it
 * (lo x y z, hi x y z; within the root's grid step of the true box), for a
 * home camera before any other camera: hand over the root's payload first
 * (GET /models/NAME/cells/0/geometry). Brings the root, while it is the whole
 * cut, to the precision its bytes allow. MS_ERR_RANGE once the root is split;
 * MS_ERR_EMPTY for a model without a vertex. */
ms_status ms_web_view_bounds(ms_web_view *view, double out[6]);

/* The camera: position, target, up (3 doubles each), vertical field of view in
 * degrees, the viewport in pixels, near and far distances (<= 0: from the
 * model's box, as meshrender chooses them) and the screen tolerance in pixels
 * (> 0). MS_ERR_ARG for an invalid camera. */
ms_status ms_web_view_camera(ms_web_view *view, const double position[3], const double target[3],
                             const double up[3], double fovy_degrees, double width, double height,
                             double near_distance, double far_distance, double tolerance_px);

/* Bits given up on cells outside the view (>= 0): ms_view_select_params'
 * culled_bits_less. A new view has the decoder's default, 2 (meshrender's
 * cut); the client core uses 6, fewer bytes for what is not seen. */
void ms_web_view_culled(ms_web_view *view, double bits_less);

/* Caps every cell at bits 0 .. steps - 1 (a reader without a token on a
 * preview model: public_max_bits + 1); 0 lifts the cap. */
void ms_web_view_permit(ms_web_view *view, unsigned steps);

/* Decoding on `helpers` threads besides the caller's (at most
 * MS_WEB_VIEW_HELPERS_MAX; 0: the caller's alone, as a new view decodes):
 * each plan refines the cells that can go up with the bytes held on all of
 * them at once (ms_view_set_bits on distinct cells), the splits and merges
 * staying on the caller's; the same cut and mesh whatever the count. Returns
 * the helpers that started (0 where threads cannot be made: WebAssembly
 * built without pthreads, or a page not cross-origin isolated). */
#define MS_WEB_VIEW_HELPERS_MAX 7u
unsigned ms_web_view_threads(ms_web_view *view, unsigned helpers);

/* Selects for the camera and applies as far as the bytes allow, repeating
 * while the cut still changes. Then lists the cells whose target needs bytes
 * not held, of the next step only (the shown and split cells, and the children
 * of a shown cell that is to split: a plan after their bytes lists the level
 * below, so the first plans ask for little and each round shows more):
 * ms_web_view_plan_count of them, the k-th with its cell id, the precision
 * (bits) wanted and the byte length of the payload prefix complete at it (GET /models/NAME/cells/ID/geometry?bits=BITS), in cell order, at
 * most `max` cells (0: no limit). On a view of the index head it also lists
 * the subtrees it lacks (ms_web_view_plan_subtree: those holding the children
 * of the cells the selection would split, then, with plans that look ahead,
 * of those within a bit of splitting, as the client core asks for them;
 * each once; fetch them before the cells), and on a colour model the colour
 * prefixes (ms_web_view_plan_colour_count). *settled (may be NULL) is true
 * when the cut no longer changes and nothing is wanted, cells, subtrees or
 * colour: the view is complete. */
ms_status ms_web_view_plan(ms_web_view *view, uint32_t max, int *settled);
uint32_t ms_web_view_plan_count(const ms_web_view *view);
uint32_t ms_web_view_plan_subtree_count(const ms_web_view *view);
/* The k-th subtree id the plan lists (GET /models/NAME/subtrees/ID). */
uint32_t ms_web_view_plan_subtree(const ms_web_view *view, uint32_t k);

/* Plans that look ahead (on != 0; a new view's plans do not): after the
 * next step, a plan lists the rest of the cut the selection targets, the
 * cells below the shown ones that its splits will need, level by level from
 * the root (by cell number within a level), so that a caller can keep the
 * link busy while it decodes what came; the same cells and bytes in the
 * end, asked for sooner. MS_ERR_NOMEM. */
ms_status ms_web_view_plan_ahead(ms_web_view *view, int on);
uint32_t ms_web_view_plan_cell(const ms_web_view *view, uint32_t k);
uint32_t ms_web_view_plan_bits(const ms_web_view *view, uint32_t k);
uint32_t ms_web_view_plan_bytes(const ms_web_view *view, uint32_t k);
/* The byte length of the cell's payload prefix complete at `bits` (clamped to
 * its window; 0 for a cell whose record is not known): what a caller hands
 * over to bring a cell to those bits (the home camera: the root's bounds at
 * a few bits, before the rest of its bytes). */
uint32_t ms_web_view_prefix(const ms_web_view *view, uint32_t cell, uint32_t bits);
/* Bytes of the cell's payload already held (a fetch may ask for the rest with
 * Range: bytes=HELD-). */
uint32_t ms_web_view_held(const ms_web_view *view, uint32_t cell);

/* Hands over bytes [offset, offset + length) of the cell's geometry payload:
 * offset must be what is held (a longer prefix extends it). MS_ERR_RANGE
 * past the payload's length, MS_ERR_ARG for a gap or an unknown cell. */
ms_status ms_web_view_give(ms_web_view *view, uint32_t cell, uint32_t offset, const uint8_t *data,
                           uint32_t length);

/* Colour (docs/BROWSER.md, "Colour"). A model with a colour stream per cell
 * (has_colour) draws its vertices in their scanned colours: every plan also
 * lists the colour prefixes the target cut lacks (each cell's stream to its
 * goal's bits, split cells too: a child's colour starts from its parent's
 * whole colour), read with the plan_colour accessors (k < count; out of
 * range: MS_ARCHIVE_NONE, 0), and a plan is settled only once they are
 * held. give_colour hands over bytes [offset, offset + length) of a cell's
 * colour stream as give does the geometry (MS_ERR_ARG: a gap, an unknown
 * cell, a model without colour; MS_ERR_RANGE: past the stream's length). A
 * damaged stream fails the stitch with one line. colours: r g b a, 8 bits
 * each, per vertex of the last stitch (sRGB as scanned; a cell whose colour
 * is not held yet in the renderers' default grey), or NULL (no colour, or
 * nothing stitched); valid until the next stitch or free. */
int ms_web_view_has_colour(const ms_web_view *view);
uint32_t ms_web_view_plan_colour_count(const ms_web_view *view);
uint32_t ms_web_view_plan_colour_cell(const ms_web_view *view, uint32_t k);
uint32_t ms_web_view_plan_colour_bits(const ms_web_view *view, uint32_t k);
uint32_t ms_web_view_plan_colour_bytes(const ms_web_view *view, uint32_t k);
uint32_t ms_web_view_colour_prefix(const ms_web_view *view, uint32_t cell, uint32_t bits);
uint32_t ms_web_view_colour_held(const ms_web_view *view, uint32_t cell);
ms_status ms_web_view_give_colour(ms_web_view *view, uint32_t cell, uint32_t offset, const uint8_t *data,
                                  uint32_t length);
const uint8_t *ms_web_view_colours(const ms_web_view *view);

/* Section planes (docs/BROWSER.md, "Sections"): count (0 to 3) planes of 4
 * doubles a b c d each, the side a x + b y + c z + d > 0 cut away. The
 * selection then treats a cell wholly cut away as one outside the view
 * (culled: coarser, never split for the view; ms_view_select_params.sections,
 * as meshview's ms_core_set_sections), and ms_web_view_cast skips what they
 * cut away. MS_ERR_ARG (the planes unchanged) for more than three, a zero
 * normal or a number not finite. */
ms_status ms_web_view_sections(ms_web_view *view, const double *planes, uint32_t count);

/* Measuring (docs/BROWSER.md, "Measuring"): the ray from origin along
 * direction (need not be unit) cast on the last stitched mesh in doubles
 * (ms_web_cast.h): of the hits with t >= t_min not cut away by the sections,
 * the one whose t is nearest t_near (0, 0: the first surface in front).
 * out: x y z (the point), t, the bits its triangle's cell is shown at, and
 * the grid step at those bits (box side / 2^bits): the point's precision,
 * then the model's bits (7 doubles). 1 on a hit, 0 otherwise (nothing
 * stitched, a zero or not finite direction, nothing hit). */
int ms_web_view_cast(ms_web_view *view, const double origin[3], const double direction[3], double t_min,
                     double t_near, double out[7]);

/* Builds the mesh of the cut (every shown cell). Read it with the accessors
 * below; valid until the next stitch or free. */
ms_status ms_web_view_stitch(ms_web_view *view);
uint32_t ms_web_view_vertex_count(const ms_web_view *view);
uint32_t ms_web_view_triangle_count(const ms_web_view *view);
/* 3 floats per vertex (world units), 3 corners per triangle (oriented), and
 * 3 floats per vertex of unit normal: the area-weighted mean of its
 * triangles' (0 0 0 for a vertex of degenerate triangles only). */
const float *ms_web_view_positions(const ms_web_view *view);
const uint32_t *ms_web_view_triangles(const ms_web_view *view);
const float *ms_web_view_normals(const ms_web_view *view);
/* Shown cells, the highest precision (bits) any of them is shown at, and the
 * geometry bytes held: the page's figures. */
uint32_t ms_web_view_shown_cells(const ms_web_view *view);
uint32_t ms_web_view_max_bits(const ms_web_view *view);
uint64_t ms_web_view_bytes_held(const ms_web_view *view);

/* The renderer's cells (docs/BROWSER.md, "Drawing"): the last stitch's mesh
 * grouped by the cell that drew each triangle (ms_view_mesh's runs), so that
 * the page draws cell by cell, with its number (CELLS shading) and its cube
 * (the frame of its APO chunk). ms_web_view_run_count cells, ascending; cell
 * run_cells[k] drew triangles [run_firsts[k], run_firsts[k + 1]), the
 * triangles of ms_web_view_triangles (run_count + 1 entries; both NULL when
 * nothing is stitched). Valid until the next stitch or free. */
uint32_t ms_web_view_run_count(const ms_web_view *view);
const uint32_t *ms_web_view_run_cells(const ms_web_view *view);
const uint32_t *ms_web_view_run_firsts(const ms_web_view *view);

/* A cell's cube: origin x y z and side (4 doubles), as the native renderer
 * places a cell (ms_render_cell_cube): the cell-local frame its positions and
 * its APO chunk are given in. MS_ERR_ARG for a cell not in the model. */
ms_status ms_web_view_cell_cube(ms_web_view *view, uint32_t cell, double out[4]);

/* The memory budget (docs/BROWSER.md, "Memory"): at most `bytes` of the
 * cells' received streams (geometry and colour) stay held. Each plan, once
 * the cut is selected, forgets the cells the view neither shows nor targets,
 * farthest from the camera first, until the view holds at most that; a cell
 * forgotten and wanted again is planned again from its first byte. The cells
 * shown or targeted are never forgotten (a shown cell keeps the bytes of the
 * finer bits it had), so a cut that alone needs more holds what it needs. 0
 * (the default): no limit. 32 bits: a WebAssembly module has at most 4 GiB. */
void ms_web_view_budget(ms_web_view *view, uint32_t bytes);
/* What the budget forgot since the view was made: cells, and their bytes (a
 * double: exact to 2^53, and a plain number in JavaScript). */
uint32_t ms_web_view_forgotten_cells(const ms_web_view *view);
double ms_web_view_forgotten_bytes(const ms_web_view *view);

/* For the room's own files (ms_web_apo.c): the view's index, decoder, camera
 * (NULL before ms_web_view_camera), selection parameters and error. */
struct ms_archive;
struct ms_view;
struct ms_camera;
struct ms_view_select_params;
typedef struct ms_web_view_parts {
    const struct ms_archive *index;
    const struct ms_view *view;
    const struct ms_camera *camera;
    struct ms_view_select_params *params;
    ms_error *err;
} ms_web_view_parts;
void ms_web_view_parts_get(ms_web_view *view, ms_web_view_parts *out);

#endif
