/* One binary-protocol connection: see ms_proto_conn.h. */
#include "ms_proto_conn.h"

#include <arpa/inet.h>
#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include "ms_frame_out.h"
#include "ms_progress.h"
#include "ms_registry.h"
#include "ms_server_internal.h"
#include "ms_subtree.h"

#define CHUNK_BYTES MS_PROTO_PAYLOAD_CHUNK

static struct evbuffer *output(const ms_serve_conn *c) { return bufferevent_get_output(c->bev); }
static ms_server *server_of(const ms_serve_conn *c) { return c->door->server; }
static ms_server_metrics *metrics_of(const ms_serve_conn *c) { return &c->door->server->metrics; }

/* --- Closing ---------------------------------------------------------------- */

void ms_serve_conn_start_closing(ms_serve_conn *c)
{
    if (c->state == MS_CONN_CLOSING)
        return;
    c->state = MS_CONN_CLOSING;
    c->closing_since = ms_now_seconds();
    ms_fair_scheduler_forget(&c->door->scheduler, &c->link);
    /* Keep reading (and discarding) so that the peer's last bytes do not turn
     * our close into a reset that could destroy the ERROR in flight. */
    if (!c->peer_eof)
        bufferevent_enable(c->bev, EV_READ);
    c->reading_paused = false;
    bufferevent_setwatermark(c->bev, EV_WRITE, 0, 0);
}

/* The output buffer refused bytes: nothing coherent can follow. */
void ms_serve_conn_broken(ms_serve_conn *c)
{
    ms_serve_conn_start_closing(c);
    c->closing_since -= MS_PROTO_CONN_LINGER_SECONDS; /* freed at the next sweep */
}

void ms_serve_conn_fail(ms_serve_conn *c, uint16_t code, uint64_t detail, const char *text)
{
    if (c->state == MS_CONN_CLOSING)
        return;
    metrics_of(c)->binary_errors++;
    c->fatal_code = code;
    ms_error err;
    if (ms_frame_out_error(output(c), code, true, 0, 0, detail, text, &err) != MS_OK) {
        ms_server_log_client(server_of(c), "binary: cannot send %s: %s", ms_proto_error_name(code),
                      err.text);
        ms_serve_conn_broken(c);
        return;
    }
    ms_serve_conn_start_closing(c);
}

/* --- Sending answers ---------------------------------------------------------- */

void ms_serve_conn_send_error(ms_serve_conn *c, uint16_t code, uint32_t request_id, uint32_t count,
                              uint64_t detail, const char *text)
{
    if (ms_proto_error_fatality(code) == MS_PROTO_FATAL_ALWAYS) {
        ms_serve_conn_fail(c, code, detail, text);
        return;
    }
    metrics_of(c)->binary_errors += count ? count : 1;
    if (code == MS_PROTO_E_FORBIDDEN)
        metrics_of(c)->binary_forbidden += count ? count : 1;
    ms_error err;
    if (ms_frame_out_error(output(c), code, false, request_id, count, detail, text, &err) != MS_OK)
        ms_serve_conn_broken(c);
}

void ms_serve_conn_send_message(ms_serve_conn *c, const ms_proto_message *msg)
{
    ms_error err;
    if (ms_frame_out_message(output(c), msg, &err) != MS_OK) {
        ms_server_log_client(server_of(c), "binary: cannot send %s: %s", ms_proto_type_name(msg->type),
                      err.text);
        ms_serve_conn_broken(c);
    }
}

/* --- Input ------------------------------------------------------------------ */

static void pause_reading_if_full(ms_serve_conn *c)
{
    if (c->state != MS_CONN_CLOSING &&
        evbuffer_get_length(output(c)) > MS_PROTO_CONN_OUTPUT_LIMIT) {
        bufferevent_disable(c->bev, EV_READ);
        c->reading_paused = true;
    }
}

