/* The HTTP door's catalogue (GET /catalog): one page of the registry's
 * entries, filtered, sorted and paged on the server, so that a client shows
 * the first page of a 10,000-model collection without fetching the whole list
 * (docs/DEPLOY.md, "The catalogue"). Built from the catalogue entries alone:
 * listing opens no archive. */
#include <ctype.h>
#include <event2/buffer.h>
#include <event2/http.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "ms_catalog_page.h"
#include "ms_http_door.h"
#include "ms_http_internal.h"
#include "ms_server_internal.h"

enum { CATALOG_PAGE_DEFAULT = 100, CATALOG_PAGE_MAX = 1000 };

/* Reads the query; false with a one-line reason in why. */
static bool parse_request(const struct evkeyvalq *query, ms_catalog_page_query *out, const char **why)
{
    memset(out, 0, sizeof *out);
    out->limit = CATALOG_PAGE_DEFAULT;
    const char *v;
    if ((v = evhttp_find_header(query, "offset")) &&
        !ms_http_parse_u32(v, MS_CATALOG_MAX_ENTRIES, &out->offset)) {
        *why = "error: offset must be an integer in 0..200000";
        return false;
    }
    if ((v = evhttp_find_header(query, "limit")) &&
        (!ms_http_parse_u32(v, CATALOG_PAGE_MAX, &out->limit) || out->limit == 0)) {
        *why = "error: limit must be an integer in 1..1000";
        return false;
    }
    if ((v = evhttp_find_header(query, "sort"))) {
        static const char *const names[] = {"name", "size", "date", "triangles"};
        size_t k = 0;
        while (k < 4 && strcmp(v, names[k]))
            ++k;
        if (k == 4) {
            *why = "error: sort must be name, size, date or triangles";
            return false;
        }
        out->sort = (ms_catalog_sort)k;
    }
    if ((v = evhttp_find_header(query, "order"))) {
        if (strcmp(v, "asc") && strcmp(v, "desc")) {
            *why = "error: order must be asc or desc";
            return false;
        }
        out->descending = !strcmp(v, "desc");
    }
    if ((v = evhttp_find_header(query, "q"))) {
        size_t n = strlen(v);
        if (n > MS_CATALOG_PAGE_QUERY_MAX) {
            *why = "error: q must be at most 64 characters";
            return false;
        }
        for (size_t i = 0; i < n; ++i)
            out->text[i] = (char)tolower((unsigned char)v[i]);
    }
    return true;
}

/* One model: its figures, "thumbnail" (true when /models/NAME/thumbnail
 * answers a picture) and, when the catalogue has them, the metadata's
 * fields as JSON strings (text as given: a page escapes it). */
json_t *ms_http_catalog_entry(const ms_catalog_entry *e)
{
    json_t *obj = json_pack("{s:s, s:I, s:I, s:I, s:i, s:i, s:b, s:I, s:s, s:b}", "name", e->name,
                            "vertices", (json_int_t)e->vertices, "triangles",
                            (json_int_t)e->triangles, "cells", (json_int_t)e->cells, "bits",
                            (int)e->bits, "public_max_bits", (int)e->public_max_bits, "apo",
                            (int)e->apo, "archive_bytes", (json_int_t)e->archive_bytes,
                            "baked_at", e->baked_at, "thumbnail",
                            ms_access_document(e, MS_DOCUMENT_THUMBNAIL));
    for (int k = 0; obj && k < MS_METADATA_FIELDS; ++k) {
        const char *v = ms_metadata_field(e->metadata, k);
        if (v)
            json_object_set_new(obj, ms_metadata_field_names[k], json_string(v));
    }
    return obj;
}

/* The page as JSON text (malloc'ed), or NULL when out of memory. */
static char *catalog_page(const ms_registry *r, const ms_catalog_page_query *q)
{
    size_t *indices, count, total;
    if (ms_catalog_page_select(r, q, &indices, &count, &total, NULL) != MS_OK)
        return NULL;
    json_t *models = json_array();
    for (size_t i = 0; models && i < count; ++i)
        json_array_append_new(models, ms_http_catalog_entry(ms_registry_entry(r, indices[i])));
    free(indices);
    json_t *root = models ? json_pack("{s:i, s:I, s:I, s:I, s:o}", "version", 1, "total",
                                      (json_int_t)total, "offset", (json_int_t)q->offset,
                                      "limit", (json_int_t)q->limit, "models", models)
                          : NULL;
    char *text = root ? json_dumps(root, JSON_INDENT(2) | JSON_SORT_KEYS) : NULL;
    json_decref(root);
    return text;
}

void ms_http_serve_catalog(ms_http_door *door, struct evhttp_request *req,
                           const struct evkeyvalq *query)
{
    ms_catalog_page_query q;
    const char *why = NULL;
    if (!parse_request(query, &q, &why)) {
        ms_http_send_text(door, req, 400, "Bad Request", why);
        return;
    }
    char *text = catalog_page(ms_http_door_server(door)->registry, &q);
    if (!text) {
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: out of memory");
        return;
    }
    struct evbuffer *body = evbuffer_new();
    if (body) {
        evbuffer_add_printf(body, "%s\n", text);
        struct evkeyvalq *out = evhttp_request_get_output_headers(req);
        evhttp_add_header(out, "Content-Type", "application/json");
        /* Kept 10 s by the browser alone (shared caches keep no catalogue:
         * it changes with every rescan, deploy/nginx.conf.in): the viewer
         * page asks for its model's entry twice, boot.js first, then its
         * worker, which the browser's cache answers (docs/BROWSER.md, "First
         * pixels"); a page opened within 10 s of a rescan may list what was
         * there before it. */
        evhttp_add_header(out, "Cache-Control", "private, max-age=10");
        ms_http_reply(door, req, 200, "OK", body, evbuffer_get_length(body));
        evbuffer_free(body);
    }
    free(text);
}
