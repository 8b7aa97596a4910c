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

/* The chain of slots whose (member, cell, stream) falls in one bucket: a fixed
 * table, whatever the models' sizes (iterations skip the other cells' slots). */
static uint32_t *head_of(ms_core_link *l, uint8_t member, uint32_t cell, uint8_t stream)
{
    uint32_t key = (cell * (uint32_t)STREAM_COUNT + stream) * MS_CORE_LINK_MAX_MEMBERS + member;
    return &l->slot_buckets[(key * 2654435761u) >> (32 - SLOT_BUCKET_BITS)];
}

static bool slot_is(const slot *s, uint8_t member, uint32_t cell, uint8_t stream)
{
    return s->member == member && s->cell == cell && s->stream == stream;
}

static ms_core *core_of(ms_core_link *l, const slot *s) { return l->members[s->member].core; }

/* A member the link streams for now: taken in, not failed or stopping. */
static bool live(const link_member *m) { return m->seen && !m->retired; }

static void slot_unlink(ms_core_link *l, uint32_t k)
{
    slot *s = &l->slots[k];
    uint32_t *p = head_of(l, s->member, s->cell, s->stream);
    while (*p != NO_SLOT && *p != k)
        p = &l->slots[*p].next;
    if (*p == k)
        *p = s->next;
    s->used = false;
    l->slots_used--;
    if (!s->done)
        l->slots_active--;
}

static uint32_t slot_find(ms_core_link *l, uint32_t id)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (l->slots[k].used && !l->slots[k].done && l->slots[k].id == id)
            return k;
    return NO_SLOT;
}

/* Bytes of slot s no longer in flight: off the link's window and its
 * member's figure. */
static void in_flight_less(ms_core_link *l, const slot *s, uint64_t bytes)
{
    ms_core *c = core_of(l, s);
    l->in_flight -= bytes;
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight -= bytes;
    pthread_mutex_unlock(&c->lock);
}

static void end_slot(ms_core_link *l, uint32_t k)
{
    slot *s = &l->slots[k];
    if (!s->done)
        in_flight_less(l, s, s->end - s->start - s->got);
    slot_unlink(l, k);
}

/* Ends every slot of member i (all members: i < 0). */
static void end_slots(ms_core_link *l, int i)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (l->slots[k].used && (i < 0 || l->slots[k].member == i))
            end_slot(l, k);
}

/* The request's last byte arrived: keep covering its range until the
 * member's decode thread has taken it. */
static void finish_slot(ms_core_link *l, uint32_t k)
{
    slot *s = &l->slots[k];
    ms_core *c = core_of(l, s);
    uint64_t left = s->end - s->start - s->got;
    l->in_flight -= left;
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight -= left;
    s->last_seq = c->push_seq;
    pthread_mutex_unlock(&c->lock);
    s->got = s->end - s->start;
    s->done = true;
    l->slots_active--;
}

/* Adds what the connection read since the last look to the link's total and
 * every member's; true when it read anything. */
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

