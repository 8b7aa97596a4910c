/* HTTP side door: see ms_http_door.h. */
#include "ms_http_door.h"

#include <errno.h>
#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <event2/http.h>
#include <event2/keyvalq_struct.h>
#include <event2/listener.h>
#include <inttypes.h>
#include <jansson.h>
#include <netinet/in.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/queue.h>
#include <fcntl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ms_access.h"
#include "ms_http_conns.h"
#include "ms_http_cors.h"
#include "ms_http_internal.h"
#include "ms_http_parse.h"
#include "ms_page_cache.h"
#include "ms_progress.h"
#include "ms_server_internal.h"

#define RATE_BUCKETS 1024
/* The browser pages' deflated files kept (ms_page_cache.h): both modules and
 * every page file of a site, a few hundred kB, with room. */
#define PAGE_CACHE_BYTES (8u << 20)

/* Token bucket per hashed client address (collisions share, which only errs on
 * the strict side). */
typedef struct rate_bucket {
    double tokens;
    double updated;
} rate_bucket;

struct ms_http_door {
    ms_server *server;
    struct evhttp *http;
    ms_http_conns *conns;       /* the cap, the deadlines, the trickle priority */
    rate_bucket buckets[RATE_BUCKETS];
    double request_started;     /* when the request being handled arrived, for the access log */
    ms_page_cache *pages;       /* the browser pages' files deflated (ms_http_pages.c) */
};

/* --- Small helpers ---------------------------------------------------------- */

ms_server *ms_http_door_server(const ms_http_door *door) { return door->server; }
ms_page_cache *ms_http_door_page_cache(ms_http_door *door) { return door->pages; }

bool ms_http_is_head(struct evhttp_request *req)
{
    return evhttp_request_get_command(req) == EVHTTP_REQ_HEAD;
}

/* Sends an answer whose body is `length` bytes. A HEAD gets the GET's headers,
 * Content-Length included, and no body: evhttp neither adds the length for HEAD
 * nor leaves the body out, which would desynchronise a keep-alive connection. */
/* The model named in a /models/NAME... path, into out ("" for other paths). */
static void model_of_path(const char *path, char *out, size_t size)
{
    out[0] = '\0';
    if (!path || strncmp(path, "/models/", 8) != 0)
        return;
    size_t length = strcspn(path + 8, "/");
    if (length && length < size)
        snprintf(out, size, "%.*s", (int)length, path + 8);
}

/* One access log line per answer (ms_server_access_log): the URL's path only,
 * never its query. */
static void log_answer(ms_http_door *door, struct evhttp_request *req, int code, uint64_t length)
{
    if (!ms_server_access_log_on(door->server))
        return;
    char client[80] = "", model[80], status[16];
    struct evhttp_connection *conn = evhttp_request_get_connection(req);
    char *address = NULL;
    ev_uint16_t port = 0;
    if (conn)
        evhttp_connection_get_peer(conn, &address, &port);
    if (address)
        snprintf(client, sizeof client, strchr(address, ':') ? "[%s]:%u" : "%s:%u", address,
                 (unsigned)port);
    const struct evhttp_uri *uri = evhttp_request_get_evhttp_uri(req);
    const char *path = uri ? evhttp_uri_get_path(uri) : NULL;
    model_of_path(path, model, sizeof model);
    snprintf(status, sizeof status, "%d", code);
    ms_server_access_log(door->server, "http", client, model, path, 1,
                         ms_http_is_head(req) ? 0 : length, ms_now_seconds() - door->request_started,
                         status);
}

void ms_http_reply(ms_http_door *door, struct evhttp_request *req, int code, const char *reason,
                  struct evbuffer *body, uint64_t length)
{
    log_answer(door, req, code, length);
    if (ms_http_is_head(req)) {
        if (code != 304) {
            char text[32];
            snprintf(text, sizeof text, "%" PRIu64, length);
            evhttp_remove_header(evhttp_request_get_output_headers(req), "Content-Length");
            evhttp_add_header(evhttp_request_get_output_headers(req), "Content-Length", text);
        }
        evhttp_send_reply(req, code, reason, NULL);
        return;
    }
    evhttp_send_reply(req, code, reason, body);
}

void ms_http_send_text(ms_http_door *door, struct evhttp_request *req, int code,
                      const char *reason, const char *text)
{
    struct evbuffer *body = evbuffer_new();
    if (body)
        evbuffer_add_printf(body, "%s\n", text);
    evhttp_remove_header(evhttp_request_get_output_headers(req), "Content-Type");
    evhttp_add_header(evhttp_request_get_output_headers(req), "Content-Type",
                      "text/plain; charset=utf-8");
    if (code >= 400)
        door->server->metrics.http_errors++;
    if (code == 403)
        door->server->metrics.http_forbidden++;
    ms_http_reply(door, req, code, reason, body, body ? evbuffer_get_length(body) : 0);
    if (body)
        evbuffer_free(body);
}

