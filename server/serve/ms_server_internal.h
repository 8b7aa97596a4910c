/* Inside the meshserve process (ms_server.h): the state its doors
 * (ms_proto_door.c, ms_proto_conn.c, ms_proto_requests.c, ms_http_door.c)
 * read and update on the loop's thread. Private to server/. */
#ifndef MS_SERVER_INTERNAL_H
#define MS_SERVER_INTERNAL_H

#include <stdio.h>

#include "ms_server.h"

/* Log lines that a client causes (the text of its fatal ERROR, a slow reader
 * dropped, an answer that cannot be sent): a client makes them as fast as it
 * connects (issue 32: 45,712 connections in 10.8 s wrote 7 MB to stderr), so
 * at most MS_CLIENT_LOG_LINES are written per MS_CLIENT_LOG_WINDOW_S seconds,
 * the window opening at the first line. The rest are counted, and when the
 * window ends (checked each second, and when the server stops) one line
 * summarises them: "N more since TIME: client log lines held back (at most
 * 20 per 10 s)", TIME being when the first was held back. One per server,
 * in ms_server; zero-initialised. */
#define MS_CLIENT_LOG_LINES 20u
#define MS_CLIENT_LOG_WINDOW_S 10.0
typedef struct ms_client_log {
    double window_started;     /* ms_now_seconds of the window's first line; 0: none open */
    unsigned lines;            /* written in the window */
    uint64_t held;             /* held back in the window */
    char held_since[32];       /* ms_catalog_now of the first held back */
} ms_client_log;

/* The loop's priorities (event_base_priority_init): each turn libevent runs
 * the ready events of the most urgent level that has any and leaves the rest
 * for the next turns, which poll without waiting. Everything runs at
 * MS_PRIORITY_NORMAL (libevent's default for three levels), except the side
 * door's connections whose request header arrives in pieces: a slowloris
 * connection's bytes wait behind every other connection's work
 * (ms_http_door.c). MS_PRIORITY_URGENT is unused: room above the default. */
#define MS_PRIORITY_LEVELS 3
#define MS_PRIORITY_URGENT 0
#define MS_PRIORITY_NORMAL 1
#define MS_PRIORITY_TRICKLE 2

struct ms_server {
    struct event_base *base;
    ms_server_config config;     /* owned */
    ms_registry *registry;       /* owned */
    ms_server_metrics metrics;
    ms_serve_door *binary;
    ms_http_door *http;
    uint16_t bound_port, bound_http_port;
    struct event *signal_events[3];
    struct event *drain_timer;
    bool draining;
    double drain_started_at;
    double started_at;
    FILE *access_log;            /* config.access_log, open for appending; NULL: none */
    ms_client_log client_log;    /* ms_server_log_client's limit */
    struct event *client_log_timer; /* once a second: ends the client log's windows,
                                     * closes idle models' archives */
};

/* Logs one line caused by a client, within the limit of ms_client_log. */
void ms_server_log_client(ms_server *server, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));

/* The descriptors meshserve needs besides the HTTP door's parked connections
 * (ms_http_conns.h): max_clients, http_max_connections and room for rejected
 * connections and the archives; the limit it raises is this plus the lot. */
size_t ms_server_descriptors_besides_parked(const ms_server_config *config);

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

/* The argument of the first event of base whose callback is cb, or NULL: for
 * a callback that libevent hands someone else's argument (evhttp's listener
 * error callback gets evhttp's, not the door's). A walk over the loop's
 * events: for rare calls only. */
void *ms_server_event_arg(struct event_base *base, void (*cb)(int, short, void *));

#endif
