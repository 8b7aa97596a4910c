/* Refining and splitting shown cells on a pool, in waves (ms_view_refine.h). */
#include "ms_view_refine.h"

#include <pthread.h>
#include <stdlib.h>

typedef struct refine_batch {
    ms_view *view;
    ms_view_refine_job *jobs;
    pthread_t caller;
} refine_batch;

static void refine_one(void *ctx, size_t k)
{
    const refine_batch *b = ctx;
    ms_view_refine_job *j = &b->jobs[k];
    unsigned long long t0 = ms_thread_cpu_ns();
    bool ok = j->bits <= ms_view_bits(b->view, j->cell) ||
              ms_view_set_bits(b->view, j->cell, j->bits, NULL) == MS_OK;
    if (ok && j->split)
        (void)ms_view_split(b->view, j->cell, NULL);
    j->cpu_ns = ms_thread_cpu_ns() - t0;
    j->on_helper = !pthread_equal(pthread_self(), b->caller);
}

/* Largest first (longest processing time first: the threads finish
 * together); ties by cell, so the order is the work's alone. */
static int compare_jobs_by_work(const void *x, const void *y)
{
    const ms_view_refine_job *a = x, *b = y;
    if (a->cost != b->cost)
        return a->cost > b->cost ? -1 : 1;
    return a->cell < b->cell ? -1 : a->cell > b->cell;
}

/* The job for `cell`, if any: false when it is not to be refined or split. */
static bool refine_job(const ms_view *view, uint32_t cell, ms_view_refine_job *job)
{
    uint8_t target = ms_view_target(view, cell);
    if (ms_view_state(view, cell) != MS_VIEW_SHOWN || target == MS_VIEW_TARGET_HIDDEN)
        return false;
    const ms_archive_cell *rec = ms_view_cell(view, cell);
    if (!rec)
        return false;
    unsigned bits = ms_view_bits(view, cell), goal = bits;
    /* an empty cell needs no bytes to change precision (nothing to decode) */
    if (rec->geometry_length == 0 || ms_view_held_bytes(view, cell) > 0) {
        unsigned want = target == MS_VIEW_TARGET_SPLIT || target > rec->bits_max ? rec->bits_max
                                                                                 : target;
        unsigned avail = ms_view_available_bits(view, cell);
        goal = want < avail ? want : avail;
        if (goal < bits)
            goal = bits;
    }
    /* as ms_view_apply: a cell to split goes to bits_max first */
    bool split = target == MS_VIEW_TARGET_SPLIT && rec->first_child != MS_ARCHIVE_NONE &&
                 goal == rec->bits_max && ms_view_children_known(view, cell);
    if (goal <= bits && !split)
        return false;
    *job = (ms_view_refine_job){.cell = cell, .bits = goal, .split = split,
                                .cost = ms_view_held_bytes(view, cell) +
                                        (split ? rec->triangle_count : 0)};
    return true;
}

static bool grow_jobs(ms_view_refine_jobs *list)
{
    if (list->count < list->cap)
        return true;
    size_t cap = list->cap ? 2 * list->cap : 64;
    ms_view_refine_job *grown = realloc(list->jobs, cap * sizeof *grown);
    if (!grown)
        return false;
    list->jobs = grown;
    list->cap = cap;
    return true;
}

/* The children of the wave's split cells, for the next wave; false when out
 * of memory (the next wave then does not run: apply does the rest). */
static bool note_children(const ms_view *view, ms_view_refine_jobs *list)
{
    list->next_count = 0;
    const ms_archive_header *h = ms_view_header(view);
    size_t group = (size_t)h->n * h->n * h->n;
    for (size_t k = 0; k < list->count; ++k) {
        const ms_view_refine_job *j = &list->jobs[k];
        if (!j->split || ms_view_state(view, j->cell) != MS_VIEW_SPLIT)
            continue;
        if (list->next_count + group > list->next_cap) {
            size_t cap = list->next_cap ? 2 * list->next_cap : 256;
            while (cap < list->next_count + group)
                cap *= 2;
            uint32_t *grown = realloc(list->next, cap * sizeof *grown);
            if (!grown)
                return false;
            list->next = grown;
            list->next_cap = cap;
        }
        uint32_t first = ms_view_cell(view, j->cell)->first_child;
        for (size_t c = 0; c < group; ++c)
            list->next[list->next_count++] = first + (uint32_t)c;
    }
    return true;
}

/* One wave: the jobs listed, largest first, on the pool; the figures summed. */
static void run_wave(ms_view *view, ms_pool *pool, ms_view_refine_jobs *list)
{
    if (list->count > 1)
        qsort(list->jobs, list->count, sizeof *list->jobs, compare_jobs_by_work);
    refine_batch batch = {view, list->jobs, pthread_self()};
    if (pool)
        ms_pool_for(pool, list->count, refine_one, &batch);
    else
        for (size_t k = 0; k < list->count; ++k)
            refine_one(&batch, k);
    ms_view_refine_stats *st = &list->stats;
    st->waves++;
    st->jobs += list->count;
    uint64_t sum = 0, longest = 0;
    for (size_t k = 0; k < list->count; ++k) {
        const ms_view_refine_job *j = &list->jobs[k];
        sum += j->cpu_ns;
        longest = j->cpu_ns > longest ? j->cpu_ns : longest;
        st->splits += j->split && ms_view_state(view, j->cell) == MS_VIEW_SPLIT;
        st->jobs_on_helpers += j->on_helper;
        *(j->on_helper ? &st->helper_cpu_ns : &st->caller_cpu_ns) += j->cpu_ns;
    }
    /* two threads cannot end the wave before its longest job, nor before
     * half its work */
    st->span2_ns += longest > sum / 2 ? longest : sum / 2;
}

size_t ms_view_refine_parallel(ms_view *view, ms_pool *pool, ms_view_refine_jobs *list)
{
    list->stats.calls++;
    size_t done = 0;
    /* the first wave: every known cell */
    list->count = 0;
    for (uint32_t c = 0; c != MS_ARCHIVE_NONE; c = ms_view_next_known(view, c)) {
        if (!grow_jobs(list))
            break;
        list->count += refine_job(view, c, &list->jobs[list->count]);
    }
    while (list->count > 0) {
        run_wave(view, pool, list);
        done += list->count;
        if (!note_children(view, list))
            break;
        /* the next: the children of the cells just split */
        list->count = 0;
        for (size_t k = 0; k < list->next_count; ++k) {
            if (!grow_jobs(list))
                break;
            list->count += refine_job(view, list->next[k], &list->jobs[list->count]);
        }
    }
    return done;
}

void ms_view_refine_jobs_free(ms_view_refine_jobs *list)
{
    free(list->jobs);
    free(list->next);
    *list = (ms_view_refine_jobs){0};
}
