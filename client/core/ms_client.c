/* Binary-protocol client connection: see ms_client.h. */
#include "ms_client.h"
#include "ms_client_internal.h"

#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <zlib.h>

#define DEFAULT_MAX_FRAME (1u << 20)


void ms_client_finish(ms_client *c, const char *why)
{
    if (c->over)
        return;
    c->over = true;
    snprintf(c->why, sizeof c->why, "%s", why);
    bufferevent_disable(c->bev, EV_READ | EV_WRITE);
    if (c->handlers->closed)
        c->handlers->closed(c, why, c->arg);
}

/* A frame from the server broke the protocol: the client can no longer trust
 * the connection (PROTOCOL.md 9, last paragraph). It says so to the server
 * (a fatal ERROR, 4.13) and ends the connection with
 * "protocol violation: WHY"; its owner reconnects. */
static void violation(ms_client *c, uint16_t code, uint64_t detail, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
static void violation(ms_client *c, uint16_t code, uint64_t detail, const char *fmt, ...)
{
    if (c->over)
        return;
    char what[200], why[240];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    ms_proto_message e = {.type = MS_PROTO_ERROR};
    e.body.error.code = code;
    e.body.error.fatal = true;
    e.body.error.detail = detail;
    e.body.error.text = what;
    e.body.error.text_length = (uint16_t)strlen(what);
    /* best effort, now: the connection is dropped right after, with its
     * output buffer (which a socket bufferevent lets only its own callbacks
     * drain). When nothing else is queued, the frame goes to the socket
     * directly (non-blocking: a full socket loses it); else it is queued. */
    uint8_t frame[MS_PROTO_HEADER_SIZE + 18 + sizeof what];
    size_t n;
    int fd = bufferevent_getfd(c->bev);
    if (fd >= 0 && evbuffer_get_length(bufferevent_get_output(c->bev)) == 0 &&
        ms_proto_encode(&e, frame, sizeof frame, &n, NULL) == MS_OK)
        (void)!send(fd, frame, n, MSG_NOSIGNAL | MSG_DONTWAIT);
    else
        ms_client_send_message(c, &e, NULL);
    snprintf(why, sizeof why, "protocol violation: %s", what);
    ms_client_finish(c, why);
}

void ms_client_violation(ms_client *c, uint16_t code, uint64_t detail, const char *why)
{
    violation(c, code, detail, "%s", why);
}

static int compare_pending(const void *key, const void *entry)
{
    uint32_t a = *(const uint32_t *)key, b = ((const pending *)entry)->id;
    return a < b ? -1 : a > b;
}

/* The outstanding request id, or NULL (never sent, or ended). */
pending *ms_client_pending_find(ms_client *c, uint32_t id)
{
    pending *p = c->pending_count ? bsearch(&id, c->pending, c->pending_count, sizeof *p,
                                            compare_pending)
                                  : NULL;
    return p && !p->done ? p : NULL;
}

pending *ms_client_pending_add(ms_client *c, uint32_t id)
{
    if (c->pending_count == c->pending_cap) {
        size_t cap = c->pending_cap ? 2 * c->pending_cap : 64;
        pending *grown = realloc(c->pending, cap * sizeof *grown);
        if (!grown)
            return NULL;
        c->pending = grown, c->pending_cap = cap;
    }
    size_t at = c->pending_count; /* ids ascend but for a wrap of the counter */
    while (at > 0 && c->pending[at - 1].id > id)
        --at;
    memmove(c->pending + at + 1, c->pending + at, (c->pending_count - at) * sizeof *c->pending);
    c->pending_count++;
    pending *p = &c->pending[at];
    memset(p, 0, sizeof *p);
    p->id = id;
    return p;
}

void ms_client_pending_end(ms_client *c, pending *p)
{
    p->done = true;
    c->pending_done++;
}

/* Drops the ended requests once they are most of the table (after each
 * frame, never while a loop walks the table). */
static void pending_compact(ms_client *c)
{
    if (c->pending_done < 64 || c->pending_done * 2 < c->pending_count)
        return;
    size_t kept = 0;
    for (size_t i = 0; i < c->pending_count; ++i)
        if (!c->pending[i].done)
            c->pending[kept++] = c->pending[i];
    c->pending_count = kept;
    c->pending_done = 0;
}

/* A PAYLOAD must answer an outstanding cell request, for its cell and stream,
 * contiguous from its range's start, with the same end (PROTOCOL.md 4.11). */
static bool payload_acceptable(ms_client *c, uint32_t id, const ms_proto_payload *p, bool last)
{
    pending *q = ms_client_pending_find(c, id);
    if (!q || q->kind != PENDING_CELLS) {
        violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_PAYLOAD,
                  "PAYLOAD for request %u, which is not an outstanding cell request", id);
        return false;
    }
    if (p->cell_id != q->cell || p->stream != q->stream) {
        violation(c, MS_PROTO_E_FIELD_OUT_OF_RANGE, 0,
                  "PAYLOAD for request %u names cell %u stream %u; it asked for cell %u stream %u",
                  id, p->cell_id, p->stream, q->cell, q->stream);
        return false;
    }
    uint32_t want_offset = q->started ? q->next : q->start;
    bool free_start = !q->started && q->unit == MS_PROTO_UNIT_STEPS &&
                      q->stream != MS_PROTO_STREAM_INDEX; /* STEPS: the server maps them */
    bool steps_end = !q->started && q->unit == MS_PROTO_UNIT_STEPS;
    if ((!free_start && p->offset != want_offset) || (!steps_end && p->end != q->end)) {
        violation(c, MS_PROTO_E_FIELD_OUT_OF_RANGE, 8,
                  "PAYLOAD for request %u covers [%u, %u) of %u; expected from %u to %u", id,
                  p->offset, p->offset + p->data_length, p->end, want_offset, q->end);
        return false;
    }
    q->started = true;
    q->end = p->end;
    q->next = p->offset + p->data_length;
    if (last)
        ms_client_pending_end(c, q);
    return true;
}

