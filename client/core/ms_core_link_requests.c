/* A link's requests (ms_core_link, ms_client_core.h): the slots of the
 * requests in flight, found by (member, cell, stream) through a fixed table of
 * buckets, and each round's plan: the members' want lists merged by priority
 * under the one window, what a member no longer wants cancelled, and the
 * REQUEST_CELLS sent, one a run of one member's entries; the link's clock and
 * its mark of a dead connection. The link thread's own (ms_client_core_net.c
 * runs the connection and uses this file, never the other way). */
#include "ms_client_core_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"
#include "ms_proto.h"

double ms_core_link_since_start(const ms_core_link *l) { return ms_now_seconds() - l->t0; }

void ms_core_link_mark_dead(ms_core_link *l, const char *why)
{
    if (!l->dead) {
        l->dead = true;
        snprintf(l->dead_why, sizeof l->dead_why, "%.240s", why);
    }
}

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

ms_core *ms_core_link_core_of(ms_core_link *l, const slot *s) { return l->members[s->member].core; }

/* A member the link streams for now: taken in, not failed or stopping. */
bool ms_core_link_live(const link_member *m) { return m->seen && !m->retired; }

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

uint32_t ms_core_link_slot_find(ms_core_link *l, uint32_t id)
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
    ms_core *c = ms_core_link_core_of(l, s);
    l->in_flight -= bytes;
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight -= bytes;
    pthread_mutex_unlock(&c->lock);
}

void ms_core_link_end_slot(ms_core_link *l, uint32_t k)
{
    slot *s = &l->slots[k];
    if (!s->done)
        in_flight_less(l, s, s->end - s->start - s->got);
    slot_unlink(l, k);
}

/* Ends every slot of member i (all members: i < 0). */
void ms_core_link_end_slots(ms_core_link *l, int i)
{
    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (l->slots[k].used && (i < 0 || l->slots[k].member == i))
            ms_core_link_end_slot(l, k);
}

/* The request's last byte arrived: keep covering its range until the
 * member's decode thread has taken it. */
void ms_core_link_finish_slot(ms_core_link *l, uint32_t k)
{
    slot *s = &l->slots[k];
    ms_core *c = ms_core_link_core_of(l, s);
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
        bool planned = ms_core_link_live(m) && m->ready;
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
        ms_core_link_mark_dead(l, err.text);
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
bool ms_core_link_opening(const ms_core_link *l)
{
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        if (ms_core_link_live(&l->members[i]) && l->members[i].open_request)
            return true;
    return false;
}

/* Sends what the wants call for: releases finished requests the decode
 * threads have taken, cancels requests no longer wanted, then issues the best
 * missing ranges of all the members while the window allows. Nothing new is
 * asked while a model is being opened: the server answers every OPEN_MODEL
 * before any payload, so waiting costs nothing on the wire, and the first
 * window then goes by priority across all the models. */
void ms_core_link_fill(ms_core_link *l)
{
    if (!l->client || l->dead)
        return;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        bool fresh;
        if (!ms_core_link_live(m) || !m->ready || !take_wants(m, &fresh))
            continue;
        for (uint32_t k = 0; k < MAX_SLOTS; ++k)
            if (l->slots[k].used && l->slots[k].member == i && l->slots[k].done &&
                l->slots[k].last_seq <= m->consumed_seq)
                slot_unlink(l, k);
        if (fresh)
            cancel_unwanted(l, (uint8_t)i);
    }
    if (ms_core_link_opening(l))
        return;
    request_batch batch;
    net_plan(l, &batch);
    if (batch.n)
        net_send(l, &batch);
}

/* Sends OPEN_MODEL for member i on the current connection. */
