/* The common thread pool and parallel-for: every block runs exactly once per
 * loop, on the helpers and the caller, across many loops of one pool; a pair
 * runs its block 0 on the caller; the thread's CPU clock (ms_thread_cpu_ns)
 * counts the thread's work and not its sleep. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>
#include <pthread.h>

#include "ms_parallel.h"

typedef struct counts {
    atomic_uint *runs; /* per block */
    uint64_t *out;     /* per block: its own output */
    uint64_t salt;
} counts;

static void count_block(void *ctx, size_t block)
{
    counts *c = ctx;
    atomic_fetch_add(&c->runs[block], 1);
    c->out[block] = block * 2654435761u + c->salt;
}

static void expect_each_once(const counts *c, size_t n, unsigned loops)
{
    for (size_t b = 0; b < n; ++b) {
        if (atomic_load(&c->runs[b]) != loops)
            fail_msg("block %zu ran %u times, expected %u", b, atomic_load(&c->runs[b]), loops);
        assert_int_equal(c->out[b], b * 2654435761u + c->salt);
    }
}

static void test_pool_runs_every_block_once_per_loop(void **state)
{
    (void)state;
    enum { N = 1000, LOOPS = 200 };
    atomic_uint runs[N];
    uint64_t out[N];
    for (size_t b = 0; b < N; ++b)
        atomic_init(&runs[b], 0);
    counts c = {runs, out, 0};
    ms_pool *pool;
    ms_error err;
    assert_int_equal(ms_pool_new(3, &pool, &err), MS_OK);
    assert_int_equal(ms_pool_helpers(pool), 3);
    for (unsigned loop = 0; loop < LOOPS; ++loop) {
        c.salt = loop;
        /* loops of varied size, one block and none among them */
        size_t n = loop % 7 == 0 ? 0 : loop % 5 == 0 ? 1 : N;
        memset(out, 0, sizeof out);
        ms_pool_for(pool, n, count_block, &c);
        for (size_t b = 0; b < n; ++b)
            assert_int_equal(out[b], b * 2654435761u + loop);
    }
    ms_pool_free(pool);
    unsigned full = 0, single = 0;
    for (unsigned loop = 0; loop < LOOPS; ++loop) {
        full += !(loop % 7 == 0) && !(loop % 5 == 0);
        single += !(loop % 7 == 0) && loop % 5 == 0;
    }
    assert_int_equal(atomic_load(&runs[0]), full + single);
    for (size_t b = 1; b < N; ++b)
        assert_int_equal(atomic_load(&runs[b]), full);
}

static void test_pool_without_helpers_runs_on_the_caller(void **state)
{
    (void)state;
    enum { N = 50 };
    atomic_uint runs[N];
    uint64_t out[N];
    for (size_t b = 0; b < N; ++b)
        atomic_init(&runs[b], 0);
    counts c = {runs, out, 7};
    ms_pool *pool;
    ms_error err;
    assert_int_equal(ms_pool_new(0, &pool, &err), MS_OK);
    assert_int_equal(ms_pool_helpers(pool), 0);
    ms_pool_for(pool, N, count_block, &c);
    ms_pool_free(pool);
    expect_each_once(&c, N, 1);
    ms_pool_free(NULL);
}

static void test_parallel_for_any_thread_count(void **state)
{
    (void)state;
    enum { N = 333 };
    static const unsigned threads[] = {0, 1, 2, 5, 1000};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; ++t) {
        atomic_uint runs[N];
        uint64_t out[N];
        for (size_t b = 0; b < N; ++b)
            atomic_init(&runs[b], 0);
        counts c = {runs, out, t};
        ms_error err;
        assert_int_equal(ms_parallel_for(threads[t], N, count_block, &c, &err), MS_OK);
        expect_each_once(&c, N, 1);
    }
    ms_error err;
    assert_int_equal(ms_parallel_for(4, 0, count_block, NULL, &err), MS_OK);
    assert_true(ms_parallel_cores() >= 1);
}

typedef struct pair_run {
    pthread_t caller, ran_on[2];
    atomic_uint runs[2];
} pair_run;

static void pair_block(void *ctx, size_t block)
{
    pair_run *r = ctx;
    r->ran_on[block] = pthread_self();
    atomic_fetch_add(&r->runs[block], 1);
}

static void test_pool_pair_runs_block_0_on_the_caller(void **state)
{
    (void)state;
    for (unsigned helpers = 0; helpers <= 2; ++helpers) {
        ms_pool *pool;
        ms_error err;
        assert_int_equal(ms_pool_new(helpers, &pool, &err), MS_OK);
        for (unsigned loop = 0; loop < 500; ++loop) {
            pair_run r;
            r.caller = pthread_self();
            atomic_init(&r.runs[0], 0);
            atomic_init(&r.runs[1], 0);
            ms_pool_pair(pool, pair_block, &r);
            assert_int_equal(atomic_load(&r.runs[0]), 1);
            assert_int_equal(atomic_load(&r.runs[1]), 1);
            assert_true(pthread_equal(r.ran_on[0], r.caller));
            if (helpers == 0)
                assert_true(pthread_equal(r.ran_on[1], r.caller));
        }
        /* ms_pool_for still hands out every block after pairs */
        atomic_uint runs[40];
        uint64_t out[40];
        for (size_t b = 0; b < 40; ++b)
            atomic_init(&runs[b], 0);
        counts c = {runs, out, 3};
        ms_pool_for(pool, 40, count_block, &c);
        expect_each_once(&c, 40, 1);
        ms_pool_free(pool);
    }
}

/* The thread's CPU clock: it moves with the thread's own work (a busy loop of
 * about 20 ms of CPU at the least, however loaded the machine), never back,
 * and not with a sleep of the thread (50 ms asleep add under 5 ms). */
static void test_thread_cpu_clock(void **state)
{
    (void)state;
    unsigned long long t0 = ms_thread_cpu_ns();
    assert_true(t0 > 0);
    volatile uint64_t x = 1;
    while (ms_thread_cpu_ns() - t0 < 20000000ull)
        for (int k = 0; k < 100000; ++k)
            x = x * 6364136223846793005ull + 1442695040888963407ull;
    unsigned long long t1 = ms_thread_cpu_ns();
    assert_true(t1 - t0 >= 20000000ull);
    struct timespec nap = {0, 50000000L};
    nanosleep(&nap, NULL);
    unsigned long long t2 = ms_thread_cpu_ns();
    assert_true(t2 >= t1);
    assert_true(t2 - t1 < 5000000ull);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pool_runs_every_block_once_per_loop),
        cmocka_unit_test(test_pool_without_helpers_runs_on_the_caller),
        cmocka_unit_test(test_parallel_for_any_thread_count),
        cmocka_unit_test(test_pool_pair_runs_block_0_on_the_caller),
        cmocka_unit_test(test_thread_cpu_clock),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
