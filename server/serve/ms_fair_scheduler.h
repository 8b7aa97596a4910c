/* Fair sharing of the server's output between connections: a ring of the
 * connections that have payload to send and room in their write buffer, served
 * round robin one chunk at a time by a "pump" event, so that no connection gets
 * a second chunk before every other ready one got its first (PROTOCOL.md
 * section 7). A connection whose write buffer is full leaves the ring and is
 * woken again by its write callback, so a slow reader never holds up the others.
 *
 * The pump serves a bounded number of chunks per loop iteration and then yields
 * to the event loop, so reads, accepts and timers keep flowing under load.
 *
 * Ownership: links are embedded in the caller's connection objects; the
 * scheduler never frees them. Thread-safety: the loop's thread only.
 */
#ifndef MS_FAIR_SCHEDULER_H
#define MS_FAIR_SCHEDULER_H

#include <stdbool.h>

#include "ms_error.h"

struct event_base;
struct event;

typedef struct ms_fair_link {
    struct ms_fair_link *prev, *next; /* NULL when not in the ring */
} ms_fair_link;

/* Sends one chunk for the connection that embeds link. Returns true when it
 * still has something to send and room to send it (stays in the ring). */
typedef bool (*ms_fair_send_fn)(ms_fair_link *link, void *arg);

typedef struct ms_fair_scheduler {
    struct event *pump;
    ms_fair_link ring; /* sentinel */
    ms_fair_send_fn send;
    void *arg;
    unsigned chunks_per_turn;
} ms_fair_scheduler;

ms_status ms_fair_scheduler_init(ms_fair_scheduler *scheduler, struct event_base *base,
                                 ms_fair_send_fn send, void *arg, unsigned chunks_per_turn,
                                 ms_error *err);
void ms_fair_scheduler_free(ms_fair_scheduler *scheduler);

/* Puts link in the ring (at the tail, if not there yet) and schedules the pump. */
void ms_fair_scheduler_wake(ms_fair_scheduler *scheduler, ms_fair_link *link);

/* Takes link out of the ring (no-op if absent); call before freeing its owner. */
void ms_fair_scheduler_forget(ms_fair_scheduler *scheduler, ms_fair_link *link);

#endif
