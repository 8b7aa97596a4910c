/* One page of the catalogue: see ms_catalog_page.h. */
#include "ms_catalog_page.h"

#include <ctype.h>
#include <stdlib.h>
#include <string.h>

/* Case-insensitive substring test: ASCII letters fold, other bytes (the
 * UTF-8 of a title) compare as they are. */
static bool contains_folded(const char *haystack, const char *needle)
{
    size_t n = strlen(needle);
    for (const char *h = haystack; *h; ++h) {
        size_t i = 0;
        while (i < n && h[i] && tolower((unsigned char)h[i]) == (unsigned char)needle[i])
            ++i;
        if (i == n)
            return true;
    }
    return n == 0;
}

/* The text filter: name, source, and the metadata's title and description
 * (docs/ARCHIVE.md, "Metadata"). */
static bool entry_matches(const ms_catalog_entry *e, const char *text)
{
    const ms_metadata *m = e->metadata;
    return !text[0] || contains_folded(e->name, text) ||
           (e->source && contains_folded(e->source, text)) ||
           (m && m->title && contains_folded(m->title, text)) ||
           (m && m->description && contains_folded(m->description, text));
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

ms_status ms_catalog_page_select(const ms_registry *r, const ms_catalog_page_query *q,
                                 size_t **indices, size_t *count, size_t *total, ms_error *err)
{
    *indices = NULL;
    *count = *total = 0;
    char text[MS_CATALOG_PAGE_QUERY_MAX + 1];
    size_t length = strnlen(q->text, MS_CATALOG_PAGE_QUERY_MAX);
    for (size_t i = 0; i < length; ++i)
        text[i] = (char)tolower((unsigned char)q->text[i]);
    text[length] = '\0';
    size_t models = ms_registry_count(r), matched = 0;
    sort_item *items = malloc((models ? models : 1) * sizeof *items);
    if (!items)
        return ms_error_set(err, MS_ERR_NOMEM, "catalogue page: out of memory");
    for (size_t i = 0; i < models; ++i) {
        const ms_catalog_entry *e = ms_registry_entry(r, i);
        if (!entry_matches(e, text))
            continue;
        sort_item *it = &items[matched++];
        it->key = q->sort == MS_CATALOG_SORT_SIZE ? e->archive_bytes : e->triangles;
        it->date = q->sort == MS_CATALOG_SORT_DATE ? e->baked_at : NULL;
        it->index = i;
        it->sign = q->descending ? -1 : 1;
    }
    if (q->sort != MS_CATALOG_SORT_NAME)
        qsort(items, matched, sizeof *items, compare_items);
    else if (q->descending) /* already by name: reversed */
        for (size_t i = 0; i < matched / 2; ++i) {
            sort_item t = items[i];
            items[i] = items[matched - 1 - i];
            items[matched - 1 - i] = t;
        }
    size_t first = q->offset < matched ? q->offset : matched;
    size_t n = matched - first < q->limit ? matched - first : q->limit;
    size_t *out = malloc((n ? n : 1) * sizeof *out);
    if (!out) {
        free(items);
        return ms_error_set(err, MS_ERR_NOMEM, "catalogue page: out of memory");
    }
    for (size_t i = 0; i < n; ++i)
        out[i] = items[first + i].index;
    free(items);
    *indices = out;
    *count = n;
    *total = matched;
    return MS_OK;
}
