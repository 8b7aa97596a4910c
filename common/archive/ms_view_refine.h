/* Refining a view's shown cells on a pool of threads: the part of a pass that
 * parallelises (ms_view_set_bits on distinct cells may run at once,
 * ms_view_decoder.h), shared by the client core's decode thread and the
 * browser's web view.
 *
 * Thread-safety: call from the thread that owns the view, with no other call
 * on it running; the pool's helpers touch only the listed cells. */
#ifndef MS_VIEW_REFINE_H
#define MS_VIEW_REFINE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_parallel.h"
#include "ms_view_decoder.h"

/* A shown cell to bring up to `bits`. */
typedef struct ms_view_refine_job {
    uint32_t cell, bits;
} ms_view_refine_job;

/* The caller's job list, kept between passes so that its room is reused
 * (zero it before the first call; ms_view_refine_jobs_free releases it). */
typedef struct ms_view_refine_jobs {
    ms_view_refine_job *jobs;
    size_t count, cap;
} ms_view_refine_jobs;

/* Lists every SHOWN, not hidden-target cell whose target (bits_max for one
 * that will split) is finer than its bits and whose held bytes allow some of
 * it, largest precision first, and refines them to min(target, available) on
 * `pool` (on the caller's thread alone when pool is NULL). What ms_view_apply
 * would decode first, in another order: the same cut after it. A failure is
 * left for ms_view_apply, which meets it again and reports it; out of memory
 * for the list refines fewer cells (apply does the rest). Returns the number
 * of cells refined. */
size_t ms_view_refine_parallel(ms_view *view, ms_pool *pool, ms_view_refine_jobs *jobs);

void ms_view_refine_jobs_free(ms_view_refine_jobs *jobs);

#endif
