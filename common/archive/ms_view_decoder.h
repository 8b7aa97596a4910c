/* View-dependent decoding of an nSP archive (reference 003 §6): the client-side
 * logic that keeps a cut of the nSP-tree decoded at chosen precisions and turns
 * it into one crack-free mesh.
 *
 * Cells are numbered as in the archive index (docs/ARCHIVE.md). Each cell is
 *   HIDDEN  an ancestor stands for it;
 *   SHOWN   part of the cut, decoded at a precision `bits` within its window
 *           [bits_min, bits_max];
 *   SPLIT   its children stand for it; it stays decoded at bits_max so that a
 *           merge is immediate and exact.
 * The SHOWN cells always tile the whole cube (the root starts SHOWN at 0 bits),
 * whether they are visible or not: culled cells stay in the cut at a low
 * precision, which keeps the stitching rule well defined everywhere.
 *
 * A cell decodes from its geometry payload, which may arrive in pieces: hand over
 * any prefix with ms_view_set_bytes (the per-bit prefix table of the index says
 * how long a prefix each precision needs). A child's decoder starts from the
 * complex its parent has at bits_max, split by ms_nsp_partition_state: the same
 * start state the baker encoded it from (the codec header's checksum proves it).
 *
 * Stitching (ms_view_stitch): a triangle of shown cell c at kd-level L_c is drawn
 * unless one of its vertices lies in a shown cell that is finer (higher kd-level),
 * or equally fine with a higher cell number, which then draws its own copy; each
 * vertex lying in another shown cell is drawn at that cell's representative of
 * the kd-cell containing it; triangles made degenerate or repeated by this
 * snapping are dropped. The result is exactly the image of the model with every
 * vertex rounded to the precision of the shown cell holding it: every vertex has
 * one position, a triangle present in several cells is drawn once, and nothing
 * is missing along cell borders. (Where two sheets of the surface press together,
 * one triangle stands for both, as in a uniform decode; with very different
 * precisions side by side this can happen where no uniform decode does it, which
 * is why culled cells are kept only a couple of bits coarser than they need.)
 *
 * Units: precisions in bits per coordinate (kd-level = 3 bits); world coordinates
 * as doubles in the archive's box. Errors: ms_status with one line; MS_ERR_RANGE
 * for a request outside a cell's window or state, MS_ERR_FORMAT for bytes not yet
 * received, MS_ERR_CORRUPT for a damaged payload.
 * Thread-safety: one object per client, used from one thread, except that
 * ms_view_set_bits and ms_view_set_bytes on *distinct* cells may run concurrently
 * when no merge, select, apply or stitch runs at the same time, and so may
 * ms_view_split of a shown cell beside them (it touches the cell and its
 * children's state alone, which no other of those calls may name): the
 * decode pool's waves (ms_view_refine.h).
 */
#ifndef MS_VIEW_DECODER_H
#define MS_VIEW_DECODER_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_codec.h"
#include "ms_error.h"
#include "ms_parallel.h"

typedef struct ms_view ms_view;

typedef enum ms_view_cell_state {
    MS_VIEW_HIDDEN = 0,
    MS_VIEW_SHOWN = 1,
    MS_VIEW_SPLIT = 2
} ms_view_cell_state;

/* Creates a view over a model from its header and its cell_count cell records
 * (both copied). The root is SHOWN at 0 bits. MS_ERR_ARG when the records do not
 * form a valid tree (the archive reader has already checked this for files). */
ms_status ms_view_create(const ms_archive_header *header, const ms_archive_cell *cells,
                         ms_view **view, ms_error *err);

/* ---- a partly known index (records that arrive by subtree) ------------------
 *
 * A view may know only some cells' records: the client learns them subtree by
 * subtree (docs/CLIENT.md) and forgets those the view no longer needs. Memory
 * follows the records known: cells are kept per sibling group (n^3 consecutive
 * ids), a block per group that has a known record, plus one pointer per group
 * for the model. A cell whose children's records are not known cannot split:
 * selection shows it at most at bits_max and reports it (ms_view_select).
 * Functions given a cell whose record is not known behave as for a cell out of
 * range (NULL, HIDDEN, 0, MS_ERR_RANGE). */

/* A view with no record known yet (header copied): learn the root's before
 * selecting. MS_ERR_ARG for a bad header, MS_ERR_NOMEM. */
