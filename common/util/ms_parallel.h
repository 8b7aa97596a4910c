/* A deterministic parallel loop over numbered blocks of work, on pthreads.
 *
 * ms_parallel_for runs fn(ctx, block) once for every block in [0, block_count),
 * on up to `threads` threads (0 = the number of online cores), and returns when
 * all are done. Blocks are handed out dynamically, so which thread runs a block
 * varies; callers get results that do not depend on the thread count by making
 * each block write only its own outputs and by fixing the block split from the
 * work size alone (never from the thread count). fn must be thread-safe across
 * distinct blocks. With one thread (or one block) everything runs on the caller's
 * thread. Returns MS_ERR_NOMEM (with err set) if no thread could be started; if
 * some could, the work still completes on those.
 */
#ifndef MS_PARALLEL_H
#define MS_PARALLEL_H

#include <stddef.h>

#include "ms_error.h"

typedef void (*ms_parallel_fn)(void *ctx, size_t block);

/* Number of online cores (at least 1). */
unsigned ms_parallel_cores(void);

ms_status ms_parallel_for(unsigned threads, size_t block_count, ms_parallel_fn fn, void *ctx, ms_error *err);

#endif