bool ms_http_parse_u32(const char *text, uint32_t max, uint32_t *out)
{
    if (!text || *text < '0' || *text > '9' || strlen(text) > 10)
        return false;
    char *end;
    errno = 0;
    unsigned long v = strtoul(text, &end, 10);
    if (errno || *end || v > max)
        return false;
    *out = (uint32_t)v;
    return true;
}

/* Compares without an early exit, so response time does not leak the token. */
static bool token_equal(const char *given, size_t a, const char *expected)
{
    size_t b = strlen(expected);
    unsigned diff = (unsigned)(a ^ b);
    for (size_t i = 0; i < b; ++i)
        diff |= (unsigned char)(i < a ? given[i] : 0) ^ (unsigned char)expected[i];
    return diff == 0;
}

/* True when the request carries the configured token in an Authorization:
 * Bearer header (the only place it is accepted: a URL ends up in logs); the
 * scheme in any case, as RFC 9110 wants (ms_http_bearer_credential). */
static bool authorized(const ms_http_door *door, struct evhttp_request *req)
{
    const char *expected = door->server->config.token;
    if (!expected)
        return false;
    const char *auth = evhttp_find_header(evhttp_request_get_input_headers(req), "Authorization");
    const char *given;
    size_t length;
    return ms_http_bearer_credential(auth, &given, &length) &&
           token_equal(given, length, expected);
}

/* The reader's grant of model; *token_used says whether the token widened it
 * (the answer then depends on the token and must not reach a shared cache). */
ms_access ms_http_reader_grant(const ms_http_door *door, struct evhttp_request *req,
                              const ms_model *model, bool *token_used)
{
    ms_access anonymous = ms_access_grant(model, false);
    *token_used = !ms_access_is_full(&anonymous) && authorized(door, req);
    return *token_used ? ms_access_grant(model, true) : anonymous;
}

static bool rate_allowed(ms_http_door *door, struct evhttp_request *req)
{
    struct evhttp_connection *conn = evhttp_request_get_connection(req);
    char *host = NULL;
    ev_uint16_t port = 0;
    if (conn)
        evhttp_connection_get_peer(conn, &host, &port);
    uint64_t h = 1469598103934665603ull;
    for (const char *c = host ? host : ""; *c; ++c)
        h = (h ^ (unsigned char)*c) * 1099511628211ull;
    rate_bucket *b = &door->buckets[h % RATE_BUCKETS];
    double now = ms_now_seconds(), rate = door->server->config.http_rate;
    if (b->updated == 0.0)
        b->tokens = 2.0 * rate;
    b->tokens += (now - b->updated) * rate;
    if (b->tokens > 2.0 * rate)
        b->tokens = 2.0 * rate;
    b->updated = now;
    if (b->tokens < 1.0)
        return false;
    b->tokens -= 1.0;
    return true;
}

/* Splits path into at most `max` segments; false on empty segments or too many. */
static int split_path(char *path, char **segments, int max)
{
    int n = 0;
    char *save = NULL;
    if (path[0] != '/')
        return -1;
    for (char *s = strtok_r(path + 1, "/", &save); s; s = strtok_r(NULL, "/", &save)) {
        if (n == max)
            return -1;
        segments[n++] = s;
    }
    return n;
}

/* --- JSON and metrics -------------------------------------------------------- */

