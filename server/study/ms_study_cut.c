/* The cut a client shows for a camera, made locally (ms_study_cut.h). */
#include "ms_study_cut.h"

#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"

#define MAX_PASSES 64u

ms_status ms_study_cut(const ms_archive *archive, ms_view *view, const ms_camera *camera,
                       const ms_view_select_params *params, const uint32_t *apo_levels, ms_view_mesh *mesh,
                       ms_study_cut_report *report, ms_error *err)
{
    memset(report, 0, sizeof *report);
    double start = ms_now_seconds();
    uint32_t n = ms_view_cell_count(view);
    ms_status st = MS_OK;
    bool settled = false;
    while (!settled && st == MS_OK) {
        if (report->passes == MAX_PASSES) {
            st = ms_error_set(err, MS_ERR_RANGE, "study cut: the selection still changes after %u rounds",
                              MAX_PASSES);
            break;
        }
        report->passes++;
        ms_view_select(view, camera, params, NULL);
        ms_view_apply_report r;
        st = ms_view_apply(view, &r, err);
        settled = !r.splits && !r.merges && !r.refined && !r.coarsened;
    }
    if (st == MS_OK)
        st = ms_view_stitch(view, NULL, mesh, err);
    if (st != MS_OK)
        return st;
    size_t index_size;
    ms_archive_index_bytes(archive, &index_size);
    report->index_bytes = index_size;
    bool *draws = calloc(n ? n : 1, sizeof *draws);
    if (!draws)
        return ms_error_set(err, MS_ERR_NOMEM, "study cut: out of memory for %u cells", n);
    for (size_t t = 0; t < mesh->triangle_count; ++t)
        draws[mesh->triangle_cell[t]] = true;
    for (uint32_t c = 0; c < n; ++c) {
        ms_view_cell_state s = ms_view_state(view, c);
        if (s == MS_VIEW_HIDDEN)
            continue;
        report->geometry_bytes += ms_archive_geometry_prefix(archive, c, ms_view_bits(view, c));
        if (s == MS_VIEW_SHOWN) {
            report->shown_cells++;
            if (draws[c] && ms_view_cell_need(view, camera, c, params) >= 0)
                report->apo_bytes += apo_levels && apo_levels[c]
                                         ? ms_archive_apo_prefix(archive, c, apo_levels[c] - 1, NULL)
                                         : ms_archive_get_cell(archive, c)->apo_length;
        }
    }
    free(draws);
    report->triangles = mesh->triangle_count;
    report->seconds = ms_now_seconds() - start;
    return MS_OK;
}
