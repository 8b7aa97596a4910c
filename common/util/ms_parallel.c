/* Parallel loops over numbered blocks on a pool of pthreads (see ms_parallel.h).
 *
 * A loop is a round: the caller publishes fn, ctx and the block count under the
 * pool's lock and bumps the round number; every thread (helpers and caller)
 * claims blocks under the lock and counts them finished, and the caller waits
 * until all blocks are. A helper that wakes late finds no block left, so a
 * round never runs a block of another. */
#include "ms_parallel.h"

#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>
#include <unistd.h>

struct ms_pool {
    pthread_t *threads;
    unsigned count;
    pthread_mutex_t lock;
    pthread_cond_t go, done;
    bool quit;
    uint64_t round; /* incremented per loop */
    ms_parallel_fn fn;
    void *ctx;
    size_t block_count, next_block, finished;
};

unsigned ms_parallel_cores(void)
{
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1u : (unsigned)n;
}

unsigned long long ms_thread_cpu_ns(void)
{
    struct timespec t;
    if (clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) != 0)
        return 0;
    return (unsigned long long)t.tv_sec * 1000000000ull + (unsigned long long)t.tv_nsec;
}

/* Claims and runs blocks of the current round until none is left. */
static void run_blocks(ms_pool *p)
{
    for (;;) {
        pthread_mutex_lock(&p->lock);
        if (p->next_block >= p->block_count) {
            pthread_mutex_unlock(&p->lock);
            return;
        }
        size_t block = p->next_block++;
        ms_parallel_fn fn = p->fn;
        void *ctx = p->ctx;
        pthread_mutex_unlock(&p->lock);
        fn(ctx, block);
        pthread_mutex_lock(&p->lock);
        if (++p->finished == p->block_count)
            pthread_cond_broadcast(&p->done);
        pthread_mutex_unlock(&p->lock);
    }
}

static void *helper_main(void *arg)
{
    ms_pool *p = arg;
    uint64_t seen = 0;
    pthread_mutex_lock(&p->lock);
    for (;;) {
        while (!p->quit && p->round == seen)
            pthread_cond_wait(&p->go, &p->lock);
        if (p->quit)
            break;
        seen = p->round;
        pthread_mutex_unlock(&p->lock);
        run_blocks(p);
        pthread_mutex_lock(&p->lock);
    }
    pthread_mutex_unlock(&p->lock);
    return NULL;
}

ms_status ms_pool_new(unsigned helpers, ms_pool **out, ms_error *err)
{
    *out = NULL;
    ms_pool *p = calloc(1, sizeof *p);
    if (!p || (helpers && !(p->threads = calloc(helpers, sizeof *p->threads)))) {
        free(p);
        return ms_error_set(err, MS_ERR_NOMEM, "parallel: no memory for %u threads", helpers);
    }
    pthread_mutex_init(&p->lock, NULL);
    pthread_cond_init(&p->go, NULL);
    pthread_cond_init(&p->done, NULL);
    for (unsigned k = 0; k < helpers; ++k) {
        if (pthread_create(&p->threads[k], NULL, helper_main, p) != 0)
            break;
        p->count++;
    }
    *out = p;
    return MS_OK;
}

unsigned ms_pool_helpers(const ms_pool *pool)
{
    return pool->count;
}

void ms_pool_for(ms_pool *p, size_t block_count, ms_parallel_fn fn, void *ctx)
{
    if (p->count == 0 || block_count <= 1) {
        for (size_t b = 0; b < block_count; ++b)
            fn(ctx, b);
        return;
    }
    pthread_mutex_lock(&p->lock);
    p->fn = fn, p->ctx = ctx;
    p->block_count = block_count, p->next_block = 0, p->finished = 0;
    p->round++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->lock);
    run_blocks(p); /* the caller works too */
    pthread_mutex_lock(&p->lock);
    while (p->finished < p->block_count)
        pthread_cond_wait(&p->done, &p->lock);
    p->block_count = 0;
    pthread_mutex_unlock(&p->lock);
}

void ms_pool_pair(ms_pool *p, ms_parallel_fn fn, void *ctx)
{
    if (p->count == 0) {
        fn(ctx, 0);
        fn(ctx, 1);
        return;
    }
    pthread_mutex_lock(&p->lock);
    p->fn = fn, p->ctx = ctx;
    /* Only block 1 is handed out; block 0 is counted finished by the caller. */
    p->block_count = 2, p->next_block = 1, p->finished = 1;
    p->round++;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->lock);
    fn(ctx, 0);
    run_blocks(p); /* block 1, if no helper has taken it */
    pthread_mutex_lock(&p->lock);
    while (p->finished < p->block_count)
        pthread_cond_wait(&p->done, &p->lock);
    p->block_count = 0;
    pthread_mutex_unlock(&p->lock);
}

void ms_pool_free(ms_pool *p)
{
    if (!p)
        return;
    pthread_mutex_lock(&p->lock);
    p->quit = true;
    pthread_cond_broadcast(&p->go);
    pthread_mutex_unlock(&p->lock);
    for (unsigned k = 0; k < p->count; ++k)
        pthread_join(p->threads[k], NULL);
    free(p->threads);
    pthread_mutex_destroy(&p->lock);
    pthread_cond_destroy(&p->go);
    pthread_cond_destroy(&p->done);
    free(p);
}

ms_status ms_parallel_for(unsigned threads, size_t block_count, ms_parallel_fn fn, void *ctx,
                          ms_error *err)
{
    if (threads == 0)
        threads = ms_parallel_cores();
    if ((size_t)threads > block_count)
        threads = (unsigned)(block_count ? block_count : 1);
    ms_pool *p = NULL;
    ms_status s = MS_OK;
    if (threads > 1)
        s = ms_pool_new(threads - 1, &p, err);
    if (!p) {
        for (size_t b = 0; b < block_count; ++b)
            fn(ctx, b);
        return s;
    }
    ms_pool_for(p, block_count, fn, ctx);
    ms_pool_free(p);
    return MS_OK;
}
