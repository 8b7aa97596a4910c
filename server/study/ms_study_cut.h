/* The cut a client shows for a camera, made locally from an archive file: the
 * view (ms_view_decoder.h) holds every payload, so selection and application
 * converge without waiting for bytes; what a client would have fetched for it is
 * counted from the index.
 *
 * Bytes of a cut: the index blob (ms_archive_index_bytes), plus per cell the
 * geometry prefix it is decoded at (a SHOWN cell at its precision, a SPLIT cell
 * at its bits_max: both are what a client must hold), plus, with APO, the chunk
 * prefix of apo_levels[cell] whole levels (0, or apo_levels NULL: the whole
 * chunk) of every SHOWN cell
 * that draws triangles and meets the frustum (grown by the selection's margin):
 * culled cells get no APO.
 *
 * Thread-safety: the view is changed; one caller per view.
 */
#ifndef MS_STUDY_CUT_H
#define MS_STUDY_CUT_H

#include <stdint.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_error.h"
#include "ms_view_decoder.h"

typedef struct ms_study_cut_report {
    uint32_t passes;          /* select + apply rounds until nothing changed */
    uint32_t shown_cells;
    uint64_t index_bytes, geometry_bytes, apo_bytes;
    uint64_t triangles;       /* of the stitched mesh */
    double seconds;           /* selection, application (decoding) and stitching */
} ms_study_cut_report;

/* Selects and applies until the view stops changing (at most 64 rounds:
 * MS_ERR_RANGE beyond, which would be a selection that oscillates), then
 * stitches every shown cell into *mesh (zeroed or previously filled). */
ms_status ms_study_cut(const ms_archive *archive, ms_view *view, const ms_camera *camera,
                       const ms_view_select_params *params, const uint32_t *apo_levels, ms_view_mesh *mesh,
                       ms_study_cut_report *report, ms_error *err);

#endif
