/* The client core's network thread: one connection to meshserve at a time
 * (reconnecting with backoff), the requests in flight as slots, cancels of
 * what the decode thread no longer wants, and the chunks received passed on
 * to it (ms_core_push_chunk). Everything here but the figures under the lock
 * is the network thread's own. */
#include "ms_client_core_internal.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_proto.h"
#include "ms_subtree.h"

static void net_connect(ms_core *c);

/* The chain of slots whose (cell, stream) falls in one bucket: a fixed table,
 * whatever the model's size (iterations skip the other cells' slots). */
static uint32_t *head_of(ms_core *c, uint32_t cell, uint8_t stream)
{
    uint32_t h = (cell * (uint32_t)STREAM_COUNT + stream) * 2654435761u;
    return &c->slot_buckets[h >> (32 - SLOT_BUCKET_BITS)];
}

static bool slot_is(const slot *s, uint32_t cell, uint8_t stream)
{
    return s->cell == cell && s->stream == stream;
}

static void slot_unlink(ms_core *c, uint32_t k)
{
    slot *s = &c->slots[k];
    uint32_t *p = head_of(c, s->cell, s->stream);
    while (*p != NO_SLOT && *p != k)
        p = &c->slots[*p].next;
    if (*p == k)
        *p = s->next;
    s->used = false;
    c->slots_used--;
    if (!s->done)
        c->slots_active--;
}

static uint32_t slot_find(ms_core *c, uint32_t id)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used && !c->slots[k].done && c->slots[k].id == id)
            return k;
    return NO_SLOT;
}

static void record_latency(ms_core *c, double seconds)
{
    pthread_mutex_lock(&c->lock);
    if (c->latency_count < LATENCY_KEEP)
        c->latencies[c->latency_count++] = seconds;
    pthread_mutex_unlock(&c->lock);
}

static void end_slot(ms_core *c, uint32_t k)
{
    slot *s = &c->slots[k];
    if (!s->done) {
        pthread_mutex_lock(&c->lock);
        c->bytes_in_flight -= s->end - s->start - s->got;
        pthread_mutex_unlock(&c->lock);
    }
    slot_unlink(c, k);
}

/* The request's last byte arrived: keep covering its range until the decode
 * thread has taken it. */
static void finish_slot(ms_core *c, uint32_t k)
{
    slot *s = &c->slots[k];
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight -= s->end - s->start - s->got;
    s->last_seq = c->push_seq;
    pthread_mutex_unlock(&c->lock);
    s->got = s->end - s->start;
    s->done = true;
    c->slots_active--;
}

/* Adds what the connection read since the last look to the socket total;
 * true when it read anything. */
static bool note_socket_bytes(ms_core *c)
{
    uint64_t read = ms_client_bytes_read(c->client);
    if (read == c->last_read)
        return false;
    pthread_mutex_lock(&c->lock);
    c->socket_bytes += read - c->last_read;
    pthread_mutex_unlock(&c->lock);
    c->last_read = read;
    return true;
}

/* Drops the connection; everything in flight is forgotten (the decode thread
 * knows exactly what arrived and asks for the rest again, as BYTES ranges). */
static void net_drop(ms_core *c, const char *why)
{
    if (c->client) {
        note_socket_bytes(c);
        ms_client_free(c->client);
        c->client = NULL;
    }
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used)
            end_slot(c, k);
    double t = ms_core_since_start(c);
    if (c->down_since < 0)
        c->down_since = t;
    c->reconnect_at = t + c->backoff;
    c->backoff = c->backoff * 2 > 2.0 ? 2.0 : c->backoff * 2;
    c->ready = false;
    pthread_mutex_lock(&c->lock);
    c->connected = false;
    if (!c->stats.warning[0] || strncmp(c->stats.warning, "connection", 10) == 0)
        snprintf(c->stats.warning, sizeof c->stats.warning, "connection lost: %.200s", why);
    pthread_mutex_unlock(&c->lock);
}

/* Copies the decode thread's wants when they changed since the last look;
 * *fresh tells whether they did. False when out of memory for the copy.
 * *in_flight: the bytes requested and not yet received. */
static bool net_take_wants(ms_core *c, bool *fresh, uint64_t *in_flight)
{
    pthread_mutex_lock(&c->lock);
    *fresh = c->want_serial != c->net_want_serial;
    if (*fresh) {
        if (c->want_count > c->net_want_cap) {
            want *grown = realloc(c->net_wants, c->want_count * sizeof *grown);
            if (!grown) {
                pthread_mutex_unlock(&c->lock);
                return false;
            }
            c->net_wants = grown;
            c->net_want_cap = c->want_count;
        }
        if (c->want_count)
            memcpy(c->net_wants, c->wants, c->want_count * sizeof *c->wants);
        c->net_want_count = c->want_count;
        c->net_want_serial = c->want_serial;
        c->net_consumed_seq = c->want_consumed_seq;
    }
    *in_flight = c->bytes_in_flight;
    pthread_mutex_unlock(&c->lock);
    return true;
}

