/* meshserve process core: see ms_server.h. */
#include "ms_server_internal.h"

#include <errno.h>
#include <event2/event.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "ms_http_conns.h"
#include "ms_http_door.h"
#include "ms_json_out.h"
#include "ms_progress.h"
#include "ms_proto_door.h"

#define DRAIN_LIMIT_SECONDS 10.0

void ms_server_log(const ms_server *server, const char *fmt, ...)
{
    (void)server;
    char stamp[32];
    ms_catalog_now(stamp, sizeof stamp);
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    fprintf(stderr, "%s meshserve: %s\n", stamp, line);
}

/* Ends the client log's window when it is over (or now, when ending): writes
 * the summary of what it held back, if anything. */
static void client_log_end_window(ms_server *server, bool ending)
{
    ms_client_log *log = &server->client_log;
    if (!log->window_started ||
        (!ending && ms_now_seconds() - log->window_started < MS_CLIENT_LOG_WINDOW_S))
        return;
    if (log->held)
        ms_server_log(server, "%llu more since %s: client log lines held back (at most %u per "
                      "%.0f s)", (unsigned long long)log->held, log->held_since,
                      MS_CLIENT_LOG_LINES, MS_CLIENT_LOG_WINDOW_S);
    server->metrics.log_lines_held_back += log->held;
    memset(log, 0, sizeof *log);
}

void ms_server_log_client(ms_server *server, const char *fmt, ...)
{
    ms_client_log *log = &server->client_log;
    client_log_end_window(server, false);
    if (!log->window_started)
        log->window_started = ms_now_seconds();
    if (log->lines >= MS_CLIENT_LOG_LINES) {
        if (!log->held++)
            ms_catalog_now(log->held_since, sizeof log->held_since);
        return;
    }
    log->lines++;
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    ms_server_log(server, "%s", line);
}

static void on_client_log_tick(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_server *s = arg;
    client_log_end_window(s, false);
    /* Archives nobody used for model_idle_timeout close (docs/DEPLOY.md). */
    ms_registry_close_idle(s->registry, ms_now_seconds(), s->config.model_idle_timeout_s);
}

typedef struct event_search {
    void (*cb)(int, short, void *);
    void *arg;
} event_search;

static int match_event(const struct event_base *base, const struct event *ev, void *arg)
{
    (void)base;
    event_search *search = arg;
    if (event_get_callback(ev) != search->cb)
        return 0;
    search->arg = event_get_callback_arg(ev);
    return 1; /* found: stop */
}

void *ms_server_event_arg(struct event_base *base, void (*cb)(int, short, void *))
{
    event_search search = {cb, NULL};
    event_base_foreach_event(base, match_event, &search);
    return search.arg;
}

void ms_server_log_limited(const ms_server *server, ms_log_limit *limit, const char *fmt, ...)
{
    double now = ms_now_seconds();
    if (limit->last_line_at > 0 && now - limit->last_line_at < MS_LOG_INTERVAL_S) {
        limit->held++;
        return;
    }
    char line[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    if (limit->held)
        ms_server_log(server, "%s (%llu more since the last line)", line,
                      (unsigned long long)limit->held);
    else
        ms_server_log(server, "%s", line);
    limit->last_line_at = now;
    limit->held = 0;
}

bool ms_server_payload_intact(const ms_server *s, ms_model *model, uint32_t cell, uint8_t stream)
{
    bool first_report;
    ms_error err;
    if (ms_model_check_payload(model, cell, stream, &first_report, &err) == MS_OK)
        return true;
    if (first_report)
        ms_server_log(s, "model '%s': %s; not served", model->entry.name, err.text);
    return false;
}

void ms_server_access_log(ms_server *s, const char *door, const char *client, const char *model,
                          const char *request, uint64_t requests, uint64_t bytes, double seconds,
                          const char *status)
{
    if (!s->access_log)
        return;
    char stamp[32];
    ms_catalog_now(stamp, sizeof stamp);
    json_t *line = json_pack("{s:s, s:s, s:o, s:o, s:o, s:I, s:I, s:o, s:o}", "time", stamp,
                             "door", door, "client", ms_json_text(client ? client : ""), "model",
                             ms_json_text(model ? model : ""), "request",
                             ms_json_text(request ? request : ""), "requests",
                             (json_int_t)requests, "bytes", (json_int_t)bytes, "seconds",
                             ms_json_fixed(seconds, 6), "status", ms_json_text(status));
    /* a full disk loses lines, never the service */
    if (ms_json_print(s->access_log, line, MS_JSON_COMPACT) == 0)
        fflush(s->access_log);
}

bool ms_server_access_log_on(const ms_server *s) { return s->access_log != NULL; }

ms_status ms_server_reopen_access_log(ms_server *s, ms_error *err)
{
    if (!s->config.access_log)
        return MS_OK;
    FILE *f = fopen(s->config.access_log, "a");
    if (!f)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open the access log: %s",
                            s->config.access_log, strerror(errno));
    if (s->access_log)
        fclose(s->access_log);
    s->access_log = f;
    return MS_OK;
}

