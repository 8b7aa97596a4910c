/* Cell selection for a camera: see ms_view_select.h. */
#include "ms_view_select.h"

#include <math.h>

#define MAX_DEPTH 16

typedef struct selection {
    const ms_archive *index;
    const ms_camera *camera;
    ms_frustum frustum;
    double tolerance, margin;
    double side[MAX_DEPTH + 1]; /* cube side per nSP level */
    ms_view_cell *out;
    size_t capacity, count;
} selection;

static void visit(selection *s, uint32_t id, unsigned depth)
{
    const ms_archive_header *h = ms_archive_get_header(s->index);
    const ms_archive_cell *c = ms_archive_get_cell(s->index, id);
    if (!c || depth > MAX_DEPTH)
        return;
    double side = s->side[c->level < MAX_DEPTH ? c->level : MAX_DEPTH], lo[3], hi[3];
    for (int k = 0; k < 3; ++k) {
        lo[k] = h->box_origin[k] + side * c->position[k];
        hi[k] = lo[k] + side;
    }
    if (!ms_frustum_keeps_box(&s->frustum, lo, hi, s->margin))
        return;
    double distance = ms_camera_box_distance(s->camera, lo, hi);
    double ppu = distance > 0 ? ms_camera_pixels_per_unit(s->camera) / distance : INFINITY;
    double need = ms_archive_bits_needed(h, c, ppu, s->tolerance);
    if (id == 0 && need < MS_ARCHIVE_ROOT_FLOOR_BITS)
        need = MS_ARCHIVE_ROOT_FLOOR_BITS; /* a model in view is drawn (ms_archive.h) */
    unsigned bits = c->bits_max;
    if (need < c->bits_max)
        bits = need <= c->bits_min ? c->bits_min : (unsigned)ceil(need);
    bool refine = need > c->bits_max && c->first_child != MS_ARCHIVE_NONE;
    if (s->count < s->capacity)
        s->out[s->count] = (ms_view_cell){id, (uint8_t)bits, refine, distance};
    s->count++;
    if (!refine)
        return;
    uint32_t children = (uint32_t)h->n * h->n * h->n;
    for (uint32_t k = 0; k < children; ++k)
        visit(s, c->first_child + k, depth + 1);
}

size_t ms_view_select_cells(const ms_archive *index, const ms_camera *camera, double tolerance_px,
                      ms_view_cell *out, size_t capacity)
{
    selection s = {.index = index, .camera = camera, .tolerance = tolerance_px, .out = out, .capacity = capacity};
    ms_camera_frustum(camera, &s.frustum);
    const ms_archive_header *h = ms_archive_get_header(index);
    s.side[0] = h->box_side;
    for (int l = 1; l <= MAX_DEPTH; ++l)
        s.side[l] = s.side[l - 1] / h->n;
    s.margin = ms_archive_get_header(index)->box_side * 0.01;
    visit(&s, 0, 0);
    return s.count;
}
