/* The HTTP side door's parsing of request headers that select what is sent:
 * Range, If-None-Match and Authorization. Strict, answering as nginx does
 * where nginx has an answer (one range; several are refused, where nginx
 * would send a multipart body that no meshstream client asks for), so that
 * meshserve and a static server holding meshexport's tree agree on the
 * requests clients make. Pure functions of their arguments; thread-safe.
 */
#include <stddef.h>
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
 * A header that does not start with "bytes=" is ignored (NONE). After
 * "bytes=", several ranges (any comma) are UNSATISFIABLE (docs/SECURITY.md:
 * one range per request); one range of the forms FIRST-LAST, FIRST- or
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

/* Finds the credential of an Authorization header (NULL: none) of the Bearer
 * scheme, as RFC 9110 section 11 (formerly RFC 7235) writes credentials:
 * optional spaces or tabs, the scheme in any case ("Bearer", "bearer",
 * "BEARER"), one or more spaces, the credential (a run of visible ASCII
 * characters: token68, or any token the server's config accepts), optional
 * trailing spaces or tabs, and nothing else. True with *token pointing at the
 * credential inside header and *length its length; false (outputs untouched)
 * for another scheme, no credential, or text after it. */
bool ms_http_bearer_credential(const char *header, const char **token, size_t *length);

/* Whether an Accept-Encoding header (NULL: none) accepts the content coding
 * `coding` (lower case, e.g. "deflate"), as RFC 9110 section 12.5.3 reads
 * it: a comma-separated list of codings (any case), each with an optional
 * ";q=VALUE" weight (0 to 1, at most three decimals; a weight of 0 refuses).
 * The coding named with a weight above 0 is accepted; named with 0, refused;
 * not named, accepted when "*" is listed with a weight above 0. An element
 * with a malformed weight counts as refusing. No header: not accepted (the
 * identity body is always sent then). */
bool ms_http_accepts_coding(const char *header, const char *coding);

#endif
