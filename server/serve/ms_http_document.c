/* The HTTP door's model documents (GET /models/NAME/thumbnail, /metadata and
 * /annotations, ms_http_internal.h): read through ms_model_document_read, the
 * reader the binary door's GET_DOCUMENT uses, so both doors answer the same
 * bytes under the same rule (ms_access_document). Opens no archive: a
 * catalogue page of 100 pictures opens nothing. A file's ETag and the 304
 * come from the same descriptor's fstat as the bytes sent. */
#include <event2/buffer.h>
#include <event2/http.h>
#include <inttypes.h>
#include <stdio.h>

#include "ms_http_internal.h"
#include "ms_http_parse.h"
#include "ms_model_document.h"
#include "ms_server_internal.h"

void ms_http_serve_document(ms_http_door *door, struct evhttp_request *req, const char *name,
                            int kind)
{
    ms_server *server = ms_http_door_server(door);
    ms_model_document doc;
    ms_document_refusal why;
    ms_error err;
    if (ms_model_document_read(server->registry, server->config.archive_dir, name, kind, &doc,
                               &why, &err) != MS_OK) {
        char line[MS_ERROR_TEXT_MAX + 8];
        snprintf(line, sizeof line, "error: %s", err.text);
        if (why == MS_DOCUMENT_NO_MODEL || why == MS_DOCUMENT_ABSENT)
            ms_http_send_text(door, req, 404, "Not Found", line);
        else
            ms_http_send_text(door, req, 500, "Internal Server Error", line);
        return;
    }
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    evhttp_add_header(out, "Content-Type", doc.content_type);
    /* the same document for every reader (a thumbnail within the public
     * preview, public descriptive data): shared caches may keep it */
    evhttp_add_header(out, "Cache-Control", kind == MS_DOCUMENT_THUMBNAIL
                                                 ? "public, max-age=3600"
                                                 : "public, max-age=60");
    if (doc.inode || doc.mtime_ns) {
        static const char *const suffix[] = {"", "thumb", "meta", "notes"};
        char etag[96];
        snprintf(etag, sizeof etag, "\"%" PRIx64 "-%" PRIx64 "-%" PRIx64 "-%s\"", doc.inode,
                 doc.mtime_ns, doc.size, suffix[kind]);
        evhttp_add_header(out, "ETag", etag);
        struct evkeyvalq *in = evhttp_request_get_input_headers(req);
        if (ms_http_none_match(evhttp_find_header(in, "If-None-Match"), etag)) {
            ms_model_document_free(&doc);
            ms_http_reply(door, req, 304, "Not Modified", NULL, 0);
            return;
        }
    }
    struct evbuffer *body = evbuffer_new();
    if (!body || evbuffer_add(body, doc.bytes, doc.length) != 0) {
        if (body)
            evbuffer_free(body);
        ms_model_document_free(&doc);
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: out of memory");
        return;
    }
    if (!ms_http_is_head(req))
        server->metrics.http_bytes_sent += doc.length;
    ms_http_reply(door, req, 200, "OK", body, doc.length);
    evbuffer_free(body);
    ms_model_document_free(&doc);
}