ms_status ms_view_create_partial(const ms_archive_header *header, ms_view **view,
                                 ms_error *err);

/* Makes the records of `count` cells known (copied; ids[k] is recs[k]'s cell).
 * Records already known stay as they are. Each must keep the tree rules, alone
 * and against its parent when that is known (MS_ERR_ARG, nothing learned).
 * Learning the root makes it SHOWN at bits_min. MS_ERR_NOMEM. */
ms_status ms_view_learn(ms_view *view, const uint32_t *ids, const ms_archive_cell *recs,
                        size_t count, ms_error *err);

/* Forgets the records of `count` cells (unknown ones are skipped), with their
 * bytes and decoders. Each must be HIDDEN and not the root, else MS_ERR_RANGE
 * and nothing is forgotten. */
ms_status ms_view_unlearn(ms_view *view, const uint32_t *ids, size_t count, ms_error *err);

/* The cells the view holds per-cell state for: every cell of each sibling
 * group with a known record (the root's group is the root alone), known or
 * not; each costs ms_view_cell_state_size() bytes (sizeof the view's cell
 * state, its record included; the bytes, decoders and caches a cell points to
 * are not counted here). With the whole index, every cell of the model. */
uint32_t ms_view_state_cells(const ms_view *view);
size_t ms_view_cell_state_size(void);

bool ms_view_known(const ms_view *view, uint32_t cell);
/* Cells whose records are known now. */
uint32_t ms_view_known_count(const ms_view *view);
/* The smallest known cell id after `after` (MS_ARCHIVE_NONE: from the start),
 * or MS_ARCHIVE_NONE: `for (id = 0; id != MS_ARCHIVE_NONE; id = next(v, id))`
 * visits every known cell (the root is known once learned). Skips a group
 * without a known record in one step. */
uint32_t ms_view_next_known(const ms_view *view, uint32_t after);
/* Whether cell is known, inner, and all its children's records are known. */
bool ms_view_children_known(const ms_view *view, uint32_t cell);

/* A view over every record of an open archive: with every cell's full geometry
 * payload handed over (CRC-checked) for an archive file, with none for an index
 * received alone (ms_archive_open_index), whose bytes come by ms_view_set_bytes. */
ms_status ms_view_create_from_archive(const ms_archive *archive, ms_view **view, ms_error *err);

void ms_view_destroy(ms_view *view);

const ms_archive_header *ms_view_header(const ms_view *view);
uint32_t ms_view_cell_count(const ms_view *view);
const ms_archive_cell *ms_view_cell(const ms_view *view, uint32_t cell);

/* Hands over the first `length` bytes of a cell's geometry payload (copied). A
 * later call must extend what was given (a longer prefix of the same payload).
 * MS_ERR_RANGE when length exceeds the payload length in the index. */
ms_status ms_view_set_bytes(ms_view *view, uint32_t cell, const uint8_t *data, size_t length,
                            ms_error *err);

/* Appends length bytes to what the cell holds (the next part of its payload,
 * from offset ms_view_held_bytes). MS_ERR_RANGE past the payload's end. */
ms_status ms_view_append_bytes(ms_view *view, uint32_t cell, const uint8_t *data, size_t length,
                               ms_error *err);

/* Hands over the first `length` bytes of a cell's colour stream (copied;
 * docs/ARCHIVE.md, "Colour streams"): a later call must extend what was given.
 * Colour decodes in lockstep with the cell's geometry, as far as the colour
 * bytes allow (a prefix stops colour at fewer bits than geometry); the
 * stitched mesh then carries colours (ms_view_mesh.colours). A stream that
 * turns out damaged fails the stitch with one line. MS_ERR_RANGE for an
 * unknown cell, MS_ERR_ARG for bytes that do not extend those held. */
ms_status ms_view_set_colour_bytes(ms_view *view, uint32_t cell, const uint8_t *data,
                                   size_t length, ms_error *err);
/* Appends `added` bytes to the cell's colour stream (the next part, from
 * offset ms_view_held_colour_bytes); the same rules as above. */
ms_status ms_view_append_colour_bytes(ms_view *view, uint32_t cell, const uint8_t *data,
                                      size_t added, ms_error *err);
/* Bytes of the cell's colour stream held. */
size_t ms_view_held_colour_bytes(const ms_view *view, uint32_t cell);