static void mark_dead(ms_core_link *l, const char *why)
{
    if (!l->dead) {
        l->dead = true;
        snprintf(l->dead_why, sizeof l->dead_why, "%.240s", why);
    }
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
    end_slots(l, (int)i);
    ms_error err;
    if (l->client && !l->dead && m->ready &&
        ms_client_close_model(l->client, m->handle, &err) != MS_OK)
        mark_dead(l, err.text);
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
    end_slots(l, -1);
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
static bool take_wants(link_member *m, bool *fresh)
{
    ms_core *c = m->core;
    pthread_mutex_lock(&c->lock);
    *fresh = c->want_serial != m->want_serial;
    if (*fresh) {
        if (c->want_count > m->want_cap) {
            want *grown = realloc(m->wants, c->want_count * sizeof *grown);
            if (!grown) {
                pthread_mutex_unlock(&c->lock);
                return false;
            }
            m->wants = grown;
            m->want_cap = c->want_count;
        }
        if (c->want_count)
            memcpy(m->wants, c->wants, c->want_count * sizeof *c->wants);
        m->want_count = c->want_count;
        m->want_serial = c->want_serial;
        m->consumed_seq = c->want_consumed_seq;
    }
    pthread_mutex_unlock(&c->lock);
    return true;
}

/* Cancels member i's requests in flight that none of its fresh wants still
 * covers. */
static void cancel_unwanted(ms_core_link *l, uint8_t i)
{
    const link_member *m = &l->members[i];
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        l->slots[k].keep = false;
    for (size_t j = 0; j < m->want_count; ++j) {
        const want *w = &m->wants[j];
        for (uint32_t k = *head_of(l, i, w->cell, w->stream); k != NO_SLOT; k = l->slots[k].next)
            if (slot_is(&l->slots[k], i, w->cell, w->stream) &&
                (w->stream == STREAM_INDEX || /* a subtree still wanted: its request stays */
                 (l->slots[k].start + l->slots[k].got < w->end && l->slots[k].end > w->start)))
                l->slots[k].keep = true;
    }
    ms_proto_id_range ranges[64];
    uint16_t nr = 0;
    uint64_t cancels = 0;
    for (uint32_t k = 0; k < MAX_SLOTS; ++k) {
        slot *s = &l->slots[k];
        if (!s->used || s->member != i || s->keep || s->cancelled || s->done)
            continue;
        s->cancelled = true;
        ranges[nr].first_id = s->id, ranges[nr].count = 1;
        if (++nr == 64) {
            ms_client_cancel(l->client, ranges, nr, NULL);
            nr = 0;
        }
        cancels++;
    }
    if (nr)
        ms_client_cancel(l->client, ranges, nr, NULL);
    if (cancels) {
        pthread_mutex_lock(&m->core->lock);
        m->core->cancels += cancels;
        pthread_mutex_unlock(&m->core->lock);
    }
}

/* A round of requests being planned: each with the slot reserved for it. */
typedef struct request_batch {
    ms_proto_cell_request req[256];
    uint32_t slot[256];
    uint16_t n;
} request_batch;

/* The part of member i's want w not already on its way (requests are whole
 * ranges from the same table, so a covering request is the usual case) nor
 * in the batch; false when nothing of it is left. */
static bool missing_part(ms_core_link *l, uint8_t i, const want *w, const request_batch *batch,
                         uint32_t *start_out, uint32_t *end_out)
{
    uint32_t start = w->start, end = w->end;
    if (w->stream == STREAM_INDEX) {
        /* a subtree is asked for whole (or from where its bytes stopped), once */
        for (uint32_t k = *head_of(l, i, w->cell, w->stream); k != NO_SLOT; k = l->slots[k].next)
            if (slot_is(&l->slots[k], i, w->cell, w->stream) && !l->slots[k].cancelled)
                return false;
        for (uint16_t j = 0; j < batch->n; ++j)
            if (l->slots[batch->slot[j]].member == i && batch->req[j].cell_id == w->cell &&
                batch->req[j].stream == STREAM_INDEX)
                return false;
        *start_out = start, *end_out = end;
        return start < end;
    }
    for (uint32_t k = *head_of(l, i, w->cell, w->stream); k != NO_SLOT; k = l->slots[k].next) {
        const slot *s = &l->slots[k];
        if (s->cancelled || !slot_is(s, i, w->cell, w->stream))
            continue;
        if (s->start <= start && s->end > start)
            start = s->end;
        if (s->start < end && s->end >= end && s->start > start)
            end = s->start;
    }
    bool dup = false;
    for (uint16_t j = 0; j < batch->n; ++j)
        if (l->slots[batch->slot[j]].member == i && batch->req[j].cell_id == w->cell &&
            batch->req[j].stream == w->stream && batch->req[j].a <= start &&
            batch->req[j].a + batch->req[j].b >= end)
            dup = true;
    *start_out = start, *end_out = end;
    return start < end && !dup;
}

/* A free slot not yet reserved by the batch, or NO_SLOT. */
static uint32_t free_slot(const ms_core_link *l, const request_batch *batch)
{
    uint32_t k = 0;
    while (k < MAX_SLOTS && l->slots[k].used)
        ++k;
    if (k == MAX_SLOTS)
        return NO_SLOT;
    for (uint16_t j = 0; j < batch->n; ++j)
        if (batch->slot[j] == k)
            return NO_SLOT;
    return k;
}

int ms_core_merge_next(const want *const *lists, const size_t *counts, const size_t *cursors,
                       unsigned n)
{
    int best = -1;
    for (unsigned i = 0; i < n; ++i) {
        if (!lists[i] || cursors[i] >= counts[i])
            continue;
        if (best < 0 || lists[i][cursors[i]].priority < lists[best][cursors[best]].priority)
            best = (int)i;
    }
    return best;
}

/* Plans the best missing ranges of all the members while the window, the
 * server's limits and the slots allow, reserving a slot for each. */
static void net_plan(ms_core_link *l, request_batch *batch)
{
    const ms_proto_hello_reply *lim = ms_client_limits(l->client);
    uint32_t max_batch = lim->max_batch ? lim->max_batch : 64;
    uint32_t max_out = lim->max_outstanding ? lim->max_outstanding : 64;
    if (max_out > MAX_SLOTS)
        max_out = MAX_SLOTS;
    if (max_batch > 256)
        max_batch = 256;
    batch->n = 0;
    uint64_t in_flight = l->in_flight;
    /* whole subtrees on their way: their size comes with their first frame,
     * so the window counts each as a typical stored subtree */
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (l->slots[k].used && !l->slots[k].done && !l->slots[k].cancelled &&
            l->slots[k].stream == STREAM_INDEX && l->slots[k].start == l->slots[k].end)
            in_flight += SUBTREE_BYTES_GUESS;
    /* the members' lists, merged by priority as the round goes */
    const want *lists[MS_CORE_LINK_MAX_MEMBERS];
    size_t counts[MS_CORE_LINK_MAX_MEMBERS], cursors[MS_CORE_LINK_MAX_MEMBERS] = {0};
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        const link_member *m = &l->members[i];
        bool planned = live(m) && m->ready;
        lists[i] = planned ? m->wants : NULL;
        counts[i] = planned ? m->want_count : 0;
    }
    while (batch->n < max_batch) {
        if (l->slots_active + batch->n >= max_out || l->slots_used + batch->n >= MAX_SLOTS ||
            (in_flight > 0 && in_flight >= l->window))
            break;
        int i = ms_core_merge_next(lists, counts, cursors, MS_CORE_LINK_MAX_MEMBERS);
        if (i < 0)
            break;
        const want *w = &lists[i][cursors[i]++];
        uint32_t start, end;
        if (!missing_part(l, (uint8_t)i, w, batch, &start, &end))
            continue;
        uint32_t k = free_slot(l, batch);
        if (k == NO_SLOT)
            break;
        /* reserve the slot now so the next search skips it */
        slot *s = &l->slots[k];
        memset(s, 0, sizeof *s);
        s->used = true;
        /* a whole subtree of unknown size: one step (PROTOCOL.md); in the
         * figures it counts as nothing in flight, in the window as a guess */
        bool whole = w->stream == STREAM_INDEX && end == UINT32_MAX;
        if (whole)
            end = start;
        s->member = (uint8_t)i, s->cell = w->cell, s->stream = w->stream;
        s->start = start, s->end = end;
        l->slots_used++;
        l->slots_active++;
        s->next = *head_of(l, s->member, w->cell, w->stream);
        *head_of(l, s->member, w->cell, w->stream) = k;
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

/* Sends entries [a, b) of the batch, all of one member, as one REQUEST_CELLS
 * on its handle; false (the connection marked dead) when it fails. */
static bool send_run(ms_core_link *l, const request_batch *batch, uint16_t a, uint16_t b)
{
    uint8_t i = l->slots[batch->slot[a]].member;
    link_member *m = &l->members[i];
    uint32_t first;
    ms_error err;
    if (ms_client_request_cells(l->client, m->handle, &batch->req[a], (uint16_t)(b - a), &first,
                                &err) != MS_OK) {
        mark_dead(l, err.text);
        return false;
    }
    double t = ms_core_link_since_start(l);
    uint64_t bytes = 0;
    for (uint16_t j = a; j < b; ++j) {
        slot *s = &l->slots[batch->slot[j]];
        s->id = first + (j - a);
        s->sent_at = t;
        bytes += s->end - s->start;
        if (l->o.request_hook)
            l->o.request_hook(m->core, s->cell, s->stream, batch->req[j].priority, l->plans,
                              l->o.request_hook_arg);
    }
    l->in_flight += bytes;
    pthread_mutex_lock(&m->core->lock);
    m->core->bytes_in_flight += bytes;
    m->core->requests += b - a;
    pthread_mutex_unlock(&m->core->lock);
    pthread_mutex_lock(&l->lock);
    l->requests += b - a;
    pthread_mutex_unlock(&l->lock);
    return true;
}

/* Sends the round in its order, one REQUEST_CELLS per run of one member's
 * entries (request ids are consecutive across them); what a dead connection
 * did not take is released. */
static void net_send(ms_core_link *l, const request_batch *batch)
{
    uint16_t a = 0;
    while (a < batch->n) {
        uint16_t b = a + 1;
        while (b < batch->n && l->slots[batch->slot[b]].member == l->slots[batch->slot[a]].member)
            ++b;
        if (!send_run(l, batch, a, b)) {
            for (uint16_t j = a; j < batch->n; ++j)
                slot_unlink(l, batch->slot[j]);
            break;
        }
        a = b;
    }
    l->plans++;
}

/* True while a live member's model is being opened on this connection. */
static bool opening(const ms_core_link *l)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (live(&l->members[i]) && l->members[i].open_request)
            return true;
    return false;
}

/* Sends what the wants call for: releases finished requests the decode
 * threads have taken, cancels requests no longer wanted, then issues the best
 * missing ranges of all the members while the window allows. Nothing new is
 * asked while a model is being opened: the server answers every OPEN_MODEL
 * before any payload, so waiting costs nothing on the wire, and the first
 * window then goes by priority across all the models. */
static void net_fill(ms_core_link *l)
{
    if (!l->client || l->dead)
        return;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        bool fresh;
        if (!live(m) || !m->ready || !take_wants(m, &fresh))
            continue;
        for (uint32_t k = 0; k < MAX_SLOTS; ++k)
            if (l->slots[k].used && l->slots[k].member == i && l->slots[k].done &&
                l->slots[k].last_seq <= m->consumed_seq)
                slot_unlink(l, k);
        if (fresh)
            cancel_unwanted(l, (uint8_t)i);
    }
    if (opening(l))
        return;
    request_batch batch;
    net_plan(l, &batch);
    if (batch.n)
        net_send(l, &batch);
}

