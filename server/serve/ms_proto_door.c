/* The binary-protocol door: see ms_proto_door.h. */
#include "ms_proto_door.h"

#include <errno.h>
#include <event2/buffer.h>
#include <event2/event.h>
#include <event2/listener.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>

#include "ms_frame_out.h"
#include "ms_progress.h"
#include "ms_proto_conn.h"
#include "ms_server_internal.h"

#define SWEEP_INTERVAL_US 250000
#define MAX_REJECTED_LINGERING 64u
#define CHUNKS_PER_TURN 64u
#define SERVER_NAME "meshserve/0.1"

struct ms_serve_door {
    ms_serve_door_shared shared; /* first: connections point at it */
    struct evconnlistener *listener;
    struct event *sweep;
    struct event *accept_resume;  /* after running out of descriptors */
    uint32_t accept_pause_us;     /* the next pause after a failed accept; 0 = the first */
    ms_log_limit accept_log;
    ms_serve_conn *connections;  /* doubly linked */
    size_t connection_count, rejected_count;
    /* ERROR TOO_MANY_CONNECTIONS, encoded once: what a connection past the
     * lingering cap gets straight from accept, so none is closed unanswered. */
    uint8_t reject_frame[128];
    size_t reject_frame_length;
};

static ms_serve_door *door_of(ms_serve_door_shared *shared) { return (ms_serve_door *)shared; }

void ms_serve_door_connection_done(ms_serve_door_shared *shared, ms_serve_conn *c)
{
    ms_serve_door *door = door_of(shared);
    if (c->prev)
        c->prev->next = c->next;
    else
        door->connections = c->next;
    if (c->next)
        c->next->prev = c->prev;
    door->connection_count--;
    if (c->rejected)
        door->rejected_count--;
    else
        shared->server->metrics.binary_connections--;
    ms_serve_conn_free(c);
}

static void on_accept(struct evconnlistener *listener, evutil_socket_t fd, struct sockaddr *address,
                      int length, void *arg)
{
    (void)listener, (void)address, (void)length;
    ms_serve_door *door = arg;
    ms_server *s = door->shared.server;
    door->accept_pause_us = 0; /* accepting works again: the back-off starts over */
    bool rejected = s->metrics.binary_connections >= s->config.max_clients;
    if (rejected && door->rejected_count >= MAX_REJECTED_LINGERING) {
        /* No room to linger: the answer goes in one send (a fresh socket's
         * buffer takes it whole), what the peer sent is read away so that the
         * close is a FIN, not a reset that could destroy the answer. */
        send(fd, door->reject_frame, door->reject_frame_length, MSG_DONTWAIT | MSG_NOSIGNAL);
        shutdown(fd, SHUT_WR);
        uint8_t sink[4096];
        while (recv(fd, sink, sizeof sink, MSG_DONTWAIT) > 0) {
        }
        evutil_closesocket(fd);
        return;
    }
    int one = 1;
    setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &one, sizeof one);
    ms_serve_conn *c = ms_serve_conn_new(&door->shared, fd, rejected);
    if (!c)
        return;
    c->next = door->connections;
    if (c->next)
        c->next->prev = c;
    door->connections = c;
    door->connection_count++;
    if (rejected) {
        door->rejected_count++;
    } else {
        s->metrics.binary_connections++;
        s->metrics.binary_connections_total++;
    }
}

static void resume_accepting(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_serve_door *door = arg;
    if (!door->shared.draining)
        evconnlistener_enable(door->listener);
}

/* Out of descriptors, the pending connection stays in the backlog and the
 * listener stays readable: instead of spinning, accepting pauses, 25 ms after
 * the first failure, twice as long after each further one in a row, at most
 * ACCEPT_PAUSE_MAX_US; a successful accept starts over. The failures are
 * logged at most once per MS_LOG_INTERVAL_S, with their count. */