/* Releases the bytes (colour included) and decoder of a HIDDEN cell (a client's cache eviction);
 * the cell needs its payload again before it can be refined once shown.
 * MS_ERR_RANGE when the cell is not HIDDEN. */
ms_status ms_view_forget(ms_view *view, uint32_t cell, ms_error *err);

/* Bytes of the cell's payload held (what ms_view_set_bytes was given). */
size_t ms_view_held_bytes(const ms_view *view, uint32_t cell);

/* Highest precision of the cell decodable from the bytes held (bits_min when no
 * complete bit is held; bits_max for an empty cell). */
unsigned ms_view_available_bits(const ms_view *view, uint32_t cell);

ms_view_cell_state ms_view_state(const ms_view *view, uint32_t cell);
/* Current precision of a SHOWN cell (bits_max for a SPLIT one, 0 for HIDDEN). */
unsigned ms_view_bits(const ms_view *view, uint32_t cell);

/* Refines or coarsens a SHOWN cell to `bits` in its window. Exactly reversible:
 * going to b' and back to b restores the identical complex. */
ms_status ms_view_set_bits(ms_view *view, uint32_t cell, unsigned bits, ms_error *err);

/* Splits a SHOWN non-leaf cell at bits_max: its children become SHOWN at their
 * bits_min (no bytes needed for that). */
ms_status ms_view_split(ms_view *view, uint32_t cell, ms_error *err);

/* Merges a SPLIT cell back (merging split descendants first): it becomes SHOWN at
 * bits_max, exactly as it was before the split (decoded again from its bytes
 * when its decoder was dropped; an error from that leaves it SHOWN without
 * one). */
ms_status ms_view_merge(ms_view *view, uint32_t cell, ms_error *err);

/* Frees the decoder of a SPLIT cell: the complex at bits_max that its
 * children now hold, refined (a client's memory budget: the ancestors of a
 * close-up held most of its decoded memory). The bytes and start state stay,
 * so ms_view_merge decodes the cell again (the identical complex, decoding
 * being deterministic) and ms_view_cell_state_copy decodes it for the copy.
 * A no-op when it holds none. MS_ERR_RANGE when the cell is not SPLIT. */
ms_status ms_view_drop_decoder(ms_view *view, uint32_t cell, ms_error *err);
/* Whether the cell holds a decoder (a decoded complex). */
bool ms_view_holds_decoder(const ms_view *view, uint32_t cell);

/* The current complex of a SHOWN or SPLIT cell, canonical (ms_codec.h); caller
 * frees. Empty cells give vertex_count 0. */
ms_status ms_view_cell_state_copy(const ms_view *view, uint32_t cell, ms_codec_state *out,
                                  ms_error *err);

/* The box (world units) of the kd-cells of a SHOWN or SPLIT cell's current
 * complex: the union of the grid cells its vertices stand for (each vertex
 * decodes to its kd-cell's centre, docs/CODEC.md), so every vertex of the
 * model that the complex represents lies in it, and at b bits it is within
 * box_side / 2^b of their box on every side. For the root at b bits that is
 * every vertex of the model. MS_ERR_EMPTY for a complex without a vertex,
 * MS_ERR_RANGE for a HIDDEN or unknown cell, MS_ERR_NOMEM. Keeps the cell's
 * stitching cache (as ms_view_stitch would). */
ms_status ms_view_cell_bounds(ms_view *view, uint32_t cell, double lo[3], double hi[3],
                              ms_error *err);

/* The error of a SHOWN cell's current complex (docs/CLIENT.md, "The error of
 * a cut"), world units: its record's measured surface error at its current
 * precision (ms_archive_cell_error, docs/CODEC.md §4.3: how far the model's
 * vertices lie from the surface drawn through their points). 0 for an empty
 * cell; -1 for a cell not SHOWN. */
double ms_view_cell_error_bound(ms_view *view, uint32_t cell);

/* ---- selection: what the client calls every frame ---------------------- */

#define MS_VIEW_TARGET_HIDDEN 0xFFu /* an ancestor is shown */
#define MS_VIEW_TARGET_SPLIT 0xFEu  /* the children are shown */

