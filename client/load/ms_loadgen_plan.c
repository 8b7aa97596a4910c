/* A virtual client's camera-driven request sequence: see ms_loadgen_plan.h. */
#include "ms_loadgen_plan.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_camera.h"
#include "ms_preview.h"
#include "ms_proto.h"

struct ms_loadgen_plan {
    const ms_archive *index;
    double phase, zoom_phase;
    uint64_t step;             /* camera steps taken */
    uint8_t max_geometry_step; /* permitted geometry steps - 1 */
    bool apo;                  /* request APO chunks */
    uint8_t *next_geometry;    /* per cell: first geometry step not yet requested */
    uint8_t *apo_requested;    /* per cell */
    uint8_t *selected;         /* per cell: in the current view */
    ms_view_cell *view, *spare; /* current and previous selection */
    size_t view_count, view_capacity, view_cursor;
    bool pass_produced;        /* the current pass over the view yielded a request */
};

#define TOLERANCE_PX 1.0

static void move_camera(ms_loadgen_plan *p);
#define APO_PRIORITY 200

ms_status ms_loadgen_plan_new(const ms_archive *index, uint32_t seed,
                              uint8_t permitted_geometry_steps, bool apo, ms_loadgen_plan **plan,
                              ms_error *err)
{
    *plan = NULL;
    ms_loadgen_plan *p = calloc(1, sizeof *p);
    uint32_t cells = ms_archive_get_header(index)->cell_count;
    if (!p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a load plan of %u cells", cells);
    p->index = index;
    p->phase = (seed * 2654435761u % 6283u) / 1000.0;
    p->zoom_phase = (seed * 40503u % 6283u) / 1000.0;
    p->max_geometry_step = permitted_geometry_steps ? permitted_geometry_steps - 1 : 0;
    p->apo = apo;
    p->next_geometry = calloc(cells, 1);
    p->apo_requested = calloc(cells, 1);
    p->selected = calloc(cells, 1);
    p->view_capacity = cells;
    p->view = malloc(cells * sizeof *p->view);
    p->spare = malloc(cells * sizeof *p->spare);
    if (!p->next_geometry || !p->apo_requested || !p->selected || !p->view || !p->spare) {
        ms_loadgen_plan_free(p);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a load plan of %u cells", cells);
    }
    move_camera(p); /* the first view, now rather than on the first request */
    *plan = p;
    return MS_OK;
}

void ms_loadgen_plan_free(ms_loadgen_plan *p)
{
    if (!p)
        return;
    free(p->next_geometry);
    free(p->apo_requested);
    free(p->selected);
    free(p->view);
    free(p->spare);
    free(p);
}

/* The camera at step t: an orbit around the model, zooming in and out. */
static void camera_at(const ms_loadgen_plan *p, ms_camera *camera)
{
    const ms_archive_header *h = ms_archive_get_header(p->index);
    double s = h->box_side, t = (double)p->step, center[3];
    for (int k = 0; k < 3; ++k)
        center[k] = h->box_origin[k] + s / 2;
    double angle = p->phase + 0.03 * t, elevation = 0.5 * sin(0.011 * t + p->phase);
    double radius = s * (1.1 + 0.8 * sin(0.017 * t + p->zoom_phase));
    double position[3] = {center[0] + radius * cos(elevation) * cos(angle),
                          center[1] + radius * sin(elevation),
                          center[2] + radius * cos(elevation) * sin(angle)};
    double target[3] = {center[0] + 0.2 * s * sin(0.05 * t), center[1], center[2]};
    const double up[3] = {0, 1, 0};
    if (ms_camera_look_at(position, target, up, 60.0, 1280, 720, s * 0.001, s * 100, camera,
                          NULL) != MS_OK)
        ms_camera_look_at(position, center, up, 60.0, 1280, 720, s * 0.001, s * 100, camera, NULL);
}

static void move_camera(ms_loadgen_plan *p)
{
    p->step++;
    ms_camera camera;
    camera_at(p, &camera);
    /* The previous view goes to the spare array; flags: 1 = was selected. */
    ms_view_cell *old = p->view;
    size_t old_count = p->view_count;
    p->view = p->spare;
    p->spare = old;
    size_t n = ms_view_select_cells(p->index, &camera, TOLERANCE_PX, p->view, p->view_capacity);
    if (n > p->view_capacity)
        n = p->view_capacity;
    for (size_t i = 0; i < n; ++i)
        p->selected[p->view[i].cell] = 2;
    /* Evict what left the view, as a client's cache would. */
    for (size_t i = 0; i < old_count; ++i) {
        uint32_t c = old[i].cell;
        if (p->selected[c] == 1)
            p->selected[c] = 0, p->next_geometry[c] = 0, p->apo_requested[c] = 0;
    }
    for (size_t i = 0; i < n; ++i)
        p->selected[p->view[i].cell] = 1;
    p->view_count = n;
    p->view_cursor = 0;
    p->pass_produced = false;
}

bool ms_loadgen_plan_next(ms_loadgen_plan *p, ms_loadgen_item *item, unsigned max_moves)
{
    for (unsigned moves = 0; moves <= max_moves;) {
        while (p->view_cursor < p->view_count) {
            const ms_view_cell *v = &p->view[p->view_cursor];
            const ms_archive_cell *c = ms_archive_get_cell(p->index, v->cell);
            unsigned want = v->bits < p->max_geometry_step ? v->bits : p->max_geometry_step;
            unsigned next = p->next_geometry[v->cell];
            if (next < c->bits_min)
                next = 0; /* the stream starts with its header */
            if (next <= want && want >= c->bits_min) {
                /* Two requests per cell: its header and first refinement at a low
                 * priority value (the first bits of every cell in view come
                 * first), then the rest of what the view needs. */
                unsigned first_batch_end = c->bits_min + 1u < want ? c->bits_min + 1u : want;
                unsigned last = next <= first_batch_end ? first_batch_end : want;
                uint8_t priority = (uint8_t)(next <= first_batch_end ? c->level : 64u + last);
                *item = (ms_loadgen_item){v->cell, MS_PROTO_STREAM_GEOMETRY, (uint8_t)next,
                                          (uint8_t)last, priority};
                p->next_geometry[v->cell] = (uint8_t)(last + 1);
                p->view_cursor++;
                p->pass_produced = true;
                return true;
            }
            /* under a preview, the levels it reads (the server's rule); else all */
            unsigned readable = ms_archive_preview_apo_levels(
                ms_archive_get_header(p->index), c, p->max_geometry_step + 1u);
            if (p->apo && !v->refined && !p->apo_requested[v->cell] && c->apo_levels &&
                readable > 0) {
                p->apo_requested[v->cell] = 1;
                unsigned last = readable >= MS_ARCHIVE_MAX_APO_LEVELS ? MS_PROTO_MAX_STEP : readable - 1u;
                *item = (ms_loadgen_item){v->cell, MS_PROTO_STREAM_APO, 0, (uint8_t)last,
                                          APO_PRIORITY};
                p->view_cursor++;
                p->pass_produced = true;
                return true;
            }
            p->view_cursor++;
        }
        if (p->pass_produced) { /* another pass: the next finer step of each cell */
            p->pass_produced = false;
            p->view_cursor = 0;
            continue;
        }
        if (moves++ == max_moves)
            break;
        move_camera(p);
    }
    return false;
}

bool ms_loadgen_plan_wanted(const ms_loadgen_plan *p, uint32_t cell) { return p->selected[cell]; }

uint64_t ms_loadgen_plan_steps(const ms_loadgen_plan *p) { return p->step; }

void ms_loadgen_plan_forget(ms_loadgen_plan *p, const ms_loadgen_item *item)
{
    if (item->stream == MS_PROTO_STREAM_APO)
        p->apo_requested[item->cell] = 0;
    else if (p->next_geometry[item->cell] > item->first)
        p->next_geometry[item->cell] = item->first;
    if (p->selected[item->cell] && p->view_cursor > 0)
        p->view_cursor = 0; /* look again from the top */
}

void ms_loadgen_item_range(const ms_archive *index, const ms_loadgen_item *item, uint32_t *start,
                           uint32_t *end)
{
    const ms_archive_cell *c = ms_archive_get_cell(index, item->cell);
    *start = *end = 0;
    if (!c)
        return;
    if (item->stream == MS_PROTO_STREAM_GEOMETRY) {
        unsigned first = item->first > c->bits_min ? item->first : c->bits_min;
        unsigned last = item->last < c->bits_max ? item->last : c->bits_max;
        if (first > last)
            return;
        *start = first == c->bits_min ? 0 : ms_archive_geometry_prefix(index, item->cell, first - 1);
        *end = ms_archive_geometry_prefix(index, item->cell, last);
        return;
    }
    if (!c->apo_levels || item->first >= c->apo_levels)
        return;
    unsigned last = item->last < c->apo_levels ? item->last : c->apo_levels - 1u;
    *start = item->first ? ms_archive_apo_prefix(index, item->cell, item->first - 1u, NULL) : 0;
    *end = ms_archive_apo_prefix(index, item->cell, last, NULL);
}
