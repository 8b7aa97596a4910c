/* Deterministic block-parallel loop on pthreads (see ms_parallel.h). */
#include "ms_parallel.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

typedef struct parallel_job {
    ms_parallel_fn fn;
    void *ctx;
    size_t block_count;
    atomic_size_t next;
} parallel_job;

unsigned ms_parallel_cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1u : (unsigned)n;
}

static void *worker(void *arg)
{
    parallel_job *job = arg;
    for (;;) {
        size_t b = atomic_fetch_add(&job->next, 1);
        if (b >= job->block_count)
            break;
        job->fn(job->ctx, b);
    }
    return NULL;
}

ms_status ms_parallel_for(unsigned threads, size_t block_count, ms_parallel_fn fn, void *ctx, ms_error *err)
{
    if (threads == 0)
        threads = ms_parallel_cores();
    if ((size_t)threads > block_count)
        threads = (unsigned)(block_count ? block_count : 1);
    parallel_job job = {.fn = fn, .ctx = ctx, .block_count = block_count};
    atomic_init(&job.next, 0);
    if (threads <= 1) {
        worker(&job);
        return MS_OK;
    }
    pthread_t *ids = malloc((threads - 1) * sizeof *ids);
    unsigned started = 0;
    if (ids)
        for (; started < threads - 1; ++started)
            if (pthread_create(&ids[started], NULL, worker, &job) != 0)
                break;
    worker(&job); /* the caller works too */
    for (unsigned i = 0; i < started; ++i)
        pthread_join(ids[i], NULL);
    free(ids);
    if (!ids)
        return ms_error_set(err, MS_ERR_NOMEM, "parallel: no memory for %u threads", threads);
    return MS_OK;
}
