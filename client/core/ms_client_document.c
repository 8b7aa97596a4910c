/* A model's documents over a client connection (ms_client.h,
 * PROTOCOL.md 4.5b): GET_DOCUMENT, the DOCUMENT frames reassembled, and the
 * blocking fetch that waits for them on the connection's own loop. */
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_client.h"
#include "ms_client_internal.h"

/* One DOCUMENT frame (PROTOCOL.md 4.5b): reassembled into c->doc, handed to
 * the waiting ms_client_fetch_document or to handlers->document at LAST. */
static void handle_document(ms_client *c, const ms_proto_message *m)
{
    const ms_proto_document *d = &m->body.document;
    pending *q = ms_client_pending_find(c, m->request_id);
    bool first = !c->doc_request;
    if (ms_proto_check_negotiated(m, c->limits.version, c->limits.capabilities, NULL, NULL) !=
            MS_OK ||
        !q || q->kind != PENDING_DOCUMENT || q->stream != d->kind || q->started != !first ||
        (!first && (m->request_id != c->doc_request || d->total_length != c->doc_total)) ||
        d->offset != (first ? 0 : c->doc_have)) {
        char why[120];
        snprintf(why, sizeof why, "DOCUMENT for request %u out of order, or for no document "
                 "request", m->request_id);
        ms_client_violation(c, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_DOCUMENT, why);
        return;
    }
    if (first) {
        q->started = true;
        c->doc_request = m->request_id;
        c->doc_total = d->total_length; /* at most 1 MiB: the decoder checked */
        c->doc_have = 0;
        c->doc = malloc(d->total_length ? d->total_length : 1);
        if (!c->doc) {
            ms_client_finish(c, "out of memory for a document");
            return;
        }
    }
    if (d->data_length)
        memcpy(c->doc + c->doc_have, d->data, d->data_length);
    c->doc_have += d->data_length;
    if (!(m->flags & MS_PROTO_FLAG_LAST))
        return;
    ms_client_pending_end(c, q);
    uint8_t *doc = c->doc;
    size_t length = c->doc_have;
    c->doc = NULL;
    c->doc_request = 0;
    if (c->waiting && m->request_id == c->wait_id) {
        c->wait_bytes = doc;
        c->wait_length = length;
        c->wait_done = true;
        return;
    }
    if (c->handlers->document)
        c->handlers->document(c, m->request_id, d->kind, doc, length, c->arg);
    free(doc);
}

ms_status ms_client_request_document(ms_client *c, const char *model, int kind,
                                     uint32_t *request_id, ms_error *err)
{
    size_t n = model ? strlen(model) : 0;
    if (!model || !ms_proto_model_name_valid(model, n, NULL))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", model ? model : "");
    if (kind < MS_DOCUMENT_FIRST || kind > MS_DOCUMENT_LAST)
        return ms_error_set(err, MS_ERR_ARG, "document kind %d undefined (%d..%d)", kind,
                            MS_DOCUMENT_FIRST, MS_DOCUMENT_LAST);
    if (c->limits.version && c->limits.version < 3)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "the server speaks protocol version %u, "
                            "which has no documents (version 3)", c->limits.version);
    ms_proto_message m = {.type = MS_PROTO_GET_DOCUMENT, .request_id = ms_client_take_ids(c, 1)};
    m.body.get_document = (ms_proto_get_document){(uint8_t)kind, model, (uint8_t)n};
    *request_id = m.request_id;
    ms_status st = ms_client_send_message(c, &m, err);
    pending *p = st == MS_OK ? ms_client_pending_add(c, m.request_id) : NULL;
    if (st == MS_OK && !p)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a request");
    if (p) {
        p->kind = PENDING_DOCUMENT, p->stream = (uint8_t)kind;
        c->on_document = handle_document;
    }
    return st;
}

static void on_wait_timeout(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ((ms_client *)arg)->wait_timed_out = true;
}

/* Runs the client's loop until done() or the connection ends or the wait
 * times out; false when the loop cannot run here (inside it). */
static bool wait_for(ms_client *c, bool (*done)(const ms_client *))
{
    struct event_base *base = bufferevent_get_base(c->bev);
    while (!c->over && !c->wait_timed_out && !done(c))
        if (event_base_loop(base, EVLOOP_ONCE) < 0)
            return false;
    return true;
}

static bool hello_done(const ms_client *c) { return c->limits.version != 0; }
static bool wait_over(const ms_client *c) { return c->wait_done; }

ms_status ms_client_fetch_document(ms_client *c, const char *model, int kind, uint8_t **bytes,
                                   size_t *length, ms_error *err)
{
    *bytes = NULL;
    *length = 0;
    if (!c || c->waiting)
        return ms_error_set(err, MS_ERR_ARG, "document: %s", c ? "another fetch is waiting"
                                                               : "no connection");
    struct event *timer = evtimer_new(bufferevent_get_base(c->bev), on_wait_timeout, c);
    if (!timer)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a document request");
    double limit_s = c->wait_limit_s > 0 ? c->wait_limit_s : MS_CLIENT_DOCUMENT_TIMEOUT_S;
    struct timeval limit = {(time_t)limit_s,
                            (suseconds_t)((limit_s - (double)(time_t)limit_s) * 1e6)};
    evtimer_add(timer, &limit);
    c->waiting = true;
    c->wait_done = c->wait_timed_out = false;
    c->wait_id = 0;
    ms_status st = MS_OK;
    uint32_t id;
    if (!wait_for(c, hello_done))
        st = ms_error_set(err, MS_ERR_ARG, "document: called inside the connection's own "
                          "event loop (use ms_client_request_document there)");
    else if (!c->over && !c->wait_timed_out &&
             (st = ms_client_request_document(c, model, kind, &id, err)) == MS_OK) {
        c->wait_id = id;
        if (!wait_for(c, wait_over))
            st = ms_error_set(err, MS_ERR_ARG, "document: the event loop cannot run here");
    }
    if (st == MS_OK && c->wait_bytes) {
        *bytes = c->wait_bytes;
        *length = c->wait_length;
    } else if (st == MS_OK) {
        st = ms_error_set(err, MS_ERR_IO, "document '%s' of %s: %s", ms_document_kind_name(kind),
                          model, c->wait_done ? c->why : c->over ? c->why
                                                   : "no answer in time");
    }
    c->wait_bytes = NULL;
    c->waiting = c->wait_done = false;
    c->wait_id = 0;
    event_free(timer);
    return st;
}


/* --- ms_client_fetch_document_at: one connection, one GET_DOCUMENT ---------- */

static void document_on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client, (void)why, (void)arg; /* ms_client_fetch_document reports it */
}

ms_status ms_client_fetch_document_at(const ms_client_options *options, double timeout_s,
                                      const char *model, int kind, uint8_t **bytes,
                                      size_t *length, ms_error *err)
{
    *bytes = NULL;
    *length = 0;
    if (!options || !options->host || !(timeout_s >= 0) || timeout_s > 86400)
        return ms_error_set(err, MS_ERR_ARG, "document: a server address and a time-out in "
                            "[0, 86400] s are needed");
    static const ms_client_handlers handlers = {.closed = document_on_closed};
    struct event_base *base = event_base_new();
    if (!base)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a document request");
    ms_client *client = NULL;
    ms_status st = ms_client_connect(base, options, &handlers, NULL, &client, err);
    if (st == MS_OK) {
        client->wait_limit_s = timeout_s ? timeout_s : 5.0;
        st = ms_client_fetch_document(client, model, kind, bytes, length, err);
    }
    ms_client_free(client);
    event_base_free(base);
    return st;
}
