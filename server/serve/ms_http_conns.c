/* The HTTP side door's connections: see ms_http_conns.h. */
#include "ms_http_conns.h"

#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <event2/http.h>
#include <event2/listener.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/queue.h>
#include <sys/resource.h>
#include <sys/socket.h>

#include "ms_progress.h"
#include "ms_server_internal.h"

#define SWEEP_INTERVAL_US 250000
/* A parked socket's receive buffer (the kernel doubles it): what a client
 * can make the kernel hold for it while it is parked. */
#define PARK_RECEIVE_BUFFER 2048

/* One HTTP connection, as the door tracks it: evhttp owns the connection;
 * the door holds a reference on its bufferevent (so the record never points
 * at freed memory) and learns of evhttp's free from the connection's close
 * callback (or, should that not come, from the sweep: the callbacks gone). */
typedef struct tracked_connection {
    ms_http_conns *conns;
    struct bufferevent *bev;
    struct evhttp_connection *evcon;    /* NULL until evhttp has made it (adopt) */
    struct evbuffer_cb_entry *on_input; /* watches the reads (trickle_check) */
    TAILQ_ENTRY(tracked_connection) waiting; /* in conns->waiting[trickling] unless dropped */
    size_t slot;           /* its index in conns->all */
    double deadline_from;  /* accept, or the last request received */
    size_t output_length;  /* bytes waiting at the last sweep */
    double output_since;   /* when output_length last changed */
    bool dropped;          /* shut down by the door; evhttp frees it next */
    bool answered;         /* a request of its own handled: an answer may be on its way */
    bool header_begun;     /* bytes of a request header read, the request not yet handled */
    bool trickling;        /* at MS_PRIORITY_TRICKLE: its header came in pieces */
    bool parked;           /* shed, held unread in conns->parked (dropped too) */
    double parked_since;
    TAILQ_ENTRY(tracked_connection) park; /* in conns->parked while parked */
} tracked_connection;

TAILQ_HEAD(waiting_list, tracked_connection);

struct ms_http_conns {
    ms_server *server;
    struct evconnlistener *listener;
    struct event *sweep;
    struct event *next_turn;    /* zero-delay timer: the loop's next turn */
    size_t accepts_this_turn;   /* connections accepted since next_turn was armed */
    tracked_connection **all;
    size_t count, capacity;
    size_t live;                /* not dropped: those that hold a slot */
    /* The live connections in the order of deadline_from, oldest first:
     * [0] those sending whole headers (or nothing yet), [1] the trickling. */
    struct waiting_list waiting[2];
    tracked_connection *pending; /* the last accepted, maybe not yet adopted */
    bool accept_held;           /* at http_max_connections, or this turn's accepts made */
    ms_log_limit accept_log;    /* accept failures */
    /* The parked connections in the order they were parked, oldest first;
     * park_capacity 0: none are parked. */
    struct waiting_list parked;
    size_t park_capacity, park_count;
};

/* --- The waiting lists ------------------------------------------------------- */

/* Puts t in its list by deadline_from, searching from the newest end (t is
 * almost always the newest). */
static void wait_insert(tracked_connection *t)
{
    struct waiting_list *list = &t->conns->waiting[t->trickling];
    tracked_connection *after = TAILQ_LAST(list, waiting_list);
    while (after && after->deadline_from > t->deadline_from)
        after = TAILQ_PREV(after, waiting_list, waiting);
    if (after)
        TAILQ_INSERT_AFTER(list, after, t, waiting);
    else
        TAILQ_INSERT_HEAD(list, t, waiting);
}

static void wait_remove(tracked_connection *t)
{
    TAILQ_REMOVE(&t->conns->waiting[t->trickling], t, waiting);
}

/* --- Records ---------------------------------------------------------------- */

/* True once evhttp has freed the connection (it clears the callbacks). */
static bool freed_by_evhttp(const tracked_connection *t)
{
    bufferevent_data_cb read_cb, write_cb;
    bufferevent_event_cb event_cb;
    void *cb_arg;
    bufferevent_getcb(t->bev, &read_cb, &write_cb, &event_cb, &cb_arg);
    return !read_cb && !write_cb && !event_cb;
}

/* Out of the lot (forget, or the reset). */
static void unpark(tracked_connection *t)
{
    ms_http_conns *conns = t->conns;
    TAILQ_REMOVE(&conns->parked, t, park);
    t->parked = false;
    conns->park_count--;
    conns->server->metrics.http_connections_parked--;
}

