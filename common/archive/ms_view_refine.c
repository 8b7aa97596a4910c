/* Refining shown cells on a pool (ms_view_refine.h). */
#include "ms_view_refine.h"

#include <stdlib.h>

typedef struct refine_batch {
    ms_view *view;
    const ms_view_refine_job *jobs;
} refine_batch;

static void refine_one(void *ctx, size_t k)
{
    const refine_batch *b = ctx;
    (void)ms_view_set_bits(b->view, b->jobs[k].cell, b->jobs[k].bits, NULL);
}

/* Largest precision first: the longest decodes start first, so the threads
 * finish together. */
static int compare_jobs_by_work(const void *x, const void *y)
{
    const ms_view_refine_job *a = x, *b = y;
    return a->bits > b->bits ? -1 : a->bits < b->bits;
}

/* The precision `cell` can go up to now, or 0 when it is not to be refined. */
static unsigned refine_goal(const ms_view *view, uint32_t cell)
{
    uint8_t target = ms_view_target(view, cell);
    if (ms_view_state(view, cell) != MS_VIEW_SHOWN || target == MS_VIEW_TARGET_HIDDEN)
        return 0;
    const ms_archive_cell *rec = ms_view_cell(view, cell);
    if (!rec || rec->geometry_length == 0 || ms_view_held_bytes(view, cell) == 0)
        return 0;
    unsigned goal = target == MS_VIEW_TARGET_SPLIT ? rec->bits_max : target;
    unsigned avail = ms_view_available_bits(view, cell);
    if (goal > avail)
        goal = avail;
    return goal > ms_view_bits(view, cell) ? goal : 0;
}

size_t ms_view_refine_parallel(ms_view *view, ms_pool *pool, ms_view_refine_jobs *list)
{
    list->count = 0;
    for (uint32_t c = 0; c != MS_ARCHIVE_NONE; c = ms_view_next_known(view, c)) {
        unsigned goal = refine_goal(view, c);
        if (!goal)
            continue;
        if (list->count == list->cap) {
            size_t cap = list->cap ? 2 * list->cap : 64;
            ms_view_refine_job *grown = realloc(list->jobs, cap * sizeof *grown);
            if (!grown)
                break;
            list->jobs = grown;
            list->cap = cap;
        }
        list->jobs[list->count++] = (ms_view_refine_job){c, goal};
    }
    if (list->count > 1)
        qsort(list->jobs, list->count, sizeof *list->jobs, compare_jobs_by_work);
    refine_batch batch = {view, list->jobs};
    if (pool)
        ms_pool_for(pool, list->count, refine_one, &batch);
    else
        for (size_t k = 0; k < list->count; ++k)
            refine_one(&batch, k);
    return list->count;
}

void ms_view_refine_jobs_free(ms_view_refine_jobs *list)
{
    free(list->jobs);
    *list = (ms_view_refine_jobs){0};
}
