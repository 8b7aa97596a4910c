/* Selection: the target of every known cell for a camera (ms_view_select,
 * ms_view_cell_need; see ms_view_decoder.h). ms_view_apply, in
 * ms_view_decoder.c, then moves the view towards those targets. */
#include "ms_view_decoder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_grow.h"
#include "ms_view_decoder_internal.h"

static void cell_box(const ms_view *v, const ms_archive_cell *c, double lo[3], double hi[3])
{
    double side = v->header.box_side / (double)(1u << (v->shape.log2n * c->level));
    for (int a = 0; a < 3; ++a) {
        lo[a] = v->header.box_origin[a] + side * c->position[a];
        hi[a] = lo[a] + side;
    }
}

void ms_view_select_params_default(ms_view_select_params *p)
{
    p->tolerance_px = 1.0;
    p->margin = 0.0;
    p->hysteresis = MS_SELECT_HYSTERESIS_DEFAULT;
    p->culled_bits_less = 2.0;
    p->tolerance_scale = NULL;
    p->chunkless_tolerance_scale = 0.0;
    p->permitted_steps = 0;
    p->section_count = 0;
    p->no_root_floor = false;
}

/* The camera's frustum with the params' sections. */
static void params_frustum(const ms_camera *cam, const ms_view_select_params *p, ms_frustum *f)
{
    ms_camera_frustum(cam, f);
    for (unsigned k = 0; k < p->section_count && k < MS_SECTIONS_MAX; ++k)
        ms_frustum_add_section(f, p->sections[k]);
}

static double cell_tolerance(const ms_view_select_params *p, uint32_t cell,
                             const ms_archive_cell *rec)
{
    if (p->tolerance_scale)
        return p->tolerance_px * p->tolerance_scale[cell];
    if (p->chunkless_tolerance_scale > 0 && rec->apo_levels == 0)
        return p->tolerance_px * p->chunkless_tolerance_scale;
    return p->tolerance_px;
}

/* Pixels per world unit at distance d (+INFINITY at the eye). */
static double pixels_per_unit_at(const ms_camera *cam, double d)
{
    return d > 0 ? ms_camera_pixels_per_unit(cam) / d : INFINITY;
}

double ms_view_cell_need(const ms_view *v, const ms_camera *cam, uint32_t cell,
                         const ms_view_select_params *p)
{
    const vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return -1.0;
    double lo[3], hi[3];
    cell_box(v, &c->rec, lo, hi);
    ms_frustum f;
    params_frustum(cam, p, &f);
    if (!ms_frustum_keeps_box(&f, lo, hi, p->margin))
        return -1.0;
    double ppu = pixels_per_unit_at(cam, ms_camera_box_distance(cam, lo, hi));
    return ms_archive_bits_needed(&v->header, &c->rec, ppu, cell_tolerance(p, cell, &c->rec));
}

/* The need selection uses: the bits at which the cell's measured error
 * (ms_archive_bits_needed) projects to its tolerance at its box's nearest
 * point, for the root in view at least MS_ARCHIVE_ROOT_FLOOR_BITS; culled
 * cells get theirs less culled_bits_less. */
static double select_need(const ms_view *v, const ms_camera *cam, const ms_frustum *f,
                          const ms_view_select_params *p, uint32_t cell, const vcell *c)
{
    double lo[3], hi[3];
    cell_box(v, &c->rec, lo, hi);
    double ppu = pixels_per_unit_at(cam, ms_camera_box_distance(cam, lo, hi));
    double need = ms_archive_bits_needed(&v->header, &c->rec, ppu, cell_tolerance(p, cell, &c->rec));
    if (!ms_frustum_keeps_box(f, lo, hi, p->margin))
        need -= p->culled_bits_less;
    else if (cell == 0 && !p->no_root_floor && need < MS_ARCHIVE_ROOT_FLOOR_BITS)
        need = MS_ARCHIVE_ROOT_FLOOR_BITS; /* however small or coarse, a model in view is drawn */
    return need;
}