static void serve_metrics(ms_http_door *door, struct evhttp_request *req)
{
    const ms_server *s = door->server;
    const ms_server_metrics *m = &s->metrics;
    struct evbuffer *body = evbuffer_new();
    if (!body)
        return;
    const struct {
        const char *name, *type, *help;
        uint64_t value;
    } rows[] = {
        {"meshstream_models", "gauge", "Models being served", ms_registry_count(s->registry)},
        {"meshstream_connections", "gauge", "Open binary-protocol connections", m->binary_connections},
        {"meshstream_connections_total", "counter", "Binary-protocol connections accepted", m->binary_connections_total},
        {"meshstream_requests_total{door=\"binary\"}", "counter", "Requests received", m->binary_requests},
        {"meshstream_requests_total{door=\"http\"}", NULL, NULL, m->http_requests},
        {"meshstream_errors_total{door=\"binary\"}", "counter", "Requests answered with an error", m->binary_errors},
        {"meshstream_errors_total{door=\"http\"}", NULL, NULL, m->http_errors},
        {"meshstream_forbidden_total{door=\"binary\"}", "counter",
         "Requests refused as past the public preview (FORBIDDEN, 403)", m->binary_forbidden},
        {"meshstream_forbidden_total{door=\"http\"}", NULL, NULL, m->http_forbidden},
        {"meshstream_bytes_sent_total{door=\"binary\"}", "counter", "Payload bytes sent", m->binary_bytes_sent},
        {"meshstream_bytes_sent_total{door=\"http\"}", NULL, NULL, m->http_bytes_sent},
        {"meshstream_queued_requests", "gauge", "Requests queued over all connections", m->queued_requests},
        {"meshstream_queued_bytes", "gauge", "Payload bytes queued over all connections", m->queued_bytes},
        {"meshstream_rescans_total", "counter", "Archive directory rescans", m->rescans},
        {"meshstream_rescan_failures_total", "counter", "Rescans that failed", m->rescan_failures},
        {"meshstream_http_connections", "gauge", "Open HTTP connections", m->http_connections},
        {"meshstream_http_connections_dropped_total", "counter",
         "HTTP connections closed for a late request header or no send progress",
         m->http_connections_dropped},
        {"meshstream_http_connections_shed_total", "counter",
         "Idle HTTP connections closed at http_max_connections to admit a new one",
         m->http_connections_shed},
        {"meshstream_http_connections_trickling", "gauge",
         "Open HTTP connections whose request header arrives in pieces (read after the others)",
         m->http_connections_trickling},
        {"meshstream_http_connections_parked", "gauge",
         "HTTP connections shed at the cap and held, unread, until their reset (http_park)",
         m->http_connections_parked},
        {"meshstream_connections_dropped_total", "counter",
         "Binary-protocol connections closed for no send progress", m->binary_connections_dropped},
        {"meshstream_log_lines_held_back_total", "counter",
         "Log lines caused by clients and held back by the rate limit (counted as each "
         "window ends)", m->log_lines_held_back},
    };
    for (size_t i = 0; i < sizeof rows / sizeof *rows; ++i) {
        if (rows[i].type) {
            size_t base = strcspn(rows[i].name, "{");
            evbuffer_add_printf(body, "# HELP %.*s %s\n# TYPE %.*s %s\n", (int)base, rows[i].name,
                                rows[i].help, (int)base, rows[i].name, rows[i].type);
        }
        evbuffer_add_printf(body, "%s %" PRIu64 "\n", rows[i].name, rows[i].value);
    }
    /* Per model, for the open models only, so that the page stays bounded by
     * max_open_models and by what clients hold, whatever the collection's size
     * (names are [A-Za-z0-9_-]: nothing to escape in a label). */
    const ms_registry *r = s->registry;
    size_t models = ms_registry_count(r);
    evbuffer_add_printf(body, "# HELP meshstream_open_models Models whose archive is open\n"
                              "# TYPE meshstream_open_models gauge\n"
                              "meshstream_open_models %zu\n",
                        ms_registry_open_count(r));
    evbuffer_add_printf(body, "# HELP meshstream_model_requests_total Requests received for the "
                              "model (opens, cell requests, HTTP answers); open models only\n"
                              "# TYPE meshstream_model_requests_total counter\n");
    for (size_t i = 0; i < models; ++i) {
        const ms_model *model = ms_registry_open_model_at(r, i);
        if (model)
            evbuffer_add_printf(body,
                                "meshstream_model_requests_total{model=\"%s\"} %" PRIu64 "\n",
                                model->entry.name, model->requests);
    }
    evbuffer_add_printf(body, "# HELP meshstream_model_bytes_sent_total Payload bytes of the "
                              "model sent, both doors; open models only\n"
                              "# TYPE meshstream_model_bytes_sent_total counter\n");
    for (size_t i = 0; i < models; ++i) {
        const ms_model *model = ms_registry_open_model_at(r, i);
        if (model)
            evbuffer_add_printf(body,
                                "meshstream_model_bytes_sent_total{model=\"%s\"} %" PRIu64 "\n",
                                model->entry.name, model->bytes_sent);
    }
    evhttp_add_header(evhttp_request_get_output_headers(req), "Content-Type",
                      "text/plain; version=0.0.4");
    ms_http_reply(door, req, 200, "OK", body, evbuffer_get_length(body));
    evbuffer_free(body);
}

/* --- Routing ----------------------------------------------------------------- */