/* Lets go of a record and the door's reference on its bufferevent. */
static void forget(tracked_connection *t)
{
    ms_http_conns *conns = t->conns;
    if (!t->dropped) {
        wait_remove(t);
        conns->live--;
    }
    if (t->trickling)
        conns->server->metrics.http_connections_trickling--;
    if (t->parked)
        unpark(t);
    if (conns->pending == t)
        conns->pending = NULL;
    tracked_connection *last = conns->all[--conns->count];
    conns->all[t->slot] = last;
    last->slot = t->slot;
    if (t->on_input)
        evbuffer_remove_cb_entry(bufferevent_get_input(t->bev), t->on_input);
    bufferevent_decref(t->bev);
    free(t);
}

/* evhttp frees the connection: the record goes first. */
static void on_close(struct evhttp_connection *evcon, void *arg)
{
    (void)evcon;
    forget(arg);
}

/* Learns the evhttp connection that evhttp made around t's bufferevent (after
 * the bufferevent callback returned) and asks to hear of its free. */
static void adopt(tracked_connection *t)
{
    if (!t || t->evcon)
        return;
    bufferevent_data_cb read_cb, write_cb;
    bufferevent_event_cb event_cb;
    void *cb_arg = NULL;
    bufferevent_getcb(t->bev, &read_cb, &write_cb, &event_cb, &cb_arg);
    if (!cb_arg || !read_cb)
        return; /* not made (yet), or already freed: the sweep sees to it */
    t->evcon = cb_arg;
    evhttp_connection_set_closecb(t->evcon, on_close, t);
}

/* Moves a connection to MS_PRIORITY_TRICKLE or back to MS_PRIORITY_NORMAL.
 * libevent refuses while one of its events is ready to run; it then stays
 * where it is until the next change. */
static void set_trickling(tracked_connection *t, bool trickling)
{
    if (t->trickling == trickling ||
        bufferevent_priority_set(t->bev, trickling ? MS_PRIORITY_TRICKLE : MS_PRIORITY_NORMAL) != 0)
        return;
    if (!t->dropped)
        wait_remove(t);
    t->trickling = trickling;
    if (!t->dropped)
        wait_insert(t);
    if (trickling)
        t->conns->server->metrics.http_connections_trickling++;
    else
        t->conns->server->metrics.http_connections_trickling--;
}

/* Each read into a connection's input (the callback runs inside the read,
 * before evhttp parses): the first read of a request that holds no end of
 * header (an empty line) demotes the connection to MS_PRIORITY_TRICKLE, so
 * that the rest of its header is read only when no connection at
 * MS_PRIORITY_NORMAL has work ready (a slowloris connection's byte waits
 * behind every complete request). A request handled (ms_http_conns_request)
 * or the connection shut down (drop_connection) restores it. The search runs
 * once per request, over that first read: later pieces cost nothing here. */
static void trickle_check(struct evbuffer *input, const struct evbuffer_cb_info *info, void *arg)
{
    tracked_connection *t = arg;
    if (!info->n_added || t->header_begun || t->dropped)
        return;
    t->header_begun = true;
    adopt(t);
    if (evbuffer_search(input, "\n\r\n", 3, NULL).pos < 0 &&
        evbuffer_search(input, "\n\n", 2, NULL).pos < 0)
        set_trickling(t, true);
}

/* A connection accepted in this turn's batch, before its first read (evhttp
 * has made its connection; the next poll reads it): when the start of a
 * request header waits in its socket without the header's end, it is
 * demoted now (trickle_check's rule, applied before the read instead of
 * after it), so that in the next turns the complete requests of the batch
 * are read first and its own bytes only when no other work is ready. At the
 * cap a connection demoted so is shed like any trickling one, and one shed
 * before its read costs no read and no parse: in a burst of reconnections the
 * server falls behind, and the slowloris connections queued in the batches
 * before a ready request no longer delay it by their reads. A connection
 * with nothing in its socket yet (a client slow to send) stays at the normal
 * priority, counted as quiet. One peek of at most 4 KiB (evbuffer's own
 * largest read). */