ms_status ms_client_send_message(ms_client *c, const ms_proto_message *msg, ms_error *err)
{
    if (c->over)
        return ms_error_set(err, MS_ERR_IO, "the connection is closed");
    size_t size;
    ms_status st = ms_proto_encoded_size(msg, &size, err);
    if (st != MS_OK)
        return st;
    uint8_t small[2048];
    uint8_t *buf = size <= sizeof small ? small : malloc(size);
    if (!buf)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a %zu-byte frame", size);
    size_t written;
    st = ms_proto_encode(msg, buf, size, &written, err);
    if (st == MS_OK && bufferevent_write(c->bev, buf, written) != 0)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the output buffer");
    if (buf != small)
        free(buf);
    if (st == MS_ERR_RANGE || st == MS_ERR_FORMAT)
        st = MS_ERR_ARG;
    return st;
}

uint32_t ms_client_take_ids(ms_client *c, uint32_t count)
{
    if (c->next_id == 0 || (uint64_t)c->next_id + count > 0xFFFFFFFFull)
        c->next_id = 1;
    uint32_t first = c->next_id;
    c->next_id += count;
    return first;
}

/* Checks the received wire form and leaves the decoded blob in c->index. */
static bool index_complete(ms_client *c)
{
    if (c->opened.index_encoding == MS_PROTO_INDEX_ZLIB) {
        ms_error err;
        ms_status st = ms_proto_index_inflate(c->index_zlib, c->index_have, c->opened.index_size,
                                              c->opened.index_crc32, c->index, &err);
        free(c->index_zlib);
        c->index_zlib = NULL;
        if (st != MS_OK) {
            char why[MS_ERROR_TEXT_MAX + 40];
            snprintf(why, sizeof why, "bad model index from the server: %s", err.text);
            ms_client_finish(c, why);
        }
        return st == MS_OK;
    }
    if (c->index_have != c->opened.index_size ||
        crc32_z(0L, c->index, c->index_have) != c->opened.index_crc32) {
        ms_client_finish(c, "model index blob fails its CRC-32");
        return false;
    }
    return true;
}

