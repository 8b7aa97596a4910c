/* Refining and splitting a view's shown cells on a pool of threads: the part
 * of a pass that parallelises (ms_view_set_bits and ms_view_split on distinct
 * cells may run at once, ms_view_decoder.h), shared by the client core's
 * decode thread and the browser's web view.
 *
 * Thread-safety: call from the thread that owns the view, with no other call
 * on it running; the pool's helpers touch only the listed cells (and a split
 * cell's children). */
#ifndef MS_VIEW_REFINE_H
#define MS_VIEW_REFINE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_parallel.h"
#include "ms_view_decoder.h"

/* A shown cell to bring up to `bits`, then to split when `split`; what the
 * job did, filled by the thread that ran it. */
typedef struct ms_view_refine_job {
    uint32_t cell, bits;
    uint64_t cost;          /* the order's estimate: bytes held, and the
                               triangles a split partitions */
    bool split;
    bool on_helper;         /* a pool helper ran it, not the caller */
    uint64_t cpu_ns;        /* the running thread's CPU time inside the job */
} ms_view_refine_job;

/* What the calls did, summed (counts are exact; CPU times per thread,
 * CLOCK_THREAD_CPUTIME_ID, which the machine's load does not change much). */
typedef struct ms_view_refine_stats {
    uint64_t calls;           /* ms_view_refine_parallel calls */
    uint64_t waves;           /* pool loops (a wave: the cells shown when it starts) */
    uint64_t jobs, splits;    /* cells refined or split, and of them splits */
    uint64_t jobs_on_helpers; /* jobs a helper ran */
    uint64_t caller_cpu_ns, helper_cpu_ns; /* CPU time inside jobs, by thread kind */
    /* per wave max(its longest job, half its jobs' CPU time), summed: what
     * the waves take at the least on two threads (Amdahl, jobs indivisible) */
    uint64_t span2_ns;
} ms_view_refine_stats;

/* The caller's job list, kept between passes so that its room is reused
 * (zero it before the first call; ms_view_refine_jobs_free releases it). */
typedef struct ms_view_refine_jobs {
    ms_view_refine_job *jobs;
    size_t count, cap;
    uint32_t *next;           /* the cells the next wave looks at (scratch) */
    size_t next_count, next_cap;
    ms_view_refine_stats stats; /* summed over calls */
} ms_view_refine_jobs;

/* Moves the shown cells towards the last selection's targets in waves, each
 * wave one loop on `pool` (on the caller's thread alone when pool is NULL):
 * every SHOWN, not hidden-target cell whose target (bits_max for one that
 * will split) is finer than its bits and whose held bytes allow some of it
 * is refined to min(target, available); one whose target is SPLIT, whose
 * children's records are known and whose bytes reach bits_max is then split
 * too, and its children (SHOWN at bits_min) are the next wave's cells. Jobs
 * run largest first (bytes held, and for a split the triangles it
 * partitions: longest processing time first, so the threads finish
 * together). This is what ms_view_apply would do for those cells, in another
 * order: the same cut and complexes after it (apply does the rest: merges,
 * coarsening, cells waiting for bytes). A failure is left for ms_view_apply,
 * which meets it again and reports it; out of memory for the lists refines
 * fewer cells (apply does the rest). Returns the number of jobs run (cells
 * refined or split). */
size_t ms_view_refine_parallel(ms_view *view, ms_pool *pool, ms_view_refine_jobs *jobs);

void ms_view_refine_jobs_free(ms_view_refine_jobs *jobs);

#endif
