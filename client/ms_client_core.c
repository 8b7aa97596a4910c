/* The client core: see ms_client_core.h. Three parts share one mutex:
 * the byte source (the network thread, net_*, or with archive_path the local
 * responder, local_*), the decode thread (dec_*) and the caller. */
#include "ms_client_core.h"

#include <errno.h>
#include <event2/event.h>
#include <math.h>
#include <pthread.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "ms_archive.h"
#include "ms_client.h"
#include "ms_codec.h"
#include "ms_parallel.h"
#include "ms_proto.h"

#define MAX_SLOTS 512u
#define LATENCY_KEEP 65536u
#define NO_SLOT 0xFFFFFFFFu
#define BYTES_PER_VERTEX 64.0
#define MAX_TOLERANCE_FACTOR 4096.0

/* A received payload chunk (or a failed request: length 0, failed true),
 * passed from the network thread to the decode thread. */
typedef struct chunk_msg {
    struct chunk_msg *next;
    uint64_t seq;
    uint32_t cell, offset, length;
    bool apo, failed;
    uint8_t data[];
} chunk_msg;

/* A byte range the decode thread wants, best first. */
typedef struct want {
    uint32_t cell, start, end;
    bool apo;
    uint8_t priority;
    uint32_t decoded_growth; /* estimated decoded bytes the range adds */
} want;

/* A request in flight on the current connection. A finished request stays
 * (done) until the decode thread has taken its last chunk (last_seq), so
 * that wants computed before that do not ask for its bytes again. */
typedef struct slot {
    bool used, cancelled, keep, done;
    uint64_t last_seq;
    uint32_t id, cell, start, end, got;
    bool apo;
    double sent_at;
    uint32_t next; /* next slot of the same cell and stream */
} slot;

/* Reception of one stream of one cell: the bytes from `base` (what the
 * consumer already took) onwards; out-of-order pieces as intervals. */
typedef struct rx {
    uint8_t *buf;       /* bytes [base, base + cap) */
    uint32_t base, cap;
    uint32_t end;       /* [base, end) received contiguously */
    uint32_t iv[8][2];  /* received pieces beyond end, absolute offsets */
    unsigned niv;
} rx;

typedef struct dcell {
    rx geo, apo;
    ms_codec_header *header; /* parsed once the header arrived */
    uint32_t given;          /* geometry bytes handed to the view */
    uint32_t apo_given;      /* APO bytes complete (in apo.buf from 0: base stays 0) */
    uint32_t goal_bytes;     /* geometry prefix the current target needs */
    double handed_at;        /* last hand-over, seconds since start */
    uint8_t retries;
    bool failed, pending;    /* pending: verified bytes not yet handed over */
} dcell;

/* Decode helpers: refine distinct shown cells in parallel before the
 * (single-threaded) apply does the splits and merges (ms_view_decoder.h
 * allows ms_view_set_bits on distinct cells concurrently). */
typedef struct refine_job {
    uint32_t cell;
    unsigned bits;
} refine_job;

typedef struct refine_batch {
    ms_view *view;
    const refine_job *jobs;
} refine_batch;

struct ms_core {
    ms_core_options o;
    char *host, *model, *token, *agent, *archive_path;
    double t0;

    pthread_mutex_t lock;
    pthread_cond_t wake;
    /* --- shared, under lock --- */
    bool stopping, fatal;
    ms_camera camera;
    bool have_camera;
    uint64_t camera_serial;
    chunk_msg *inbox, *inbox_tail;
    ms_archive *index;          /* set once by the network thread */
    bool index_new, republish;
    want *wants;
    size_t want_count;
    uint64_t want_serial;
    uint64_t push_seq;          /* chunks pushed by the network thread */
    uint64_t want_consumed_seq; /* chunks the decode thread had taken for `wants` */
    ms_core_frame *frame;
    ms_core_stats stats;        /* decode thread's figures */
    /* network figures */
    bool connected, model_open;
    uint64_t bytes_received, bytes_in_flight, requests, cancels, reconnects;
    uint64_t geometry_bytes_received, apo_bytes_received;
    uint64_t socket_bytes;      /* read from every connection, frames and index included */
    double *latencies;
    size_t latency_count;

    pthread_t net_thread, dec_thread;
    bool net_started, dec_started;

    /* --- network thread only --- */
    struct event_base *base;
    struct event *tick;
    ms_client *client;
    uint32_t handle, open_request;
    uint64_t content_id;
    bool ready;                 /* model opened on this connection */
    bool dead;                  /* the connection ended: freed on the next tick */
    char dead_why[256];
    double last_activity, reconnect_at, down_since, backoff;
    uint64_t last_read;         /* ms_client_bytes_read at the last tick */
    slot slots[MAX_SLOTS];
    unsigned slots_used, slots_active;
    uint64_t net_consumed_seq;
    uint32_t *slot_head;        /* 2 per cell */
    uint32_t cell_count;
    want *net_wants;
    size_t net_want_count, net_want_cap;
    uint64_t net_want_serial;
    uint64_t window;

    /* --- decode thread only --- */
    ms_view *view;
    dcell *cells;
    uint8_t *target;
    float *tolerance_scale; /* per cell, on the geometric tolerance (APO on: see dec_take_index) */
    double tolerance_factor, last_budget_step, last_blocked;
    uint64_t generation;
    uint64_t consumed_seq;
    bool first_display_seen;
    ms_pool *pool;          /* decode helpers */
    refine_job *jobs;
    size_t job_cap;
};

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

static double since_start(const ms_core *c) { return now_s() - c->t0; }

/* Records a fatal error once (caller holds the lock). */
static void set_fatal_locked(ms_core *c, const char *fmt, const char *text)
{
    if (c->stats.error[0])
        return;
    snprintf(c->stats.error, sizeof c->stats.error, fmt, text);
    c->fatal = true;
    pthread_cond_broadcast(&c->wake);
}

static void set_fatal(ms_core *c, const char *fmt, const char *text)
{
    pthread_mutex_lock(&c->lock);
    set_fatal_locked(c, fmt, text);
    pthread_mutex_unlock(&c->lock);
}

/* ======================== network thread ================================= */

static void net_connect(ms_core *c);

static uint32_t *head_of(ms_core *c, uint32_t cell, bool apo)
{
    return &c->slot_head[2 * (size_t)cell + apo];
}