static void route(ms_http_door *door, struct evhttp_request *req, char *path,
                  const struct evkeyvalq *query)
{
    char *seg[6];
    int n = split_path(path, seg, 6);
    if (n == 1 && !strcmp(seg[0], "healthz")) {
        ms_http_send_text(door, req, 200, "OK", door->server->draining ? "draining" : "ok");
        return;
    }
    /* catalog.json: the same, at the path of a static export's catalogue
     * (meshexport --web-dir), so the catalogue page reads either */
    if (n == 1 && (!strcmp(seg[0], "catalog") || !strcmp(seg[0], "catalog.json"))) {
        ms_http_serve_catalog(door, req, query);
        return;
    }
    if (n == 1 && !strcmp(seg[0], "metrics")) {
        serve_metrics(door, req);
        return;
    }
    /* a model's documents: no archive opened */
    if (n == 3 && !strcmp(seg[0], "models") &&
        (!strcmp(seg[2], "thumbnail") || !strcmp(seg[2], "metadata") ||
         !strcmp(seg[2], "annotations"))) {
        int kind = !strcmp(seg[2], "thumbnail")  ? MS_DOCUMENT_THUMBNAIL
                   : !strcmp(seg[2], "metadata") ? MS_DOCUMENT_METADATA
                                                 : MS_DOCUMENT_ANNOTATIONS;
        ms_http_serve_document(door, req, seg[1], kind);
        return;
    }
    if (n >= 2 && !strcmp(seg[0], "models")) {
        ms_model *model = ms_registry_find(door->server->registry, seg[1]);
        if (!model) {
            ms_http_send_text(door, req, 404, "Not Found", "error: no such model");
            return;
        }
        if (ms_http_route_model(door, req, model, seg + 1, n - 1, query))
            return;
    }
    if (n >= 0 && ms_http_route_page(door, req, seg, n))
        return;
    ms_http_send_text(door, req, 404, "Not Found", "error: no such resource");
}

/* OPTIONS: a CORS preflight (an Origin and Access-Control-Request-Method)
 * from an allowed origin gets 204 and the preflight headers, from another
 * origin 403 and one line; any other OPTIONS the methods. */
static void answer_options(ms_http_door *door, struct evhttp_request *req)
{
    struct evkeyvalq *in = evhttp_request_get_input_headers(req);
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    if (!evhttp_find_header(in, "Origin") || !evhttp_find_header(in, "Access-Control-Request-Method")) {
        evhttp_add_header(out, "Allow", "GET, HEAD, OPTIONS");
        ms_http_reply(door, req, 204, "No Content", NULL, 0);
        return;
    }
    if (ms_http_cors_preflight(door->server->config.cors_origins, req)) {
        ms_http_reply(door, req, 204, "No Content", NULL, 0);
        return;
    }
    /* Not ms_http_send_text's 403, which counts a read past a preview. */
    struct evbuffer *body = evbuffer_new();
    if (body)
        evbuffer_add_printf(body, "error: origin not allowed to read this server (meshserve "
                                  "cors_origins)\n");
    evhttp_add_header(out, "Content-Type", "text/plain; charset=utf-8");
    door->server->metrics.http_errors++;
    ms_http_reply(door, req, 403, "Forbidden", body, body ? evbuffer_get_length(body) : 0);
    if (body)
        evbuffer_free(body);
}

static void handle_request(struct evhttp_request *req, void *arg)
{
    ms_http_door *door = arg;
    door->request_started = ms_now_seconds();
    ms_http_conns_request(door->conns, req);
    door->server->metrics.http_requests++;
    enum evhttp_cmd_type cmd = evhttp_request_get_command(req);
    bool options = cmd == EVHTTP_REQ_OPTIONS;
    /* Every other answer, errors included, is readable by an allowed origin's
     * page (a 429's Retry-After too). */
    if (!options)
        ms_http_cors_headers(door->server->config.cors_origins, req);
    if (!options && cmd != EVHTTP_REQ_GET && cmd != EVHTTP_REQ_HEAD) {
        evhttp_add_header(evhttp_request_get_output_headers(req), "Allow", "GET, HEAD, OPTIONS");
        ms_http_send_text(door, req, 405, "Method Not Allowed", "error: only GET and HEAD");
        return;
    }
    if (!rate_allowed(door, req)) {
        evhttp_add_header(evhttp_request_get_output_headers(req), "Retry-After", "1");
        ms_http_send_text(door, req, 429, "Too Many Requests", "error: request rate limit");
        return;
    }
    if (options) {
        answer_options(door, req);
        return;
    }
    const struct evhttp_uri *uri = evhttp_request_get_evhttp_uri(req);
    const char *raw_path = uri ? evhttp_uri_get_path(uri) : NULL;
    if (!raw_path || strlen(raw_path) > 512) {
        ms_http_send_text(door, req, 400, "Bad Request", "error: bad path");
        return;
    }
    char path[513];
    snprintf(path, sizeof path, "%s", raw_path);
    struct evkeyvalq query;
    TAILQ_INIT(&query);
    const char *query_text = evhttp_uri_get_query(uri);
    if (query_text && evhttp_parse_query_str(query_text, &query) != 0) {
        evhttp_clear_headers(&query);
        ms_http_send_text(door, req, 400, "Bad Request", "error: bad query string");
        return;
    }
    if (evhttp_find_header(&query, "token")) {
        ms_http_send_text(door, req, 400, "Bad Request",
                  "error: the token is not accepted in the URL (URLs end up in logs); send "
                  "Authorization: Bearer TOKEN");
        evhttp_clear_headers(&query);
        return;
    }
    route(door, req, path, &query);
    evhttp_clear_headers(&query);
}

