/* One HTTP/1.1 GET for the client-side tools (meshload's Draco baseline), on
 * libevent's HTTP client (evhttp): its own event loop, blocking the calling
 * thread until the answer is complete, the time-out passes or the connection
 * fails. Reads are throttled to `bandwidth` with a token bucket (the same
 * shaping as the streaming client), so a baseline download sees the link a
 * stream sees.
 *
 * The body is bounded: at most max_body bytes (MS_HTTP_GET_MAX_BODY when 0)
 * are read, whatever the server announces; a Content-Length above it fails at
 * once, before any body byte is read, and a longer chunked body fails as it
 * passes the bound, so a hostile or broken server cannot make the client
 * hold gigabytes.
 *
 * Errors: MS_ERR_IO with one line naming host:port when there is no answer
 * (connection refused or dropped, time-out); MS_ERR_RANGE with one line
 * ("host:port: the answer's body is larger than the N-byte maximum") past the
 * bound; an answer of any status is MS_OK with *status set (the caller judges
 * it). MS_ERR_NOMEM, MS_ERR_ARG (a host that is not a numeric address).
 * Thread-safety: calls on different threads are independent.
 */
#ifndef MS_HTTP_GET_H
#define MS_HTTP_GET_H

#include <stdint.h>

#include "ms_error.h"

struct evbuffer;

/* The default bound of a body: 1 GiB (a Draco file of the largest models
 * served is some hundreds of MB). */
#define MS_HTTP_GET_MAX_BODY ((uint64_t)1 << 30)

typedef struct ms_http_get_options {
    const char *host;   /* numeric IPv4 address */
    uint16_t port;
    const char *path;   /* "/models/NAME/draco" */
    const char *token;  /* sent as "Authorization: Bearer TOKEN"; NULL: none */
    double bandwidth;   /* bytes per second read; 0 = unlimited */
    double timeout_s;   /* the whole exchange, seconds (> 0) */
    uint64_t max_body;  /* bytes at most in the body; 0: MS_HTTP_GET_MAX_BODY */
} ms_http_get_options;

/* The answer's body is appended to body (the caller's); *status is its HTTP
 * status code. */
ms_status ms_http_get(const ms_http_get_options *options, struct evbuffer *body, int *status,
                      ms_error *err);

#endif