static void warn_model(void *arg, const char *message) { ms_server_log(arg, "%s", message); }

ms_status ms_server_rescan(ms_server *s, ms_error *err)
{
    ms_registry *fresh;
    ms_status st = ms_registry_scan(s->config.archive_dir, s->registry, s->config.max_open_models,
                                    &fresh, warn_model, s, err);
    if (st != MS_OK) {
        s->metrics.rescan_failures++;
        return st;
    }
    ms_registry_free(s->registry);
    s->registry = fresh;
    s->metrics.rescans++;
    /* Handles of replaced or removed models close now, with MODEL_CHANGED,
     * instead of streaming the old version until the client disconnects. */
    ms_serve_door_models_changed(s->binary, s->registry);
    return MS_OK;
}

static void check_drained(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_server *s = arg;
    double waited = ms_now_seconds() - s->drain_started_at;
    size_t connections = ms_serve_door_connection_count(s->binary);
    if ((s->metrics.transfers_in_flight == 0 && connections == 0) || waited > DRAIN_LIMIT_SECONDS) {
        if (s->metrics.transfers_in_flight || connections)
            ms_server_log(s, "drain: giving up on %llu transfers and %zu connections after %.0f s",
                          (unsigned long long)s->metrics.transfers_in_flight, connections, waited);
        event_base_loopexit(s->base, NULL);
    }
}

void ms_server_drain(ms_server *s)
{
    if (s->draining)
        return;
    s->draining = true;
    s->drain_started_at = ms_now_seconds();
    ms_server_log(s, "draining: %llu transfers in flight, %zu binary connections",
                  (unsigned long long)s->metrics.transfers_in_flight,
                  ms_serve_door_connection_count(s->binary));
    ms_serve_door_drain(s->binary);
    struct timeval tick = {0, 50000};
    s->drain_timer = event_new(s->base, -1, EV_PERSIST, check_drained, s);
    if (!s->drain_timer || event_add(s->drain_timer, &tick) != 0)
        event_base_loopexit(s->base, NULL);
}

static void on_signal(evutil_socket_t signal_number, short what, void *arg)
{
    (void)what;
    ms_server *s = arg;
    if (signal_number == SIGHUP) {
        ms_error err;
        if (ms_server_reopen_access_log(s, &err) != MS_OK)
            ms_server_log(s, "%s; still writing to the previous one", err.text);
        if (ms_server_rescan(s, &err) == MS_OK)
            ms_server_log(s, "rescan: %zu models", ms_registry_count(s->registry));
        else
            ms_server_log(s, "rescan failed, keeping the previous models: %s", err.text);
        return;
    }
    ms_server_drain(s);
}

static ms_status write_port_file(const ms_server *s, ms_error *err)
{
    const char *path = s->config.port_file;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "w");
    if (!f || fprintf(f, "%u %u\n", s->bound_port, s->bound_http_port) < 0 || fclose(f) != 0 ||
        rename(tmp, path) != 0)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot write the port file", path);
    return MS_OK;
}

size_t ms_server_descriptors_besides_parked(const ms_server_config *config)
{
    return (size_t)config->max_clients + config->http_max_connections + 256 + 2 * 64;
}

/* Room for max_clients connections (plus rejected ones, HTTP clients, the
 * archives and the HTTP door's parked connections): raises the soft
 * descriptor limit up to the hard one. */
static void raise_descriptor_limit(ms_server *s)
{
    struct rlimit rl;
    rlim_t want = (rlim_t)ms_server_descriptors_besides_parked(&s->config) +
                  ms_http_park_capacity(&s->config);
    if (getrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur >= want)
        return;
    rl.rlim_cur = want < rl.rlim_max ? want : rl.rlim_max;
    if (setrlimit(RLIMIT_NOFILE, &rl) != 0 || rl.rlim_cur < want)
        ms_server_log(s, "warning: %llu file descriptors allowed, fewer than max_clients needs",
                      (unsigned long long)rl.rlim_cur);
}

