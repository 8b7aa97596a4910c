/* The HTTP side door's parsing of request headers that select what is sent:
 * Range and If-None-Match. Strict, answering as nginx does, so that meshserve
 * and a static server holding meshexport's tree agree on every request.
 * Pure functions of their arguments; thread-safe.
 */
#ifndef MS_HTTP_PARSE_H
#define MS_HTTP_PARSE_H

#include <stdbool.h>
#include <stdint.h>

typedef enum ms_http_range_result {
    MS_HTTP_RANGE_NONE,          /* no usable Range: send the whole body (200) */
    MS_HTTP_RANGE_OK,            /* send bytes [*first, *last] (206) */
    MS_HTTP_RANGE_UNSATISFIABLE, /* 416, with Content-Range: bytes * / length */
} ms_http_range_result;

/* Interprets a Range header (NULL: none) against a body of `length` bytes.
 * A header that does not start with "bytes=", or asks for several ranges, is
 * ignored (NONE). After "bytes=", one range of the forms FIRST-LAST, FIRST- or
 * -SUFFIX (decimal digits only, spaces allowed around the parts, no sign, no
 * value past 2^63 - 1) is accepted; any other text, FIRST > LAST, FIRST at or
 * past the end, a suffix of 0 or an empty body is UNSATISFIABLE. LAST is
 * clamped to the end, a suffix to the whole body. */
ms_http_range_result ms_http_parse_range(const char *header, uint64_t length, uint64_t *first,
                                         uint64_t *last);

/* True when an If-None-Match header (NULL: none) matches etag (a quoted
 * strong entity tag): "*", or a comma-separated list holding etag, compared
 * weakly (a W/ prefix is ignored), as RFC 9110 section 13.1.2 requires. */
bool ms_http_none_match(const char *header, const char *etag);

#endif