static void process_input(ms_serve_conn *c)
{
    struct evbuffer *in = bufferevent_get_input(c->bev);
    while (evbuffer_get_length(in) && c->state != MS_CONN_CLOSING && !c->reading_paused &&
           !(c->door->draining)) {
        struct evbuffer_iovec v;
        if (evbuffer_peek(in, -1, NULL, &v, 1) < 1)
            break;
        size_t consumed = 0;
        ms_proto_message msg;
        bool have = false;
        ms_proto_fault fault;
        ms_error err;
        ms_status st = ms_proto_decoder_feed(c->decoder, v.iov_base, v.iov_len, &consumed, &msg,
                                             &have, &fault, &err);
        evbuffer_drain(in, consumed);
        if (st != MS_OK) {
            c->last_frame_at = ms_now_seconds();
            if (fault.fatal) {
                ms_serve_conn_fail(c, fault.code, fault.detail, err.text);
            } else {
                metrics_of(c)->binary_requests += fault.request_count;
                c->requests += fault.request_count;
                ms_serve_conn_send_error(c, fault.code, fault.request_id, fault.request_count,
                                         fault.detail, err.text);
            }
        } else if (have) {
            c->last_frame_at = ms_now_seconds();
            ms_serve_conn_handle_message(c, &msg);
        }
        pause_reading_if_full(c);
    }
    if (c->state == MS_CONN_CLOSING)
        evbuffer_drain(in, evbuffer_get_length(in));
}

static void on_read(struct bufferevent *bev, void *arg)
{
    (void)bev;
    process_input(arg);
}

static void on_write(struct bufferevent *bev, void *arg)
{
    ms_serve_conn *c = arg;
    size_t pending = evbuffer_get_length(bufferevent_get_output(bev));
    if (c->state == MS_CONN_CLOSING) {
        if (pending == 0 && !c->write_shut) {
            shutdown(bufferevent_getfd(bev), SHUT_WR);
            c->write_shut = true;
            if (c->peer_eof)
                ms_serve_door_connection_done(c->door, c);
        }
        return;
    }
    if (c->reading_paused && pending <= MS_PROTO_CONN_LOW_WATER) {
        c->reading_paused = false;
        if (!c->door->draining) {
            bufferevent_enable(bev, EV_READ);
            process_input(c);
        }
    }
    if (c->state == MS_CONN_READY && c->queue.count && pending < MS_PROTO_CONN_HIGH_WATER)
        ms_fair_scheduler_wake(&c->door->scheduler, &c->link);
}

static void on_event(struct bufferevent *bev, short what, void *arg)
{
    (void)bev;
    ms_serve_conn *c = arg;
    if ((what & BEV_EVENT_EOF) && !(what & BEV_EVENT_ERROR) && c->state != MS_CONN_CLOSING &&
        ms_proto_decoder_buffered(c->decoder) > 0) {
        /* Truncated frame: say so, in case the peer only shut down writing. */
        ms_proto_fault fault;
        ms_error err;
        ms_proto_decoder_finish(c->decoder, &fault, &err);
        c->peer_eof = true;
        ms_serve_conn_fail(c, fault.code, fault.detail, err.text);
        return;
    }
    ms_serve_door_connection_done(c->door, c);
}

/* --- Output ----------------------------------------------------------------- */

