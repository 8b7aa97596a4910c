/* The client core's network part (internal to client/core; docs/CLIENT.md,
 * "The core's parts"): a link (ms_core_link, ms_client_core.h) owns one
 * connection to meshserve (ms_client.h) and everything on it: the link's
 * thread and event loop, the requests in flight for every member core (slots),
 * the window, the read throttle, the answer time-out, reconnecting with
 * backoff, reopening each member's model and resuming its ranges, giving up.
 *
 *   ms_core_link.c            the link object: made, freed, members joining and
 *                             leaving (under the link's lock), its figures
 *   ms_client_core_net.c      the link's thread: connecting, frames received,
 *                             models opened, reconnects, the tick
 *   ms_core_link_requests.c   its requests: slots, each round's plan (members'
 *                             wants merged by priority under the window), cancels
 *
 * Thread: the link's own, but for ms_core_link_join/leave/get_stats (the
 * caller's, under the link's lock). It meets a member core only through what
 * the core shares under its lock (ms_client_core_internal.h): the inbox it
 * pushes received chunks into (ms_core_push_chunk), the want list it reads, the
 * index it hands over at open, and the network figures; it never touches the
 * decoder's state. */
#ifndef MS_CORE_NET_H
#define MS_CORE_NET_H

#include <event2/event.h>
#include <pthread.h>
#include <stdbool.h>
#include <stdint.h>

#include "ms_client.h"
#include "ms_client_core.h"
#include "ms_core_queue.h"

#define MAX_SLOTS 512u
#define NO_SLOT 0xFFFFFFFFu
#define SLOT_BUCKET_BITS 10u /* 1,024 chains for at most MAX_SLOTS slots */
/* A stored subtree's size before its first frame tells it (a window's guess:
 * the dragon's average is 1.5 KB, a 30,000-triangle demo's 0.9 KB) */
#define SUBTREE_BYTES_GUESS 2048u

/* A request in flight on the current connection, for member `member` of the
 * link. A finished request stays (done) until the member's decode thread has
 * taken its last chunk (last_seq), so that wants computed before that do not
 * ask for its bytes again. */
typedef struct slot {
    bool used, cancelled, keep, done;
    uint64_t last_seq;
    uint32_t id, cell, start, end, got;
    uint8_t stream, member;
    double sent_at;
    uint32_t next; /* next slot of the same chain (slot_buckets) */
} slot;

/* A core's place in a link: what the connection knows of it. The entry is
 * filled by ms_core_link_join (under the link's lock, state JOINING) and
 * otherwise the link thread's own. */
enum { MEMBER_FREE = 0, MEMBER_JOINING, MEMBER_ACTIVE, MEMBER_LEAVING };

typedef struct link_member {
    uint8_t state;              /* MEMBER_*: under the link's lock */
    bool seen;                  /* the link's thread took it in (and has not let go) */
    bool retired;               /* failed or stopping: its model closed, nothing sent */
    ms_core *core;              /* NULL once retired and left */
    uint32_t handle;            /* its model's handle on this connection (ready) */
    uint32_t open_request;      /* the OPEN_MODEL in flight, 0 none */
    bool ready;                 /* its model is open on this connection */
    bool opened_once;           /* its model opened once: content_id, by_subtree hold */
    uint64_t content_id;
    uint32_t cell_count;        /* the model's, from its index */
    bool by_subtree;            /* it opened with its index head */
    double down_since;          /* its model not open since (link time), < 0 open */
    want *wants;                /* a copy of its decode thread's wants */
    size_t want_count, want_cap;
    uint64_t want_serial;
    uint64_t consumed_seq;      /* chunks its decode thread had taken for `wants` */
} link_member;

struct ms_core_link {
    ms_core_link_options o;
    char *host, *token, *agent;
    double t0;
    uint64_t window;

    pthread_mutex_t lock;
    pthread_cond_t left;        /* a leaving member was retired */
    /* --- shared, under lock --- */
    bool stopping;
    link_member members[MS_CORE_LINK_MAX_MEMBERS];
    bool connected;
    uint64_t connections, socket_bytes, requests;

    pthread_t thread;
    bool started;

    /* --- the link's thread only --- */
    struct event_base *base;
    struct event *tick;
    ms_client *client;
    bool dead;                  /* the connection ended: freed on the next tick */
    char dead_why[256];
    double last_activity, reconnect_at, down_since, backoff;
    bool was_waiting;           /* at the last tick something was awaited */
    uint64_t last_read;         /* ms_client_bytes_read at the last tick */
    uint64_t in_flight;         /* bytes requested, not yet received, all members */
    uint64_t plans;             /* planning rounds that sent something */
    /* OPEN_MODELs of members that left before the answer: the handle it
     * brings is closed at once */
    uint32_t orphan_opens[MS_CORE_LINK_MAX_MEMBERS];
    unsigned orphan_count;
    slot slots[MAX_SLOTS];
    unsigned slots_used, slots_active;
    uint32_t slot_buckets[1u << SLOT_BUCKET_BITS]; /* chains by (member, cell, stream) */
};

/* The link's thread (arg: the ms_core_link) and its periodic event (5 ms),
 * created with the event base. */
void *ms_core_net_main(void *arg);
void ms_core_net_tick(evutil_socket_t fd, short what, void *arg);
/* The merge of several want lists, each best first (a link's members'):
 * the list whose next want, lists[i][cursors[i]], is the most urgent (lowest
 * priority; of equals, the lowest i), or -1 when every list is exhausted.
 * NULL lists are skipped. */
int ms_core_merge_next(const want *const *lists, const size_t *counts, const size_t *cursors,
                       unsigned n);
/* The link's requests (ms_core_link_requests.c), all on the link's thread:
 * seconds since the link started;
 * the core of slot s's member; whether member m is live (taken in, not failed
 * or stopping); the slot of request id (UINT32_MAX: none); ending slot k
 * (forgotten, its bytes out of the window), every slot of member i (i < 0:
 * of all), or slot k on its last chunk; whether a member's model is being
 * opened (no requests go out meanwhile); and one round of requests: the
 * members' wants merged by priority under the window, cancels of the
 * unwanted, REQUEST_CELLS sent. */
double ms_core_link_since_start(const ms_core_link *link);
ms_core *ms_core_link_core_of(ms_core_link *l, const slot *s);
bool ms_core_link_live(const link_member *m);
uint32_t ms_core_link_slot_find(ms_core_link *l, uint32_t id);
void ms_core_link_end_slot(ms_core_link *l, uint32_t k);
void ms_core_link_end_slots(ms_core_link *l, int i);
void ms_core_link_finish_slot(ms_core_link *l, uint32_t k);
bool ms_core_link_opening(const ms_core_link *l);
void ms_core_link_fill(ms_core_link *l);
/* Drops the connection at the end of this turn, with why as the reason. */
void ms_core_link_mark_dead(ms_core_link *l, const char *why);
/* Makes c a member (state JOINING: the link's thread opens its model);
 * MS_ERR_ARG when the link is full. */
ms_status ms_core_link_join(ms_core_link *link, ms_core *c, ms_error *err);
/* Waits until the link's thread has retired c (its model closed, its
 * requests forgotten); the link no longer touches c after. */
void ms_core_link_leave(ms_core_link *link, ms_core *c);

#endif
