/* APO chunks for the browser client: see ms_web_apo.h. */
#include "ms_web_apo.h"

#include <stdbool.h>
#include <stdlib.h>

#include "ms_apo_chunk.h"
#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_preview.h"
#include "ms_view_decoder.h"

typedef struct apo_planned {
    uint32_t cell, levels, bytes;
} apo_planned;

struct ms_web_apo {
    ms_web_view *web;
    uint8_t *held; /* per cell: levels held */
    uint32_t cells;
    apo_planned *plan;
    uint32_t plan_count;
};

ms_web_apo *ms_web_apo_new(ms_web_view *view)
{
    ms_web_apo *a = calloc(1, sizeof *a);
    if (!a)
        return NULL;
    a->web = view;
    a->cells = ms_web_view_cell_count(view);
    a->held = calloc(a->cells ? a->cells : 1, 1);
    a->plan = malloc((a->cells ? a->cells : 1) * sizeof *a->plan);
    if (!a->held || !a->plan) {
        ms_web_apo_free(a);
        return NULL;
    }
    return a;
}

void ms_web_apo_free(ms_web_apo *a)
{
    if (!a)
        return;
    free(a->held);
    free(a->plan);
    free(a);
}

/* The cell's cube as the client core takes it (ms_core_cell_box). */
static double cell_box(const ms_archive_header *h, const ms_archive_cell *rec, double lo[3], double hi[3])
{
    double side = h->box_side;
    for (unsigned l = 0; l < rec->level; ++l)
        side /= (double)h->n;
    for (int a = 0; a < 3; ++a) {
        lo[a] = h->box_origin[a] + side * rec->position[a];
        hi[a] = lo[a] + side;
    }
    return side;
}

void ms_web_apo_geometry(ms_web_apo *a, int on, double detail_tolerance_px)
{
    ms_web_view_parts p;
    ms_web_view_parts_get(a->web, &p);
    bool apo = on && ms_archive_get_header(p.index)->has_apo && detail_tolerance_px > 0 &&
               p.params->tolerance_px > 0;
    p.params->chunkless_tolerance_scale = apo ? detail_tolerance_px / p.params->tolerance_px : 0.0;
}

uint32_t ms_web_apo_plan(ms_web_apo *a, unsigned max_levels, double detail_tolerance_px)
{
    a->plan_count = 0;
    ms_web_view_parts p;
    ms_web_view_parts_get(a->web, &p);
    if (!p.camera)
        return 0;
    const ms_archive_header *h = ms_archive_get_header(p.index);
    ms_frustum frustum;
    ms_camera_frustum(p.camera, &frustum);
    for (uint32_t i = 0; i < a->cells; ++i) {
        const ms_archive_cell *rec = ms_archive_get_cell(p.index, i);
        /* shown, with a chunk, not about to split (its children replace it) */
        if (!rec || rec->apo_length == 0 || rec->apo_levels == 0 || ms_view_state(p.view, i) != MS_VIEW_SHOWN ||
            ms_view_target(p.view, i) == MS_VIEW_TARGET_SPLIT)
            continue;
        double lo[3], hi[3];
        double side = cell_box(h, rec, lo, hi);
        if (!ms_frustum_keeps_box(&frustum, lo, hi, p.params->margin))
            continue;
        unsigned cap = max_levels < rec->apo_levels ? max_levels : rec->apo_levels;
        if (p.params->permitted_steps) {
            /* a preview reads no texel finer than its own grid step (the
             * server's rule, the same function) */
            unsigned readable = ms_archive_preview_apo_levels(h, rec, p.params->permitted_steps);
            if (readable < cap)
                cap = readable;
        }
        if (cap == 0)
            continue;
        unsigned levels = ms_apo_footprint_levels(p.camera, lo, side, detail_tolerance_px, cap);
        if (levels <= a->held[i])
            continue;
        a->plan[a->plan_count++] =
            (apo_planned){i, levels, ms_archive_apo_prefix(p.index, i, levels - 1, NULL)};
    }
    return a->plan_count;
}

uint32_t ms_web_apo_plan_cell(const ms_web_apo *a, uint32_t k) { return k < a->plan_count ? a->plan[k].cell : 0; }
uint32_t ms_web_apo_plan_levels(const ms_web_apo *a, uint32_t k)
{
    return k < a->plan_count ? a->plan[k].levels : 0;
}
uint32_t ms_web_apo_plan_bytes(const ms_web_apo *a, uint32_t k) { return k < a->plan_count ? a->plan[k].bytes : 0; }

uint32_t ms_web_apo_held(const ms_web_apo *a, uint32_t cell) { return cell < a->cells ? a->held[cell] : 0; }

uint32_t ms_web_apo_level_texels(const ms_web_apo *a, uint32_t cell, uint32_t level)
{
    ms_web_view_parts p;
    ms_web_view_parts_get(a->web, &p);
    const ms_archive_cell *rec = cell < a->cells ? ms_archive_get_cell(p.index, cell) : NULL;
    if (!rec || level >= rec->apo_levels || rec->apo_length == 0)
        return 0;
    uint32_t upto = 0, below = 0;
    ms_archive_apo_prefix(p.index, cell, level, &upto);
    if (level > 0)
        ms_archive_apo_prefix(p.index, cell, level - 1, &below);
    return upto - below;
}

ms_status ms_web_apo_give(ms_web_apo *a, uint32_t cell, uint32_t levels, const uint32_t *words, uint32_t count)
{
    ms_web_view_parts p;
    ms_web_view_parts_get(a->web, &p);
    const ms_archive_cell *rec = cell < a->cells ? ms_archive_get_cell(p.index, cell) : NULL;
    if (!rec || rec->apo_length == 0 || levels == 0 || levels > rec->apo_levels || levels > MS_APO_MAX_LEVELS)
        return ms_error_set(p.err, MS_ERR_ARG, "cell %u: no such APO levels (%u)", cell, levels);
    uint32_t table[MS_APO_MAX_LEVELS], total = 0;
    for (uint32_t l = 0; l < rec->apo_levels && l < MS_APO_MAX_LEVELS; ++l)
        table[l] = ms_web_apo_level_texels(a, cell, l);
    for (uint32_t l = 0; l < levels; ++l)
        total += table[l];
    if (count != total)
        return ms_error_set(p.err, MS_ERR_ARG, "cell %u: %u APO words for %u levels, which hold %u", cell, count,
                            levels, total);
    ms_apo_view check;
    ms_status st = ms_apo_view_init(&check, table, rec->apo_levels, words, count, p.err);
    if (st != MS_OK)
        return st;
    if (check.complete_levels != levels)
        return ms_error_set(p.err, MS_ERR_CORRUPT, "cell %u: %u APO levels complete of %u", cell,
                            check.complete_levels, levels);
    if (levels > a->held[cell])
        a->held[cell] = (uint8_t)levels;
    return MS_OK;
}