static void handle_index(ms_client *c, const ms_proto_message *m)
{
    const ms_proto_index_data *d = &m->body.index_data;
    bool zlib = c->opened.index_encoding == MS_PROTO_INDEX_ZLIB;
    /* A compressed index is shorter than the blob (section 4.8): that bounds
     * what a hostile server can make us buffer before inflating. */
    uint64_t wire_limit = zlib ? (uint64_t)c->opened.index_size - 1 : c->opened.index_size;
    if (m->request_id != c->index_request || !c->index || d->offset != c->index_have ||
        (uint64_t)d->offset + d->data_length > wire_limit) {
        violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_INDEX_DATA,
                  "INDEX_DATA for request %u out of order", m->request_id);
        return;
    }
    uint8_t *to = c->index;
    if (zlib) {
        to = realloc(c->index_zlib, (size_t)c->index_have + d->data_length);
        if (!to) {
            ms_client_finish(c, "out of memory for a model index");
            return;
        }
        c->index_zlib = to;
    }
    memcpy(to + c->index_have, d->data, d->data_length);
    c->index_have += d->data_length;
    if (!(m->flags & MS_PROTO_FLAG_LAST) || !index_complete(c))
        return;
    pending *q = ms_client_pending_find(c, m->request_id);
    if (q)
        ms_client_pending_end(c, q);
    uint8_t *index = c->index;
    c->index = NULL;
    c->index_request = 0;
    c->index_wire = c->index_have;
    if (c->handlers->model_opened)
        c->handlers->model_opened(c, m->request_id, &c->opened, index, c->arg);
    free(index);
}

/* The server must pick a version and capabilities out of what HELLO offered
 * (section 3); anything else ends the connection with a clear reason. */
static bool reply_acceptable(ms_client *c, const ms_proto_hello_reply *r)
{
    char why[160];
    uint16_t code = MS_PROTO_E_FIELD_OUT_OF_RANGE;
    uint32_t asked = MS_PROTO_CAP_APO | MS_PROTO_CAP_COLOUR |
                     (c->ask_index_zlib ? MS_PROTO_CAP_INDEX_ZLIB : 0) |
                     (c->ask_index_subtrees ? MS_PROTO_CAP_INDEX_SUBTREES : 0);
    if (r->version < MS_PROTO_MIN_VERSION || r->version > MS_PROTO_VERSION)
        snprintf(why, sizeof why, "server chose protocol version %u, outside our %u..%u",
                 r->version, MS_PROTO_MIN_VERSION, MS_PROTO_VERSION);
    else if (r->capabilities & ~asked)
        snprintf(why, sizeof why, "server granted capabilities 0x%x beyond the 0x%x asked",
                 (unsigned)r->capabilities, (unsigned)asked);
    else if (r->capabilities & ~ms_proto_version_capabilities(r->version))
        snprintf(why, sizeof why, "server granted capabilities 0x%x that protocol version %u "
                 "does not define", (unsigned)r->capabilities, r->version);
    else
        return true;
    violation(c, code, 0, "%s", why);
    return false;
}