/* Sends OPEN_MODEL for member i on the current connection. */
static void open_member(ms_core_link *l, unsigned i)
{
    link_member *m = &l->members[i];
    ms_error err;
    m->ready = false;
    m->handle = 0;
    if (ms_client_open_model(l->client, m->core->model, &m->open_request, &err) != MS_OK) {
        m->open_request = 0;
        mark_dead(l, err.text);
    }
}

static int member_by_open(const ms_core_link *l, uint32_t request_id)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (live(&l->members[i]) && l->members[i].open_request == request_id)
            return (int)i;
    return -1;
}

static int member_by_handle(const ms_core_link *l, uint32_t handle)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (live(&l->members[i]) && l->members[i].ready && l->members[i].handle == handle)
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
    m->opened_once = true;
    m->content_id = o->content_id;
    m->by_subtree = head;
    ms_core_keep_opening(c, a, head);
    pthread_mutex_lock(&c->lock);
    c->stats.index_bytes_received += ms_client_index_wire_bytes(l->client);
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
            mark_dead(l, err.text);
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
    if (outage > c->longest_outage)
        c->longest_outage = outage;
    c->republish = true;                  /* the decode thread recomputes its wants */
    m->want_serial = c->want_serial - 1;  /* and we re-read them */
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
    net_fill(l);
}