static void classify_unread(tracked_connection *t)
{
    if (!t || !t->evcon || t->header_begun || t->trickling ||
        evbuffer_get_length(bufferevent_get_input(t->bev)) != 0)
        return;
    evutil_socket_t fd = bufferevent_getfd(t->bev);
    char peek[4096];
    ssize_t n = fd >= 0 ? recv(fd, peek, sizeof peek, MSG_PEEK | MSG_DONTWAIT) : -1;
    if (n <= 0)
        return;
    for (ssize_t i = 1; i < n; ++i)
        if (peek[i] == '\n' && (peek[i - 1] == '\n' || (i >= 2 && peek[i - 1] == '\r' &&
                                                           peek[i - 2] == '\n')))
            return; /* a whole header: read it as any other */
    set_trickling(t, true);
}

void ms_http_conns_request(ms_http_conns *conns, struct evhttp_request *req)
{
    struct evhttp_connection *evcon = evhttp_request_get_connection(req);
    struct bufferevent *bev = evcon ? evhttp_connection_get_bufferevent(evcon) : NULL;
    evutil_socket_t fd = bev ? bufferevent_getfd(bev) : -1;
    int one = 1;
    if (fd >= 0)
        setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    for (size_t i = 0; bev && i < conns->count; ++i) {
        tracked_connection *t = conns->all[i];
        if (t->bev != bev)
            continue;
        adopt(t);
        t->answered = true;
        t->header_begun = false;
        set_trickling(t, false);
        t->deadline_from = ms_now_seconds();
        if (!t->dropped) { /* to the newest end of its list */
            wait_remove(t);
            wait_insert(t);
        }
        return;
    }
}

/* --- The cap ----------------------------------------------------------------- */

/* The connection to shed when a newcomer finds every slot taken: among those
 * with no answer being sent, the one waiting longest for a request header
 * (since its accept or its previous request), taken first among those whose
 * header arrives in pieces (trickling); NULL when every connection is sending.
 * A slowloris connection waits for ever and trickles; a legitimate client
 * sends its header with its connection, so it is the newest, not the oldest,
 * and one that has not sent its header yet (a client slow to be scheduled) is
 * shed only when no trickling connection is left (before, 1 of 1,000 such
 * requests in scripts/attack was closed unanswered 4 ms after its connect).
 * The lists are in that order: the first connection not sending is the one. */
static tracked_connection *shed_candidate(ms_http_conns *conns)
{
    for (int list = 1; list >= 0; --list) {
        tracked_connection *t;
        TAILQ_FOREACH(t, &conns->waiting[list], waiting)
            if (evbuffer_get_length(bufferevent_get_output(t->bev)) == 0)
                return t;
    }
    return NULL;
}

/* Accepts per turn of the loop: well under the cap, so that a connection
 * accepted in a burst has its request read (the next turn) before the rest of
 * the burst could push it out as the oldest idle one. */
static size_t accepts_per_turn(const ms_http_conns *conns)
{
    size_t per_turn = conns->server->config.http_max_connections / 4;
    return per_turn ? per_turn : 1;
}

static void update_accepting(ms_http_conns *conns)
{
    conns->server->metrics.http_connections = conns->live;
    bool full = conns->live >= conns->server->config.http_max_connections &&
                !shed_candidate(conns);
    bool hold = full || conns->accepts_this_turn >= accepts_per_turn(conns);
    if (!conns->listener || (hold && conns->accept_held))
        return;
    conns->accept_held = hold;
    /* At the cap with every connection sending an answer, further clients
     * wait in the kernel's backlog: they hold no descriptor of ours, and the
     * binary door's stay free. At the cap with an idle connection, a newcomer
     * takes its slot (new_connection): waiting in the backlog behind slowloris
     * connections that each hold a slot for http_header_timeout made
     * legitimate requests wait 11.5-19 s (issue 32, item 8). Below the cap,
     * enabling also ends a pause after an accept failure (on_accept_error).
     * Disabling inside evhttp's accept callback also ends libevent's accept
     * loop for this turn. */
    if (hold)
        evconnlistener_disable(conns->listener);
    else
        evconnlistener_enable(conns->listener);
}

static void on_next_turn(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_http_conns *conns = arg;
    adopt(conns->pending);
    conns->pending = NULL;
    conns->accepts_this_turn = 0;
    update_accepting(conns);
}

/* --- The parked connections ------------------------------------------------------ */

size_t ms_http_park_capacity(const ms_server_config *config)
{
    return config->http_park_s ? config->http_park_max : 0;
}

/* The lot: as ms_http_park_capacity says, less where the descriptor limit
 * could not make room (the other doors' needs, as ms_server.c counts them,
 * come first). */