ms_status ms_http_door_open(ms_server *server, ms_http_door **out, uint16_t *bound_port,
                            ms_error *err)
{
    *out = NULL;
    ms_http_door *door = calloc(1, sizeof *door);
    if (!door)
        return ms_error_set(err, MS_ERR_NOMEM, "http: out of memory");
    door->server = server;
    door->http = evhttp_new(server->base);
    door->pages = ms_page_cache_new(PAGE_CACHE_BYTES);
    if (!door->http || !door->pages) {
        ms_http_door_close(door);
        return ms_error_set(err, MS_ERR_NOMEM, "http: cannot create the HTTP server");
    }
    evhttp_set_allowed_methods(door->http, EVHTTP_REQ_GET | EVHTTP_REQ_HEAD | EVHTTP_REQ_POST |
                                               EVHTTP_REQ_PUT | EVHTTP_REQ_DELETE |
                                               EVHTTP_REQ_OPTIONS);
    evhttp_set_max_headers_size(door->http, 16384);
    evhttp_set_max_body_size(door->http, 4096);
    evhttp_set_timeout(door->http, (int)server->config.idle_timeout_s);
    evhttp_set_gencb(door->http, handle_request, door);
    const char *address = server->config.bind_address ? server->config.bind_address : "127.0.0.1";
    struct evhttp_bound_socket *socket =
        evhttp_bind_socket_with_handle(door->http, address, (ev_uint16_t)server->config.http_port);
    if (!socket) {
        ms_status st = ms_error_set(err, MS_ERR_IO, "http: cannot listen on %s:%u: %s", address,
                                    server->config.http_port, strerror(errno));
        ms_http_door_close(door);
        return st;
    }
    /* evhttp listens with a backlog of 128: a burst of reconnections
     * (slowloris) fills it, and a SYN that finds it full is dropped, its
     * client retrying after a second (1.03 s in scripts/attack). The binary
     * door's 1024; listen() again only resizes the queue. */
    if (listen(evhttp_bound_socket_get_fd(socket), 1024) != 0) {
        ms_status st = ms_error_set(err, MS_ERR_IO, "http: cannot listen on %s:%u: %s", address,
                                    server->config.http_port, strerror(errno));
        ms_http_door_close(door);
        return st;
    }
    struct evconnlistener *listener = evhttp_bound_socket_get_listener(socket);
    if (!listener) {
        ms_http_door_close(door);
        return ms_error_set(err, MS_ERR_NOMEM, "http: cannot set up connection tracking");
    }
    ms_status st = ms_http_conns_new(server, door->http, listener, &door->conns, err);
    if (st != MS_OK) {
        ms_http_door_close(door);
        return st;
    }
    struct sockaddr_storage ss;
    socklen_t len = sizeof ss;
    *bound_port = 0;
    if (getsockname(evhttp_bound_socket_get_fd(socket), (struct sockaddr *)&ss, &len) == 0)
        *bound_port = ntohs(ss.ss_family == AF_INET6 ? ((struct sockaddr_in6 *)&ss)->sin6_port
                                                     : ((struct sockaddr_in *)&ss)->sin_port);
    *out = door;
    return MS_OK;
}

void ms_http_door_close(ms_http_door *door)
{
    if (!door)
        return;
    if (door->http)
        evhttp_free(door->http); /* frees its connections, then the door's references go */
    ms_http_conns_free(door->conns);
    ms_page_cache_free(door->pages);
    free(door);
}
