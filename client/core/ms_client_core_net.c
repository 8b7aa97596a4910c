/* A link's network thread (ms_core_link, ms_client_core.h): one connection to
 * meshserve at a time (reconnecting with backoff), every member's model open
 * on it by handle, the requests in flight as slots, the members' wants merged
 * by priority under one window, cancels of what a member no longer wants, and
 * the chunks received passed on to their member's decode thread
 * (ms_core_push_chunk). Everything here but the figures under the locks is
 * the link thread's own; a member's core is used only while it is a member
 * (ms_core_link_leave waits until it is retired). */
#include "ms_client_core_internal.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_proto.h"
#include "ms_subtree.h"

static bool note_socket_bytes(ms_core_link *l)
{
    uint64_t read = ms_client_bytes_read(l->client);
    if (read == l->last_read)
        return false;
    uint64_t delta = read - l->last_read;
    l->last_read = read;
    pthread_mutex_lock(&l->lock);
    l->socket_bytes += delta;
    pthread_mutex_unlock(&l->lock);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        if (!l->members[i].seen)
            continue;
        ms_core *c = l->members[i].core;
        pthread_mutex_lock(&c->lock);
        c->socket_bytes += delta;
        pthread_mutex_unlock(&c->lock);
    }
    return true;
}

/* Member i stops being streamed (its core failed or stops): its model is
 * closed on the server, which cancels its requests there; its slots are
 * forgotten here, so late frames for them are dropped. */
static void retire(ms_core_link *l, unsigned i)
{
    link_member *m = &l->members[i];
    if (m->retired)
        return;
    m->retired = true;
    ms_core_link_end_slots(l, (int)i);
    ms_error err;
    if (l->client && !l->dead && m->ready &&
        ms_client_close_model(l->client, m->handle, &err) != MS_OK)
        ms_core_link_mark_dead(l, err.text);
    if (m->open_request && l->orphan_count < MS_CORE_LINK_MAX_MEMBERS)
        l->orphan_opens[l->orphan_count++] = m->open_request;
    m->ready = false;
    m->handle = m->open_request = 0;
}

/* A member's fatal error (the core keeps it in its figures); the link goes on
 * with the others. */
static void member_fail(ms_core_link *l, unsigned i, const char *fmt, const char *text)
{
    ms_core_fail(l->members[i].core, fmt, text);
    retire(l, i);
}

/* Drops the connection; everything in flight is forgotten (each member's
 * decode thread knows exactly what arrived and asks for the rest again, as
 * BYTES ranges). */
static void net_drop(ms_core_link *l, const char *why)
{
    if (l->client) {
        note_socket_bytes(l);
        ms_client_free(l->client);
        l->client = NULL;
    }
    ms_core_link_end_slots(l, -1);
    l->orphan_count = 0;
    double t = ms_core_link_since_start(l);
    if (l->down_since < 0)
        l->down_since = t;
    l->reconnect_at = t + l->backoff;
    l->backoff = l->backoff * 2 > 2.0 ? 2.0 : l->backoff * 2;
    pthread_mutex_lock(&l->lock);
    l->connected = false;
    pthread_mutex_unlock(&l->lock);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        if (!m->seen)
            continue;
        m->ready = false;
        m->handle = m->open_request = 0;
        if (m->retired)
            continue;
        if (m->down_since < 0)
            m->down_since = t;
        ms_core *c = m->core;
        pthread_mutex_lock(&c->lock);
        c->connected = false;
        if (!c->stats.warning[0] || strncmp(c->stats.warning, "connection", 10) == 0)
            snprintf(c->stats.warning, sizeof c->stats.warning, "connection lost: %.200s", why);
        pthread_mutex_unlock(&c->lock);
    }
}

/* Copies member m's wants when they changed since the last look; *fresh
 * tells whether they did. False when out of memory for the copy. */
static void open_member(ms_core_link *l, unsigned i)
{
    link_member *m = &l->members[i];
    ms_error err;
    m->ready = false;
    m->handle = 0;
    if (ms_client_open_model(l->client, m->core->model, &m->open_request, &err) != MS_OK) {
        m->open_request = 0;
        ms_core_link_mark_dead(l, err.text);
    }
}

