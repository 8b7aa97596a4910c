/* One HTTP/1.1 GET for the client-side tools (meshload's Draco baseline), on
 * libevent's HTTP client (evhttp): its own event loop, blocking the calling
 * thread until the answer is complete, the time-out passes or the connection
 * fails. Reads are throttled to `bandwidth` with a token bucket (the same
 * shaping as the streaming client), so a baseline download sees the link a
 * stream sees.
 *
 * Errors: MS_ERR_IO with one line naming host:port when there is no answer
 * (connection refused or dropped, time-out); an answer of any status is MS_OK
 * with *status set (the caller judges it). MS_ERR_NOMEM, MS_ERR_ARG (a host
 * that is not a numeric address).
 * Thread-safety: calls on different threads are independent.
 */
#ifndef MS_HTTP_GET_H
#define MS_HTTP_GET_H

#include <stdint.h>

#include "ms_error.h"

struct evbuffer;

typedef struct ms_http_get_options {
    const char *host;   /* numeric IPv4 address */
    uint16_t port;
    const char *path;   /* "/models/NAME/draco" */
    const char *token;  /* sent as "Authorization: Bearer TOKEN"; NULL: none */
    double bandwidth;   /* bytes per second read; 0 = unlimited */
    double timeout_s;   /* the whole exchange, seconds (> 0) */
} ms_http_get_options;

/* The answer's body is appended to body (the caller's); *status is its HTTP
 * status code. */
ms_status ms_http_get(const ms_http_get_options *options, struct evbuffer *body, int *status,
                      ms_error *err);

#endif