#define ACCEPT_PAUSE_FIRST_US 25000u
#define ACCEPT_PAUSE_MAX_US 800000u
static void on_accept_error(struct evconnlistener *listener, void *arg)
{
    int error = EVUTIL_SOCKET_ERROR();
    ms_serve_door *door = arg;
    bool out_of_room = error == EMFILE || error == ENFILE || error == ENOBUFS || error == ENOMEM;
    uint32_t pause_us = door->accept_pause_us ? door->accept_pause_us : ACCEPT_PAUSE_FIRST_US;
    if (!out_of_room) {
        ms_server_log_limited(door->shared.server, &door->accept_log, "binary: accept failed: %s",
                              strerror(error));
        return;
    }
    ms_server_log_limited(door->shared.server, &door->accept_log,
                          "binary: accept failed: %s; accepting paused %u ms", strerror(error),
                          pause_us / 1000);
    struct timeval pause = {0, (suseconds_t)pause_us};
    door->accept_pause_us = pause_us * 2 < ACCEPT_PAUSE_MAX_US ? pause_us * 2 : ACCEPT_PAUSE_MAX_US;
    evconnlistener_disable(listener);
    if (door->accept_resume)
        event_add(door->accept_resume, &pause);
}

static void sweep(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_serve_door *door = arg;
    double now = ms_now_seconds();
    for (ms_serve_conn *c = door->connections, *next; c; c = next) {
        next = c->next;
        if (!ms_serve_conn_sweep(c, now))
            ms_serve_door_connection_done(&door->shared, c);
    }
}

static void announce_limits(const ms_server_config *config, ms_proto_hello_reply *r)
{
    memset(r, 0, sizeof *r);
    r->version = MS_PROTO_VERSION;
    r->capabilities = MS_PROTO_CAP_APO;
    /* Nothing a client may send is larger than a batch of the protocol's
     * largest size, so that bounds what a connection's decoder ever holds. */
    const uint32_t largest_client_frame =
        MS_PROTO_REQUEST_CELLS_FIXED + MS_PROTO_CELL_REQUEST_SIZE * MS_PROTO_MAX_BATCH;
    r->max_frame = config->max_frame < largest_client_frame ? config->max_frame
                                                             : largest_client_frame;
    r->max_batch = config->max_batch < MS_PROTO_MAX_BATCH ? config->max_batch : MS_PROTO_MAX_BATCH;
    r->max_outstanding = config->max_outstanding < MS_PROTO_MAX_OUTSTANDING
                             ? config->max_outstanding
                             : MS_PROTO_MAX_OUTSTANDING;
    r->max_queued_bytes = config->max_queued_bytes < MS_PROTO_MAX_QUEUED_BYTES
                              ? config->max_queued_bytes
                              : MS_PROTO_MAX_QUEUED_BYTES;
    r->idle_timeout_ms = config->idle_timeout_s * 1000u;
    r->max_request_rate = config->request_rate;
    r->max_open_models = MS_PROTO_CONN_MAX_OPEN_MODELS;
    r->server_name = SERVER_NAME;
    r->server_name_length = (uint16_t)strlen(SERVER_NAME);
}

