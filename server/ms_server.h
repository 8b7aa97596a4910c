/* The meshserve process: one libevent loop that owns the model registry, the
 * settings, the metrics and the doors (the binary protocol and the HTTP side
 * door), plus signal handling: SIGTERM/SIGINT drain and stop, SIGHUP rescans the
 * archive directory without dropping connections.
 *
 * Thread-safety: everything runs on the loop's thread.
 */
#ifndef MS_SERVER_H
#define MS_SERVER_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_registry.h"
#include "ms_server_config.h"

struct event_base;
struct event;
struct evhttp;

/* Counters exported on /metrics (Prometheus text format). */
typedef struct ms_server_metrics {
    uint64_t http_requests;
    uint64_t http_errors;
    uint64_t http_bytes_sent;
    uint64_t binary_connections;       /* open now */
    uint64_t binary_connections_total;
    uint64_t binary_requests;
    uint64_t binary_errors;
    uint64_t binary_bytes_sent;
    uint64_t queued_requests;          /* over all connections, now */
    uint64_t queued_bytes;             /* over all connections, now */
    uint64_t rescans;
    uint64_t rescan_failures;
    uint64_t transfers_in_flight;      /* payload buffers not yet sent, both doors */
    uint64_t http_connections;         /* open now */
    uint64_t http_connections_dropped; /* closed for a late header or no send progress */
} ms_server_metrics;

typedef struct ms_http_door ms_http_door;
typedef struct ms_proto_door ms_proto_door;

typedef struct ms_server {
    struct event_base *base;
    ms_server_config config;     /* owned */
    ms_registry registry;
    ms_server_metrics metrics;
    ms_proto_door *binary;
    ms_http_door *http;
    uint16_t bound_port, bound_http_port;
    struct event *signal_events[3];
    struct event *drain_timer;
    bool draining;
    double drain_started_at;
    double started_at;
} ms_server;

/* Loads the registry, binds the doors, installs the signal handlers. Takes
 * ownership of config. On failure everything is released. */
ms_status ms_server_start(ms_server *server, ms_server_config *config, ms_error *err);

/* Runs the loop until a drain completes. */
void ms_server_run(ms_server *server);

/* Rescans the archive directory (what SIGHUP does). */
ms_status ms_server_rescan(ms_server *server, ms_error *err);

/* Stops accepting, lets transfers in progress finish, then ends the loop. */
void ms_server_drain(ms_server *server);

void ms_server_stop(ms_server *server);

/* True when payload (a cell's geometry, or its APO chunk when apo) is intact:
 * checked against its CRC once, on first use (ms_model_check_payload); a
 * damaged one is logged once, and both doors refuse to serve it (INTERNAL,
 * 500). */
bool ms_server_payload_intact(const ms_server *server, ms_model *model, uint32_t cell, bool apo);

/* Logs one line to stderr with a timestamp. */
void ms_server_log(const ms_server *server, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* For an event that can repeat very fast (an accept failing for want of
 * descriptors): at most one line per MS_LOG_INTERVAL_S seconds. An occurrence
 * within the interval after a line is only counted; the next line says how
 * many there were ("(N more since the last line)"). Zero-initialise; one per
 * kind of event, owned by whoever reports it. */
#define MS_LOG_INTERVAL_S 2.0
typedef struct ms_log_limit {
    double last_line_at; /* ms_now_seconds of the last line; 0 = none yet */
    uint64_t held;       /* occurrences since then, not yet reported */
} ms_log_limit;

void ms_server_log_limited(const ms_server *server, ms_log_limit *limit, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

#endif