/* Cancels the requests in flight that no fresh want still covers. */
static void net_cancel_unwanted(ms_core *c)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        c->slots[k].keep = false;
    for (size_t i = 0; i < c->net_want_count; ++i) {
        const want *w = &c->net_wants[i];
        for (uint32_t k = *head_of(c, w->cell, w->stream); k != NO_SLOT; k = c->slots[k].next)
            if (slot_is(&c->slots[k], w->cell, w->stream) &&
                (w->stream == STREAM_INDEX || /* a subtree still wanted: its request stays */
                 (c->slots[k].start + c->slots[k].got < w->end && c->slots[k].end > w->start)))
                c->slots[k].keep = true;
    }
    ms_proto_id_range ranges[64];
    uint16_t nr = 0;
    for (uint32_t k = 0; k < MAX_SLOTS; ++k) {
        slot *s = &c->slots[k];
        if (!s->used || s->keep || s->cancelled || s->done)
            continue;
        s->cancelled = true;
        ranges[nr].first_id = s->id, ranges[nr].count = 1;
        if (++nr == 64) {
            ms_client_cancel(c->client, ranges, nr, NULL);
            nr = 0;
        }
        pthread_mutex_lock(&c->lock);
        c->cancels++;
        pthread_mutex_unlock(&c->lock);
    }
    if (nr)
        ms_client_cancel(c->client, ranges, nr, NULL);
}

/* A batch of requests being planned: each with the slot reserved for it. */
typedef struct request_batch {
    ms_proto_cell_request req[256];
    uint32_t slot[256];
    uint16_t n;
} request_batch;

/* The part of want w not already on its way (requests are whole ranges from
 * the same table, so a covering request is the usual case) nor in the batch;
 * false when nothing of it is left. */
static bool net_missing_part(ms_core *c, const want *w, const request_batch *batch,
                             uint32_t *start_out, uint32_t *end_out)
{
    uint32_t start = w->start, end = w->end;
    if (w->stream == STREAM_INDEX) {
        /* a subtree is asked for whole (or from where its bytes stopped), once */
        for (uint32_t k = *head_of(c, w->cell, w->stream); k != NO_SLOT; k = c->slots[k].next)
            if (slot_is(&c->slots[k], w->cell, w->stream) && !c->slots[k].cancelled)
                return false;
        for (uint16_t j = 0; j < batch->n; ++j)
            if (batch->req[j].cell_id == w->cell && batch->req[j].stream == STREAM_INDEX)
                return false;
        *start_out = start, *end_out = end;
        return start < end;
    }
    for (uint32_t k = *head_of(c, w->cell, w->stream); k != NO_SLOT; k = c->slots[k].next) {
        const slot *s = &c->slots[k];
        if (s->cancelled || !slot_is(s, w->cell, w->stream))
            continue;
        if (s->start <= start && s->end > start)
            start = s->end;
        if (s->start < end && s->end >= end && s->start > start)
            end = s->start;
    }
    bool dup = false;
    for (uint16_t j = 0; j < batch->n; ++j)
        if (batch->req[j].cell_id == w->cell && batch->req[j].stream == w->stream &&
            batch->req[j].a <= start && batch->req[j].a + batch->req[j].b >= end)
            dup = true;
    *start_out = start, *end_out = end;
    return start < end && !dup;
}

/* A free slot not yet reserved by the batch, or NO_SLOT. */
static uint32_t net_free_slot(const ms_core *c, const request_batch *batch)
{
    uint32_t k = 0;
    while (k < MAX_SLOTS && c->slots[k].used)
        ++k;
    if (k == MAX_SLOTS)
        return NO_SLOT;
    for (uint16_t j = 0; j < batch->n; ++j)
        if (batch->slot[j] == k)
            return NO_SLOT;
    return k;
}

/* Plans the best missing ranges while the window, the server's limits and
 * the slots allow, reserving a slot for each. */
