/* Cross-origin reads of the HTTP side door: see ms_http_cors.h. */
#include "ms_http_cors.h"

#include <event2/http.h>
#include <event2/keyvalq_struct.h>
#include <stddef.h>
#include <string.h>
#include <strings.h>

#define SEPARATORS ", \t"

/* The length of the valid origin at text (ending at a separator or the end),
 * or 0: "http" or "https", "://", a host of letters, digits, dots and hyphens
 * or a bracketed IPv6 address, an optional ":PORT" of 1-5 digits. */
static size_t origin_length(const char *text)
{
    const char *p = text;
    if (!strncasecmp(p, "https://", 8))
        p += 8;
    else if (!strncasecmp(p, "http://", 7))
        p += 7;
    else
        return 0;
    size_t host;
    if (*p == '[') {
        host = strspn(p + 1, "0123456789abcdefABCDEF:.");
        if (host == 0 || p[1 + host] != ']')
            return 0;
        host += 2;
    } else {
        host = strspn(p, "abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789.-");
    }
    if (host == 0 || host > 253)
        return 0;
    p += host;
    if (*p == ':') {
        size_t digits = strspn(p + 1, "0123456789");
        if (digits < 1 || digits > 5)
            return 0;
        p += 1 + digits;
    }
    if (*p && !strchr(SEPARATORS, *p))
        return 0;
    return (size_t)(p - text);
}

ms_status ms_http_cors_check(const char *list, const char *where, ms_error *err)
{
    const char *p = list + strspn(list, SEPARATORS);
    if (!*p)
        return ms_error_set(err, MS_ERR_RANGE, "%s: cors_origins wants origins "
                            "(https://host[:port], separated by commas) or '*'", where);
    if (!strcmp(p, "*") || (p[0] == '*' && !p[1 + strspn(p + 1, SEPARATORS)]))
        return MS_OK;
    while (*p) {
        size_t n = origin_length(p);
        if (n == 0) {
            size_t bad = strcspn(p, SEPARATORS);
            return ms_error_set(err, MS_ERR_RANGE,
                                "%s: cors_origins: '%.*s' is not an origin (scheme://host[:port], "
                                "no path; or '*' alone)",
                                where, (int)(bad > 200 ? 200 : bad), p);
        }
        p += n;
        p += strspn(p, SEPARATORS);
    }
    return MS_OK;
}

/* True when list is "*" (with separators about it). */
static bool any_origin(const char *list)
{
    const char *p = list + strspn(list, SEPARATORS);
    return p[0] == '*' && !p[1 + strspn(p + 1, SEPARATORS)];
}

bool ms_http_cors_allowed(const char *list, const char *origin)
{
    if (!list || !origin || !*origin)
        return false;
    if (any_origin(list))
        return true;
    size_t want = strlen(origin);
    for (const char *p = list + strspn(list, SEPARATORS); *p; p += strspn(p, SEPARATORS)) {
        size_t n = strcspn(p, SEPARATORS);
        if (n == want && !strncasecmp(p, origin, n))
            return true;
        p += n;
    }
    return false;
}

/* The Origin of req when list allows it, else NULL. */
static const char *allowed_origin(const char *list, struct evhttp_request *req)
{
    const char *origin = evhttp_find_header(evhttp_request_get_input_headers(req), "Origin");
    return ms_http_cors_allowed(list, origin) ? origin : NULL;
}

/* Allow-Origin: "*" for any origin (the answer is then the same for every
 * origin), else the request's own, with Vary: Origin for caches. */
static void allow_origin(const char *list, const char *origin, struct evkeyvalq *out)
{
    if (any_origin(list)) {
        evhttp_add_header(out, "Access-Control-Allow-Origin", "*");
        return;
    }
    evhttp_add_header(out, "Access-Control-Allow-Origin", origin);
    evhttp_add_header(out, "Vary", "Origin");
}

void ms_http_cors_headers(const char *list, struct evhttp_request *req)
{
    const char *origin = allowed_origin(list, req);
    if (!origin)
        return;
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    allow_origin(list, origin, out);
    /* What a page's script may read of an answer beyond the CORS-safelisted
     * headers: the ranges, the validators and the rate limit's wait. */
    evhttp_add_header(out, "Access-Control-Expose-Headers",
                      "Content-Range, Content-Length, Accept-Ranges, ETag, Retry-After");
}

bool ms_http_cors_preflight(const char *list, struct evhttp_request *req)
{
    const char *origin = allowed_origin(list, req);
    if (!origin)
        return false;
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    allow_origin(list, origin, out);
    evhttp_add_header(out, "Access-Control-Allow-Methods", "GET, HEAD");
    evhttp_add_header(out, "Access-Control-Allow-Headers", "Authorization, Range, If-None-Match");
    evhttp_add_header(out, "Access-Control-Max-Age", "600");
    return true;
}