bool ms_serve_conn_send_chunk(ms_fair_link *link, void *arg)
{
    (void)arg;
    ms_serve_conn *c = (ms_serve_conn *)link;
    if (c->state != MS_CONN_READY)
        return false;
    struct evbuffer *out = output(c);
    if (evbuffer_get_length(out) >= MS_PROTO_CONN_HIGH_WATER)
        return false;
    ms_cell_request *r = ms_request_queue_top(&c->queue);
    if (!r)
        return false;
    uint32_t chunk = r->end - r->next;
    if (chunk > CHUNK_BYTES)
        chunk = CHUNK_BYTES;
    if (chunk > c->client_max_frame - MS_PROTO_PAYLOAD_FIXED)
        chunk = c->client_max_frame - MS_PROTO_PAYLOAD_FIXED;
    size_t length;
    const uint8_t *base = r->stream == MS_PROTO_STREAM_GEOMETRY
                              ? ms_archive_geometry(r->model->archive, r->cell, &length)
                          : r->stream == MS_PROTO_STREAM_APO
                              ? ms_archive_apo(r->model->archive, r->cell, &length)
                          : r->stream == MS_PROTO_STREAM_COLOUR
                              ? ms_archive_colour(r->model->archive, r->cell, &length)
                              : ms_archive_subtree(r->model->archive, r->cell, &length);
    bool last = r->next + chunk == r->end;
    ms_error err;
    ms_server_metrics *m = metrics_of(c);
    if (!base || length < r->end) { /* resolved against the same bytes: never expected */
        ms_serve_conn_send_error(c, MS_PROTO_E_INTERNAL, r->id, 1, 0,
                                 "the archive's bytes for this request are gone");
        m->queued_requests--;
        m->queued_bytes -= r->end - r->next;
        ms_request_queue_remove(&c->queue, r);
        free(r);
        return c->queue.count && c->state == MS_CONN_READY;
    }
    if (ms_frame_out_payload(out, r->id, r->cell, r->stream, r->next, r->end, last, base + r->next,
                             chunk, r->model, &m->transfers_in_flight, &err) != MS_OK) {
        ms_serve_conn_broken(c);
        return false;
    }
    ms_request_queue_sent(&c->queue, r, chunk);
    m->binary_bytes_sent += chunk;
    c->bytes_sent += chunk;
    r->model->bytes_sent += chunk;
    m->queued_bytes -= chunk;
    if (last) {
        ms_request_queue_remove(&c->queue, r);
        free(r);
        m->queued_requests--;
    }
    if (!c->queue.count) {
        if (c->door->draining)
            ms_serve_conn_fail(c, MS_PROTO_E_SHUTTING_DOWN, 0, "server shutting down");
        return false;
    }
    return evbuffer_get_length(out) < MS_PROTO_CONN_HIGH_WATER;
}

/* --- Life cycle ------------------------------------------------------------- */

static void on_output_change(struct evbuffer *buffer, const struct evbuffer_cb_info *info,
                             void *arg)
{
    (void)buffer;
    ms_serve_conn *c = arg;
    if (info->n_deleted || (info->orig_size == 0 && info->n_added))
        c->last_send_progress = ms_now_seconds();
}

/* "ADDRESS:PORT" of the socket's peer ("[ADDRESS]:PORT" for IPv6), or "". */
static void describe_peer(evutil_socket_t fd, char *out, size_t size)
{
    struct sockaddr_storage address;
    socklen_t length = sizeof address;
    char host[INET6_ADDRSTRLEN] = "";
    out[0] = '\0';
    if (getpeername(fd, (struct sockaddr *)&address, &length) != 0)
        return;
    if (address.ss_family == AF_INET) {
        const struct sockaddr_in *v4 = (const struct sockaddr_in *)&address;
        inet_ntop(AF_INET, &v4->sin_addr, host, sizeof host);
        snprintf(out, size, "%s:%u", host, (unsigned)ntohs(v4->sin_port));
    } else if (address.ss_family == AF_INET6) {
        const struct sockaddr_in6 *v6 = (const struct sockaddr_in6 *)&address;
        inet_ntop(AF_INET6, &v6->sin6_addr, host, sizeof host);
        snprintf(out, size, "[%s]:%u", host, (unsigned)ntohs(v6->sin6_port));
    }
}

ms_serve_conn *ms_serve_conn_new(ms_serve_door_shared *door, evutil_socket_t fd, bool rejected)
{
    ms_serve_conn *c = calloc(1, sizeof *c);
    if (!c) {
        evutil_closesocket(fd);
        return NULL;
    }
    c->door = door;
    c->rejected = rejected;
    c->state = MS_CONN_AWAIT_HELLO;
    c->client_max_frame = MS_PROTO_MIN_FRAME;
    c->last_frame_at = c->rate_updated = c->last_send_progress = c->opened_at = ms_now_seconds();
    describe_peer(fd, c->peer, sizeof c->peer);
    c->rate_tokens = door->limits.max_batch;
    ms_request_queue_init(&c->queue);
    ms_proto_decoder_config dc = {MS_PROTO_ROLE_SERVER, door->limits.max_frame,
                                  door->limits.max_batch};
    c->bev = bufferevent_socket_new(door->server->base, fd, BEV_OPT_CLOSE_ON_FREE);
    if (!c->bev || ms_proto_decoder_new(&dc, &c->decoder, NULL) != MS_OK) {
        if (c->bev)
            bufferevent_free(c->bev);
        else
            evutil_closesocket(fd);
        free(c);
        return NULL;
    }
    bufferevent_setcb(c->bev, on_read, on_write, on_event, c);
    if (!evbuffer_add_cb(bufferevent_get_output(c->bev), on_output_change, c)) {
        ms_proto_decoder_free(c->decoder);
        bufferevent_free(c->bev);
        free(c);
        return NULL;
    }
    bufferevent_setwatermark(c->bev, EV_WRITE, MS_PROTO_CONN_LOW_WATER, 0);
    bufferevent_setwatermark(c->bev, EV_READ, 0, 256u << 10);
    bufferevent_set_max_single_read(c->bev, 256u << 10);
    bufferevent_set_max_single_write(c->bev, 1u << 20);
    bufferevent_enable(c->bev, EV_READ | EV_WRITE);
    if (rejected)
        ms_serve_conn_fail(c, MS_PROTO_E_TOO_MANY_CONNECTIONS, 0, "too many connections");
    return c;
}