static int member_by_open(const ms_core_link *l, uint32_t request_id)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (ms_core_link_live(&l->members[i]) && l->members[i].open_request == request_id)
            return (int)i;
    return -1;
}

static int member_by_handle(const ms_core_link *l, uint32_t handle)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (ms_core_link_live(&l->members[i]) && l->members[i].ready && l->members[i].handle == handle)
            return (int)i;
    return -1;
}

/* An OPEN_MODEL of a member that left: true (and forgotten) when it was one. */
static bool take_orphan(ms_core_link *l, uint32_t request_id)
{
    for (unsigned k = 0; k < l->orphan_count; ++k)
        if (l->orphan_opens[k] == request_id) {
            l->orphan_opens[k] = l->orphan_opens[--l->orphan_count];
            return true;
        }
    return false;
}

/* The first open of member i's model: its index to the decode thread. */
static bool first_open(ms_core_link *l, unsigned i, const ms_proto_model_opened *o,
                       const uint8_t *index)
{
    link_member *m = &l->members[i];
    ms_core *c = m->core;
    bool head = o->index_encoding == MS_PROTO_INDEX_SUBTREES;
    ms_archive *a;
    ms_error err;
    ms_status st = head ? ms_archive_open_head(index, o->index_size, c->model, &a, &err)
                        : ms_archive_open_index(index, o->index_size, c->model, &a, &err);
    if (st != MS_OK) {
        member_fail(l, i, head ? "bad model index head: %.200s" : "bad model index: %.200s",
                    err.text);
        return false;
    }
    uint32_t cells = ms_archive_get_header(a)->cell_count;
    if (o->cell_count != cells) { /* the server contradicts itself: reconnect */
        ms_archive_close(a);
        char why[160];
        snprintf(why, sizeof why, "MODEL_OPENED says %u cells, its index %u", o->cell_count,
                 cells);
        ms_client_violation(l->client, MS_PROTO_E_FIELD_OUT_OF_RANGE, 4, why);
        return false;
    }
    m->opened_once = true;
    m->content_id = o->content_id;
    m->cell_count = cells;
    m->by_subtree = head;
    ms_core_keep_opening(c, a, head);
    pthread_mutex_lock(&c->lock);
    c->stats.index_bytes_received += ms_client_index_wire_bytes(l->client);
    /* before the index: the decode thread's first pass already keeps to it */
    c->permitted_geometry_steps =
        o->permitted_geometry_steps < o->geometry_steps ? o->permitted_geometry_steps : 0;
    c->index = a;
    c->index_new = true;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
    return true;
}

/* A reopen (after a reconnect or MODEL_CHANGED): the same model, or the
 * member fails. */
static bool same_model(ms_core_link *l, unsigned i, const ms_proto_model_opened *o)
{
    link_member *m = &l->members[i];
    bool head = o->index_encoding == MS_PROTO_INDEX_SUBTREES;
    if (head != m->by_subtree) {
        /* what the decode thread holds is of the other kind */
        member_fail(l, i, "%.240s", head ? "the server now sends the index by subtree"
                                         : "the server no longer sends the index by subtree");
        return false;
    }
    if (o->content_id == m->content_id && o->cell_count != m->cell_count) {
        char why[160];
        snprintf(why, sizeof why, "MODEL_OPENED says %u cells, the model's index %u",
                 o->cell_count, m->cell_count);
        ms_client_violation(l->client, MS_PROTO_E_FIELD_OUT_OF_RANGE, 4, why);
        return false;
    }
    if (o->content_id != m->content_id) {
        ms_core *c = m->core;
        pthread_mutex_lock(&c->lock);
        c->stats.model_changed = true;
        pthread_mutex_unlock(&c->lock);
        member_fail(l, i, "%.240s", "the model changed on the server while it was streamed");
        return false;
    }
    return true;
}