typedef struct ms_view_select_params {
    double tolerance_px;  /* screen error allowed for a vertex, pixels (> 0) */
    double margin;        /* frustum margin, world units (>= 0) */
    double hysteresis;    /* bits to spare before coarsening (ms_select_bits), e.g. MS_SELECT_HYSTERESIS_DEFAULT */
    double culled_bits_less; /* cells outside the frustum get their need minus this */
    /* NULL, or per cell a factor on tolerance_px (> 0): a client with APO on
     * refines cells that carry a chunk only to a coarse geometric tolerance and
     * the cells without one (their geometry is all the shading they get) to the
     * full one. Borrowed; cell_count entries. */
    const float *tolerance_scale;
    /* When tolerance_scale is NULL and this is > 0: the factor for cells whose
     * record has no APO chunk (apo_levels 0), 1 for the others; the same rule
     * without a per-cell array (a partly known index). */
    double chunkless_tolerance_scale;
    /* 0: no cap. Else the reader's permitted geometry steps under a public
     * preview (PROTOCOL.md section 8: it may read bits 0 .. permitted_steps - 1):
     * no cell is wanted above permitted_steps - 1 bits, so none splits into
     * children it could not read, and a cell so capped counts as at its
     * target (reported in capped_count). */
    unsigned permitted_steps;
    /* Section planes (ms_frustum_add_section: a b c d, the side a x + b y + c z
     * + d > 0 cut away): a cell wholly cut away counts as outside the frustum
     * (culled: its need less culled_bits_less, never split for the view).
     * Default none. */
    unsigned section_count;
    double sections[MS_SECTIONS_MAX][4];
    /* false (the default): the root of a model in view is wanted at
     * MS_ARCHIVE_ROOT_FLOOR_BITS at least, so no model vanishes; true: as its
     * need says (a client's own passes that only look for the model's
     * bounds draw nothing for anyone). */
    bool no_root_floor;
} ms_view_select_params;

/* 1 pixel, no margin, MS_SELECT_HYSTERESIS_DEFAULT bits of hysteresis, culled cells 2 bits coarser (keeps
 * the precision steps at the frustum border small: see ms_view_stitch), one
 * tolerance for every cell, no sections, the root's floor. */
void ms_view_select_params_default(ms_view_select_params *params);

/* Real-valued precision (bits) a cell needs for the camera, or -1 when it is
 * outside the frustum grown by margin. */
double ms_view_cell_need(const ms_view *view, const ms_camera *camera, uint32_t cell,
                         const ms_view_select_params *params);

/* The need ms_view_select uses for a known cell: its real-valued precision,
 * less culled_bits_less outside the frustum (-INFINITY for an unknown cell). */
double ms_view_cell_select_need(const ms_view *view, const ms_camera *camera, uint32_t cell,
                                const ms_view_select_params *params);

/* Where the records of a partly known view fall short, or soon may: `blocked`:
 * cells whose target would be SPLIT but whose children's records are not known
 * (they get bits_max instead); `near`: inner cells of the cut, not split, whose
 * selection need is within one bit of splitting (need > bits_max - 1: their
 * children's records are worth holding, or fetching, ahead), children known
 * or not. The lists grow by realloc and are reused from call to call;
 * out_of_memory says a cell could not be listed. Free with
 * ms_view_select_report_free. Zero-initialise before the first use. */
typedef struct ms_view_select_report {
    uint32_t *blocked, *near;
    size_t blocked_count, near_count;
    size_t blocked_cap, near_cap;
    bool out_of_memory;
    /* cells whose target params->permitted_steps lowered: with a token the
     * camera would get more of them */
    size_t capped_count;
} ms_view_select_report;

/* Gives every known cell its target, kept in the view with the cell (so a
 * partly known view holds targets for its known cells only, nothing by the
 * model's size) and read with ms_view_target: bits to show it at,
 * MS_VIEW_TARGET_SPLIT or MS_VIEW_TARGET_HIDDEN. Visible cells get the
 * precision their nearest point needs (with hysteresis against the current
 * state); culled cells get that need less culled_bits_less bits (a large value
 * keeps them at their bits_min; a small one keeps precision jumps at the
 * frustum border small). The need is where the cell's measured surface
 * error (its record's table, ms_archive_bits_needed) projects to its
 * tolerance, so a cell shown at its target draws within it, whatever
 * precisions it came through. On a partly known view a cell whose children's
 * records are not known gets bits_max instead of SPLIT; report (NULL: none)
 * lists such cells and those near splitting. With the root not known yet
 * every target is HIDDEN. */
void ms_view_select(ms_view *view, const ms_camera *camera, const ms_view_select_params *params,
                    ms_view_select_report *report);