void ms_serve_conn_free(ms_serve_conn *c)
{
    if (!c)
        return;
    ms_fair_scheduler_forget(&c->door->scheduler, &c->link);
    ms_server_access_log(server_of(c), "binary", c->peer, c->model_names, NULL, c->requests,
                         c->bytes_sent, ms_now_seconds() - c->opened_at,
                         c->fatal_code ? ms_proto_error_name(c->fatal_code) : "ok");
    ms_server_metrics *m = metrics_of(c);
    m->queued_requests -= c->queue.count;
    m->queued_bytes -= c->queue.queued_bytes;
    ms_request_queue_free(&c->queue);
    for (unsigned i = 0; i < MS_PROTO_CONN_MAX_OPEN_MODELS; ++i)
        if (c->models[i].handle)
            ms_model_unref(c->models[i].model);
    ms_proto_decoder_free(c->decoder);
    if (c->bev)
        bufferevent_free(c->bev);
    free(c);
}

bool ms_serve_conn_sweep(ms_serve_conn *c, double now)
{
    if (c->state == MS_CONN_CLOSING)
        return now - c->closing_since < MS_PROTO_CONN_LINGER_SECONDS;
    /* Idle: no frame for idle_timeout while nothing is outstanding; before
     * the handshake, at most MS_PROTO_CONN_HANDSHAKE_SECONDS (a connection
     * that never says HELLO only holds a slot). */
    uint32_t idle_ms = c->door->limits.idle_timeout_ms;
    if (c->state == MS_CONN_AWAIT_HELLO &&
        (!idle_ms || idle_ms > MS_PROTO_CONN_HANDSHAKE_SECONDS * 1000u))
        idle_ms = MS_PROTO_CONN_HANDSHAKE_SECONDS * 1000u;
    if (idle_ms && !c->queue.count && (now - c->last_frame_at) * 1000.0 > idle_ms)
        ms_serve_conn_fail(c, MS_PROTO_E_IDLE_TIMEOUT, idle_ms, "idle time-out");
    /* A slow reader: bytes wait for it and it has read none of them for
     * send_timeout. Its slot, queue and buffers go; the ERROR may never reach
     * it, the linger bounds the rest. */
    size_t waiting = evbuffer_get_length(output(c));
    if (c->state != MS_CONN_CLOSING && waiting && c->door->send_timeout_s > 0 &&
        now - c->last_send_progress > c->door->send_timeout_s) {
        char text[96];
        snprintf(text, sizeof text, "no send progress for %.0f s", c->door->send_timeout_s);
        ms_server_log_client(server_of(c), "binary: connection dropped: %s (%zu bytes waiting)",
                             text, waiting);
        metrics_of(c)->binary_connections_dropped++;
        ms_serve_conn_fail(c, MS_PROTO_E_IDLE_TIMEOUT, (uint64_t)(c->door->send_timeout_s * 1000),
                           text);
    }
    return true;
}

void ms_serve_conn_drain(ms_serve_conn *c)
{
    if (c->state == MS_CONN_CLOSING)
        return;
    bufferevent_disable(c->bev, EV_READ);
    if (!c->queue.count)
        ms_serve_conn_fail(c, MS_PROTO_E_SHUTTING_DOWN, 0, "server shutting down");
}

void ms_serve_conn_flush_now(ms_serve_conn *c)
{
    evbuffer_write(output(c), bufferevent_getfd(c->bev));
}
