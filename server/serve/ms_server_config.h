/* meshserve settings: defaults, command-line overrides and the config file.
 *
 * The config file is plain text, one `key = value` per line, `#` starts a
 * comment. Keys (and their command-line twins) are listed in ms_server_config.c
 * and in `meshserve --help`; every value is range-checked, and an unknown key, a
 * bad value or a repeated key is an error naming the file and the line.
 *
 * Ownership: strings inside the struct are owned by it; free with
 * ms_server_config_free. Thread-safety: plain data.
 */
#ifndef MS_SERVER_CONFIG_H
#define MS_SERVER_CONFIG_H

#include <stdint.h>

#include "ms_error.h"

typedef struct ms_server_config {
    char *archive_dir;
    char *bind_address;       /* default 127.0.0.1 */
    uint32_t port;            /* binary protocol; 0 = ephemeral; default 7800 */
    uint32_t http_port;       /* HTTP side door; 0 = ephemeral; default 7801 */
    int http_enabled;         /* 0 when http_port is "off" */
    uint32_t max_clients;     /* simultaneous binary connections; default 1024 */
    uint32_t idle_timeout_s;  /* close a connection idle this long; default 120 */
    uint32_t send_timeout_s;  /* close a binary connection whose peer reads nothing of
                                 what waits for it this long (a slow reader); default 60 */
    uint32_t max_frame;       /* largest frame body accepted (binary door: at most 65,544, the largest batch); default 1 MiB */
    uint32_t max_batch;       /* entries in one request batch; default 1024 */
    uint32_t max_outstanding; /* queued requests per connection; default 4096 */
    uint64_t max_queued_bytes;/* payload bytes queued per connection; default 64 MiB */
    uint32_t request_rate;    /* requests per second per connection (burst max_batch); default 20000 */
    uint32_t http_rate;       /* HTTP requests per second per client address; default 2000 */
    uint32_t http_max_connections; /* open HTTP connections; more wait in the backlog; default 256 */
    uint32_t http_header_timeout_s; /* most time for an HTTP request header to arrive (after
                                       the accept or the previous request); default 30 */
    uint32_t http_park_s;     /* a connection shed at the cap is held this long, unread and
                                 unanswered, before its reset (0: closed at once); default 20 */
    uint32_t http_park_max;   /* the most connections held so; default 4096 */
    uint32_t max_open_models; /* archives kept open that no client holds; default 256 */
    uint32_t model_idle_timeout_s; /* close a model's archive no client used this long; default 300 */
    char *token;              /* full-precision access token; NULL = none configured */
    char *port_file;          /* if set, "PORT HTTP_PORT\n" is written there once listening */
    char *access_log;         /* if set, one JSON line per binary connection and per HTTP
                                 request is appended there (ms_server.h); reopened on SIGHUP */
    char *web_dir;            /* if set, the browser pages (make wasm: build/wasm/site) are
                                 served from there at /, /view/NAME and /web/FILE
                                 (docs/BROWSER.md) */
    char *cors_origins;       /* if set, the origins (or "*") whose pages may read the HTTP
                                 side door's answers (ms_http_cors.h); default none */
} ms_server_config;

void ms_server_config_defaults(ms_server_config *config);
void ms_server_config_free(ms_server_config *config);

/* Applies one setting by name (file key spelling, e.g. "max_clients"), from a
 * file line or a command-line option. where names the origin for errors
 * ("meshserve.conf:12" or "--max-clients"). */
ms_status ms_server_config_set(ms_server_config *config, const char *key, const char *value,
                               const char *where, ms_error *err);

/* Reads a config file, applying each setting in order. */
ms_status ms_server_config_load(ms_server_config *config, const char *path, ms_error *err);

#endif