static void slot_unlink(ms_core *c, uint32_t k)
{
    slot *s = &c->slots[k];
    uint32_t *p = head_of(c, s->cell, s->apo);
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

static void push_chunk(ms_core *c, chunk_msg *m)
{
    pthread_mutex_lock(&c->lock);
    m->seq = ++c->push_seq;
    if (c->inbox_tail)
        c->inbox_tail->next = m;
    else
        c->inbox = m;
    c->inbox_tail = m;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
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

/* Drops the connection; everything in flight is forgotten (the decode thread
 * knows exactly what arrived and asks for the rest again, as BYTES ranges). */
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
    double t = since_start(c);
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

/* Sends what the wants call for: cancels requests no longer wanted, then
 * issues the best missing ranges while the window allows. */
static void net_fill(ms_core *c)
{
    if (!c->client || !c->ready || c->dead)
        return;
    pthread_mutex_lock(&c->lock);
    bool fresh = c->want_serial != c->net_want_serial;
    if (fresh) {
        if (c->want_count > c->net_want_cap) {
            want *grown = realloc(c->net_wants, c->want_count * sizeof *grown);
            if (!grown) {
                pthread_mutex_unlock(&c->lock);
                return;
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
    uint64_t in_flight = c->bytes_in_flight;
    pthread_mutex_unlock(&c->lock);

    for (uint32_t k = 0; k < MAX_SLOTS; ++k)
        if (c->slots[k].used && c->slots[k].done && c->slots[k].last_seq <= c->net_consumed_seq)
            slot_unlink(c, k);
    if (fresh) {
        for (uint32_t k = 0; k < MAX_SLOTS; ++k)
            c->slots[k].keep = false;
        for (size_t i = 0; i < c->net_want_count; ++i) {
            const want *w = &c->net_wants[i];
            for (uint32_t k = *head_of(c, w->cell, w->apo); k != NO_SLOT; k = c->slots[k].next)
                if (c->slots[k].start + c->slots[k].got < w->end && c->slots[k].end > w->start)
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

    const ms_proto_hello_reply *lim = ms_client_limits(c->client);
    uint32_t max_batch = lim->max_batch ? lim->max_batch : 64;
    uint32_t max_out = lim->max_outstanding ? lim->max_outstanding : 64;
    if (max_out > MAX_SLOTS)
        max_out = MAX_SLOTS;
    if (max_batch > 256)
        max_batch = 256;
    ms_proto_cell_request batch[256];
    uint32_t where[256];
    uint16_t n = 0;
    for (size_t i = 0; i < c->net_want_count && n < max_batch; ++i) {
        if (c->slots_active + n >= max_out || c->slots_used + n >= MAX_SLOTS ||
            (in_flight > 0 && in_flight >= c->window))
            break;
        const want *w = &c->net_wants[i];
        uint32_t start = w->start, end = w->end;
        /* Skip what is already on its way (requests are whole ranges from
         * the same table, so a covering request is the usual case). */
        for (uint32_t k = *head_of(c, w->cell, w->apo); k != NO_SLOT; k = c->slots[k].next) {
            const slot *s = &c->slots[k];
            if (s->cancelled)
                continue;
            if (s->start <= start && s->end > start)
                start = s->end;
            if (s->start < end && s->end >= end && s->start > start)
                end = s->start;
        }
        bool dup = false;
        for (uint16_t j = 0; j < n; ++j)
            if (batch[j].cell_id == w->cell && batch[j].stream == (w->apo ? 1 : 0) &&
                batch[j].a <= start && batch[j].a + batch[j].b >= end)
                dup = true;
        if (start >= end || dup)
            continue;
        uint32_t k = 0;
        while (k < MAX_SLOTS && c->slots[k].used)
            ++k;
        if (k == MAX_SLOTS)
            break;
        for (uint16_t j = 0; j < n; ++j)
            if (where[j] == k)
                k = NO_SLOT;
        if (k == NO_SLOT)
            break;
        /* reserve the slot now so the next search skips it */
        slot *s = &c->slots[k];
        memset(s, 0, sizeof *s);
        s->used = true;
        s->cell = w->cell, s->apo = w->apo, s->start = start, s->end = end;
        c->slots_used++;
        c->slots_active++;
        s->next = *head_of(c, w->cell, w->apo);
        *head_of(c, w->cell, w->apo) = k;
        batch[n] = (ms_proto_cell_request){.cell_id = w->cell,
                                           .stream = w->apo ? MS_PROTO_STREAM_APO
                                                            : MS_PROTO_STREAM_GEOMETRY,
                                           .unit = MS_PROTO_UNIT_BYTES,
                                           .priority = w->priority,
                                           .a = start,
                                           .b = end - start};
        where[n++] = k;
        in_flight += end - start;
    }
    if (!n)
        return;
    uint32_t first;
    ms_error err;
    if (ms_client_request_cells(c->client, c->handle, batch, n, &first, &err) != MS_OK) {
        for (uint16_t j = 0; j < n; ++j)
            slot_unlink(c, where[j]);
        if (!c->dead) {
            c->dead = true;
            snprintf(c->dead_why, sizeof c->dead_why, "%.240s", err.text);
        }
        return;
    }
    double t = since_start(c);
    uint64_t bytes = 0;
    for (uint16_t j = 0; j < n; ++j) {
        slot *s = &c->slots[where[j]];
        s->id = first + j;
        s->sent_at = t;
        bytes += s->end - s->start;
    }
    pthread_mutex_lock(&c->lock);
    c->bytes_in_flight += bytes;
    c->requests += n;
    pthread_mutex_unlock(&c->lock);
}

static void on_model_opened(ms_client *client, uint32_t request_id,
                            const ms_proto_model_opened *o, const uint8_t *index, void *arg)
{
    (void)client;
    ms_core *c = arg;
    if (request_id != c->open_request)
        return;
    c->last_activity = since_start(c);
    if (c->index) {
        if (o->content_id != c->content_id) {
            set_fatal(c, "%.240s", "the model changed on the server while it was streamed");
            event_base_loopbreak(c->base);
            return;
        }
    } else {
        ms_archive *a;
        ms_error err;
        if (ms_archive_open_index(index, o->index_size, c->model, &a, &err) != MS_OK) {
            set_fatal(c, "bad model index: %.200s", err.text);
            event_base_loopbreak(c->base);
            return;
        }
        c->cell_count = ms_archive_get_header(a)->cell_count;
        c->slot_head = malloc(2 * (size_t)c->cell_count * sizeof *c->slot_head);
        if (!c->slot_head) {
            ms_archive_close(a);
            set_fatal(c, "%.240s", "out of memory");
            event_base_loopbreak(c->base);
            return;
        }
        for (size_t i = 0; i < 2 * (size_t)c->cell_count; ++i)
            c->slot_head[i] = NO_SLOT;
        c->content_id = o->content_id;
        pthread_mutex_lock(&c->lock);
        c->index = a;
        c->index_new = true;
        pthread_cond_broadcast(&c->wake);
        pthread_mutex_unlock(&c->lock);
    }
    c->handle = o->model_handle;
    c->ready = true;
    c->down_since = -1;
    c->backoff = 0.1;
    pthread_mutex_lock(&c->lock);
    c->model_open = true;
    c->connected = true;
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
    c->last_activity = since_start(c);
    uint32_t k = slot_find(c, id);
    if (k == NO_SLOT)
        return;
    slot *s = &c->slots[k];
    if (p->data_length) {
        chunk_msg *m = malloc(sizeof *m + p->data_length);
        if (m) {
            m->next = NULL;
            m->cell = s->cell, m->apo = s->apo, m->offset = p->offset, m->length = p->data_length;
            m->failed = false;
            memcpy(m->data, p->data, p->data_length);
            push_chunk(c, m);
        }
        uint32_t got = p->offset + p->data_length - s->start;
        if (got > s->end - s->start)
            got = s->end - s->start;
        pthread_mutex_lock(&c->lock);
        c->bytes_received += p->data_length;
        *(s->apo ? &c->apo_bytes_received : &c->geometry_bytes_received) += p->data_length;
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

static void on_request_error(ms_client *client, uint32_t first, uint32_t count,
                             const ms_proto_error_body *e, void *arg)
{
    (void)client;
    ms_core *c = arg;
    c->last_activity = since_start(c);
    if (count == 0) {
        if (e->code == MS_PROTO_E_UNKNOWN_MODEL || e->code == MS_PROTO_E_BAD_MODEL_NAME) {
            char text[300];
            snprintf(text, sizeof text, "model '%.64s': %s", c->model,
                     ms_proto_error_name(e->code));
            set_fatal(c, "%.240s", text);
            event_base_loopbreak(c->base);
        }
        return;
    }
    if (first == c->open_request) {
        char text[300];
        snprintf(text, sizeof text, "cannot open model '%.64s': %s %.*s", c->model,
                 ms_proto_error_name(e->code), (int)(e->text_length > 150 ? 150 : e->text_length),
                 e->text);
        set_fatal(c, "%.240s", text);
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
                m->cell = c->slots[k].cell, m->apo = c->slots[k].apo, m->failed = true;
                push_chunk(c, m);
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
                            .raw_index = c->o.raw_index};
    ms_error err;
    c->last_activity = since_start(c);
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

static void on_tick(evutil_socket_t fd, short what, void *arg)
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
    double t = since_start(c);
    if (c->dead) {
        c->dead = false;
        net_drop(c, c->dead_why);
    }
    if (!c->client) {
        if (c->down_since >= 0 && t - c->down_since > c->o.give_up_seconds) {
            char text[200];
            snprintf(text, sizeof text, "%s:%u: no usable connection for %.1f s", c->host,
                     c->o.port, t - c->down_since);
            set_fatal(c, "%.240s", text);
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

static void *net_main(void *arg)
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


/* ======================== local responder ================================ */

/* With archive_path, this thread stands where the network thread stands: it
 * opens the archive (the whole file, so the decode thread's index is the
 * archive itself), then answers the decode thread's want lists from the
 * mapping. It hands over at most `window` bytes of the best ranges, in the
 * list's order, as chunk messages like the network's, then waits until the
 * decode thread has taken them and published its next list (which then asks
 * only for what is still missing, so nothing is handed over twice and a new
 * camera reorders what comes next). With `bandwidth` it sleeps as long as the
 * bytes would take on such a link. */

/* Waits up to `seconds` unless the core stops; caller holds the lock. */
static void local_pause_locked(ms_core *c, double seconds)
{
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    double whole = floor(seconds);
    until.tv_sec += (time_t)whole;
    until.tv_nsec += (long)((seconds - whole) * 1e9);
    if (until.tv_nsec >= 1000000000L)
        until.tv_sec++, until.tv_nsec -= 1000000000L;
    while (!c->stopping && !c->fatal &&
           pthread_cond_timedwait(&c->wake, &c->lock, &until) != ETIMEDOUT)
        ;
}

/* One want as a chunk message from the archive (a failed one if the archive
 * does not hold the range, which its validated index rules out). */
static chunk_msg *local_chunk(const ms_archive *a, const want *w)
{
    size_t length;
    const uint8_t *src = w->apo ? ms_archive_apo(a, w->cell, &length)
                                : ms_archive_geometry(a, w->cell, &length);
    bool held = src && w->start < w->end && w->end <= length;
    uint32_t n = held ? w->end - w->start : 0;
    chunk_msg *m = malloc(sizeof *m + n);
    if (!m)
        return NULL;
    memset(m, 0, sizeof *m);
    m->cell = w->cell, m->apo = w->apo, m->offset = w->start, m->length = n;
    m->failed = !held;
    if (held)
        memcpy(m->data, src + w->start, n);
    return m;
}

static void *local_main(void *arg)
{
    ms_core *c = arg;
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(c->archive_path, &a, &err) != MS_OK) {
        set_fatal(c, "%.240s", err.text);
        return NULL;
    }
    want *list = NULL;
    size_t cap = 0;
    uint64_t served_serial = 0, handed_seq = 0;
    pthread_mutex_lock(&c->lock);
    c->index = a;
    c->index_new = true;
    c->connected = c->model_open = true;
    pthread_cond_broadcast(&c->wake);
    for (;;) {
        /* a fresh list, computed after the decode thread took what we handed */
        while (!c->stopping && !c->fatal &&
               (c->want_serial == served_serial || c->want_consumed_seq < handed_seq))
            pthread_cond_wait(&c->wake, &c->lock);
        if (c->stopping || c->fatal)
            break;
        served_serial = c->want_serial;
        size_t count = c->want_count;
        if (count > cap) {
            want *grown = realloc(list, count * sizeof *grown);
            if (!grown) {
                set_fatal_locked(c, "%.240s", "out of memory for the local responder");
                break;
            }
            list = grown;
            cap = count;
        }
        if (count)
            memcpy(list, c->wants, count * sizeof *list);
        pthread_mutex_unlock(&c->lock);

        uint64_t handed = 0, geometry = 0, apo = 0, ranges = 0;
        for (size_t i = 0; i < count && handed < c->window; ++i) {
            chunk_msg *m = local_chunk(a, &list[i]);
            if (!m) {
                set_fatal(c, "%.240s", "out of memory for the local responder");
                break;
            }
            handed += m->length;
            *(m->apo ? &apo : &geometry) += m->length;
            ranges++;
            push_chunk(c, m);
        }
        pthread_mutex_lock(&c->lock);
        c->bytes_received += handed;
        c->geometry_bytes_received += geometry;
        c->apo_bytes_received += apo;
        c->requests += ranges;
        handed_seq = c->push_seq;
        if (c->o.bandwidth > 0 && handed > 0)
            local_pause_locked(c, (double)handed / c->o.bandwidth);
    }
    c->connected = false;
    pthread_mutex_unlock(&c->lock);
    free(list);
    return NULL;
}

/* ======================== decode thread ================================== */

static void rx_free(rx *r)
{
    free(r->buf);
    memset(r, 0, sizeof *r);
}

/* Forgets what was received beyond `keep` (>= base). */
static void rx_cut(rx *r, uint32_t keep)
{
    if (r->end > keep)
        r->end = keep;
    r->niv = 0;
}

/* Adds received bytes; ignores what is already held or below base. */
static bool rx_add(rx *r, uint32_t offset, const uint8_t *data, uint32_t length)
{
    uint64_t end = (uint64_t)offset + length;
    if (end <= r->end)
        return true;
    if (offset < r->end) {
        data += r->end - offset;
        length -= r->end - offset;
        offset = r->end;
    }
    if (end - r->base > r->cap) {
        uint64_t cap = r->cap ? r->cap : 4096;
        while (cap < end - r->base)
            cap *= 2;
        uint8_t *b = realloc(r->buf, cap);
        if (!b)
            return false;
        r->buf = b;
        r->cap = (uint32_t)cap;
    }
    memcpy(r->buf + (offset - r->base), data, length);
    if (offset == r->end) {
        r->end = (uint32_t)end;
    } else if (r->niv < 8) {
        r->iv[r->niv][0] = offset, r->iv[r->niv][1] = (uint32_t)end;
        r->niv++;
    }
    /* absorb pieces that now touch the contiguous part */
    for (bool moved = true; moved;) {
        moved = false;
        for (unsigned i = 0; i < r->niv; ++i) {
            if (r->iv[i][0] <= r->end) {
                if (r->iv[i][1] > r->end)
                    r->end = r->iv[i][1];
                r->iv[i][0] = r->iv[--r->niv][0];
                r->iv[i][1] = r->iv[r->niv][1];
                moved = true;
                break;
            }
        }
    }
    return true;
}

/* Drops bytes below `upto` from the buffer (the consumer took them). */
static void rx_consume(rx *r, uint32_t upto)
{
    if (upto <= r->base)
        return;
    uint32_t drop = upto - r->base;
    uint32_t held = r->end > upto ? r->end - upto : 0;
    uint32_t span = 0;
    for (unsigned i = 0; i < r->niv; ++i)
        if (r->iv[i][1] - upto > span)
            span = r->iv[i][1] - upto;
    if (span < held)
        span = held;
    if (span == 0) {
        free(r->buf);
        r->buf = NULL;
        r->cap = 0;
    } else {
        memmove(r->buf, r->buf + drop, span);
    }
    r->base = upto;
}

static void set_warning(ms_core *c, const char *text)
{
    pthread_mutex_lock(&c->lock);
    snprintf(c->stats.warning, sizeof c->stats.warning, "%.240s", text);
    pthread_mutex_unlock(&c->lock);
}

/* A corrupt or failed range of cell: fetch it once more, then give up. */
static void cell_trouble(ms_core *c, uint32_t cell, const char *what)
{
    dcell *d = &c->cells[cell];
    rx_cut(&d->geo, d->given);
    d->retries++;
    pthread_mutex_lock(&c->lock);
    c->stats.refetches += d->retries == 1;
    pthread_mutex_unlock(&c->lock);
    if (d->retries >= 2 && !d->failed) {
        d->failed = true;
        char text[256];
        snprintf(text, sizeof text, "cell %u: %.180s (after a refetch); cell left at its "
                 "last good precision", cell, what);
        set_warning(c, text);
    }
}

/* Hands the newly received, verified geometry bytes of cell to the view. */
static void dec_hand_over(ms_core *c, uint32_t cell)
{
    dcell *d = &c->cells[cell];
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, cell);
    if (d->geo.end <= d->given)
        return;
    if (!d->header) {
        /* the header sits at the start: parse it once prefix(bits_min) arrived */
        uint32_t hsize = ms_archive_geometry_prefix(c->index, cell, rec->bits_min);
        if (d->geo.end < hsize || d->given != 0)
            return;
        ms_codec_header h;
        ms_error err;
        if (ms_codec_read_header(d->geo.buf, d->geo.end, &h, &err) != MS_OK ||
            h.header_size != hsize || h.p_min != rec->bits_min || h.p_max != rec->bits_max) {
            cell_trouble(c, cell, "payload header does not match the index");
            return;
        }
        for (unsigned k = 0; k < h.p_max - h.p_min; ++k)
            if (h.header_size + h.chunk_end[k] !=
                ms_archive_geometry_prefix(c->index, cell, h.p_min + k + 1)) {
                cell_trouble(c, cell, "payload header does not match the index");
                return;
            }
        d->header = malloc(sizeof *d->header);
        if (!d->header)
            return;
        *d->header = h;
    }
    const ms_codec_header *h = d->header;
    uint32_t good = d->given;
    for (unsigned k = 0; k < h->p_max - h->p_min; ++k) {
        uint32_t a = (uint32_t)h->header_size + (k ? h->chunk_end[k - 1] : 0);
        uint32_t b = (uint32_t)h->header_size + h->chunk_end[k];
        if (b <= d->given)
            continue;
        if (b > d->geo.end)
            break;
        if (a < d->given)
            break; /* cannot happen: given ends on a chunk boundary */
        uint32_t crc = (uint32_t)crc32(0L, d->geo.buf + (a - d->geo.base), b - a);
        if (crc != h->chunk_crc[k]) {
            char what[96];
            snprintf(what, sizeof what, "precision bit %u fails its CRC", h->p_min + k + 1);
            rx_cut(&d->geo, good);
            cell_trouble(c, cell, what);
            return;
        }
        good = b;
    }
    if (good == d->given)
        return;
    /* The view's decoder restarts from the cell's first bit whenever it gets
     * more bytes, so hand over in few steps: the first bits at once (something
     * to show; the root bit by bit), then when the target's prefix is
     * complete, or every 0.25 s. */
    double t = since_start(c);
    if (d->given > 0 && rec->level > 0 && good < d->goal_bytes && good < rec->geometry_length &&
        t - d->handed_at < 0.25) {
        d->pending = true;
        return;
    }
    d->pending = false;
    d->handed_at = t;
    ms_error err;
    if (ms_view_append_bytes(c->view, cell, d->geo.buf + (d->given - d->geo.base),
                             good - d->given, &err) != MS_OK) {
        set_warning(c, err.text);
        return;
    }
    d->given = good;
    rx_consume(&d->geo, good);
}

/* APO chunks have no per-level checksum: a complete chunk is checked whole. */
static void dec_apo_received(ms_core *c, uint32_t cell)
{
    dcell *d = &c->cells[cell];
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, cell);
    if (d->apo.end < rec->apo_length) {
        d->apo_given = d->apo.end;
        return;
    }
    ms_error err;
    if (ms_archive_check_payload(c->index, cell, true, d->apo.buf, d->apo.end, &err) != MS_OK) {
        rx_free(&d->apo);
        d->apo_given = 0;
        d->retries++;
        if (d->retries >= 2 && !d->failed) {
            d->failed = true;
            set_warning(c, err.text);
        }
        return;
    }
    d->apo_given = d->apo.end;
}

static bool dec_take_index(ms_core *c, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    ms_archive_cell *recs = malloc((size_t)h->cell_count * sizeof *recs);
    c->cells = calloc(h->cell_count, sizeof *c->cells);
    c->target = malloc(h->cell_count);
    c->tolerance_scale = malloc((size_t)h->cell_count * sizeof *c->tolerance_scale);
    if (!recs || !c->cells || !c->target || !c->tolerance_scale) {
        free(recs);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
        return false;
    }
    /* With APO on, geometry refines only to apo_geometry_tolerance_px where a
     * chunk carries the shading; a cell baked without one (its geometry renders
     * the input: every leaf, docs/APO.md) is shaded by its triangles alone, so
     * it refines to tolerance_px as with APO off. */
    bool apo_on = c->o.apo_levels > 0 && h->has_apo;
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        recs[i] = *ms_archive_get_cell(c->index, i);
        c->tolerance_scale[i] = apo_on && recs[i].apo_levels == 0
                                    ? (float)(c->o.tolerance_px / c->o.apo_geometry_tolerance_px)
                                    : 1.0f;
    }
    ms_status s = ms_view_create(h, recs, &c->view, err);
    free(recs);
    return s == MS_OK;
}

/* The side of a cell's cube, world units. */
static double cell_side(const ms_archive_header *h, const ms_archive_cell *rec)
{
    double side = h->box_side;
    for (unsigned l = 0; l < rec->level; ++l)
        side /= h->n;
    return side;
}

static void cell_box(const ms_archive_header *h, const ms_archive_cell *rec, double lo[3],
                     double hi[3])
{
    double side = cell_side(h, rec);
    for (int a = 0; a < 3; ++a) {
        lo[a] = h->box_origin[a] + side * rec->position[a];
        hi[a] = lo[a] + side;
    }
}

typedef struct frame_view {
    ms_camera cam;
    ms_frustum frustum;
    double tolerance;
} frame_view;

/* The precision (real bits) the camera wants of cell; *visible tells whether
 * its cube meets the frustum. */
static double cell_need(const ms_core *c, const frame_view *fv, uint32_t cell, bool *visible)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    double lo[3], hi[3];
    cell_box(h, ms_archive_get_cell(c->index, cell), lo, hi);
    *visible = ms_frustum_keeps_box(&fv->frustum, lo, hi, c->o.frustum_margin);
    double d = ms_camera_box_distance(&fv->cam, lo, hi);
    double need = ms_screen_bits_needed(&fv->cam, h->box_side, d, fv->tolerance);
    return isfinite(need) ? need : 64.0;
}

static double cell_error_px(const ms_core *c, const frame_view *fv, uint32_t cell, unsigned bits)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    double lo[3], hi[3];
    cell_box(h, ms_archive_get_cell(c->index, cell), lo, hi);
    double d = ms_camera_box_distance(&fv->cam, lo, hi);
    /* nothing nearer than the near plane is drawn */
    if (d < fv->cam.near_distance)
        d = fv->cam.near_distance;
    double side = h->box_side / ldexp(1.0, (int)bits);
    double px = sqrt(3.0) * side * ms_camera_pixels_per_unit(&fv->cam);
    return px / d;
}

static uint8_t clamp_priority(double p)
{
    return p < 0 ? 0 : p > 255 ? 255 : (uint8_t)p;
}

static int compare_wants(const void *x, const void *y)
{
    const want *a = x, *b = y;
    if (a->priority != b->priority)
        return a->priority < b->priority ? -1 : 1;
    if (a->cell != b->cell)
        return a->cell < b->cell ? -1 : 1;
    return a->start < b->start ? -1 : a->start > b->start;
}

typedef struct want_list {
    want *w;
    size_t n, cap;
} want_list;

static bool want_push(want_list *l, want w)
{
    if (l->n == l->cap) {
        size_t cap = l->cap ? l->cap * 2 : 256;
        want *g = realloc(l->w, cap * sizeof *g);
        if (!g)
            return false;
        l->w = g;
        l->cap = cap;
    }
    l->w[l->n++] = w;
    return true;
}

/* Decoded bytes of a cell shown at `bits` (an estimate: the vertex count
 * grows about 4x a bit on a surface). */
static double decoded_estimate(const ms_archive_cell *rec, unsigned bits)
{
    if (rec->geometry_length == 0)
        return 0;
    double v = rec->vertex_count * ldexp(1.0, -2 * (int)(rec->bits_max - bits));
    return (v < 1 ? 1 : v) * BYTES_PER_VERTEX;
}

static uint64_t cell_memory(const ms_core *c, uint32_t cell)
{
    const dcell *d = &c->cells[cell];
    uint64_t m = ms_view_held_bytes(c->view, cell) + d->geo.cap + d->apo.cap;
    if (ms_view_state(c->view, cell) != MS_VIEW_HIDDEN)
        m += (uint64_t)decoded_estimate(ms_archive_get_cell(c->index, cell),
                                        ms_view_bits(c->view, cell));
    return m;
}

static void dec_evict(ms_core *c, uint32_t cell)
{
    dcell *d = &c->cells[cell];
    ms_view_forget(c->view, cell, NULL);
    rx_free(&d->geo);
    rx_free(&d->apo);
    free(d->header);
    d->header = NULL;
    d->given = d->apo_given = 0;
    pthread_mutex_lock(&c->lock);
    c->stats.evictions++;
    pthread_mutex_unlock(&c->lock);
}

typedef struct evict_candidate {
    uint32_t cell;
    double usefulness;
    uint64_t bytes;
} evict_candidate;

static int compare_candidates(const void *x, const void *y)
{
    const evict_candidate *a = x, *b = y;
    return a->usefulness < b->usefulness ? -1 : a->usefulness > b->usefulness;
}

static uint64_t dec_memory(const ms_core *c)
{
    uint64_t m = 0;
    for (uint32_t i = 0; i < ms_view_cell_count(c->view); ++i)
        m += cell_memory(c, i);
    return m;
}

/* Evicts hidden cells the view does not target, least useful first, until
 * memory is at most limit. */
static void dec_evict_unneeded(ms_core *c, const frame_view *fv, uint64_t limit)
{
    uint32_t n = ms_view_cell_count(c->view);
    evict_candidate *cand = malloc(n * sizeof *cand);
    if (!cand)
        return;
    size_t nc = 0;
    for (uint32_t i = 1; i < n; ++i) {
        if (ms_view_state(c->view, i) != MS_VIEW_HIDDEN || c->target[i] != MS_VIEW_TARGET_HIDDEN)
            continue;
        uint64_t b = cell_memory(c, i);
        if (!b)
            continue;
        bool visible;
        double u = cell_need(c, fv, i, &visible);
        cand[nc++] = (evict_candidate){i, visible ? u : u - 64.0, b};
    }
    qsort(cand, nc, sizeof *cand, compare_candidates);
    uint64_t m = dec_memory(c);
    for (size_t k = 0; k < nc && m > limit; ++k) {
        m -= cand[k].bytes < m ? cand[k].bytes : m;
        dec_evict(c, cand[k].cell);
    }
    free(cand);
}

static ms_core_frame *dec_make_frame(ms_core *c, ms_error *err)
{
    ms_core_frame *f = calloc(1, sizeof *f);
    uint32_t n = ms_view_cell_count(c->view);
    if (!f || !(f->cell_bits = malloc(n))) {
        free(f);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
        return NULL;
    }
    f->cell_count = n;
    for (uint32_t i = 0; i < n; ++i) {
        ms_view_cell_state st = ms_view_state(c->view, i);
        f->cell_bits[i] = st == MS_VIEW_SHOWN ? (uint8_t)ms_view_bits(c->view, i)
                          : st == MS_VIEW_SPLIT ? MS_VIEW_TARGET_SPLIT
                                                : MS_VIEW_TARGET_HIDDEN;
        const dcell *d = &c->cells[i];
        if (st == MS_VIEW_SHOWN && d->apo_given > 0) {
            ms_core_apo_chunk *g = realloc(f->apo, (f->apo_count + 1) * sizeof *g);
            uint8_t *copy = malloc(d->apo_given);
            if (!g || !copy) {
                free(copy);
                if (g)
                    f->apo = g;
                ms_core_frame_free(f);
                ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
                return NULL;
            }
            f->apo = g;
            memcpy(copy, d->apo.buf, d->apo_given);
            /* complete levels: ms_archive_apo_prefix(depth) ends depth's level */
            unsigned levels = 0;
            const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
            for (unsigned depth = 0; depth < rec->apo_levels; ++depth)
                if (ms_archive_apo_prefix(c->index, i, depth, NULL) <= d->apo_given)
                    levels = depth + 1;
            f->apo[f->apo_count++] = (ms_core_apo_chunk){i, levels, copy, d->apo_given};
        }
    }
    if (ms_view_stitch(c->view, NULL, &f->mesh, err) != MS_OK) {
        ms_core_frame_free(f);
        return NULL;
    }
    return f;
}

/* Whether some shown cell in view already has a triangle to draw. */
static bool dec_something_drawn(ms_core *c, const frame_view *fv)
{
    uint32_t n = ms_view_cell_count(c->view);
    for (uint32_t i = 0; i < n; ++i) {
        if (ms_view_state(c->view, i) != MS_VIEW_SHOWN)
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        if (rec->geometry_length == 0 || ms_view_bits(c->view, i) <= rec->bits_min)
            continue;
        bool visible;
        cell_need(c, fv, i, &visible);
        if (!visible)
            continue;
        ms_codec_state s;
        if (ms_view_cell_state_copy(c->view, i, &s, NULL) != MS_OK)
            continue;
        bool drawn = s.tri_count > 0;
        ms_codec_state_free(&s);
        if (drawn)
            return true;
    }
    return false;
}

/* One refine job: failures are seen again, and reported, by ms_view_apply. */
static void refine_one(void *ctx, size_t k)
{
    const refine_batch *b = ctx;
    (void)ms_view_set_bits(b->view, b->jobs[k].cell, b->jobs[k].bits, NULL);
}

static int compare_jobs_by_work(const void *x, const void *y)
{
    const refine_job *a = x, *b = y;
    return a->bits > b->bits ? -1 : a->bits < b->bits;
}

/* The parallel part of a pass: shown cells that can go up with the bytes held. */
static size_t dec_parallel_refine(ms_core *c)
{
    uint32_t n = ms_view_cell_count(c->view);
    size_t count = 0;
    for (uint32_t i = 0; i < n; ++i) {
        if (ms_view_state(c->view, i) != MS_VIEW_SHOWN || c->target[i] == MS_VIEW_TARGET_HIDDEN)
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        if (rec->geometry_length == 0 || ms_view_held_bytes(c->view, i) == 0)
            continue;
        unsigned goal = c->target[i] == MS_VIEW_TARGET_SPLIT ? rec->bits_max : c->target[i];
        unsigned cur = ms_view_bits(c->view, i);
        if (goal <= cur)
            continue;
        unsigned avail = ms_view_available_bits(c->view, i);
        if (goal > avail)
            goal = avail;
        if (goal <= cur)
            continue;
        if (count == c->job_cap) {
            size_t cap = c->job_cap ? 2 * c->job_cap : 64;
            refine_job *g = realloc(c->jobs, cap * sizeof *g);
            if (!g)
                break;
            c->jobs = g;
            c->job_cap = cap;
        }
        c->jobs[count++] = (refine_job){i, goal};
    }
    if (count > 1)
        qsort(c->jobs, count, sizeof *c->jobs, compare_jobs_by_work);
    refine_batch batch = {c->view, c->jobs};
    ms_pool_for(c->pool, count, refine_one, &batch);
    return count;
}

/* One pass: take inputs, decode, select, plan, publish. */
static void dec_step(ms_core *c, chunk_msg *chunks, const ms_camera *cam, uint64_t serial,
                     bool have_camera)
{
    double t_start = now_s();
    /* received bytes; new APO bytes change the frame as new geometry does */
    bool apo_changed = false;
    while (chunks) {
        chunk_msg *m = chunks;
        chunks = m->next;
        c->consumed_seq = m->seq;
        if (m->cell < ms_view_cell_count(c->view)) {
            dcell *d = &c->cells[m->cell];
            if (m->failed) {
                if (!m->apo)
                    cell_trouble(c, m->cell, "the server answered a request with an error");
            } else {
                if (c->o.payload_filter)
                    c->o.payload_filter(m->cell, m->apo, m->offset, m->data, m->length,
                                        c->o.payload_filter_arg);
                if (!rx_add(m->apo ? &d->apo : &d->geo, m->offset, m->data, m->length))
                    set_warning(c, "out of memory for received bytes");
                else if (!m->apo)
                    dec_hand_over(c, m->cell);
                else {
                    uint32_t before = d->apo_given;
                    dec_apo_received(c, m->cell);
                    apo_changed |= d->apo_given != before;
                }
            }
        }
        free(m);
    }
    if (!have_camera)
        return;

    const ms_archive_header *h = ms_archive_get_header(c->index);
    bool apo_on = c->o.apo_levels > 0 && h->has_apo;
    frame_view fv;
    fv.cam = *cam;
    ms_camera_frustum(cam, &fv.frustum);
    double base_tol = apo_on ? c->o.apo_geometry_tolerance_px : c->o.tolerance_px;
    fv.tolerance = base_tol * c->tolerance_factor;

    ms_view_select_params sp = {.tolerance_px = fv.tolerance,
                                .margin = c->o.frustum_margin,
                                .hysteresis = c->o.hysteresis_bits,
                                .culled_bits_less = c->o.culled_bits_less,
                                .tolerance_scale = c->tolerance_scale};
    ms_view_select(c->view, cam, &sp, c->target);
    size_t refined_in_parallel = dec_parallel_refine(c);
    ms_view_apply_report report;
    ms_error err;
    if (ms_view_apply(c->view, c->target, &report, &err) != MS_OK) {
        pthread_mutex_lock(&c->lock);
        set_fatal_locked(c, "decoding failed: %.200s", err.text);
        pthread_mutex_unlock(&c->lock);
        return;
    }
    bool changed = refined_in_parallel || report.splits || report.merges || report.refined ||
                   report.coarsened || apo_changed;
    /* Hard ceiling: evict what the view does not need; if that is not enough,
     * coarsen at once (double the tolerance) and evict what that frees. */
    for (int round = 0; c->o.memory_ceiling && round < 8; ++round) {
        if (dec_memory(c) <= c->o.memory_ceiling)
            break;
        dec_evict_unneeded(c, &fv, (uint64_t)(0.9 * c->o.memory_target));
        if (dec_memory(c) <= c->o.memory_ceiling || c->tolerance_factor >= MAX_TOLERANCE_FACTOR)
            break;
        c->tolerance_factor *= 2;
        c->last_budget_step = since_start(c);
        fv.tolerance = sp.tolerance_px = base_tol * c->tolerance_factor;
        ms_view_select(c->view, cam, &sp, c->target);
        if (ms_view_apply(c->view, c->target, &report, &err) != MS_OK) {
            pthread_mutex_lock(&c->lock);
            set_fatal_locked(c, "decoding failed: %.200s", err.text);
            pthread_mutex_unlock(&c->lock);
            return;
        }
        changed = true;
    }

    /* what is missing, and in which order */
    want_list wl = {0};
    uint32_t n = ms_view_cell_count(c->view);
    double worst = 0;
    uint32_t shown = 0, split = 0, cached = 0, loading = 0, failed = 0;
    bool complete = true;
    for (uint32_t i = 0; i < n; ++i) {
        ms_view_cell_state st = ms_view_state(c->view, i);
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        dcell *d = &c->cells[i];
        failed += d->failed;
        if (st == MS_VIEW_SPLIT) {
            split++;
            continue;
        }
        if (st == MS_VIEW_HIDDEN) {
            cached += ms_view_held_bytes(c->view, i) > 0;
            /* Prefetch: the children of a shown cell about to split can
             * receive their bytes while it finishes (they decode once it
             * splits), which keeps the link busy across the split. */
            uint8_t t = c->target[i];
            if (t == MS_VIEW_TARGET_HIDDEN || rec->parent == MS_ARCHIVE_NONE ||
                ms_view_state(c->view, rec->parent) != MS_VIEW_SHOWN ||
                rec->geometry_length == 0 || d->failed)
                continue;
            unsigned goal = t == MS_VIEW_TARGET_SPLIT ? rec->bits_max : t;
            if (goal > rec->bits_max)
                goal = rec->bits_max;
            bool visible;
            double need = cell_need(c, &fv, i, &visible);
            unsigned have = ms_view_available_bits(c->view, i);
            for (unsigned s2 = have + 1; s2 <= goal; ++s2) {
                uint32_t a = s2 == have + 1 ? d->geo.end
                                            : ms_archive_geometry_prefix(c->index, i, s2 - 1);
                uint32_t b = ms_archive_geometry_prefix(c->index, i, s2);
                if (a < d->geo.end)
                    a = d->geo.end;
                if (a >= b)
                    continue;
                double p = (visible ? 144.0 : 208.0) - 8.0 * (need - s2);
                double grow = decoded_estimate(rec, s2) - decoded_estimate(rec, s2 - 1);
                want_push(&wl, (want){i, a, b, false, clamp_priority(p),
                                      (uint32_t)(grow > 4e9 ? 4e9 : grow)});
            }
            continue;
        }
        shown++;
        bool visible;
        double need = cell_need(c, &fv, i, &visible);
        unsigned bits = ms_view_bits(c->view, i);
        if (visible && rec->geometry_length > 0) {
            double e = cell_error_px(c, &fv, i, bits);
            if (e > worst)
                worst = e;
        }
        uint8_t t = c->target[i];
        unsigned goal = t == MS_VIEW_TARGET_SPLIT || t == MS_VIEW_TARGET_HIDDEN ? rec->bits_max : t;
        if (goal > rec->bits_max)
            goal = rec->bits_max;
        unsigned avail = ms_view_available_bits(c->view, i);
        d->goal_bytes = ms_archive_geometry_prefix(c->index, i, goal);
        if (d->pending)
            dec_hand_over(c, i);
        bool cell_loading = false;
        if (goal > avail && rec->geometry_length > 0) {
            complete = false;
            if (!d->failed) {
                cell_loading = true;
                for (unsigned s = avail + 1; s <= goal; ++s) {
                    uint32_t a = s == avail + 1 ? d->geo.end : ms_archive_geometry_prefix(c->index, i, s - 1);
                    uint32_t b = ms_archive_geometry_prefix(c->index, i, s);
                    if (a < d->geo.end)
                        a = d->geo.end;
                    if (a >= b)
                        continue;
                    double p = (visible ? 128.0 : 192.0) - 8.0 * (need - s);
                    double grow = decoded_estimate(rec, s) - decoded_estimate(rec, s - 1);
                    if (s == rec->bits_max && t == MS_VIEW_TARGET_SPLIT)
                        grow += rec->vertex_count * BYTES_PER_VERTEX; /* the children */
                    want_push(&wl, (want){i, a, b, false, clamp_priority(p),
                                          (uint32_t)(grow > 4e9 ? 4e9 : grow)});
                }
            }
        }
        /* APO by footprint: down to the level whose texel projects to the
         * detail tolerance, at most apo_levels; none for a cell about to
         * split (its children replace it as soon as its last bits arrive:
         * on the demo close-up such passing cells would take half the APO
         * bytes) */
        if (apo_on && visible && rec->apo_length > 0 && !d->failed && t != MS_VIEW_TARGET_SPLIT) {
            unsigned cap = c->o.apo_levels < rec->apo_levels ? c->o.apo_levels : rec->apo_levels;
            double lo[3], hi[3];
            cell_box(h, rec, lo, hi);
            unsigned levels = ms_apo_footprint_levels(&fv.cam, lo, cell_side(h, rec),
                                                      c->o.tolerance_px * c->tolerance_factor, cap);
            /* levels 0 .. levels - 1; ms_archive_apo_prefix(depth) ends depth's level */
            uint32_t b = ms_archive_apo_prefix(c->index, i, levels - 1, NULL);
            if (d->apo.end < b) {
                complete = false;
                cell_loading = true;
                for (unsigned l = 1; l <= levels; ++l) {
                    uint32_t lb = ms_archive_apo_prefix(c->index, i, l - 1, NULL);
                    uint32_t la = l == 1 ? 0 : ms_archive_apo_prefix(c->index, i, l - 2, NULL);
                    if (la < d->apo.end)
                        la = d->apo.end;
                    if (la >= lb)
                        continue;
                    want_push(&wl, (want){i, la, lb, true,
                                          clamp_priority(136.0 + 8.0 * l - 8.0 * (need - bits)),
                                          0});
                }
            }
        }
        loading += cell_loading;
    }
    if (failed)
        complete = false;
    if (wl.n)
        qsort(wl.w, wl.n, sizeof *wl.w, compare_wants);

    /* memory: the budget */
    uint64_t memory = 0;
    for (uint32_t i = 0; i < n; ++i)
        memory += cell_memory(c, i);
    pthread_mutex_lock(&c->lock);
    uint64_t in_flight = c->bytes_in_flight;
    pthread_mutex_unlock(&c->lock);
    if (c->o.memory_target) {
        double t = since_start(c);
        if (memory > c->o.memory_target && c->tolerance_factor < MAX_TOLERANCE_FACTOR &&
            t - c->last_budget_step > 0.1) {
            c->tolerance_factor *= M_SQRT2;
            c->last_budget_step = t;
        } else if (memory < 0.7 * c->o.memory_target && c->tolerance_factor > 1.0 &&
                   t - c->last_budget_step > 0.1 && t - c->last_blocked > 2.0) {
            c->tolerance_factor /= M_SQRT2;
            if (c->tolerance_factor < 1.0)
                c->tolerance_factor = 1.0;
            c->last_budget_step = t;
        }
        /* candidates: hidden cells the current view does not target */
        evict_candidate *cand = NULL;
        size_t nc = 0;
        for (uint32_t i = 1; i < n; ++i) {
            if (ms_view_state(c->view, i) != MS_VIEW_HIDDEN || c->target[i] != MS_VIEW_TARGET_HIDDEN)
                continue;
            uint64_t b = cell_memory(c, i);
            if (!b)
                continue;
            evict_candidate *g = realloc(cand, (nc + 1) * sizeof *g);
            if (!g)
                break;
            cand = g;
            bool visible;
            double u = cell_need(c, &fv, i, &visible);
            cand[nc++] = (evict_candidate){i, visible ? u : u - 64.0, b};
        }
        if (nc)
            qsort(cand, nc, sizeof *cand, compare_candidates);
        size_t next = 0;
        /* over the target: free down to 90 % of it, least useful first */
        if (memory > c->o.memory_target)
            while (memory > 0.9 * c->o.memory_target && next < nc) {
                memory -= cand[next].bytes;
                dec_evict(c, cand[next++].cell);
            }
        /* loading stays under the ceiling; to make room, evict only cells
         * clearly (one bit) less useful than the one being loaded */
        uint64_t ceiling = c->o.memory_ceiling ? c->o.memory_ceiling : UINT64_MAX;
        uint64_t planned = memory + in_flight;
        size_t keep = 0;
        for (; keep < wl.n; ++keep) {
            const want *w = &wl.w[keep];
            uint64_t need_bytes = (uint64_t)(w->end - w->start) + w->decoded_growth;
            if (planned + need_bytes <= ceiling) {
                planned += need_bytes;
                continue;
            }
            bool visible;
            double u = cell_need(c, &fv, w->cell, &visible);
            if (!visible)
                u -= 64.0;
            while (planned + need_bytes > ceiling && next < nc && cand[next].usefulness + 1.0 < u) {
                planned -= cand[next].bytes < planned ? cand[next].bytes : planned;
                memory -= cand[next].bytes < memory ? cand[next].bytes : memory;
                dec_evict(c, cand[next++].cell);
            }
            if (planned + need_bytes > ceiling)
                break;
            planned += need_bytes;
        }
        if (keep < wl.n && in_flight == 0) {
            /* blocked by the ceiling with nothing on its way: the view cannot
             * complete at this tolerance, so raise it (as over the target) */
            c->last_blocked = t;
            if (t - c->last_budget_step > 0.1 && c->tolerance_factor < MAX_TOLERANCE_FACTOR) {
                c->tolerance_factor *= M_SQRT2;
                c->last_budget_step = t;
            }
        }
        wl.n = keep;
        free(cand);
    }

    /* first display, frames */
    double t_now = since_start(c);
    if (!c->first_display_seen && changed && dec_something_drawn(c, &fv)) {
        c->first_display_seen = true;
        pthread_mutex_lock(&c->lock);
        c->stats.first_display = t_now;
        pthread_mutex_unlock(&c->lock);
    }
    ms_core_frame *frame = NULL;
    if (c->o.export_frames && (changed || c->generation == 0)) {
        frame = dec_make_frame(c, &err);
        if (frame) {
            frame->generation = ++c->generation;
            frame->time = t_now;
        }
    }
    double busy = now_s() - t_start;

    pthread_mutex_lock(&c->lock);
    bool same = wl.n == c->want_count && (wl.n == 0 || !memcmp(wl.w, c->wants, wl.n * sizeof *wl.w));
    if (!same || c->republish) {
        free(c->wants);
        c->wants = wl.w;
        c->want_count = wl.n;
        c->want_serial++;
        c->republish = false;
        wl.w = NULL;
    }
    if (c->want_consumed_seq != c->consumed_seq) {
        c->want_consumed_seq = c->consumed_seq;
        c->want_serial += same; /* let the network thread release finished requests */
    }
    pthread_cond_broadcast(&c->wake); /* the local responder waits for a new list */
    if (frame) {
        if (c->frame)
            ms_core_frame_free(c->frame);
        c->frame = frame;
    }
    ms_core_stats *st = &c->stats;
    st->view_complete = complete && serial == c->camera_serial;
    st->camera_serial = serial;
    st->achieved_error_px = worst;
    st->tolerance_px = fv.tolerance;
    st->cells_shown = shown, st->cells_split = split, st->cells_cached = cached;
    st->cells_loading = loading, st->cells_failed = failed;
    st->memory = memory;
    if (memory > st->peak_memory)
        st->peak_memory = memory;
    st->decode_seconds += busy;
    pthread_mutex_unlock(&c->lock);
    free(wl.w);
}

static void *dec_main(void *arg)
{
    ms_core *c = arg;
    pthread_mutex_lock(&c->lock);
    uint64_t done_serial = 0;
    for (;;) {
        while (!c->stopping && !c->fatal && !c->inbox && !c->index_new &&
               !(c->view && c->have_camera && (c->camera_serial != done_serial || c->republish))) {
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 20 * 1000000L;
            if (until.tv_nsec >= 1000000000L)
                until.tv_sec++, until.tv_nsec -= 1000000000L;
            if (pthread_cond_timedwait(&c->wake, &c->lock, &until) == ETIMEDOUT)
                break; /* periodic pass: budget steps, memory figures */
        }
        if (c->stopping || c->fatal)
            break;
        if (c->index_new) {
            c->index_new = false;
            pthread_mutex_unlock(&c->lock);
            ms_error err;
            bool ok = dec_take_index(c, &err);
            pthread_mutex_lock(&c->lock);
            if (!ok) {
                set_fatal_locked(c, "%.240s", err.text);
                break;
            }
        }
        if (!c->view)
            continue;
        chunk_msg *chunks = c->inbox;
        c->inbox = c->inbox_tail = NULL;
        ms_camera cam = c->camera;
        uint64_t serial = c->camera_serial;
        bool have = c->have_camera;
        pthread_mutex_unlock(&c->lock);
        dec_step(c, chunks, &cam, serial, have);
        done_serial = serial;
        pthread_mutex_lock(&c->lock);
    }
    pthread_mutex_unlock(&c->lock);
    return NULL;
}

/* ======================== caller's API ==================================== */

static char *dup_or_null(const char *s, bool *fail)
{
    if (!s)
        return NULL;
    char *d = strdup(s);
    if (!d)
        *fail = true;
    return d;
}

ms_status ms_core_start(const ms_core_options *o, ms_core **out, ms_error *err)
{
    *out = NULL;
    bool local = o && o->archive_path;
    if (local && !o->archive_path[0])
        return ms_error_set(err, MS_ERR_ARG, "client core: empty archive path");
    if (!o || (!local && (!o->host || !o->model || o->port == 0)))
        return ms_error_set(err, MS_ERR_ARG, "client core: host, port and model (or an archive "
                            "path) are required");
    if (o->model && !ms_proto_model_name_valid(o->model, strlen(o->model), NULL))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", o->model);
    if (o->tolerance_px < 0 || o->bandwidth < 0 || o->answer_timeout < 0 ||
        o->give_up_seconds < 0 || !isfinite(o->tolerance_px) || !isfinite(o->bandwidth) ||
        (o->memory_ceiling && o->memory_target > o->memory_ceiling))
        return ms_error_set(err, MS_ERR_ARG, "client core: bad tolerance, bandwidth, timeout or "
                            "budget (target above ceiling?)");
    ms_core *c = calloc(1, sizeof *c);
    if (!c)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    c->o = *o;
    if (c->o.tolerance_px == 0)
        c->o.tolerance_px = 1.0;
    if (c->o.hysteresis_bits < 0)
        c->o.hysteresis_bits = 0.5;
    if (c->o.culled_bits_less == 0)
        c->o.culled_bits_less = 6.0;
    if (c->o.apo_geometry_tolerance_px == 0)
        c->o.apo_geometry_tolerance_px = 4.0;
    if (c->o.answer_timeout == 0)
        c->o.answer_timeout = 5.0;
    if (c->o.give_up_seconds == 0)
        c->o.give_up_seconds = 30.0;
    if (c->o.memory_target && !c->o.memory_ceiling)
        c->o.memory_ceiling = c->o.memory_target + c->o.memory_target / 4;
    c->window = c->o.window_bytes ? c->o.window_bytes
                : c->o.bandwidth > 0 ? (uint64_t)(c->o.bandwidth / 4) : (1u << 20);
    if (c->window < 65536)
        c->window = 65536;
    bool fail = false;
    c->host = dup_or_null(o->host, &fail);
    c->model = dup_or_null(o->model, &fail);
    c->token = dup_or_null(o->token, &fail);
    c->agent = dup_or_null(o->agent ? o->agent : "meshstream-client", &fail);
    c->archive_path = dup_or_null(o->archive_path, &fail);
    c->latencies = malloc(LATENCY_KEEP * sizeof *c->latencies);
    c->t0 = now_s();
    c->tolerance_factor = 1.0;
    c->last_blocked = -1e9;
    c->down_since = -1;
    c->backoff = 0.1;
    c->stats.first_display = -1;
    c->base = event_base_new();
    if (fail || !c->latencies || !c->base ||
        !(c->tick = event_new(c->base, -1, EV_PERSIST, on_tick, c))) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory starting the client core");
    }
    pthread_mutex_init(&c->lock, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_cond_init(&c->wake, &ca);
    pthread_condattr_destroy(&ca);
    unsigned helpers = c->o.decode_threads ? c->o.decode_threads - 1 : 1;
    ms_status pool_status = ms_pool_new(helpers, &c->pool, err);
    if (pool_status != MS_OK) {
        ms_core_stop(c);
        return pool_status;
    }
    if (pthread_create(&c->dec_thread, NULL, dec_main, c) != 0) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_IO, "cannot start the decode thread");
    }
    c->dec_started = true;
    if (pthread_create(&c->net_thread, NULL, local ? local_main : net_main, c) != 0) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_IO, "cannot start the %s thread",
                            local ? "local responder" : "network");
    }
    c->net_started = true;
    *out = c;
    return MS_OK;
}

void ms_core_stop(ms_core *c)
{
    if (!c)
        return;
    if (c->base) {
        pthread_mutex_lock(&c->lock);
        c->stopping = true;
        pthread_cond_broadcast(&c->wake);
        pthread_mutex_unlock(&c->lock);
    }
    if (c->net_started)
        pthread_join(c->net_thread, NULL);
    if (c->dec_started)
        pthread_join(c->dec_thread, NULL);
    ms_pool_free(c->pool);
    free(c->jobs);
    if (c->client)
        ms_client_free(c->client);
    if (c->tick)
        event_free(c->tick);
    if (c->base) {
        event_base_free(c->base);
        pthread_mutex_destroy(&c->lock);
        pthread_cond_destroy(&c->wake);
    }
    while (c->inbox) {
        chunk_msg *m = c->inbox;
        c->inbox = m->next;
        free(m);
    }
    if (c->cells) {
        for (uint32_t i = 0; i < ms_view_cell_count(c->view); ++i) {
            rx_free(&c->cells[i].geo);
            rx_free(&c->cells[i].apo);
            free(c->cells[i].header);
        }
    }
    free(c->cells);
    ms_view_destroy(c->view);
    free(c->target);
    free(c->tolerance_scale);
    ms_archive_close(c->index);
    free(c->slot_head);
    free(c->wants);
    free(c->net_wants);
    if (c->frame)
        ms_core_frame_free(c->frame);
    free(c->latencies);
    free(c->host);
    free(c->model);
    free(c->token);
    free(c->agent);
    free(c->archive_path);
    free(c);
}

void ms_core_set_camera(ms_core *c, const ms_camera *camera)
{
    pthread_mutex_lock(&c->lock);
    c->camera = *camera;
    c->have_camera = true;
    c->camera_serial++;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

ms_core_frame *ms_core_take_frame(ms_core *c)
{
    pthread_mutex_lock(&c->lock);
    ms_core_frame *f = c->frame;
    c->frame = NULL;
    pthread_mutex_unlock(&c->lock);
    return f;
}

void ms_core_frame_free(ms_core_frame *f)
{
    if (!f)
        return;
    ms_view_mesh_free(&f->mesh);
    for (size_t i = 0; i < f->apo_count; ++i)
        free(f->apo[i].data);
    free(f->apo);
    free(f->cell_bits);
    free(f);
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

void ms_core_get_stats(ms_core *c, ms_core_stats *out)
{
    double *copy = NULL;
    size_t n;
    pthread_mutex_lock(&c->lock);
    *out = c->stats;
    out->time = since_start(c);
    out->connected = c->connected;
    out->model_open = c->model_open;
    out->bytes_received = c->bytes_received;
    out->geometry_bytes_received = c->geometry_bytes_received;
    out->apo_bytes_received = c->apo_bytes_received;
    out->socket_bytes = c->socket_bytes;
    out->bytes_in_flight = c->bytes_in_flight;
    out->requests = c->requests;
    out->cancels = c->cancels;
    out->reconnects = c->reconnects;
    if (out->camera_serial != c->camera_serial)
        out->view_complete = false;
    n = c->latency_count;
    if (n && (copy = malloc(n * sizeof *copy)))
        memcpy(copy, c->latencies, n * sizeof *copy);
    pthread_mutex_unlock(&c->lock);
    out->latency_p50 = out->latency_p99 = 0;
    if (copy) {
        qsort(copy, n, sizeof *copy, compare_double);
        size_t k50 = (size_t)ceil(0.50 * (double)n), k99 = (size_t)ceil(0.99 * (double)n);
        out->latency_p50 = copy[k50 ? k50 - 1 : 0];
        out->latency_p99 = copy[k99 ? k99 - 1 : 0];
        free(copy);
    }
}
