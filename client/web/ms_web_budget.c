/* The browser view's memory budget (see ms_web_budget.h). */
#include "ms_web_budget.h"

#include <math.h>
#include <stdlib.h>

bool ms_web_cell_cube(const ms_archive *index, uint32_t cell, double out[4])
{
    const ms_archive_header *h = ms_archive_get_header(index);
    const ms_archive_cell *c = ms_archive_get_cell(index, cell);
    if (!c)
        return false;
    double side = h->box_side;
    for (unsigned l = 0; l < c->level; ++l)
        side /= (double)h->n;
    for (int a = 0; a < 3; ++a)
        out[a] = h->box_origin[a] + (double)c->position[a] * side;
    out[3] = side;
    return true;
}

static uint64_t cell_stream_bytes(const ms_view *view, uint32_t cell)
{
    return (uint64_t)ms_view_held_bytes(view, cell) + (uint64_t)ms_view_held_colour_bytes(view, cell);
}

/* Bytes of geometry and colour streams the view holds, over its known cells. */
static uint64_t held_stream_bytes(const ms_view *view)
{
    uint64_t total = 0;
    for (uint32_t c = ms_view_next_known(view, MS_ARCHIVE_NONE); c != MS_ARCHIVE_NONE; c = ms_view_next_known(view, c))
        total += cell_stream_bytes(view, c);
    return total;
}

typedef struct forgettable {
    uint32_t cell;
    double distance;
} forgettable;

static int compare_farthest_first(const void *x, const void *y)
{
    const forgettable *a = x, *b = y;
    if (a->distance != b->distance)
        return a->distance > b->distance ? -1 : 1;
    return a->cell < b->cell ? -1 : a->cell > b->cell;
}

/* A cell the budget may forget: hidden, not wanted by the selection, holding bytes. */
static bool forgettable_cell(const ms_view *view, uint32_t cell)
{
    return ms_view_state(view, cell) == MS_VIEW_HIDDEN && ms_view_target(view, cell) == MS_VIEW_TARGET_HIDDEN &&
           cell_stream_bytes(view, cell) > 0;
}

ms_status ms_web_budget_apply(ms_view *view, const ms_archive *index, const double eye[3], uint64_t budget,
                              uint64_t *cells, uint64_t *bytes, ms_error *err)
{
    if (budget == 0)
        return MS_OK;
    uint64_t held = held_stream_bytes(view);
    if (held <= budget)
        return MS_OK;
    size_t n = 0;
    for (uint32_t c = ms_view_next_known(view, MS_ARCHIVE_NONE); c != MS_ARCHIVE_NONE; c = ms_view_next_known(view, c))
        n += forgettable_cell(view, c);
    if (n == 0)
        return MS_OK;
    forgettable *list = malloc(n * sizeof *list);
    if (!list)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the memory budget");
    size_t k = 0;
    for (uint32_t c = ms_view_next_known(view, MS_ARCHIVE_NONE); c != MS_ARCHIVE_NONE; c = ms_view_next_known(view, c)) {
        double cube[4];
        if (!forgettable_cell(view, c) || !ms_web_cell_cube(index, c, cube))
            continue;
        double d2 = 0.0;
        for (int a = 0; a < 3; ++a) {
            double e = cube[a] + 0.5 * cube[3] - eye[a];
            d2 += e * e;
        }
        list[k++] = (forgettable){c, sqrt(d2)};
    }
    qsort(list, k, sizeof *list, compare_farthest_first);
    ms_status st = MS_OK;
    for (size_t i = 0; i < k && held > budget && st == MS_OK; ++i) {
        uint64_t b = cell_stream_bytes(view, list[i].cell);
        st = ms_view_forget(view, list[i].cell, err);
        if (st == MS_OK) {
            held -= b;
            *cells += 1;
            *bytes += b;
        }
    }
    free(list);
    return st;
}
