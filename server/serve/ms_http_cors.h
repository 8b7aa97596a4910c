/* Cross-origin reads of the HTTP side door (CORS, docs/BROWSER.md "Embed"):
 * the origins a configuration lets read (cors_origins), the headers of an
 * answer to one of them, and the answer to a preflight (OPTIONS). Private to
 * server/serve/; plain functions of the configured list, no state.
 *
 * The list is one or more origins (scheme "http" or "https", a host, an
 * optional port; no path), separated by commas or spaces, or "*" alone for
 * any origin. CORS lets a page of another site read what it fetches; it adds
 * no access: every byte still goes through ms_access, and the token only in
 * an Authorization header. */
#ifndef MS_HTTP_CORS_H
#define MS_HTTP_CORS_H

#include <stdbool.h>

#include "ms_error.h"

struct evhttp_request;

/* MS_OK when list is a valid cors_origins value; otherwise a one-line error
 * naming `where` and the bad origin. */
ms_status ms_http_cors_check(const char *list, const char *where, ms_error *err);

/* True when origin (an Origin header) is one of list's, or list is "*".
 * list may be NULL (none). Case-insensitive, as hosts are. */
bool ms_http_cors_allowed(const char *list, const char *origin);

/* Adds to req's answer the headers that let its Origin read it, when list
 * allows that origin; nothing otherwise (no Origin, none configured, another
 * origin). */
void ms_http_cors_headers(const char *list, struct evhttp_request *req);

/* Adds the headers of the answer to a preflight (OPTIONS with an Origin and
 * Access-Control-Request-Method) from an allowed origin: the methods (GET,
 * HEAD), the request headers (Authorization, Range, If-None-Match) and how
 * long a browser may keep the answer. Returns false, adding nothing, for an
 * origin list does not allow. */
bool ms_http_cors_preflight(const char *list, struct evhttp_request *req);

#endif