double ms_view_cell_select_need(const ms_view *v, const ms_camera *cam, uint32_t cell,
                                const ms_view_select_params *p)
{
    const vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return -INFINITY;
    ms_frustum f;
    params_frustum(cam, p, &f);
    return select_need(v, cam, &f, p, cell, c);
}

static void list_push(uint32_t **list, size_t *count, size_t *cap, bool *failed, uint32_t cell)
{
    if (!ms_grow((void **)list, cap, *count + 1, sizeof **list)) {
        *failed = true;
        return;
    }
    (*list)[(*count)++] = cell;
}

static void select_cell(ms_view *v, const ms_camera *cam, const ms_frustum *f,
                        const ms_view_select_params *p, uint32_t cell,
                        ms_view_select_report *report)
{
    vcell *c = ms_view_vcell(v, cell);
    double need = select_need(v, cam, f, p, cell, c);
    unsigned current = c->state == MS_VIEW_SHOWN ? c->bits
                       : c->state == MS_VIEW_SPLIT ? c->rec.bits_max + 1u
                                                   : c->rec.bits_min;
    /* a preview: nothing above its last bit is wanted (the cell's bits_min is
     * below it: its parent split only because the cap allowed more) */
    unsigned top = v->header.bits;
    if (p->permitted_steps && p->permitted_steps - 1u < top)
        top = p->permitted_steps - 1u;
    if (top < c->rec.bits_min)
        top = c->rec.bits_min;
    if (current > top)
        current = top;
    unsigned want = ms_select_bits(need, current, c->rec.bits_min, top, p->hysteresis);
    if (report && top < v->header.bits && need > (double)top)
        report->capped_count++;
    if (need > (double)top)
        need = (double)top; /* what the reader may have of it */
    bool inner = c->rec.first_child != MS_ARCHIVE_NONE;
    bool children = inner && ms_view_children_known(v, cell);
    if (want > c->rec.bits_max && children) {
        c->target = MS_VIEW_TARGET_SPLIT;
        for (uint32_t k = 0; k < v->group_size; ++k)
            select_cell(v, cam, f, p, c->rec.first_child + k, report);
        return;
    }
    c->target = (uint8_t)(want > c->rec.bits_max ? c->rec.bits_max : want);
    if (!report || !inner)
        return;
    if (want > c->rec.bits_max) /* a partial view: it stays until its children are known */
        list_push(&report->blocked, &report->blocked_count, &report->blocked_cap,
                  &report->out_of_memory, cell);
    else if (need > (double)c->rec.bits_max - 1.0 && top > c->rec.bits_max)
        list_push(&report->near, &report->near_count, &report->near_cap,
                  &report->out_of_memory, cell);
}

void ms_view_select(ms_view *v, const ms_camera *cam, const ms_view_select_params *p,
                    ms_view_select_report *report)
{
    /* every known cell's target is HIDDEN but those the walk from the root reaches */
    for (uint32_t g = 0; g < v->group_count; ++g) {
        vcell *block = v->groups[g];
        for (uint32_t k = 0; block && k < (g == 0 ? 1 : v->group_size); ++k)
            block[k].target = MS_VIEW_TARGET_HIDDEN;
    }
    if (report)
        report->blocked_count = report->near_count = report->capped_count = 0,
        report->out_of_memory = false;
    if (!ms_view_vcell(v, 0))
        return; /* nothing known yet */
    ms_frustum f;
    params_frustum(cam, p, &f);
    select_cell(v, cam, &f, p, 0, report);
}

uint8_t ms_view_target(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? c->target : MS_VIEW_TARGET_HIDDEN;
}

void ms_view_select_report_free(ms_view_select_report *report)
{
    if (!report)
        return;
    free(report->blocked);
    free(report->near);
    memset(report, 0, sizeof *report);
}
