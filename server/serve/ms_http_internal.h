/* Inside the HTTP side door (ms_http_door.h): the answers its routes share
 * (ms_http_door.c: routing, metrics; ms_http_conns.c: connections; ms_http_catalog.c: the
 * catalogue's pages; ms_http_models.c: a model's index, head, subtrees, cell
 * streams and Draco file; ms_http_pages.c: the browser pages). Private to
 * server/serve/; every function runs on the server loop.
 */
#ifndef MS_HTTP_INTERNAL_H
#define MS_HTTP_INTERNAL_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_access.h"
#include "ms_http_door.h"
#include "ms_registry.h"

struct evbuffer;
struct evhttp_request;
struct evkeyvalq;
struct ms_server;

/* The server the door belongs to. */
struct ms_server *ms_http_door_server(const ms_http_door *door);
/* The door's cache of deflated page files (ms_page_cache.h; its thread's). */
struct ms_page_cache *ms_http_door_page_cache(ms_http_door *door);

/* True for a HEAD request. */
bool ms_http_is_head(struct evhttp_request *req);

/* Sends an answer whose body is `length` bytes (body may be NULL for a HEAD or
 * an empty answer), and writes its access log line. A HEAD gets the GET's
 * headers, Content-Length included, and no body. */
void ms_http_reply(ms_http_door *door, struct evhttp_request *req, int code, const char *reason,
                   struct evbuffer *body, uint64_t length);

/* A text/plain answer of one line (errors count in the metrics from 400 on). */
void ms_http_send_text(ms_http_door *door, struct evhttp_request *req, int code,
                       const char *reason, const char *text);

/* A regular file's bytes as an answer body (the file handed to the buffer,
 * sent without copying): the body and *length, or NULL having answered 404
 * with missing (one line) when path is no regular file, or 500. */
struct evbuffer *ms_http_file_body(ms_http_door *door, struct evhttp_request *req,
                                   const char *path, const char *missing, uint64_t *length);

/* Decimal digits only (at most 10), at most max; false otherwise. */
bool ms_http_parse_u32(const char *text, uint32_t max, uint32_t *out);

/* The reader's grant of model (ms_access_grant with the token of its
 * Authorization header); *token_used says whether the token widened it, so
 * that the answer stays out of shared caches. */
ms_access ms_http_reader_grant(const ms_http_door *door, struct evhttp_request *req,
                               const ms_model *model, bool *token_used);

/* Answers a path under /models/NAME/ for model: seg[0] is NAME, seg[1..n) the
 * rest (n >= 1). Returns false, having sent nothing, for a path it does not
 * know (the caller answers 404). */
bool ms_http_route_model(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                         char **seg, int n, const struct evkeyvalq *query);

/* Answers the browser pages (ms_http_pages.c): / (index.html), /view/NAME
 * (view.html) and /web/FILE from the configured web_dir; seg[0..n) is the
 * path. Returns false, having sent nothing, for any other path. */
bool ms_http_route_page(ms_http_door *door, struct evhttp_request *req, char **seg, int n);

/* Answers GET /catalog: one page of the catalogue as JSON, with the query's
 * offset, limit (default 100, at most 1000), sort (name, size, date,
 * triangles), order (asc, desc) and q (a case-insensitive text filter on name,
 * source, and the metadata's title and description); a bad parameter gets
 * 400 and one line. Opens no archive. */
void ms_http_serve_catalog(ms_http_door *door, struct evhttp_request *req,
                           const struct evkeyvalq *query);

/* Answers GET /models/NAME/thumbnail, /metadata and /annotations
 * (ms_http_document.c) with the document of kind (ms_document_kind) read by
 * ms_model_document_read: image/png or application/json, cacheable; 404 and
 * one line for a model or document there is not (a thumbnail finer than the
 * public preview is not), 500 for a file above its limit. Opens no archive. */
void ms_http_serve_document(ms_http_door *door, struct evhttp_request *req, const char *name,
                            int kind);

#endif
