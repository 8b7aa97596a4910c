/* Parallel loops over numbered blocks of work, on pthreads: one persistent
 * pool of helper threads (ms_pool) and a one-shot parallel-for over it.
 *
 * Both run fn(ctx, block) once for every block in [0, block_count) and return
 * when all are done, the calling thread working too. Blocks are handed out
 * dynamically, so which thread runs a block varies; callers get results that do
 * not depend on the thread count by making each block write only its own
 * outputs and by fixing the block split from the work size alone (never from
 * the thread count). fn must be thread-safe across distinct blocks. With no
 * helper (or one block) everything runs on the caller's thread.
 */
#ifndef MS_PARALLEL_H
#define MS_PARALLEL_H

#include <stddef.h>

#include "ms_error.h"

typedef void (*ms_parallel_fn)(void *ctx, size_t block);

/* Number of online cores (at least 1). */
unsigned ms_parallel_cores(void);

/* The calling thread's CPU time so far, nanoseconds (CLOCK_THREAD_CPUTIME_ID;
 * 0 where the clock is missing): what a thread's work costs, which the
 * machine's load changes little, unlike wall time. */
unsigned long long ms_thread_cpu_ns(void);

/* One parallel loop on up to `threads` threads (0 = the number of online
 * cores), the caller's included; the helpers live for this call only. Returns
 * MS_ERR_NOMEM (with err set) if no helper could be set up; the work is done
 * all the same (on the threads that started, or on the caller alone). */
ms_status ms_parallel_for(unsigned threads, size_t block_count, ms_parallel_fn fn, void *ctx,
                          ms_error *err);

/* A pool of helper threads that sleep between loops, for a caller that runs
 * many short loops (the client core's decode passes). Owned by its creator. */
typedef struct ms_pool ms_pool;

/* Starts up to `helpers` threads besides the caller's (0: every loop runs on
 * the caller). Fewer start if the system refuses threads; the loops still
 * complete. MS_ERR_NOMEM if the pool itself cannot be allocated. */
ms_status ms_pool_new(unsigned helpers, ms_pool **out, ms_error *err);

/* The helper threads that did start. */
unsigned ms_pool_helpers(const ms_pool *pool);

/* Runs the blocks on the helpers and the calling thread; returns when all are
 * done. One loop at a time: a pool is used by one calling thread. */
void ms_pool_for(ms_pool *pool, size_t block_count, ms_parallel_fn fn, void *ctx);

/* Two blocks at once, for a two-stage pipeline: fn(ctx, 0) on the calling
 * thread and fn(ctx, 1) on a helper (or on the caller after block 0 when no
 * helper has taken it yet, or the pool has none); returns when both are done.
 * Block 0's thread is always the caller's, so what it allocates stays in one
 * malloc arena. One loop at a time, like ms_pool_for. */
void ms_pool_pair(ms_pool *pool, ms_parallel_fn fn, void *ctx);

/* Stops and joins the helpers (none may be inside ms_pool_for); NULL is a no-op. */
void ms_pool_free(ms_pool *pool);

#endif
