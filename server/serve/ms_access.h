/* Who may read which payload bytes of a model: the one place that decides.
 *
 * A model's operator sets a public preview (catalogue `public_max_bits`):
 * everyone may read each cell's geometry up to that precision; a reader who
 * presented the configured token may read everything. Every path to payload
 * bytes (the binary door's REQUEST_CELLS, the HTTP side door's cell URLs and
 * their Range requests, meshexport's static tree) asks ms_access_resolve, and
 * nothing else, for the byte range it may send (docs/SECURITY.md). The rules
 * are those of PROTOCOL.md sections 4.10 and 8:
 *
 *   - a limited grant reads geometry steps below permitted_geometry_steps
 *     (steps 0..public_max_bits), and bytes only up to the end of the last
 *     permitted step of the cell;
 *   - a cell whose geometric window starts at or beyond the preview is hidden:
 *     its APO (which would give its shape away) is forbidden too;
 *   - of every other cell, a limited grant reads the APO levels whose texels
 *     are no finer than the preview's grid step (ms_archive_preview_apo_levels:
 *     public_max_bits - log2(n) * level + 1 levels), so the detail normals
 *     show no more of the shape than the preview's geometry does;
 *   - a full grant reads everything; steps are only clamped;
 *   - the index's subtrees (stream INDEX) are read by every reader of the
 *     model, preview or not: they hold sizes and CRCs, no geometry. They are
 *     still resolved here, so that no door reaches bytes around this file.
 *
 * A model's documents (its thumbnail, metadata and annotations: GET_DOCUMENT
 * and /models/NAME/thumbnail, /metadata, /annotations) are decided here too,
 * by ms_access_document, from the catalogue entry alone.
 *
 * Pure functions of the model's index; no state; thread-safe.
 */
#ifndef MS_ACCESS_H
#define MS_ACCESS_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"
#include "ms_proto_range.h"
#include "ms_registry.h"

/* What one reader may read of one model (the counts of MODEL_OPENED). */
typedef struct ms_access {
    uint8_t geometry_steps;           /* the model's: bits + 1 */
    uint8_t apo_steps;                /* the model's: most APO levels of any cell */
    uint8_t permitted_geometry_steps; /* <= geometry_steps; below it: a preview */
    uint8_t permitted_apo_steps;      /* <= apo_steps; with a preview, the most
                                       * any cell gives (ms_access_cell_apo_steps) */
} ms_access;

/* The grant of a reader of model: everything with token_accepted (a token the
 * server was configured with and the reader presented), or when the preview
 * covers the whole model; otherwise the preview. */
ms_access ms_access_grant(const ms_model *model, bool token_accepted);

/* The same rule from a catalogue entry's recorded figures (bits, apo_levels,
 * public_max_bits; has_listing), for listing a model whose archive is not
 * open. Opening it applies ms_access_grant to the archive itself. */
ms_access ms_access_grant_listed(const ms_catalog_entry *entry, bool token_accepted);

/* Whether any reader may read the document of kind (ms_document_kind) of the
 * listed model entry. The thumbnail only while it was drawn within the public
 * preview (thumbnail_bits <= public_max_bits, clamped to bits by the
 * registry): it is one public picture for every reader, cached as such, so a
 * token does not widen it; the metadata and annotations (public descriptive
 * data) of every listed model. False for an undefined kind. */
bool ms_access_document(const ms_catalog_entry *entry, int kind);

/* True when the grant reads every byte of the model. */
bool ms_access_is_full(const ms_access *grant);

/* True when the grant shows nothing of the cell (its window starts beyond the
 * preview): both its streams are forbidden. False for a cell that does not
 * exist (ms_access_resolve reports that). */
bool ms_access_cell_hidden(const ms_model *model, const ms_access *grant, uint32_t cell);

/* The APO steps (levels) of cell that the grant reads: the whole model's
 * apo_steps with full geometry, else 0 for a hidden cell and otherwise
 * ms_archive_preview_apo_levels, at most apo_steps. A STEPS request on the
 * cell's APO with b at or above it, or BYTES past its end, is FORBIDDEN
 * (detail: this count), as for geometry. 0 for a cell that does not exist. */
uint8_t ms_access_cell_apo_steps(const ms_model *model, const ms_access *grant, uint32_t cell);

/* Resolves one request entry (validated as PROTOCOL.md section 4.10 requires)
 * on model under grant to the byte range [out->begin, out->end) of the cell's
 * stream that may be sent; for stream INDEX, of the stored bytes of the
 * subtree whose id is the entry's cell_id (ms_archive_subtree; UNKNOWN_CELL
 * when it is not a subtree id). Errors: MS_ERR_RANGE with fault->code
 * UNKNOWN_CELL, RANGE_NOT_SATISFIABLE or FORBIDDEN (detail as in PROTOCOL.md);
 * MS_ERR_CORRUPT (fault INTERNAL) for an inconsistent step table; MS_ERR_ARG
 * for an entry that fails validation. */
ms_status ms_access_resolve(const ms_model *model, const ms_access *grant,
                            const ms_proto_cell_request *request, ms_proto_byte_range *out,
                            ms_proto_fault *fault, ms_error *err);

#endif
