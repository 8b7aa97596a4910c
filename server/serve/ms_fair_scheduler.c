/* Round-robin output scheduler: see ms_fair_scheduler.h. */
#include "ms_fair_scheduler.h"

#include <event2/event.h>
#include <string.h>

static bool ring_empty(const ms_fair_scheduler *s) { return s->ring.next == &s->ring; }

static void unlink_node(ms_fair_link *link)
{
    link->prev->next = link->next;
    link->next->prev = link->prev;
    link->prev = link->next = NULL;
}

static void append(ms_fair_scheduler *s, ms_fair_link *link)
{
    link->prev = s->ring.prev;
    link->next = &s->ring;
    s->ring.prev->next = link;
    s->ring.prev = link;
}

static void pump(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_fair_scheduler *s = arg;
    for (unsigned served = 0; served < s->chunks_per_turn && !ring_empty(s); ++served) {
        /* Out of the ring while it sends (send may wake or forget it), back at
         * the tail if it has more and room for it. */
        ms_fair_link *link = s->ring.next;
        unlink_node(link);
        if (s->send(link, s->arg) && !link->next)
            append(s, link);
    }
    if (!ring_empty(s))
        event_active(s->pump, EV_TIMEOUT, 0);
}

ms_status ms_fair_scheduler_init(ms_fair_scheduler *s, struct event_base *base,
                                 ms_fair_send_fn send, void *arg, unsigned chunks_per_turn,
                                 ms_error *err)
{
    memset(s, 0, sizeof *s);
    s->ring.prev = s->ring.next = &s->ring;
    s->send = send;
    s->arg = arg;
    s->chunks_per_turn = chunks_per_turn ? chunks_per_turn : 1;
    s->pump = event_new(base, -1, 0, pump, s);
    if (!s->pump)
        return ms_error_set(err, MS_ERR_NOMEM, "cannot create the output scheduler");
    return MS_OK;
}

void ms_fair_scheduler_free(ms_fair_scheduler *s)
{
    if (s->pump)
        event_free(s->pump);
    while (!ring_empty(s))
        unlink_node(s->ring.next);
    s->pump = NULL;
}

void ms_fair_scheduler_wake(ms_fair_scheduler *s, ms_fair_link *link)
{
    if (!link->next)
        append(s, link);
    if (!event_pending(s->pump, EV_TIMEOUT, NULL))
        event_active(s->pump, EV_TIMEOUT, 0);
}

void ms_fair_scheduler_forget(ms_fair_scheduler *s, ms_fair_link *link)
{
    (void)s;
    if (link->next)
        unlink_node(link);
}