static size_t park_capacity(const ms_server_config *config)
{
    size_t n = ms_http_park_capacity(config);
    struct rlimit rl;
    if (!n || getrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY)
        return n;
    rlim_t others = (rlim_t)ms_server_descriptors_besides_parked(config);
    rlim_t room = rl.rlim_cur > others ? rl.rlim_cur - others : 0;
    return room < n ? (size_t)room : n;
}

/* Ends a parked connection with a reset (SO_LINGER 0: the kernel frees it at
 * once, no orderly close to wait for, no TIME_WAIT); evhttp frees it. */
static void reset_parked(tracked_connection *t)
{
    unpark(t);
    evutil_socket_t fd = bufferevent_getfd(t->bev);
    struct linger now = {.l_onoff = 1, .l_linger = 0};
    if (fd >= 0)
        (void)setsockopt(fd, SOL_SOCKET, SO_LINGER, &now, sizeof now);
    evhttp_connection_free(t->evcon); /* calls on_close: t is gone */
}

/* Holds a trickling connection shed before any request of its own was
 * handled, unread (its events disabled: no reads, no time-outs) with a small
 * receive buffer, the lot's oldest reset when it is full. False when there is
 * no lot, or t is not trickling: a client that has sent nothing yet (maybe
 * one slow to be scheduled) gets its end at once, as before, and retries. */
static bool park(ms_http_conns *conns, tracked_connection *t)
{
    if (!conns->park_capacity || !t->trickling)
        return false;
    if (conns->park_count == conns->park_capacity)
        reset_parked(TAILQ_FIRST(&conns->parked));
    bufferevent_disable(t->bev, EV_READ | EV_WRITE);
    evutil_socket_t fd = bufferevent_getfd(t->bev);
    int small = PARK_RECEIVE_BUFFER;
    if (fd >= 0)
        (void)setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    set_trickling(t, false);
    wait_remove(t);
    conns->live--;
    t->dropped = t->parked = true;
    t->parked_since = ms_now_seconds();
    TAILQ_INSERT_TAIL(&conns->parked, t, park);
    conns->park_count++;
    conns->server->metrics.http_connections_parked++;
    return true;
}

/* Resets the connections parked longer than http_park. */
static void reset_expired(ms_http_conns *conns, double now)
{
    double limit = conns->server->config.http_park_s;
    tracked_connection *t;
    while ((t = TAILQ_FIRST(&conns->parked)) && now - t->parked_since >= limit)
        reset_parked(t);
}

/* Ends a connection evhttp still owns. shed: to admit a newcomer at the cap
 * (counted apart from the time-outs). One shed before any request of its own
 * was handled has nothing of ours on its way: evhttp frees it now (the socket
 * closed, the record forgotten through on_close). Any other is shut down, so
 * that evhttp sees the end of stream after what it wrote and frees it. */
static void drop_connection(ms_http_conns *conns, tracked_connection *t, bool shed)
{
    if (t->dropped)
        return;
    if (shed)
        conns->server->metrics.http_connections_shed++;
    else
        conns->server->metrics.http_connections_dropped++;
    adopt(t);
    if (shed && !t->answered && t->evcon && !freed_by_evhttp(t)) {
        if (!park(conns, t))
            evhttp_connection_free(t->evcon); /* calls on_close: t is gone */
        return;
    }
    set_trickling(t, false); /* evhttp's reading of the end of stream is not put off */
    wait_remove(t);
    conns->live--;
    t->dropped = true;
    evutil_socket_t fd = bufferevent_getfd(t->bev);
    if (fd >= 0)
        shutdown(fd, SHUT_RDWR);
}

/* evhttp asks for each accepted connection's bufferevent: the door makes it,
 * and keeps a reference to track it. At the cap, the newcomer takes the slot
 * of the connection that has waited longest for a request header. */
