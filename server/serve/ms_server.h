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
    uint64_t http_forbidden;           /* of them 403: past the public preview */
    uint64_t http_bytes_sent;
    uint64_t binary_connections;       /* open now */
    uint64_t binary_connections_total;
    uint64_t binary_requests;
    uint64_t binary_errors;
    uint64_t binary_forbidden;         /* of them FORBIDDEN: past the public preview */
    uint64_t binary_bytes_sent;
    uint64_t queued_requests;          /* over all connections, now */
    uint64_t queued_bytes;             /* over all connections, now */
    uint64_t rescans;
    uint64_t rescan_failures;
    uint64_t transfers_in_flight;      /* payload buffers not yet sent, both doors */
    uint64_t http_connections;         /* open now */
    uint64_t http_connections_dropped; /* closed for a late header or no send progress */
    uint64_t http_connections_shed;    /* idle ones closed at the cap for a newcomer */
    uint64_t http_connections_trickling; /* open now, their request header arriving in pieces */
    uint64_t http_connections_parked;  /* shed ones held unread until their reset */
    uint64_t binary_connections_dropped; /* slow readers closed for no send progress */
    uint64_t log_lines_held_back;      /* client log lines not written (ms_server_log_client) */
} ms_server_metrics;

typedef struct ms_http_door ms_http_door;
typedef struct ms_serve_door ms_serve_door;

/* The server: opaque; its doors see inside (ms_server_internal.h). */
typedef struct ms_server ms_server;

/* Loads the registry, binds the doors, installs the signal handlers. Takes
 * ownership of config (also on failure, when everything is released). */
ms_status ms_server_new(ms_server_config *config, ms_server **server, ms_error *err);

/* Closes the doors and releases everything; NULL is a no-op. */
void ms_server_free(ms_server *server);

/* Runs the loop until a drain completes. */
void ms_server_run(ms_server *server);

/* Rescans the archive directory (what SIGHUP does). */
ms_status ms_server_rescan(ms_server *server, ms_error *err);

/* Stops accepting, lets transfers in progress finish, then ends the loop. */
void ms_server_drain(ms_server *server);

/* What meshserve reports: the models served, their directory, the ports
 * bound (the binary door's, or with http the HTTP door's: 0 when off), the
 * counters and when the server started (ms_now_seconds). */
size_t ms_server_model_count(const ms_server *server);
const char *ms_server_archive_dir(const ms_server *server);
uint16_t ms_server_bound_port(const ms_server *server, bool http);
const ms_server_metrics *ms_server_get_metrics(const ms_server *server);
double ms_server_started_at(const ms_server *server);

/* True when payload (a cell's stream: MS_PROTO_STREAM_GEOMETRY, _APO or
 * _COLOUR) is intact:
 * checked against its CRC once, on first use (ms_model_check_payload); a
 * damaged one is logged once, and both doors refuse to serve it (INTERNAL,
 * 500). */
bool ms_server_payload_intact(const ms_server *server, ms_model *model, uint32_t cell,
                              uint8_t stream);

/* The access log (config access_log): one JSON object a line, appended and
 * flushed as each entry ends (docs/DEPLOY.md, "Access log"):
 *   {"time": ISO 8601 UTC, "door": "binary"|"http", "client": "ADDRESS:PORT",
 *    "model": the model(s) (binary: every model the connection opened, comma
 *    separated; http: the model of the URL, or ""), "request": the URL path
 *    (http) or "", "requests": count, "bytes": payload (binary) or body (http)
 *    bytes sent, "seconds": the connection's life (binary) or the handling
 *    time (http), "status": "ok" or the fatal ERROR's name that closed the
 *    connection (binary), the HTTP status code (http)}
 * One line per binary connection, written when it is freed; one per HTTP
 * answer. Nothing when no access log is configured. */
void ms_server_access_log(ms_server *server, const char *door, const char *client,
                          const char *model, const char *request, uint64_t requests,
                          uint64_t bytes, double seconds, const char *status);

/* True when an access log is configured (callers skip building a line
 * otherwise). */
bool ms_server_access_log_on(const ms_server *server);

/* Opens config.access_log anew (what SIGHUP does after a rotation moved the
 * file away); on failure the previous file stays in use and the error is
 * returned. */
ms_status ms_server_reopen_access_log(ms_server *server, ms_error *err);

/* Logs one line to stderr with a timestamp. */
void ms_server_log(const ms_server *server, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

#endif