static void net_plan(ms_core *c, uint64_t in_flight, request_batch *batch)
{
    const ms_proto_hello_reply *lim = ms_client_limits(c->client);
    uint32_t max_batch = lim->max_batch ? lim->max_batch : 64;
    uint32_t max_out = lim->max_outstanding ? lim->max_outstanding : 64;
    if (max_out > MAX_SLOTS)
        max_out = MAX_SLOTS;
    if (max_batch > 256)
        max_batch = 256;
    batch->n = 0;
    /* whole subtrees on their way: their size comes with their first frame,
     * so the window counts each as a typical stored subtree */
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used && !c->slots[k].done && !c->slots[k].cancelled &&
            c->slots[k].stream == STREAM_INDEX && c->slots[k].start == c->slots[k].end)
            in_flight += SUBTREE_BYTES_GUESS;
    for (size_t i = 0; i < c->net_want_count && batch->n < max_batch; ++i) {
        if (c->slots_active + batch->n >= max_out || c->slots_used + batch->n >= MAX_SLOTS ||
            (in_flight > 0 && in_flight >= c->window))
            break;
        const want *w = &c->net_wants[i];
        uint32_t start, end;
        if (!net_missing_part(c, w, batch, &start, &end))
            continue;
        uint32_t k = net_free_slot(c, batch);
        if (k == NO_SLOT)
            break;
        /* reserve the slot now so the next search skips it */
        slot *s = &c->slots[k];
        memset(s, 0, sizeof *s);
        s->used = true;
        /* a whole subtree of unknown size: one step (PROTOCOL.md); in the
         * figures it counts as nothing in flight, in the window as a guess */
        bool whole = w->stream == STREAM_INDEX && end == UINT32_MAX;
        if (whole)
            end = start;
        s->cell = w->cell, s->stream = w->stream, s->start = start, s->end = end;
        c->slots_used++;
        c->slots_active++;
        s->next = *head_of(c, w->cell, w->stream);
        *head_of(c, w->cell, w->stream) = k;
        batch->req[batch->n] = (ms_proto_cell_request){
            .cell_id = w->cell,
            .stream = w->stream,
            .unit = whole ? MS_PROTO_UNIT_STEPS : MS_PROTO_UNIT_BYTES,
            .priority = w->priority,
            .a = whole ? 0 : start,
            .b = whole ? 0 : end - start};
        batch->slot[batch->n++] = k;
        in_flight += whole ? SUBTREE_BYTES_GUESS : end - start;
    }
}

/* Sends the batch; a connection that fails to take it is marked dead. */
static void net_send(ms_core *c, const request_batch *batch)
{
    uint16_t n = batch->n;
    uint32_t first;
    ms_error err;
    if (ms_client_request_cells(c->client, c->handle, batch->req, n, &first, &err) != MS_OK) {
        for (uint16_t j = 0; j < n; ++j)
            slot_unlink(c, batch->slot[j]);
        if (!c->dead) {
            c->dead = true;
            snprintf(c->dead_why, sizeof c->dead_why, "%.240s", err.text);
        }
        return;
    }
    double t = ms_core_since_start(c);
    uint64_t bytes = 0;
    for (uint16_t j = 0; j < n; ++j) {
        slot *s = &c->slots[batch->slot[j]];
        s->id = first + j;
        s->sent_at = t;
        bytes += s->end - s->start;
    }
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight += bytes;
    c->requests += n;
    pthread_mutex_unlock(&c->lock);
}

/* Sends what the wants call for: releases finished requests the decode thread
 * has taken, cancels requests no longer wanted, then issues the best missing
 * ranges while the window allows. */
static void net_fill(ms_core *c)
{
    if (!c->client || !c->ready || c->dead)
        return;
    bool fresh;
    uint64_t in_flight;
    if (!net_take_wants(c, &fresh, &in_flight))
        return;
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used && c->slots[k].done && c->slots[k].last_seq <= c->net_consumed_seq)
            slot_unlink(c, k);
    if (fresh)
        net_cancel_unwanted(c);
    request_batch batch;
    net_plan(c, in_flight, &batch);
    if (batch.n)
        net_send(c, &batch);
}