static void on_payload(ms_client *client, uint32_t id, const ms_proto_payload *p, bool last,
                       void *arg)
{
    (void)client;
    ms_core_link *l = arg;
    l->last_activity = ms_core_link_since_start(l);
    uint32_t k = slot_find(l, id);
    if (k == NO_SLOT)
        return;
    slot *s = &l->slots[k];
    ms_core *c = core_of(l, s);
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
        finish_slot(l, k);
        net_fill(l);
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
    end_slots(l, (int)i);
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
        uint32_t k = slot_find(l, (uint32_t)id);
        if (k == NO_SLOT)
            continue;
        if (!transient) {
            chunk_msg *m = malloc(sizeof *m);
            if (m) {
                memset(m, 0, sizeof *m);
                m->cell = l->slots[k].cell, m->stream = l->slots[k].stream, m->failed = true;
                ms_core_push_chunk(core_of(l, &l->slots[k]), m);
            }
        }
        end_slot(l, k);
    }
    if (e->code == MS_PROTO_E_RATE_LIMITED || e->code == MS_PROTO_E_QUEUE_FULL) {
        /* ask again after a pause (the next tick), with the wants read anew */
        for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
            if (l->members[i].seen)
                l->members[i].want_serial = UINT64_MAX;
        return;
    }
    net_fill(l);
}

static void on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    ms_core_link *l = arg;
    /* ms_client is still on the stack: free it from the next tick */
    mark_dead(l, why);
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
        if (!live(&l->members[i]) || !l->members[i].opened_once)
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
        if (!live(&l->members[i]))
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
        if (live(&l->members[i]))
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
        anyone |= live(&l->members[i]);
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
    bool waiting = opening(l) || l->slots_active > 0;
    if (waiting && !l->was_waiting)
        l->last_activity = t;
    l->was_waiting = waiting;
    if (waiting && t - l->last_activity > l->o.answer_timeout) {
        char why[128];
        snprintf(why, sizeof why, "the server sent nothing for %.1f s", t - l->last_activity);
        net_drop(l, why);
        return;
    }
    net_fill(l);
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
