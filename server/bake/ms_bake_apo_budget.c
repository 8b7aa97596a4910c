/* The APO byte budget applied to a bake's archive: see ms_bake_apo_budget.h. */
#include "ms_bake_apo_budget.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

/* Cuts the stored chunk of e to `keep` levels (0: none) into *out. */
static ms_status cut_stored(ms_archive_writer *w, const ms_bake_apo_params *params,
                            const ms_bake_apo_budget_entry *e, uint32_t keep, ms_bake_apo_result *out,
                            ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (keep == 0)
        return MS_OK;
    uint8_t *data;
    uint32_t length;
    const uint32_t *table;
    uint8_t levels;
    ms_status st = ms_archive_writer_get_apo(w, e->chunk.cell, &data, &length, &table, &levels, err);
    if (st == MS_OK)
        st = ms_apo_budget_cut(data, length, table, levels, keep, params->zlib_level, out, err);
    free(data);
    return st;
}

/* Puts the cut r in place of e's stored chunk and counts what went. */
static ms_status store_cut(ms_archive_writer *w, ms_bake_apo_budget_entry *e, const ms_bake_apo_result *r,
                           ms_bake_apo_budget_report *report, ms_error *err)
{
    uint8_t *data;
    uint32_t length;
    const uint32_t *table;
    uint8_t levels;
    ms_status st = ms_archive_writer_get_apo(w, e->chunk.cell, &data, &length, &table, &levels, err);
    free(data);
    if (st != MS_OK)
        return st;
    uint64_t old_texels[MS_APO_MAX_LEVELS];
    for (uint32_t d = 0; d < levels; ++d)
        old_texels[d] = table[2 * d + 1] - (d ? table[2 * d - 1] : 0);
    ms_archive_writer_drop_apo(w, e->chunk.cell); /* table is gone with it */
    if (r->levels > 0)
        st = ms_archive_writer_put_apo(w, e->chunk.cell, r->data, (uint32_t)r->size, (uint32_t)(4 * r->texels),
                                       r->level_table, (uint8_t)r->levels, err);
    if (st != MS_OK)
        return st;
    report->chunks_cut++;
    report->chunks_removed += r->levels == 0;
    report->levels_dropped += levels - r->levels;
    for (uint32_t d = 0; d < levels; ++d) {
        uint64_t gone = old_texels[d] - (d < r->levels ? r->level_texels[d] : 0);
        report->level_texels_dropped[d] += gone;
        report->texels_dropped += gone;
    }
    report->internal_dropped += e->internal_nodes - r->internal_nodes;
    report->leaves_dropped += e->leaves - r->leaves;
    e->chunk.levels = r->levels;
    e->bytes = r->size;
    e->internal_nodes = r->internal_nodes;
    e->leaves = r->leaves;
    return MS_OK;
}

ms_status ms_bake_apo_budget_apply(ms_archive_writer *w, const ms_bake_apo_params *params, uint64_t geometry_bytes,
                                   ms_bake_apo_budget_entry *entries, size_t count,
                                   ms_bake_apo_budget_report *report, ms_error *err)
{
    memset(report, 0, sizeof *report);
    uint64_t total = 0;
    for (size_t i = 0; i < count; ++i)
        total += entries[i].bytes;
    report->bytes_before = report->bytes_after = total;
    if (!(params->budget > 0.0))
        return MS_OK;
    double limit = floor(params->budget * (double)geometry_bytes);
    report->limit = limit >= 1.8e19 ? UINT64_MAX : (uint64_t)limit;
    if (total <= report->limit)
        return MS_OK;
    ms_apo_budget_chunk *plan = malloc(count * sizeof *plan);
    ms_bake_apo_result *cut = calloc(count, sizeof *cut);
    bool *touched = calloc(count, sizeof *touched);
    ms_status st = MS_OK;
    if (!plan || !cut || !touched)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory planning the APO budget");
    for (size_t i = 0; st == MS_OK && i < count; ++i)
        plan[i] = entries[i].chunk;
    /* one level at a time, each cut counted at its real size */
    while (st == MS_OK && total > report->limit) {
        size_t i = ms_apo_budget_next(plan, count);
        if (i == count)
            break; /* nothing left: total is 0 */
        uint64_t was = touched[i] ? cut[i].size : entries[i].bytes;
        ms_bake_apo_result_free(&cut[i]);
        touched[i] = true;
        st = cut_stored(w, params, &entries[i], plan[i].levels - 1, &cut[i], err);
        plan[i].levels = cut[i].levels; /* the cut may lose more than one level */
        total = total - was + cut[i].size;
    }
    for (size_t i = 0; st == MS_OK && i < count; ++i)
        if (touched[i])
            st = store_cut(w, &entries[i], &cut[i], report, err);
    report->bytes_after = 0;
    for (size_t i = 0; i < count; ++i) {
        report->bytes_after += entries[i].bytes;
        if (cut)
            ms_bake_apo_result_free(&cut[i]);
    }
    free(plan);
    free(cut);
    free(touched);
    return st;
}
