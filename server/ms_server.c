/* meshserve process core: see ms_server.h. */
#include "ms_server.h"

#include <event2/event.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ms_http_door.h"
#include "ms_progress.h"

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

static void warn_model(void *arg, const char *message) { ms_server_log(arg, "%s", message); }

ms_status ms_server_rescan(ms_server *s, ms_error *err)
{
    ms_registry fresh;
    ms_status st = ms_registry_scan(s->config.archive_dir, &s->registry, &fresh, warn_model, s, err);
    if (st != MS_OK) {
        s->metrics.rescan_failures++;
        return st;
    }
    ms_registry_release(&s->registry);
    s->registry = fresh;
    s->metrics.rescans++;
    return MS_OK;
}

static void check_drained(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_server *s = arg;
    double waited = ms_now_seconds() - s->drain_started_at;
    if (s->metrics.transfers_in_flight == 0 || waited > DRAIN_LIMIT_SECONDS) {
        if (s->metrics.transfers_in_flight)
            ms_server_log(s, "drain: giving up on %llu transfers after %.0f s",
                          (unsigned long long)s->metrics.transfers_in_flight, waited);
        event_base_loopexit(s->base, NULL);
    }
}

void ms_server_drain(ms_server *s)
{
    if (s->draining)
        return;
    s->draining = true;
    s->drain_started_at = ms_now_seconds();
    ms_server_log(s, "draining: %llu transfers in flight",
                  (unsigned long long)s->metrics.transfers_in_flight);
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
        if (ms_server_rescan(s, &err) == MS_OK)
            ms_server_log(s, "rescan: %zu models", s->registry.count);
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

ms_status ms_server_start(ms_server *s, ms_server_config *config, ms_error *err)
{
    memset(s, 0, sizeof *s);
    s->config = *config;
    memset(config, 0, sizeof *config);
    s->started_at = ms_now_seconds();
    ms_status st = ms_registry_scan(s->config.archive_dir, NULL, &s->registry, warn_model, s, err);
    if (st != MS_OK) {
        ms_server_config_free(&s->config);
        return st;
    }
    s->base = event_base_new();
    if (!s->base) {
        ms_server_stop(s);
        return ms_error_set(err, MS_ERR_NOMEM, "cannot create the event loop");
    }
    if (s->config.http_enabled) {
        st = ms_http_door_open(s, &s->http, &s->bound_http_port, err);
        if (st != MS_OK) {
            ms_server_stop(s);
            return st;
        }
    }
    const int signals[3] = {SIGTERM, SIGINT, SIGHUP};
    for (int i = 0; i < 3; ++i) {
        s->signal_events[i] = evsignal_new(s->base, signals[i], on_signal, s);
        if (!s->signal_events[i] || event_add(s->signal_events[i], NULL) != 0) {
            ms_server_stop(s);
            return ms_error_set(err, MS_ERR_IO, "cannot install signal handlers");
        }
    }
    signal(SIGPIPE, SIG_IGN);
    if (s->config.port_file && (st = write_port_file(s, err)) != MS_OK) {
        ms_server_stop(s);
        return st;
    }
    return MS_OK;
}

void ms_server_run(ms_server *s) { event_base_dispatch(s->base); }

void ms_server_stop(ms_server *s)
{
    ms_http_door_close(s->http);
    s->http = NULL;
    for (int i = 0; i < 3; ++i)
        if (s->signal_events[i])
            event_free(s->signal_events[i]);
    if (s->drain_timer)
        event_free(s->drain_timer);
    if (s->base)
        event_base_free(s->base);
    ms_registry_release(&s->registry);
    ms_server_config_free(&s->config);
    memset(s, 0, sizeof *s);
}
