/* One page of a server's catalogue, the same for both doors (the HTTP
 * door's GET /catalog and the binary door's LIST_PAGE, protocol/PROTOCOL.md
 * 4.11): the registry's entries filtered by a text, sorted and cut to
 * [offset, offset + limit). Built from the catalogue entries alone, so a page
 * opens no archive; O(models) a request (a filter and a sort of 200,000
 * entries are a few milliseconds). Not thread-safe: the server loop's. */
#ifndef MS_CATALOG_PAGE_H
#define MS_CATALOG_PAGE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_registry.h"

#define MS_CATALOG_PAGE_QUERY_MAX 64

typedef enum ms_catalog_sort {
    MS_CATALOG_SORT_NAME,
    MS_CATALOG_SORT_SIZE,      /* archive bytes */
    MS_CATALOG_SORT_DATE,      /* baked_at */
    MS_CATALOG_SORT_TRIANGLES
} ms_catalog_sort;

typedef struct ms_catalog_page_query {
    uint32_t offset, limit;
    ms_catalog_sort sort;
    bool descending;
    char text[MS_CATALOG_PAGE_QUERY_MAX + 1]; /* empty: every model; else matched
                                                * in the name, the source and the
                                                * metadata's title and description,
                                                * ASCII letters case-insensitively */
} ms_catalog_page_query;

/* The registry positions of the page's entries in order (*indices, malloc'ed,
 * the caller's; *count of them) and how many entries the filter matches
 * (*total). MS_ERR_NOMEM. */
ms_status ms_catalog_page_select(const ms_registry *registry, const ms_catalog_page_query *query,
                                 size_t **indices, size_t *count, size_t *total, ms_error *err);

#endif