static struct bufferevent *new_connection(struct event_base *base, void *arg)
{
    ms_http_conns *conns = arg;
    struct bufferevent *bev = bufferevent_socket_new(base, -1, BEV_OPT_CLOSE_ON_FREE);
    if (!bev)
        return NULL; /* evhttp makes one itself; that one goes untracked */
    adopt(conns->pending); /* evhttp has made the previous one's connection */
    classify_unread(conns->pending);
    conns->pending = NULL;
    if (conns->live >= conns->server->config.http_max_connections) {
        tracked_connection *idle = shed_candidate(conns);
        if (idle)
            drop_connection(conns, idle, true);
    }
    if (conns->count == conns->capacity) {
        size_t capacity = conns->capacity ? 2 * conns->capacity : 64;
        tracked_connection **grown = realloc(conns->all, capacity * sizeof *grown);
        if (!grown)
            return bev;
        conns->all = grown;
        conns->capacity = capacity;
    }
    tracked_connection *t = malloc(sizeof *t);
    if (!t)
        return bev;
    double now = ms_now_seconds();
    *t = (tracked_connection){.conns = conns, .bev = bev, .slot = conns->count,
                              .deadline_from = now, .output_since = now};
    t->on_input = evbuffer_add_cb(bufferevent_get_input(bev), trickle_check, t);
    bufferevent_incref(bev);
    conns->all[conns->count++] = t;
    wait_insert(t);
    conns->live++;
    conns->pending = t;
    /* A zero-delay timer runs after the next poll's reads: the count starts
     * over once the connections accepted now have had their turn. */
    static const struct timeval next_poll = {0, 0};
    if (conns->accepts_this_turn++ == 0 && evtimer_add(conns->next_turn, &next_poll) != 0)
        conns->accepts_this_turn = 0; /* no timer: no per-turn bound rather than no accepts */
    update_accepting(conns);
    return bev;
}

/* --- Deadlines --------------------------------------------------------------- */

static void sweep(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_http_conns *conns = arg;
    const ms_server_config *config = &conns->server->config;
    double now = ms_now_seconds();
    reset_expired(conns, now);
    for (size_t i = 0; i < conns->count;) {
        tracked_connection *t = conns->all[i];
        adopt(t);
        if (freed_by_evhttp(t)) { /* freed without its close callback */
            forget(t);
            continue; /* the last record took slot i */
        }
        ++i;
        if (t->dropped)
            set_trickling(t, false); /* if drop_connection could not */
        size_t waiting = evbuffer_get_length(bufferevent_get_output(t->bev));
        if (waiting != t->output_length) {
            t->output_length = waiting;
            t->output_since = now;
        }
        if (waiting && now - t->output_since > config->send_timeout_s)
            drop_connection(conns, t, false); /* a slow reader */
        else if (!waiting && now - t->deadline_from > config->http_header_timeout_s)
            drop_connection(conns, t, false); /* no complete request header in time */
    }
    update_accepting(conns);
}

/* Accept failed (out of descriptors): pause until the next sweep. The
 * tracker is its sweep timer's argument (evhttp owns the listener's); logs
 * rate-limited. */
static void on_accept_error(struct evconnlistener *listener, void *arg)
{
    (void)arg;
    int error = EVUTIL_SOCKET_ERROR();
    evconnlistener_disable(listener);
    ms_http_conns *conns = ms_server_event_arg(evconnlistener_get_base(listener), sweep);
    if (conns)
        ms_server_log_limited(conns->server, &conns->accept_log, "http: accept failed: %s; "
                              "accepting paused until the next sweep", strerror(error));
}

ms_status ms_http_conns_new(ms_server *server, struct evhttp *http,
                            struct evconnlistener *listener, ms_http_conns **out, ms_error *err)
{
    *out = NULL;
    ms_http_conns *conns = calloc(1, sizeof *conns);
    if (!conns)
        return ms_error_set(err, MS_ERR_NOMEM, "http: out of memory");
    conns->server = server;
    conns->listener = listener;
    conns->park_capacity = park_capacity(&server->config);
    TAILQ_INIT(&conns->parked);
    TAILQ_INIT(&conns->waiting[0]);
    TAILQ_INIT(&conns->waiting[1]);
    conns->sweep = event_new(server->base, -1, EV_PERSIST, sweep, conns);
    conns->next_turn = evtimer_new(server->base, on_next_turn, conns);
    struct timeval tick = {0, SWEEP_INTERVAL_US};
    if (!conns->sweep || !conns->next_turn || event_add(conns->sweep, &tick) != 0) {
        ms_http_conns_free(conns);
        return ms_error_set(err, MS_ERR_NOMEM, "http: cannot set up connection tracking");
    }
    evconnlistener_set_error_cb(listener, on_accept_error);
    evhttp_set_bevcb(http, new_connection, conns);
    *out = conns;
    return MS_OK;
}

void ms_http_conns_free(ms_http_conns *conns)
{
    if (!conns)
        return;
    while (conns->count)
        forget(conns->all[conns->count - 1]);
    free(conns->all);
    if (conns->sweep)
        event_free(conns->sweep);
    if (conns->next_turn)
        event_free(conns->next_turn);
    free(conns);
}
