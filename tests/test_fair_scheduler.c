/* meshserve's output scheduler: ready connections are served one chunk each
 * in turn (round robin), a connection that leaves the ring (full write buffer)
 * does not stop the others, and a woken one rejoins at the tail. */
#include <event2/event.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_fair_scheduler.h"

typedef struct fake_conn {
    ms_fair_link link; /* first */
    char name;
    int chunks_left;   /* data to send */
    int room;          /* chunks its write buffer still takes */
} fake_conn;

typedef struct record {
    char order[256];
    size_t count;
} record;

static bool send_one(ms_fair_link *link, void *arg)
{
    fake_conn *c = (fake_conn *)link;
    record *r = arg;
    if (c->chunks_left == 0 || c->room == 0)
        return false;
    r->order[r->count++] = c->name;
    c->chunks_left--;
    c->room--;
    return c->chunks_left > 0 && c->room > 0;
}

static void run_until_idle(struct event_base *base)
{
    for (int i = 0; i < 100; ++i)
        event_base_loop(base, EVLOOP_NONBLOCK);
}

static void test_round_robin(void **state)
{
    (void)state;
    struct event_base *base = event_base_new();
    record r = {{0}, 0};
    ms_fair_scheduler s;
    assert_int_equal(ms_fair_scheduler_init(&s, base, send_one, &r, 4, NULL), MS_OK);
    fake_conn a = {{0}, 'a', 3, 100}, b = {{0}, 'b', 1, 100}, c = {{0}, 'c', 4, 100};
    ms_fair_scheduler_wake(&s, &a.link);
    ms_fair_scheduler_wake(&s, &b.link);
    ms_fair_scheduler_wake(&s, &c.link);
    ms_fair_scheduler_wake(&s, &a.link); /* already in the ring: no second place */
    run_until_idle(base);
    r.order[r.count] = '\0';
    assert_string_equal(r.order, "abcacacc");
    ms_fair_scheduler_free(&s);
    event_base_free(base);
}

static void test_full_buffer_leaves_and_rejoins(void **state)
{
    (void)state;
    struct event_base *base = event_base_new();
    record r = {{0}, 0};
    ms_fair_scheduler s;
    assert_int_equal(ms_fair_scheduler_init(&s, base, send_one, &r, 64, NULL), MS_OK);
    fake_conn slow = {{0}, 's', 10, 1}, fast = {{0}, 'f', 5, 100};
    ms_fair_scheduler_wake(&s, &slow.link);
    ms_fair_scheduler_wake(&s, &fast.link);
    run_until_idle(base);
    r.order[r.count] = '\0';
    assert_string_equal(r.order, "sfffff"); /* the slow one's buffer is full after one chunk */
    slow.room = 2; /* its write callback: room again */
    ms_fair_scheduler_wake(&s, &slow.link);
    run_until_idle(base);
    r.order[r.count] = '\0';
    assert_string_equal(r.order, "sfffffss");
    /* A connection that goes away is forgotten. */
    slow.room = 5;
    ms_fair_scheduler_wake(&s, &slow.link);
    ms_fair_scheduler_forget(&s, &slow.link);
    run_until_idle(base);
    assert_int_equal(r.count, 8);
    ms_fair_scheduler_free(&s);
    event_base_free(base);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_robin),
        cmocka_unit_test(test_full_buffer_leaves_and_rejoins),
    };
    return cmocka_run_group_tests_name("fair scheduler", tests, NULL, NULL);
}