/* Returns false when the connection ended. */
static bool handle_message(ms_client *c, const ms_proto_message *m)
{
    switch ((ms_proto_type)m->type) {
    case MS_PROTO_HELLO_REPLY:
        if (!reply_acceptable(c, &m->body.hello_reply))
            break;
        c->limits = m->body.hello_reply;
        if (c->handlers->ready)
            c->handlers->ready(c, &c->limits, c->arg);
        break;
    case MS_PROTO_MODEL_OPENED:
        if (ms_proto_check_negotiated(m, c->limits.version, c->limits.capabilities, NULL,
                                      NULL) != MS_OK) {
            violation(c, MS_PROTO_E_FIELD_OUT_OF_RANGE, 30, "%s",
                      m->body.model_opened.index_encoding == MS_PROTO_INDEX_SUBTREES
                          ? "server sent an index head without CAP_INDEX_SUBTREES"
                          : "server sent a compressed index without CAP_INDEX_ZLIB");
            break;
        }
        {
            pending *q = ms_client_pending_find(c, m->request_id);
            if (!q || q->kind != PENDING_OPEN || q->started || c->index) {
                violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_MODEL_OPENED,
                          "MODEL_OPENED for request %u, which is no open request awaiting it",
                          m->request_id);
                break;
            }
            q->started = true;
        }
        free(c->index_zlib);
        c->index_zlib = NULL;
        c->opened = m->body.model_opened;
        c->index = malloc(c->opened.index_size);
        c->index_have = 0;
        c->index_request = m->request_id;
        if (!c->index)
            ms_client_finish(c, "out of memory for a model index");
        break;
    case MS_PROTO_INDEX_DATA: handle_index(c, m); break;
    case MS_PROTO_DOCUMENT:
        if (c->on_document)
            c->on_document(c, m);
        else
            violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_DOCUMENT,
                      "DOCUMENT for request %u out of order, or for no document request",
                      m->request_id);
        break;
    case MS_PROTO_PAYLOAD:
        if (!payload_acceptable(c, m->request_id, &m->body.payload, m->flags & MS_PROTO_FLAG_LAST))
            break;
        if (c->handlers->payload)
            c->handlers->payload(c, m->request_id, &m->body.payload, m->flags & MS_PROTO_FLAG_LAST,
                                 c->arg);
        break;
    case MS_PROTO_ERROR:
        if (m->body.error.fatal) {
            char why[400];
            snprintf(why, sizeof why, "server error %s: %.*s",
                     ms_proto_error_name(m->body.error.code), (int)m->body.error.text_length,
                     m->body.error.text);
            ms_client_finish(c, why);
        } else {
            const ms_proto_error_body *e = &m->body.error;
            for (uint64_t id = m->request_id; id < (uint64_t)m->request_id + e->request_count; ++id) {
                pending *q = ms_client_pending_find(c, (uint32_t)id);
                if (q)
                    ms_client_pending_end(c, q);
            }
            if (c->waiting && c->wait_id >= m->request_id &&
                c->wait_id - m->request_id < e->request_count) { /* the wait's answer */
                snprintf(c->why, sizeof c->why, "%s %.*s", ms_proto_error_name(e->code),
                         (int)(e->text_length > 150 ? 150 : e->text_length), e->text);
                c->wait_done = true;
                c->wait_id = 0;
                break;
            }
            if (e->request_count == 0 && e->code == MS_PROTO_E_MODEL_CHANGED)
                for (size_t i = 0; i < c->pending_count; ++i) /* the handle's requests ended */
                    if (!c->pending[i].done && c->pending[i].kind == PENDING_CELLS &&
                        c->pending[i].handle == e->detail)
                        ms_client_pending_end(c, &c->pending[i]);
        }
        if (!m->body.error.fatal && c->handlers->request_error) {
            c->handlers->request_error(c, m->request_id, m->body.error.request_count,
                                       &m->body.error, c->arg);
        }
        break;
    case MS_PROTO_PING: {
        ms_proto_message pong = {.type = MS_PROTO_PONG};
        pong.body.ping = m->body.ping;
        ms_client_send_message(c, &pong, NULL);
        break;
    }
    case MS_PROTO_PONG:
        if (c->handlers->pong)
            c->handlers->pong(c, m->body.ping.opaque, c->arg);
        break;
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE: {
        pending *q = ms_client_pending_find(c, m->request_id);
        if (!q || q->kind != PENDING_LIST) {
            violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, m->type,
                      "CATALOGUE for request %u, which is no catalogue request", m->request_id);
            break;
        }
        if (m->flags & MS_PROTO_FLAG_LAST)
            ms_client_pending_end(c, q);
        if (c->handlers->catalogue)
            c->handlers->catalogue(c, m->request_id, &m->body.catalogue,
                                   m->flags & MS_PROTO_FLAG_LAST, c->arg);
        break;
    }
    default: break;
    }
    pending_compact(c);
    return !c->over;
}

static void on_read(struct bufferevent *bev, void *arg)
{
    ms_client *c = arg;
    struct evbuffer *in = bufferevent_get_input(bev);
    while (!c->over && evbuffer_get_length(in)) {
        struct evbuffer_iovec v;
        if (evbuffer_peek(in, -1, NULL, &v, 1) < 1)
            break;
        size_t consumed;
        ms_proto_message m;
        bool have;
        ms_proto_fault fault;
        ms_error err;
        ms_status st = ms_proto_decoder_feed(c->decoder, v.iov_base, v.iov_len, &consumed, &m,
                                             &have, &fault, &err);
        evbuffer_drain(in, consumed);
        c->bytes_read += consumed;
        if (st != MS_OK) {
            char why[MS_ERROR_TEXT_MAX + 32];
            snprintf(why, sizeof why, "bad frame from the server: %s", err.text);
            ms_client_finish(c, why);
            return;
        }
        if (have && !handle_message(c, &m))
            return;
    }
}

