/* Inside the catalogue reader (ms_catalog.h): the canonical layout of
 * catalog.json as its writer produces it, cut into one span of text per model
 * entry, so that a reload parses only the entries whose text changed. Private
 * to common/archive. */
#ifndef MS_CATALOG_INTERNAL_H
#define MS_CATALOG_INTERNAL_H

#include <jansson.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_metadata.h"

/* One model entry's JSON object in the file's text. */
typedef struct ms_catalog_span {
    size_t offset, length;
} ms_catalog_span;

/* Cuts text (size bytes) into its entries' spans when it has the writer's
 * layout: `{ "models": [ {...}, ... ], "version": 1 }` with any JSON
 * whitespace between tokens (the keys in that order, as JSON_SORT_KEYS writes
 * them). Each span is a balanced object, strings and escapes respected; what a
 * span holds is left to jansson. On success *spans (malloc'ed, the caller's)
 * holds *count spans in file order and the result is 0; otherwise -1 (nothing
 * allocated): the caller parses the whole document instead. Fails with -1 past
 * max_count entries. */
int ms_catalog_cut_spans(const char *text, size_t size, size_t max_count, ms_catalog_span **spans,
                         size_t *count);

/* FNV-1a 64 of a span's text: the identity by which a reload recognises an
 * entry it has already parsed (never 0: 0 means "not from a span"). */
uint64_t ms_catalog_span_hash(const char *text, ms_catalog_span span);

/* A catalogue entry's or a sidecar's metadata object to *out (NULL when it
 * holds no non-empty member), under ms_metadata.h's rules; where names the
 * file (and entry) in errors. */
ms_status ms_metadata_from_json(json_t *obj, const char *where, ms_metadata **out, ms_error *err);

/* The object of m's present fields (an empty object for NULL); NULL when out
 * of memory. */
json_t *ms_metadata_to_json(const ms_metadata *m);

#endif
