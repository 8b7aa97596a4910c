/* A model's descriptive metadata: title, creator, date, licence, a free-text
 * description and the unit of the model's coordinates, given to meshbake as a sidecar JSON file (`--metadata
 * FILE.json`), kept in the model's catalogue entry ("metadata", ms_catalog.h)
 * and shown by both clients (docs/ARCHIVE.md, "Metadata").
 *
 * A sidecar is one JSON object of at most MS_METADATA_FILE_MAX bytes whose
 * members are among "title", "creator", "date", "licence", "description",
 * "unit", each a string (an empty string is the same as an absent member).
 * The unit, when present, is one of MS_METADATA_UNITS (lower case, exactly):
 * what one unit of the model's coordinates is, so that a measurement reads
 * "12.5 mm" (absent: "model units"). Every value is
 * valid UTF-8 (jansson checks it; ms_metadata_text_ok checks it again) of at
 * most its field's bytes, with no control character (U+0000 to U+001F, U+007F
 * to U+009F) but line feeds in the description, and no bidirectional override
 * or isolate (U+202A to U+202E, U+2066 to U+2069), which could make a title
 * read as something else. Anything else is refused with one line: an unknown
 * member, a member that is not a string, a value too long, a bad character,
 * a unit not in the list.
 * The text is kept as given: a page that shows it must escape it (meshserve's
 * /catalog sends it as JSON strings; the browser page sets it as text).
 *
 * Ownership: an ms_metadata is one allocation (ms_metadata_free); NULL is "no
 * metadata" everywhere. Pure and thread-safe.
 */
#ifndef MS_METADATA_H
#define MS_METADATA_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_error.h"

#define MS_METADATA_FILE_MAX 16384
#define MS_METADATA_TITLE_MAX 200
#define MS_METADATA_CREATOR_MAX 200
#define MS_METADATA_DATE_MAX 40
#define MS_METADATA_LICENCE_MAX 200
#define MS_METADATA_DESCRIPTION_MAX 4000
#define MS_METADATA_UNIT_MAX 2
#define MS_METADATA_FIELDS 6
/* The units a sidecar may declare, as its error line lists them. */
#define MS_METADATA_UNITS "um, mm, cm, m, in, ft"
/* What a measurement says without a declared unit. */
#define MS_METADATA_NO_UNIT "model units"

typedef struct ms_metadata {
    /* NULL: absent; else NUL-terminated UTF-8 within the limits above */
    char *title, *creator, *date, *licence, *description, *unit;
} ms_metadata;

/* The members' names in field order (title, creator, date, licence,
 * description, unit) and their byte limits. */
extern const char *const ms_metadata_field_names[MS_METADATA_FIELDS];
extern const size_t ms_metadata_field_max[MS_METADATA_FIELDS];

/* Field k of m (0 .. MS_METADATA_FIELDS - 1), or NULL. */
const char *ms_metadata_field(const ms_metadata *m, int k);

/* True when unit is one of MS_METADATA_UNITS (NULL: false). */
bool ms_metadata_unit_valid(const char *unit);

/* m's unit, or MS_METADATA_NO_UNIT when it declares none (m NULL too). */
const char *ms_metadata_unit_name(const ms_metadata *m);

/* True when text (size bytes) is valid UTF-8 without a character the rules
 * above refuse (newlines_ok: line feeds allowed); *why then names the fault
 * ("is not valid UTF-8", "holds a control character", ...). */
bool ms_metadata_text_ok(const char *text, size_t size, bool newlines_ok, const char **why);

/* Parses a sidecar's text (size bytes; where names it in errors). *out is
 * NULL when the object holds no non-empty member. MS_ERR_FORMAT (bad JSON,
 * not an object, an unknown or mistyped member, a bad character),
 * MS_ERR_RANGE (a value or the text too long), MS_ERR_NOMEM. */
ms_status ms_metadata_parse(const char *text, size_t size, const char *where, ms_metadata **out,
                            ms_error *err);

/* Reads and parses the sidecar file at path (a regular file: ms_input_file.h). */
ms_status ms_metadata_load(const char *path, ms_metadata **out, ms_error *err);

/* A copy (NULL for NULL, or when out of memory with *failed set). */
ms_metadata *ms_metadata_dup(const ms_metadata *m, bool *failed);
bool ms_metadata_equal(const ms_metadata *a, const ms_metadata *b);
void ms_metadata_free(ms_metadata *m);

#endif