static void on_model_opened(ms_client *client, uint32_t request_id,
                            const ms_proto_model_opened *o, const uint8_t *index, void *arg)
{
    (void)client;
    ms_core *c = arg;
    if (request_id != c->open_request)
        return;
    c->last_activity = ms_core_since_start(c);
    bool head = o->index_encoding == MS_PROTO_INDEX_SUBTREES;
    if (c->index) {
        if (head != c->net_by_subtree) {
            /* what the decode thread holds is of the other kind */
            ms_core_fail(c, "%.240s", head ? "the server now sends the index by subtree"
                                           : "the server no longer sends the index by subtree");
            event_base_loopbreak(c->base);
            return;
        }
        if (o->content_id != c->content_id) {
            pthread_mutex_lock(&c->lock);
            c->stats.model_changed = true;
            ms_core_fail_locked(c, "%.240s",
                                "the model changed on the server while it was streamed");
            pthread_mutex_unlock(&c->lock);
            event_base_loopbreak(c->base);
            return;
        }
    } else {
        ms_archive *a;
        ms_error err;
        ms_status st = head ? ms_archive_open_head(index, o->index_size, c->model, &a, &err)
                            : ms_archive_open_index(index, o->index_size, c->model, &a, &err);
        if (st != MS_OK) {
            ms_core_fail(c, head ? "bad model index head: %.200s" : "bad model index: %.200s",
                         err.text);
            event_base_loopbreak(c->base);
            return;
        }
        c->content_id = o->content_id;
        c->net_by_subtree = head;
        ms_core_keep_opening(c, a, head);
        pthread_mutex_lock(&c->lock);
        c->stats.index_bytes_received += ms_client_index_wire_bytes(c->client);
        c->index = a;
        c->index_new = true;
        pthread_cond_broadcast(&c->wake);
        pthread_mutex_unlock(&c->lock);
    }
    c->handle = o->model_handle;
    c->ready = true;
    double outage = c->down_since >= 0 ? c->last_activity - c->down_since : 0.0;
    c->down_since = -1;
    c->backoff = 0.1;
    pthread_mutex_lock(&c->lock);
    c->model_open = true;
    c->connected = true;
    if (outage > c->longest_outage)
        c->longest_outage = outage;
    c->republish = true;          /* the decode thread recomputes its wants */
    c->net_want_serial = c->want_serial - 1; /* and we re-read them */
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
    net_fill(c);
}

static void on_payload(ms_client *client, uint32_t id, const ms_proto_payload *p, bool last,
                       void *arg)
{
    (void)client;
    ms_core *c = arg;
    c->last_activity = ms_core_since_start(c);
    uint32_t k = slot_find(c, id);
    if (k == NO_SLOT)
        return;
    slot *s = &c->slots[k];
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
            *(s->stream == STREAM_APO ? &c->apo_bytes_received
                                      : &c->geometry_bytes_received) += p->data_length;
        }
        if (got > s->got)
            c->bytes_in_flight -= got - s->got;
        pthread_mutex_unlock(&c->lock);
        if (got > s->got)
            s->got = got;
    }
    if (last) {
        record_latency(c, c->last_activity - s->sent_at);
        finish_slot(c, k);
        net_fill(c);
    }
}

/* ERROR MODEL_CHANGED named our handle: the server closed it and ended every
 * request on it. Forget them (the decode thread knows what arrived and asks
 * for the rest again) and reopen the model by name on the same connection:
 * on_model_opened then goes on if the content_id is the same, and stops the
 * core with stats.model_changed if not; a removed model answers
 * UNKNOWN_MODEL (on_request_error). */
static void net_reopen(ms_core *c)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used)
            end_slot(c, k);
    c->ready = false;
    c->handle = 0;
    pthread_mutex_lock(&c->lock);
    c->model_open = false;
    pthread_mutex_unlock(&c->lock);
    ms_error err;
    if (ms_client_open_model(c->client, c->model, &c->open_request, &err) != MS_OK && !c->dead) {
        c->dead = true;
        snprintf(c->dead_why, sizeof c->dead_why, "%.240s", err.text);
    }
}

static void on_request_error(ms_client *client, uint32_t first, uint32_t count,
                             const ms_proto_error_body *e, void *arg)
{
    (void)client;
    ms_core *c = arg;
    c->last_activity = ms_core_since_start(c);
    if (count == 0) {
        if (e->code == MS_PROTO_E_MODEL_CHANGED) {
            if (c->ready && e->detail == c->handle)
                net_reopen(c);
            return;
        }
        if (e->code == MS_PROTO_E_UNKNOWN_MODEL || e->code == MS_PROTO_E_BAD_MODEL_NAME) {
            char text[300];
            snprintf(text, sizeof text, "model '%.64s': %s", c->model,
                     ms_proto_error_name(e->code));
            ms_core_fail(c, "%.240s", text);
            event_base_loopbreak(c->base);
        }
        return;
    }
    if (first == c->open_request) {
        char text[300];
        snprintf(text, sizeof text, "cannot open model '%.64s': %s %.*s", c->model,
                 ms_proto_error_name(e->code), (int)(e->text_length > 150 ? 150 : e->text_length),
                 e->text);
        ms_core_fail(c, "%.240s", text);
        event_base_loopbreak(c->base);
        return;
    }
    bool transient = e->code == MS_PROTO_E_CANCELLED || e->code == MS_PROTO_E_RATE_LIMITED ||
                     e->code == MS_PROTO_E_QUEUE_FULL ||
                     e->code == MS_PROTO_E_TOO_MANY_OUTSTANDING;
    for (uint64_t id = first; id < (uint64_t)first + count; ++id) {
        uint32_t k = slot_find(c, (uint32_t)id);
        if (k == NO_SLOT)
            continue;
        if (!transient) {
            chunk_msg *m = malloc(sizeof *m);
            if (m) {
                memset(m, 0, sizeof *m);
                m->cell = c->slots[k].cell, m->stream = c->slots[k].stream, m->failed = true;
                ms_core_push_chunk(c, m);
            }
        }
        end_slot(c, k);
    }
    if (e->code == MS_PROTO_E_RATE_LIMITED || e->code == MS_PROTO_E_QUEUE_FULL) {
        /* ask again after a pause: the decode thread republishes */
        pthread_mutex_lock(&c->lock);
        c->net_want_serial = c->want_serial - 1;
        pthread_mutex_unlock(&c->lock);
        return;
    }
    net_fill(c);
}

