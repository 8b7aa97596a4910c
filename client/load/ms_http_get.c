/* One HTTP GET on libevent's HTTP client: see ms_http_get.h. */
#include "ms_http_get.h"

#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <event2/http.h>
#include <event2/util.h>
#include <netinet/in.h>
#include <stdbool.h>
#include <stdio.h>

typedef struct get_state {
    struct event_base *base;
    struct evbuffer *body;
    int status;
    bool answered;
    int failure; /* the evhttp_request_error of a failed exchange, -1 none */
} get_state;

static void on_error(enum evhttp_request_error error, void *arg)
{
    get_state *g = arg;
    g->failure = (int)error;
}

static void on_done(struct evhttp_request *req, void *arg)
{
    get_state *g = arg;
    if (req && evhttp_request_get_response_code(req) > 0) {
        g->status = evhttp_request_get_response_code(req);
        g->answered = true;
        evbuffer_add_buffer(g->body, evhttp_request_get_input_buffer(req));
    }
    event_base_loopexit(g->base, NULL);
}

/* A token bucket of bandwidth bytes per second in 10 ms ticks on bev. */
static bool throttle(struct bufferevent *bev, double bandwidth, struct ev_token_bucket_cfg **cfg)
{
    double per_tick = bandwidth / 100.0;
    size_t rate = per_tick < 1 ? 1 : (size_t)per_tick;
    struct timeval tick = {0, 10000};
    *cfg = ev_token_bucket_cfg_new(rate, rate < 1460 ? 1460 : rate, EV_RATE_LIMIT_MAX,
                                   EV_RATE_LIMIT_MAX, &tick);
    return *cfg && bufferevent_set_rate_limit(bev, *cfg) == 0;
}

ms_status ms_http_get(const ms_http_get_options *o, struct evbuffer *body, int *status,
                      ms_error *err)
{
    *status = 0;
    struct in_addr probe;
    if (evutil_inet_pton(AF_INET, o->host, &probe) != 1)
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a numeric IPv4 address", o->host);
    get_state g = {NULL, body, 0, false, -1};
    uint64_t max_body = o->max_body ? o->max_body : MS_HTTP_GET_MAX_BODY;
    struct ev_token_bucket_cfg *cfg = NULL;
    struct evhttp_connection *conn = NULL;
    struct evhttp_request *req = NULL;
    ms_status st = MS_OK;
    struct event_base *base = g.base = event_base_new();
    struct bufferevent *bev = base ? bufferevent_socket_new(base, -1, BEV_OPT_CLOSE_ON_FREE) : NULL;
    if (!bev || (o->bandwidth > 0 && !throttle(bev, o->bandwidth, &cfg)) ||
        !(conn = evhttp_connection_base_bufferevent_new(base, NULL, bev, o->host, o->port))) {
        if (bev && !conn)
            bufferevent_free(bev);
        st = ms_error_set(err, MS_ERR_NOMEM, "cannot set up a connection to %s:%u", o->host,
                          o->port);
        goto out;
    }
    /* libevent refuses a Content-Length above it before reading the body,
     * and a chunked body as it grows past it (EVREQ_HTTP_DATA_TOO_LONG) */
    evhttp_connection_set_max_body_size(
        conn, max_body > (uint64_t)EV_SSIZE_MAX ? EV_SSIZE_MAX : (ev_ssize_t)max_body);
    if (!(req = evhttp_request_new(on_done, &g))) {
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for an HTTP request");
        goto out;
    }
    evhttp_request_set_error_cb(req, on_error);
    struct evkeyvalq *headers = evhttp_request_get_output_headers(req);
    evhttp_add_header(headers, "Host", o->host);
    evhttp_add_header(headers, "Connection", "close");
    if (o->token) {
        char auth[600];
        snprintf(auth, sizeof auth, "Bearer %.500s", o->token);
        evhttp_add_header(headers, "Authorization", auth);
    }
    if (evhttp_make_request(conn, req, EVHTTP_REQ_GET, o->path) != 0) {
        st = ms_error_set(err, MS_ERR_IO, "cannot send a request to %s:%u", o->host, o->port);
        goto out;
    }
    struct timeval limit = {(time_t)o->timeout_s,
                            (suseconds_t)((o->timeout_s - (double)(time_t)o->timeout_s) * 1e6)};
    event_base_loopexit(base, &limit);
    event_base_dispatch(base);
    if (!g.answered && g.failure == EVREQ_HTTP_DATA_TOO_LONG)
        st = ms_error_set(err, MS_ERR_RANGE,
                          "%s:%u: the answer's body is larger than the %llu-byte maximum", o->host,
                          o->port, (unsigned long long)max_body);
    else if (!g.answered)
        st = ms_error_set(err, MS_ERR_IO, "download from %s:%u failed", o->host, o->port);
    *status = g.status;
out:
    if (conn)
        evhttp_connection_free(conn); /* and its bufferevent, and a request still pending */
    if (cfg)
        ev_token_bucket_cfg_free(cfg);
    if (base)
        event_base_free(base);
    return st;
}