static void on_model_opened(ms_client *client, uint32_t request_id,
                            const ms_proto_model_opened *o, const uint8_t *index, void *arg)
{
    ms_core_link *l = arg;
    l->last_activity = ms_core_link_since_start(l);
    int i = member_by_open(l, request_id);
    if (i < 0) {
        ms_error err;
        if (take_orphan(l, request_id) &&
            ms_client_close_model(client, o->model_handle, &err) != MS_OK)
            ms_core_link_mark_dead(l, err.text);
        return;
    }
    link_member *m = &l->members[i];
    m->open_request = 0;
    m->handle = o->model_handle;
    m->ready = true; /* so that a failure below closes the handle */
    if (!(m->opened_once ? same_model(l, (unsigned)i, o) : first_open(l, (unsigned)i, o, index)))
        return;
    double outage = m->down_since >= 0 ? l->last_activity - m->down_since : 0.0;
    m->down_since = -1;
    l->down_since = -1;
    l->backoff = 0.1;
    ms_core *c = m->core;
    pthread_mutex_lock(&c->lock);
    c->model_open = true;
    c->connected = true;
    c->colour_served = (ms_client_limits(client)->capabilities & MS_PROTO_CAP_COLOUR) != 0;
    /* each open says what this connection may read (a SIGHUP may have
     * changed the preview between two opens) */
    c->permitted_geometry_steps =
        o->permitted_geometry_steps < o->geometry_steps ? o->permitted_geometry_steps : 0;
    if (outage > c->longest_outage)
        c->longest_outage = outage;
    c->republish = true;                  /* the decode thread recomputes its wants */
    m->want_serial = c->want_serial - 1;  /* and we re-read them */
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
    ms_core_link_fill(l);
}

static void on_payload(ms_client *client, uint32_t id, const ms_proto_payload *p, bool last,
                       void *arg)
{
    (void)client;
    ms_core_link *l = arg;
    l->last_activity = ms_core_link_since_start(l);
    uint32_t k = ms_core_link_slot_find(l, id);
    if (k == NO_SLOT)
        return;
    slot *s = &l->slots[k];
    ms_core *c = ms_core_link_core_of(l, s);
    if (p->data_length) {
        chunk_msg *m = malloc(sizeof *m + p->data_length);
        if (m) {
            m->next = NULL;
            m->cell = s->cell, m->stream = s->stream, m->offset = p->offset, m->length = p->data_length;
            m->failed = false;
            m->total = s->stream == STREAM_INDEX ? p->end : 0; /* a subtree's stored size */
            memcpy(m->data, p->data, p->data_length);
            ms_core_push_chunk(c, m);
        }
        uint32_t got = p->offset + p->data_length - s->start;
        if (got > s->end - s->start)
            got = s->end - s->start;
        pthread_mutex_lock(&c->lock);
        if (s->stream != STREAM_INDEX) { /* subtrees: stats.index_bytes_received */
            c->bytes_received += p->data_length;
            if (s->stream != STREAM_COLOUR) /* colour: bytes_received only */
                *(s->stream == STREAM_APO ? &c->apo_bytes_received
                                          : &c->geometry_bytes_received) += p->data_length;
        }
        if (got > s->got)
            c->bytes_in_flight -= got - s->got;
        pthread_mutex_unlock(&c->lock);
        if (got > s->got) {
            l->in_flight -= got - s->got;
            s->got = got;
        }
    }
    if (last) {
        pthread_mutex_lock(&c->lock);
        if (c->latency_count < LATENCY_KEEP)
            c->latencies[c->latency_count++] = l->last_activity - s->sent_at;
        pthread_mutex_unlock(&c->lock);
        ms_core_link_finish_slot(l, k);
        ms_core_link_fill(l);
    }
}

/* ERROR MODEL_CHANGED named member i's handle: the server closed it and ended
 * every request on it. Forget them (the decode thread knows what arrived and
 * asks for the rest again) and reopen the model by name on the same
 * connection: on_model_opened then goes on if the content_id is the same,
 * and fails the member with stats.model_changed if not; a removed model
 * answers UNKNOWN_MODEL (on_request_error). */
static void reopen(ms_core_link *l, unsigned i)
{
    ms_core_link_end_slots(l, (int)i);
    ms_core *c = l->members[i].core;
    pthread_mutex_lock(&c->lock);
    c->model_open = false;
    pthread_mutex_unlock(&c->lock);
    open_member(l, i);
}