static void server_stop(ms_server *s);

static ms_status server_start(ms_server *s, ms_server_config *config, ms_error *err)
{
    s->config = *config;
    memset(config, 0, sizeof *config);
    s->started_at = ms_now_seconds();
    raise_descriptor_limit(s);
    ms_status st = ms_server_reopen_access_log(s, err);
    if (st != MS_OK) {
        ms_server_config_free(&s->config);
        return st;
    }
    st = ms_registry_scan(s->config.archive_dir, NULL, s->config.max_open_models, &s->registry,
                         warn_model, s, err);
    if (st != MS_OK) {
        if (s->access_log)
            fclose(s->access_log);
        ms_server_config_free(&s->config);
        return st;
    }
    /* epoll's change list folds the add/delete of a socket's write interest
     * within one loop turn into one system call (at most), which matters with
     * many connections that each fill and drain every turn. */
    struct event_config *event_settings = event_config_new();
    if (event_settings)
        event_config_set_flag(event_settings, EVENT_BASE_FLAG_EPOLL_USE_CHANGELIST);
    s->base = event_settings ? event_base_new_with_config(event_settings) : NULL;
    if (event_settings)
        event_config_free(event_settings);
    if (s->base && event_base_priority_init(s->base, MS_PRIORITY_LEVELS) != 0) {
        server_stop(s);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot set the event loop's priorities");
    }
    if (!s->base) {
        server_stop(s);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot create the event loop");
    }
    st = ms_serve_door_open(s, &s->binary, &s->bound_port, err);
    if (st != MS_OK) {
        server_stop(s);
        return st;
    }
    if (s->config.http_enabled) {
        st = ms_http_door_open(s, &s->http, &s->bound_http_port, err);
        if (st != MS_OK) {
            server_stop(s);
            return st;
        }
    }
    struct timeval second = {1, 0};
    s->client_log_timer = event_new(s->base, -1, EV_PERSIST, on_client_log_tick, s);
    if (!s->client_log_timer || event_add(s->client_log_timer, &second) != 0) {
        server_stop(s);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot create the client log's timer");
    }
    const int signals[3] = {SIGTERM, SIGINT, SIGHUP};
    for (int i = 0; i < 3; ++i) {
        s->signal_events[i] = evsignal_new(s->base, signals[i], on_signal, s);
        if (!s->signal_events[i] || event_add(s->signal_events[i], NULL) != 0) {
            server_stop(s);
            return ms_error_set(err, MS_ERR_IO, "cannot install signal handlers");
        }
    }
    signal(SIGPIPE, SIG_IGN);
    if (s->config.port_file && (st = write_port_file(s, err)) != MS_OK) {
        server_stop(s);
        return st;
    }
    return MS_OK;
}

void ms_server_run(ms_server *s) { event_base_dispatch(s->base); }

static void server_stop(ms_server *s)
{
    client_log_end_window(s, true);
    if (s->client_log_timer)
        event_free(s->client_log_timer);
    ms_serve_door_close(s->binary);
    s->binary = NULL;
    ms_http_door_close(s->http);
    s->http = NULL;
    for (int i = 0; i < 3; ++i)
        if (s->signal_events[i])
            event_free(s->signal_events[i]);
    if (s->drain_timer)
        event_free(s->drain_timer);
    if (s->base)
        event_base_free(s->base);
    ms_registry_free(s->registry);
    ms_server_config_free(&s->config);
    if (s->access_log)
        fclose(s->access_log);
    memset(s, 0, sizeof *s);
}

ms_status ms_server_new(ms_server_config *config, ms_server **out, ms_error *err)
{
    *out = NULL;
    ms_server *s = calloc(1, sizeof *s);
    if (!s) {
        ms_server_config_free(config);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the server");
    }
    ms_status st = server_start(s, config, err);
    if (st != MS_OK) {
        free(s);
        return st;
    }
    *out = s;
    return MS_OK;
}

void ms_server_free(ms_server *s)
{
    if (!s)
        return;
    server_stop(s);
    free(s);
}

size_t ms_server_model_count(const ms_server *s) { return ms_registry_count(s->registry); }
const char *ms_server_archive_dir(const ms_server *s) { return s->config.archive_dir; }
uint16_t ms_server_bound_port(const ms_server *s, bool http)
{
    return http ? s->bound_http_port : s->bound_port;
}
const ms_server_metrics *ms_server_get_metrics(const ms_server *s) { return &s->metrics; }
double ms_server_started_at(const ms_server *s) { return s->started_at; }