static void on_event(struct bufferevent *bev, short what, void *arg)
{
    (void)bev;
    ms_client *c = arg;
    if (what & BEV_EVENT_CONNECTED) {
        int one = 1;
        setsockopt(bufferevent_getfd(c->bev), IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
        return;
    }
    ms_client_finish(c, what & BEV_EVENT_EOF ? "closed by the server" : "socket error");
}

ms_status ms_client_connect(struct event_base *base, const ms_client_options *o,
                            const ms_client_handlers *handlers, void *arg, ms_client **out,
                            ms_error *err)
{
    *out = NULL;
    struct sockaddr_storage ss;
    memset(&ss, 0, sizeof ss);
    int length;
    struct sockaddr_in *v4 = (struct sockaddr_in *)&ss;
    struct sockaddr_in6 *v6 = (struct sockaddr_in6 *)&ss;
    if (evutil_inet_pton(AF_INET, o->host, &v4->sin_addr) == 1) {
        v4->sin_family = AF_INET, v4->sin_port = htons(o->port), length = sizeof *v4;
    } else if (evutil_inet_pton(AF_INET6, o->host, &v6->sin6_addr) == 1) {
        v6->sin6_family = AF_INET6, v6->sin6_port = htons(o->port), length = sizeof *v6;
    } else {
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a numeric address", o->host);
    }
    ms_client *c = calloc(1, sizeof *c);
    if (!c)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    c->handlers = handlers;
    c->arg = arg;
    c->next_id = 1;
    uint32_t max_frame = o->max_frame ? o->max_frame : DEFAULT_MAX_FRAME;
    ms_proto_decoder_config dc = {MS_PROTO_ROLE_CLIENT, max_frame, 0};
    ms_status st = ms_proto_decoder_new(&dc, &c->decoder, err);
    if (st != MS_OK) {
        free(c);
        return st;
    }
    c->bev = bufferevent_socket_new(base, -1, BEV_OPT_CLOSE_ON_FREE);
    if (!c->bev) {
        ms_client_free(c);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot create a socket buffer");
    }
    bufferevent_setcb(c->bev, on_read, NULL, on_event, c);
    bufferevent_set_max_single_read(c->bev, 1u << 20);
    bufferevent_set_max_single_write(c->bev, 1u << 20);
    bufferevent_enable(c->bev, EV_READ | EV_WRITE);
    if (bufferevent_socket_connect(c->bev, (struct sockaddr *)&ss, length) != 0) {
        ms_client_free(c);
        return ms_error_set(err, MS_ERR_IO, "cannot connect to %s:%u", o->host, o->port);
    }
    ms_proto_message hello = {.type = MS_PROTO_HELLO};
    ms_proto_hello *h = &hello.body.hello;
    h->min_version = MS_PROTO_MIN_VERSION;
    h->max_version = MS_PROTO_VERSION;
    c->ask_index_zlib = !o->raw_index;
    c->ask_index_subtrees = o->index_subtrees;
    h->capabilities = MS_PROTO_CAP_APO | MS_PROTO_CAP_COLOUR |
                      (c->ask_index_zlib ? MS_PROTO_CAP_INDEX_ZLIB : 0) |
                      (c->ask_index_subtrees ? MS_PROTO_CAP_INDEX_SUBTREES : 0);
    h->max_frame = max_frame;
    h->token = o->token;
    h->token_length = o->token ? (uint16_t)strlen(o->token) : 0;
    h->agent = o->agent ? o->agent : "";
    h->agent_length = (uint16_t)strlen(h->agent);
    if ((st = ms_client_send_message(c, &hello, err)) != MS_OK) {
        ms_client_free(c);
        return st;
    }
    *out = c;
    return MS_OK;
}

void ms_client_free(ms_client *c)
{
    if (!c)
        return;
    if (c->bev)
        bufferevent_free(c->bev);
    if (c->rate)
        ev_token_bucket_cfg_free(c->rate);
    ms_proto_decoder_free(c->decoder);
    free(c->index);
    free(c->index_zlib);
    free(c->pending);
    free(c->doc);
    free(c->wait_bytes);
    free(c);
}

ms_status ms_client_list_catalogue(ms_client *c, const ms_client_page_request *page,
                                   uint32_t *request_id, ms_error *err)
{
    ms_proto_message m = {.type = page ? MS_PROTO_LIST_PAGE : MS_PROTO_LIST_CATALOGUE,
                          .request_id = ms_client_take_ids(c, 1)};
    if (page) {
        ms_proto_list_page *l = &m.body.list_page;
        l->offset = page->offset;
        l->limit = page->limit;
        l->sort = page->sort;
        l->descending = page->descending;
        l->query = page->query ? page->query : "";
        l->query_length = (uint8_t)strlen(l->query);
    }
    *request_id = m.request_id;
    ms_status st = ms_client_send_message(c, &m, err);
    pending *p = st == MS_OK ? ms_client_pending_add(c, m.request_id) : NULL;
    if (st == MS_OK && !p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a request");
    if (p)
        p->kind = PENDING_LIST;
    return st;
}

ms_status ms_client_open_model(ms_client *c, const char *name, uint32_t *request_id, ms_error *err)
{
    size_t n = strlen(name);
    if (!ms_proto_model_name_valid(name, n, NULL))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", name);
    ms_proto_message m = {.type = MS_PROTO_OPEN_MODEL, .request_id = ms_client_take_ids(c, 1)};
    m.body.open_model.name = name;
    m.body.open_model.name_length = (uint8_t)n;
    *request_id = m.request_id;
    ms_status st = ms_client_send_message(c, &m, err);
    pending *p = st == MS_OK ? ms_client_pending_add(c, m.request_id) : NULL;
    if (st == MS_OK && !p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a request");
    if (p)
        p->kind = PENDING_OPEN;
    return st;
}

ms_status ms_client_close_model(ms_client *c, uint32_t handle, ms_error *err)
{
    ms_proto_message m = {.type = MS_PROTO_CLOSE_MODEL};
    m.body.close_model.model_handle = handle;
    return ms_client_send_message(c, &m, err);
}

ms_status ms_client_request_cells(ms_client *c, uint32_t handle, const ms_proto_cell_request *e,
                                  uint16_t count, uint32_t *first_id, ms_error *err)
{
    if (count == 0 || count > MS_PROTO_MAX_BATCH)
        return ms_error_set(err, MS_ERR_ARG, "batch of %u requests", count);
    ms_proto_message m = {.type = MS_PROTO_REQUEST_CELLS, .request_id = ms_client_take_ids(c, count)};
    m.body.request_cells.model_handle = handle;
    m.body.request_cells.entries = e;
    m.body.request_cells.count = count;
    *first_id = m.request_id;
    ms_status st = ms_client_send_message(c, &m, err);
    for (uint16_t i = 0; st == MS_OK && i < count; ++i) {
        pending *p = ms_client_pending_add(c, m.request_id + i);
        if (!p)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a request");
        p->kind = PENDING_CELLS;
        p->handle = handle, p->cell = e[i].cell_id, p->stream = e[i].stream, p->unit = e[i].unit;
        if (e[i].unit == MS_PROTO_UNIT_BYTES)
            p->start = e[i].a, p->end = e[i].a + e[i].b;
    }
    return st;
}

ms_status ms_client_cancel(ms_client *c, const ms_proto_id_range *ranges, uint16_t count,
                           ms_error *err)
{
    ms_proto_message m = {.type = MS_PROTO_CANCEL};
    m.body.cancel.ranges = ranges;
    m.body.cancel.range_count = count;
    return ms_client_send_message(c, &m, err);
}

const ms_proto_hello_reply *ms_client_limits(const ms_client *c) { return &c->limits; }

ms_status ms_client_set_rate_limit(ms_client *c, double bytes_per_second, ms_error *err)
{
    struct ev_token_bucket_cfg *cfg = NULL;
    if (bytes_per_second > 0) {
        /* Refill every 10 ms; the burst is one refill (at least one TCP segment's worth). */
        double per_tick = bytes_per_second / 100.0;
        size_t rate = per_tick < 1 ? 1 : per_tick > 1e9 ? 1000000000u : (size_t)per_tick;
        size_t burst = rate < 1460 ? 1460 : rate;
        struct timeval tick = {0, 10000};
        cfg = ev_token_bucket_cfg_new(rate, burst, EV_RATE_LIMIT_MAX, EV_RATE_LIMIT_MAX, &tick);
        if (!cfg)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a rate limit");
    }
    if (bufferevent_set_rate_limit(c->bev, cfg) != 0) {
        if (cfg)
            ev_token_bucket_cfg_free(cfg);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot set a rate limit");
    }
    if (c->rate)
        ev_token_bucket_cfg_free(c->rate);
    c->rate = cfg;
    return MS_OK;
}

uint64_t ms_client_bytes_read(const ms_client *c) { return c->bytes_read; }

uint32_t ms_client_index_wire_bytes(const ms_client *c) { return c->index_wire; }
