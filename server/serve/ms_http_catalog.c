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

#include "ms_http_door.h"
#include "ms_http_internal.h"
#include "ms_server_internal.h"

enum { CATALOG_PAGE_DEFAULT = 100, CATALOG_PAGE_MAX = 1000, CATALOG_QUERY_MAX = 64 };

typedef enum { SORT_NAME, SORT_SIZE, SORT_DATE, SORT_TRIANGLES } catalog_sort;

typedef struct catalog_request {
    uint32_t offset, limit;
    catalog_sort sort;
    bool descending;
    char text[CATALOG_QUERY_MAX + 1]; /* lower case; empty: every model */
} catalog_request;

/* Case-insensitive substring test (ASCII: names are [A-Za-z0-9_-]). */
static bool contains_folded(const char *haystack, const char *needle)
{
    size_t n = strlen(needle);
    for (const char *h = haystack; *h; ++h) {
        size_t i = 0;
        while (i < n && h[i] && tolower((unsigned char)h[i]) == needle[i])
            ++i;
        if (i == n)
            return true;
    }
    return n == 0;
}

static bool entry_matches(const ms_catalog_entry *e, const char *text)
{
    return !text[0] || contains_folded(e->name, text) ||
           (e->source && contains_folded(e->source, text));
}

/* Reads the query; false with a one-line reason in why. */
static bool parse_request(const struct evkeyvalq *query, catalog_request *out, const char **why)
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
        out->sort = (catalog_sort)k;
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
        if (n > CATALOG_QUERY_MAX) {
            *why = "error: q must be at most 64 characters";
            return false;
        }
        for (size_t i = 0; i < n; ++i)
            out->text[i] = (char)tolower((unsigned char)v[i]);
    }
    return true;
}

/* One matched entry with its sort key; sign is -1 for a descending order. */
typedef struct sort_item {
    uint64_t key;       /* size or triangles */
    const char *date;   /* ISO 8601 UTC sorts as text */
    size_t index;       /* registry position: by name */
    int sign;
} sort_item;

static int compare_items(const void *a, const void *b)
{
    const sort_item *x = a, *y = b;
    int c = x->date ? strcmp(x->date, y->date) : (x->key > y->key) - (x->key < y->key);
    if (c == 0) /* ties, and the name order itself: by registry position */
        c = (x->index > y->index) - (x->index < y->index);
    return x->sign * c;
}

json_t *ms_http_catalog_entry(const ms_catalog_entry *e)
{
    return json_pack("{s:s, s:I, s:I, s:I, s:i, s:i, s:b, s:I, s:s}", "name", e->name, "vertices",
                     (json_int_t)e->vertices, "triangles", (json_int_t)e->triangles, "cells",
                     (json_int_t)e->cells, "bits", (int)e->bits, "public_max_bits",
                     (int)e->public_max_bits, "apo", (int)e->apo, "archive_bytes",
                     (json_int_t)e->archive_bytes, "baked_at", e->baked_at);
}

/* The page as JSON text (malloc'ed), or NULL when out of memory. */
static char *catalog_page(const ms_registry *r, const catalog_request *q)
{
    size_t count = ms_registry_count(r), matched = 0;
    sort_item *items = malloc((count ? count : 1) * sizeof *items);
    if (!items)
        return NULL;
    for (size_t i = 0; i < count; ++i) {
        const ms_catalog_entry *e = ms_registry_entry(r, i);
        if (!entry_matches(e, q->text))
            continue;
        sort_item *it = &items[matched++];
        it->key = q->sort == SORT_SIZE ? e->archive_bytes : e->triangles;
        it->date = q->sort == SORT_DATE ? e->baked_at : NULL;
        it->index = i;
        it->sign = q->descending ? -1 : 1;
    }
    if (q->sort != SORT_NAME)
        qsort(items, matched, sizeof *items, compare_items);
    else if (q->descending) /* already by name: reversed */
        for (size_t i = 0; i < matched / 2; ++i) {
            sort_item t = items[i];
            items[i] = items[matched - 1 - i];
            items[matched - 1 - i] = t;
        }
    json_t *models = json_array();
    for (size_t i = q->offset; models && i < matched && i < (size_t)q->offset + q->limit; ++i)
        json_array_append_new(models, ms_http_catalog_entry(ms_registry_entry(r, items[i].index)));
    free(items);
    json_t *root = models ? json_pack("{s:i, s:I, s:I, s:I, s:o}", "version", 1, "total",
                                      (json_int_t)matched, "offset", (json_int_t)q->offset,
                                      "limit", (json_int_t)q->limit, "models", models)
                          : NULL;
    char *text = root ? json_dumps(root, JSON_INDENT(2) | JSON_SORT_KEYS) : NULL;
    json_decref(root);
    return text;
}

void ms_http_serve_catalog(ms_http_door *door, struct evhttp_request *req,
                           const struct evkeyvalq *query)
{
    catalog_request q;
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
        evhttp_add_header(evhttp_request_get_output_headers(req), "Content-Type", "application/json");
        ms_http_reply(door, req, 200, "OK", body, evbuffer_get_length(body));
        evbuffer_free(body);
    }
    free(text);
}