static void on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    ms_core *c = arg;
    /* ms_client is still on the stack: free it from the next tick */
    c->dead = true;
    c->ready = false;
    snprintf(c->dead_why, sizeof c->dead_why, "%.240s", why);
}

static const ms_client_handlers core_handlers = {
    .model_opened = on_model_opened,
    .payload = on_payload,
    .request_error = on_request_error,
    .closed = on_closed,
};

static void net_connect(ms_core *c)
{
    ms_client_options co = {.host = c->host, .port = c->o.port, .token = c->token,
                            .agent = c->agent, .max_frame = 1u << 20,
                            .raw_index = c->o.raw_index,
                            .index_subtrees = !c->o.whole_index};
    ms_error err;
    c->last_activity = ms_core_since_start(c);
    c->last_read = 0;
    if (ms_client_connect(c->base, &co, &core_handlers, c, &c->client, &err) != MS_OK) {
        c->client = NULL;
        net_drop(c, err.text);
        return;
    }
    if (c->o.bandwidth > 0 && ms_client_set_rate_limit(c->client, c->o.bandwidth, &err) != MS_OK) {
        net_drop(c, err.text);
        return;
    }
    if (ms_client_open_model(c->client, c->model, &c->open_request, &err) != MS_OK) {
        net_drop(c, err.text);
        return;
    }
    pthread_mutex_lock(&c->lock);
    c->connected = true;
    pthread_mutex_unlock(&c->lock);
}

void ms_core_net_tick(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_core *c = arg;
    pthread_mutex_lock(&c->lock);
    bool stop = c->stopping || c->fatal;
    pthread_mutex_unlock(&c->lock);
    if (stop) {
        event_base_loopbreak(c->base);
        return;
    }
    double t = ms_core_since_start(c);
    if (c->dead) {
        c->dead = false;
        net_drop(c, c->dead_why);
    }
    if (!c->client) {
        if (c->down_since >= 0 && t - c->down_since > c->o.give_up_seconds) {
            char text[200];
            snprintf(text, sizeof text, "%s:%u: no usable connection for %.1f s", c->host,
                     c->o.port, t - c->down_since);
            ms_core_fail(c, "%.240s", text);
            event_base_loopbreak(c->base);
            return;
        }
        if (t >= c->reconnect_at) {
            if (c->index) {
                pthread_mutex_lock(&c->lock);
                c->reconnects++;
                pthread_mutex_unlock(&c->lock);
            }
            net_connect(c);
        }
        return;
    }
    if (note_socket_bytes(c)) /* any frame counts, index data included */
        c->last_activity = t;
    bool waiting = !c->ready || c->slots_active > 0;
    if (waiting && t - c->last_activity > c->o.answer_timeout) {
        char why[128];
        snprintf(why, sizeof why, "the server sent nothing for %.1f s", t - c->last_activity);
        net_drop(c, why);
        return;
    }
    net_fill(c);
}

void *ms_core_net_main(void *arg)
{
    ms_core *c = arg;
    /* A write to a connection the server has closed raises SIGPIPE in the
     * writing thread: block it here (only here) and see the error instead. */
    sigset_t pipe_only;
    sigemptyset(&pipe_only);
    sigaddset(&pipe_only, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_only, NULL);
    net_connect(c);
    struct timeval every = {0, 5000};
    event_add(c->tick, &every);
    event_base_dispatch(c->base);
    if (c->client) {
        ms_client_free(c->client);
        c->client = NULL;
    }
    pthread_mutex_lock(&c->lock);
    c->connected = false;
    pthread_mutex_unlock(&c->lock);
    return NULL;
}
