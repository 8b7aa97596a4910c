/* Inside the meshserve process (ms_server.h): the state its doors
 * (ms_proto_door.c, ms_proto_conn.c, ms_proto_requests.c, ms_http_door.c)
 * read and update on the loop's thread. Private to server/. */
#ifndef MS_SERVER_INTERNAL_H
#define MS_SERVER_INTERNAL_H

#include <stdio.h>

#include "ms_server.h"

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
};

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
