/* The per-connection request queue of meshserve: lowest priority value first,
 * ties in arrival order, removal from anywhere, look-up by id, byte counts. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_request_queue.h"

static ms_cell_request *request(uint32_t id, uint8_t priority, uint32_t bytes)
{
    ms_cell_request *r = calloc(1, sizeof *r);
    r->id = id;
    r->priority = priority;
    r->end = bytes;
    return r;
}

static void test_order_and_ties(void **state)
{
    (void)state;
    ms_request_queue q;
    ms_request_queue_init(&q);
    assert_int_equal(ms_request_queue_reserve(&q, 1000, NULL), MS_OK);
    /* 1000 requests, priorities cycling 0..9, pushed in id order. */
    for (uint32_t id = 1; id <= 1000; ++id)
        ms_request_queue_push(&q, request(id, (uint8_t)((id * 7) % 10), 10));
    assert_int_equal(q.queued_bytes, 10000);
    int last_priority = -1;
    uint32_t last_id = 0;
    for (int n = 0; n < 1000; ++n) {
        ms_cell_request *r = ms_request_queue_top(&q);
        assert_non_null(r);
        if (r->priority == last_priority)
            assert_true(r->id > last_id); /* FIFO among equals */
        else
            assert_true(r->priority > last_priority);
        last_priority = r->priority, last_id = r->id;
        ms_request_queue_remove(&q, r);
        free(r);
    }
    assert_null(ms_request_queue_top(&q));
    assert_int_equal(q.queued_bytes, 0);
    ms_request_queue_free(&q);
}

static void test_remove_anywhere_and_find(void **state)
{
    (void)state;
    ms_request_queue q;
    ms_request_queue_init(&q);
    uint32_t seed = 99;
    for (int round = 0; round < 5; ++round) {
        assert_int_equal(ms_request_queue_reserve(&q, 300, NULL), MS_OK);
        for (uint32_t k = 0; k < 300; ++k) {
            uint32_t id = 1 + round * 1000 + k;
            ms_request_queue_push(&q, request(id, (uint8_t)((seed = seed * 1103515245u + 12345u) >> 24), 5));
        }
        /* Remove every third id by look-up, wherever it sits in the heap. */
        for (uint32_t k = 0; k < 300; k += 3) {
            ms_cell_request *r = ms_request_queue_find(&q, 1 + round * 1000 + k);
            assert_non_null(r);
            ms_request_queue_remove(&q, r);
            free(r);
            assert_null(ms_request_queue_find(&q, 1 + round * 1000 + k));
        }
    }
    assert_int_equal(q.count, 5 * 200);
    /* Partly sent requests count only their remaining bytes. */
    ms_cell_request *top = ms_request_queue_top(&q);
    ms_request_queue_sent(&q, top, 2);
    assert_int_equal(q.queued_bytes, 5 * 200 * 5 - 2);
    /* The heap order still holds. */
    int last = -1;
    while ((top = ms_request_queue_top(&q))) {
        assert_true(top->priority >= last);
        last = top->priority;
        ms_request_queue_remove(&q, top);
        free(top);
    }
    assert_int_equal(q.queued_bytes, 0);
    ms_request_queue_free(&q);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_order_and_ties),
        cmocka_unit_test(test_remove_anywhere_and_find),
    };
    return cmocka_run_group_tests_name("request queue", tests, NULL, NULL);
}
