/* The catalogue screen's list in pages, searched on the server: see
 * ms_viewer_list_page (ms_viewer_model.h). A server's catalogue comes a page
 * at a time (LIST_PAGE, PROTOCOL.md 4.4a), so a collection of 10,000 models
 * shows its first page without the whole list, and the search text is the
 * server's filter (q=); a local catalogue is read whole and filtered here. */
#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_client.h"
#include "ms_viewer_model.h"

/* ASCII case-insensitive: does text hold the lower-case needle? */
static bool holds(const char *text, const char *needle)
{
    if (!*needle)
        return true;
    for (; text && *text; ++text) {
        size_t i = 0;
        while (needle[i] && text[i] && tolower((unsigned char)text[i]) == needle[i])
            ++i;
        if (!needle[i])
            return true;
    }
    return false;
}

/* Keeps the entries whose name, title or description holds list->query. */
static void filter(ms_viewer_model_list *list)
{
    size_t kept = 0;
    for (size_t i = 0; i < list->count; ++i) {
        ms_viewer_model_entry *e = &list->entries[i];
        if (holds(e->name, list->query) || holds(ms_metadata_field(e->metadata, 0), list->query) ||
            holds(ms_metadata_field(e->metadata, 4), list->query)) {
            list->entries[kept++] = *e;
        } else {
            ms_metadata_free(e->metadata);
            free(e->thumbnail_png);
        }
    }
    list->count = list->total = kept;
}

/* Appends the server's page from list->count on; *unsupported when the server
 * has no pages (below version 3). */
static ms_status server_page(const ms_viewer_source *source, ms_viewer_model_list *list,
                             const char *query, uint16_t limit, bool *unsupported, ms_error *err)
{
    ms_client_options co = {.host = source->host, .port = source->port, .token = source->token,
                            .agent = "meshview/0.1"};
    ms_client_page_request page = {.offset = (uint32_t)list->count, .limit = limit,
                                   .sort = MS_PROTO_SORT_NAME, .query = query};
    ms_client_catalogue cat;
    ms_status st = ms_client_fetch_catalogue_page(&co, source->timeout_s, &page, &cat, err);
    *unsupported = st == MS_ERR_UNSUPPORTED;
    if (st != MS_OK)
        return st;
    ms_viewer_model_entry *grown =
        cat.count ? realloc(list->entries, (list->count + cat.count) * sizeof *grown)
                  : list->entries;
    if (cat.count && !grown) {
        ms_client_catalogue_free(&cat);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the catalogue");
    }
    list->entries = grown;
    for (size_t i = 0; i < cat.count; ++i)
        ms_viewer_entry_from_server(&cat.entries[i], &list->entries[list->count + i]);
    list->count += cat.count;
    list->total = cat.total > list->count ? cat.total : list->count;
    if (cat.count == 0)
        list->total = list->count; /* nothing more comes: do not ask again */
    ms_client_catalogue_free(&cat);
    return MS_OK;
}

ms_status ms_viewer_list_page(const ms_viewer_source *source, const char *query,
                              ms_viewer_model_list *list, ms_error *err)
{
    memset(list, 0, sizeof *list);
    size_t n = query ? strlen(query) : 0;
    if (n >= sizeof list->query)
        return ms_error_set(err, MS_ERR_ARG, "a search of %zu bytes: at most %zu", n,
                            sizeof list->query - 1);
    for (size_t i = 0; i < n; ++i)
        list->query[i] = (char)tolower((unsigned char)query[i]);
    if (!source->archive_dir) {
        bool unsupported;
        ms_status st = server_page(source, list, list->query, MS_VIEWER_PAGE, &unsupported, err);
        if (st == MS_OK || !unsupported)
            return st;
    }
    char kept[sizeof list->query];
    memcpy(kept, list->query, sizeof kept);
    ms_status st = ms_viewer_list_models(source, list, err);
    memcpy(list->query, kept, sizeof kept);
    if (st == MS_OK)
        filter(list);
    return st;
}

ms_status ms_viewer_list_more(const ms_viewer_source *source, ms_viewer_model_list *list,
                              ms_error *err)
{
    if (source->archive_dir || list->total <= list->count)
        return MS_OK;
    bool unsupported;
    return server_page(source, list, list->query, MS_VIEWER_PAGE, &unsupported, err);
}

ms_status ms_viewer_list_lookup(const ms_viewer_source *source, const char *name,
                                ms_viewer_model_entry *entry, ms_error *err)
{
    ms_viewer_model_list found = {0};
    bool unsupported;
    ms_status st = server_page(source, &found, name, MS_PROTO_MAX_PAGE, &unsupported, err);
    bool listed = false;
    for (size_t i = 0; st == MS_OK && i < found.count && !listed; ++i)
        if (!strcmp(found.entries[i].name, name)) {
            *entry = found.entries[i];
            entry->metadata = NULL, entry->thumbnail_png = NULL; /* a listing has none */
            listed = true;
        }
    ms_viewer_model_list_free(&found);
    if (st == MS_OK && !listed)
        st = ms_error_set(err, MS_ERR_RANGE, "model '%s' does not exist on %s:%u", name,
                          source->host, source->port);
    return st;
}
