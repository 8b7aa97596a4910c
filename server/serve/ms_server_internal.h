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

#endif