/* A connection-level ERROR (request_count 0) naming a handle. */
static void handle_error(ms_core_link *l, const ms_proto_error_body *e)
{
    int i = member_by_handle(l, e->detail);
    if (i < 0)
        return; /* a handle closed since, or none of ours */
    if (e->code == MS_PROTO_E_MODEL_CHANGED) {
        reopen(l, (unsigned)i);
    } else if (e->code == MS_PROTO_E_UNKNOWN_MODEL || e->code == MS_PROTO_E_BAD_MODEL_NAME) {
        char text[300];
        snprintf(text, sizeof text, "model '%.64s': %s", l->members[i].core->model,
                 ms_proto_error_name(e->code));
        member_fail(l, (unsigned)i, "%.240s", text);
    }
}

static void on_request_error(ms_client *client, uint32_t first, uint32_t count,
                             const ms_proto_error_body *e, void *arg)
{
    (void)client;
    ms_core_link *l = arg;
    l->last_activity = ms_core_link_since_start(l);
    if (count == 0) {
        handle_error(l, e);
        return;
    }
    int opener = member_by_open(l, first);
    if (opener >= 0) {
        char text[300];
        snprintf(text, sizeof text, "cannot open model '%.64s': %s %.*s",
                 l->members[opener].core->model, ms_proto_error_name(e->code),
                 (int)(e->text_length > 150 ? 150 : e->text_length), e->text);
        l->members[opener].open_request = 0;
        member_fail(l, (unsigned)opener, "%.240s", text);
        return;
    }
    if (take_orphan(l, first))
        return;
    bool transient = e->code == MS_PROTO_E_CANCELLED || e->code == MS_PROTO_E_RATE_LIMITED ||
                     e->code == MS_PROTO_E_QUEUE_FULL ||
                     e->code == MS_PROTO_E_TOO_MANY_OUTSTANDING;
    for (uint64_t id = first; id < (uint64_t)first + count; ++id) {
        uint32_t k = ms_core_link_slot_find(l, (uint32_t)id);
        if (k == NO_SLOT)
            continue;
        if (!transient) {
            chunk_msg *m = malloc(sizeof *m);
            if (m) {
                memset(m, 0, sizeof *m);
                m->cell = l->slots[k].cell, m->stream = l->slots[k].stream, m->failed = true;
                ms_core_push_chunk(ms_core_link_core_of(l, &l->slots[k]), m);
            }
        }
        ms_core_link_end_slot(l, k);
    }
    if (e->code == MS_PROTO_E_RATE_LIMITED || e->code == MS_PROTO_E_QUEUE_FULL) {
        /* ask again after a pause (the next tick), with the wants read anew */
        for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
            if (l->members[i].seen)
                l->members[i].want_serial = UINT64_MAX;
        return;
    }
    ms_core_link_fill(l);
}

static void on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    ms_core_link *l = arg;
    /* ms_client is still on the stack: free it from the next tick */
    ms_core_link_mark_dead(l, why);
}

static const ms_client_handlers link_handlers = {
    .model_opened = on_model_opened,
    .payload = on_payload,
    .request_error = on_request_error,
    .closed = on_closed,
};

/* Connects and opens every live member's model. */
static void net_connect(ms_core_link *l)
{
    ms_client_options co = {.host = l->host, .port = l->o.port, .token = l->token,
                            .agent = l->agent, .max_frame = 1u << 20,
                            .raw_index = l->o.raw_index,
                            .index_subtrees = !l->o.whole_index};
    ms_error err;
    l->last_activity = ms_core_link_since_start(l);
    l->last_read = 0;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        if (!ms_core_link_live(&l->members[i]) || !l->members[i].opened_once)
            continue;
        ms_core *c = l->members[i].core;
        pthread_mutex_lock(&c->lock);
        c->reconnects++;
        pthread_mutex_unlock(&c->lock);
    }
    if (ms_client_connect(l->base, &co, &link_handlers, l, &l->client, &err) != MS_OK) {
        l->client = NULL;
        net_drop(l, err.text);
        return;
    }
    pthread_mutex_lock(&l->lock);
    l->connections++;
    l->connected = true;
    pthread_mutex_unlock(&l->lock);
    if (l->o.bandwidth > 0 && ms_client_set_rate_limit(l->client, l->o.bandwidth, &err) != MS_OK) {
        net_drop(l, err.text);
        return;
    }
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS && !l->dead; ++i) {
        if (!ms_core_link_live(&l->members[i]))
            continue;
        ms_core *c = l->members[i].core;
        pthread_mutex_lock(&c->lock);
        c->connected = true;
        pthread_mutex_unlock(&c->lock);
        open_member(l, i);
    }
}