void ms_view_select_report_free(ms_view_select_report *report);

/* The target the last ms_view_select gave cell (MS_VIEW_TARGET_HIDDEN for a
 * cell it did not reach, learned since, or unknown). */
uint8_t ms_view_target(const ms_view *view, uint32_t cell);

typedef struct ms_view_apply_report {
    uint32_t splits, merges, refined, coarsened;
    uint32_t waiting; /* cells held below their target for lack of bytes */
} ms_view_apply_report;

/* Moves the view towards the targets of the last ms_view_select: merges,
 * refines, splits and coarsens, as far as the bytes held allow. report may be
 * NULL. */
ms_status ms_view_apply(ms_view *view, ms_view_apply_report *report, ms_error *err);

/* ---- the stitched mesh --------------------------------------------------- */

typedef struct ms_view_mesh {
    size_t vertex_count, triangle_count;
    double *positions;     /* 3 per vertex, world units (kd-cell centres) */
    uint64_t *keys;        /* per vertex: kd prefix aligned to 3p bits */
    uint8_t *levels;       /* per vertex: kd-level */
    uint32_t *triangles;   /* 3 per triangle, oriented */
    uint32_t *triangle_cell; /* per triangle: the cell that drew it */
    /* per vertex r g b a (8 bits each, docs/COLOUR.md: the vertex's colour at
     * the colour bits held), or NULL when the model has no colour stream or
     * none of it is held yet; a renderer then uses its default albedo. The
     * vertices of a shown cell without its colour yet (its bytes, or for a
     * child its split parent's whole stream, not held) are the renderers'
     * default grey, 221 216 209 255. */
    uint8_t *colours;
    size_t vertex_cap, triangle_cap;
    /* diagnostics */
    size_t dropped_finer;    /* triangles left to a finer (or tie-winning) cell */
    size_t dropped_snapped;  /* triangles degenerate or repeated once their vertices snap */
    size_t unresolved;       /* vertices whose neighbour representative is missing (0) */
    size_t snapped_frozen;   /* triangle corners given by a frozen foreign vertex (known
                              * only to a lone kd-cell coarser than its holder: ms_codec.h,
                              * regions) resolved to the holder's vertex inside that cell */
    /* Shown cells whose triangles this stitch worked out again (the others'
     * were kept from an earlier stitch of the same view, every cell they
     * depend on unchanged: the run version's rule below) and, of the
     * triangles, those that came from them. The mesh is the same either way. */
    size_t cells_stitched, triangles_stitched;
    /* The stitched cells, ascending (ms_view_stitch fills them; a mesh made by
     * hand may leave run_count 0): cell run_cell[k] drew triangles
     * [run_first[k], run_first[k + 1]) (run_count + 1 entries), and
     * run_version[k] changes whenever those triangles may have changed since an
     * earlier stitch of the same view: it is a hash of the stamps of the cell
     * and of every cell its triangles' corners' owner lookups ended at (the
     * owner, or the split cell too coarse to hold the corner), a stamp being
     * renewed whenever a stitch sees a cell's state or precision changed. The
     * same version means the same triangles: same vertex positions and levels,
     * same corners, same order. */
    size_t run_count, run_cap;
    uint32_t *run_cell;
    uint32_t *run_first;
    uint64_t *run_version;
} ms_view_mesh;

/* Builds the mesh of the shown cells whose visible[cell] is true (NULL: all).
 * *out must be zeroed or previously filled (its arrays are reused). Vertices are
 * those of the drawn triangles and every vertex inside a drawn cell. The view
 * keeps each shown cell's stitched triangles (its piece) and works a cell out
 * again only when its run version would change (a cell it depends on changed:
 * out->cells_stitched); the mesh is the same as if every cell were worked out
 * (docs/CLIENT.md, "Frames"). */
ms_status ms_view_stitch(ms_view *view, const bool *visible, ms_view_mesh *out, ms_error *err);

/* A pool (ms_parallel.h, borrowed; NULL: none, the default) on which
 * ms_view_stitch works out the shown cells' caches and pieces, one job per
 * cell (each writes its own cell's state alone and reads the others' caches
 * once all are made): the same mesh on any number of threads. Set and stitch
 * from the pool's one calling thread. */
void ms_view_set_pool(ms_view *view, ms_pool *pool);
void ms_view_mesh_free(ms_view_mesh *mesh);

#endif