ms_status ms_serve_door_open(ms_server *server, ms_serve_door **out, uint16_t *bound_port,
                             ms_error *err)
{
    *out = NULL;
    ms_serve_door *door = calloc(1, sizeof *door);
    if (!door)
        return ms_error_set(err, MS_ERR_NOMEM, "binary: out of memory");
    door->shared.server = server;
    announce_limits(&server->config, &door->shared.limits);
    struct evbuffer *frame = evbuffer_new();
    if (!frame || ms_frame_out_error(frame, MS_PROTO_E_TOO_MANY_CONNECTIONS, true, 0, 0, 0,
                                     "too many connections", err) != MS_OK ||
        evbuffer_get_length(frame) > sizeof door->reject_frame) {
        if (frame)
            evbuffer_free(frame);
        free(door);
        return ms_error_set(err, MS_ERR_NOMEM, "binary: cannot encode the rejection frame");
    }
    door->reject_frame_length = evbuffer_remove(frame, door->reject_frame, sizeof door->reject_frame);
    evbuffer_free(frame);
    door->shared.send_timeout_s = server->config.send_timeout_s;
    ms_status st = ms_fair_scheduler_init(&door->shared.scheduler, server->base,
                                          ms_serve_conn_send_chunk, door, CHUNKS_PER_TURN, err);
    if (st != MS_OK) {
        free(door);
        return st;
    }
    const char *address = server->config.bind_address ? server->config.bind_address : "127.0.0.1";
    struct sockaddr_storage ss;
    memset(&ss, 0, sizeof ss);
    int ss_length;
    struct sockaddr_in *v4 = (struct sockaddr_in *)&ss;
    struct sockaddr_in6 *v6 = (struct sockaddr_in6 *)&ss;
    if (evutil_inet_pton(AF_INET, address, &v4->sin_addr) == 1) {
        v4->sin_family = AF_INET;
        v4->sin_port = htons((uint16_t)server->config.port);
        ss_length = sizeof *v4;
    } else if (evutil_inet_pton(AF_INET6, address, &v6->sin6_addr) == 1) {
        v6->sin6_family = AF_INET6;
        v6->sin6_port = htons((uint16_t)server->config.port);
        ss_length = sizeof *v6;
    } else {
        ms_serve_door_close(door);
        return ms_error_set(err, MS_ERR_ARG, "binary: bad bind address '%s' (a numeric IPv4 or IPv6 address)", address);
    }
    door->listener = evconnlistener_new_bind(
        server->base, on_accept, door, LEV_OPT_CLOSE_ON_FREE | LEV_OPT_REUSEABLE | LEV_OPT_CLOSE_ON_EXEC,
        1024, (struct sockaddr *)&ss, ss_length);
    if (!door->listener) {
        st = ms_error_set(err, MS_ERR_IO, "binary: cannot listen on %s:%u: %s", address,
                          server->config.port, strerror(errno));
        ms_serve_door_close(door);
        return st;
    }
    evconnlistener_set_error_cb(door->listener, on_accept_error);
    door->accept_resume = evtimer_new(server->base, resume_accepting, door);
    struct sockaddr_storage bound;
    socklen_t bound_length = sizeof bound;
    *bound_port = 0;
    if (getsockname(evconnlistener_get_fd(door->listener), (struct sockaddr *)&bound,
                    &bound_length) == 0)
        *bound_port = ntohs(bound.ss_family == AF_INET6
                                ? ((struct sockaddr_in6 *)&bound)->sin6_port
                                : ((struct sockaddr_in *)&bound)->sin_port);
    door->sweep = event_new(server->base, -1, EV_PERSIST, sweep, door);
    struct timeval tick = {0, SWEEP_INTERVAL_US};
    if (!door->sweep || event_add(door->sweep, &tick) != 0) {
        ms_serve_door_close(door);
        return ms_error_set(err, MS_ERR_NOMEM, "binary: cannot create the sweep timer");
    }
    *out = door;
    return MS_OK;
}

void ms_serve_door_drain(ms_serve_door *door)
{
    if (!door || door->shared.draining)
        return;
    door->shared.draining = true;
    if (door->listener)
        evconnlistener_disable(door->listener);
    for (ms_serve_conn *c = door->connections; c; c = c->next)
        ms_serve_conn_drain(c);
}

void ms_serve_door_models_changed(ms_serve_door *door, const ms_registry *registry)
{
    if (!door)
        return;
    for (ms_serve_conn *c = door->connections; c; c = c->next)
        ms_serve_conn_models_changed(c, registry);
}

size_t ms_serve_door_connection_count(const ms_serve_door *door)
{
    return door ? door->connection_count : 0;
}

void ms_serve_door_close(ms_serve_door *door)
{
    if (!door)
        return;
    if (door->listener)
        evconnlistener_free(door->listener);
    if (door->sweep)
        event_free(door->sweep);
    if (door->accept_resume)
        event_free(door->accept_resume);
    while (door->connections) {
        ms_serve_conn_fail(door->connections, MS_PROTO_E_SHUTTING_DOWN, 0, "server shutting down");
        ms_serve_conn_flush_now(door->connections);
        ms_serve_door_connection_done(&door->shared, door->connections);
    }
    ms_fair_scheduler_free(&door->shared.scheduler);
    free(door);
}