/* Takes in the members that joined and retires those that leave or failed
 * (ms_core_link_join/_leave change states under the lock; the link's thread
 * acts on them here). */
static void sync_members(ms_core_link *l)
{
    bool joining[MS_CORE_LINK_MAX_MEMBERS], leaving[MS_CORE_LINK_MAX_MEMBERS];
    pthread_mutex_lock(&l->lock);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        joining[i] = m->state == MEMBER_JOINING;
        leaving[i] = m->state == MEMBER_LEAVING;
        if (joining[i])
            m->state = MEMBER_ACTIVE;
    }
    pthread_mutex_unlock(&l->lock);
    bool left = false;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        if (joining[i]) {
            m->seen = true;
            if (l->client && !l->dead) {
                pthread_mutex_lock(&m->core->lock);
                m->core->connected = true;
                pthread_mutex_unlock(&m->core->lock);
                open_member(l, i);
            }
        }
        if (!m->seen)
            continue;
        if (leaving[i]) {
            retire(l, i);
            m->seen = false;
            left = true;
            continue;
        }
        pthread_mutex_lock(&m->core->lock);
        bool over = m->core->stopping || m->core->fatal;
        pthread_mutex_unlock(&m->core->lock);
        if (over)
            retire(l, i);
    }
    if (!left)
        return;
    pthread_mutex_lock(&l->lock);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (leaving[i]) {
            l->members[i].state = MEMBER_FREE;
            l->members[i].core = NULL;
        }
    pthread_cond_broadcast(&l->left);
    pthread_mutex_unlock(&l->lock);
}

/* Fails every live member: no usable connection for give_up_seconds. */
static void give_up(ms_core_link *l, double t)
{
    char text[200];
    snprintf(text, sizeof text, "%s:%u: no usable connection for %.1f s", l->host, l->o.port,
             t - l->down_since);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (ms_core_link_live(&l->members[i]))
            member_fail(l, i, "%.240s", text);
    l->down_since = -1;
}

void ms_core_net_tick(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_core_link *l = arg;
    pthread_mutex_lock(&l->lock);
    bool stop = l->stopping;
    pthread_mutex_unlock(&l->lock);
    if (stop) {
        event_base_loopbreak(l->base);
        return;
    }
    sync_members(l);
    double t = ms_core_link_since_start(l);
    if (l->dead) {
        l->dead = false;
        net_drop(l, l->dead_why);
    }
    bool anyone = false;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        anyone |= ms_core_link_live(&l->members[i]);
    if (!l->client) {
        if (!anyone) { /* nobody to stream for: no reconnecting, no giving up */
            l->down_since = -1;
            return;
        }
        if (l->down_since >= 0 && t - l->down_since > l->o.give_up_seconds)
            give_up(l, t);
        else if (t >= l->reconnect_at)
            net_connect(l);
        return;
    }
    if (note_socket_bytes(l)) /* any frame counts, index data included */
        l->last_activity = t;
    /* the answer time-out runs from the later of the last frame and the
     * moment something began to be awaited: a member that joins, or a first
     * request, after a quiet spell must not find the clock already run out */
    bool waiting = ms_core_link_opening(l) || l->slots_active > 0;
    if (waiting && !l->was_waiting)
        l->last_activity = t;
    l->was_waiting = waiting;
    if (waiting && t - l->last_activity > l->o.answer_timeout) {
        char why[128];
        snprintf(why, sizeof why, "the server sent nothing for %.1f s", t - l->last_activity);
        net_drop(l, why);
        return;
    }
    ms_core_link_fill(l);
}

void *ms_core_net_main(void *arg)
{
    ms_core_link *l = arg;
    /* A write to a connection the server has closed raises SIGPIPE in the
     * writing thread: block it here (only here) and see the error instead. */
    sigset_t pipe_only;
    sigemptyset(&pipe_only);
    sigaddset(&pipe_only, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_only, NULL);
    struct timeval every = {0, 5000};
    event_add(l->tick, &every);
    event_base_dispatch(l->base);
    if (l->client) {
        ms_client_free(l->client);
        l->client = NULL;
    }
    pthread_mutex_lock(&l->lock);
    l->connected = false;
    pthread_mutex_unlock(&l->lock);
    return NULL;
}
