/* The archive catalogue: `catalog.json` in an archive directory, listing every
 * model baked there (docs/ARCHIVE.md). Read and written with jansson.
 *
 * Model names are identifiers, never paths: 1 to 64 characters of [A-Za-z0-9_-].
 * The archive file of model NAME is DIR/NAME.msa.
 *
 * ms_catalog_update is the only way the baker changes the catalogue: it takes an
 * exclusive lock on DIR/catalog.lock, re-reads the file, replaces or adds the
 * entry, and writes the new file under a temporary name renamed over the old one,
 * so concurrent bakes never lose each other's entries and readers never see a
 * half-written file.
 *
 * Ownership: an ms_catalog owns its entries and their strings (source,
 * metadata); free it with ms_catalog_free. Thread-safety: a catalogue object is not shared between
 * threads; the file-level protocol is safe across processes.
 */
#ifndef MS_CATALOG_H
#define MS_CATALOG_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_metadata.h"

#define MS_CATALOG_VERSION 1
#define MS_MODEL_NAME_MAX 64
#define MS_CATALOG_MAX_ENTRIES 200000
#define MS_CATALOG_MAX_BYTES (64u << 20)

typedef struct ms_catalog_entry {
    char name[MS_MODEL_NAME_MAX + 1];
    char *source;              /* input file the model was baked from (owned) */
    char baked_at[32];         /* ISO 8601 UTC, e.g. 2026-11-22T02:30:00Z */
    uint64_t vertices;         /* welded input */
    uint64_t triangles;
    uint64_t archive_bytes;
    uint32_t cells;
    uint8_t bits, n, root_bits;
    uint32_t min_triangles;
    bool apo;
    uint8_t apo_lead, apo_max_depth;
    double apo_tolerance;
    uint8_t public_max_bits;   /* preview precision open to everyone; bits = fully public */
    /* Optional "crease_angle" (degrees, [0, 180]): where a viewer splits vertex
     * normals into hard edges for this model (docs/RENDERER.md); absent: the
     * viewer's default. Kept when the model is baked again. */
    bool has_crease_angle;
    double crease_angle_deg;
    /* What a server lists without opening the archive (written at bake by
     * ms_catalog_entry_fill_listing; "content_id" as 16 hex digits and
     * "apo_levels"): the archive's ms_archive_content_id and most APO levels
     * in a cell. Absent (has_listing false): the server opens the archive to
     * list it. */
    bool has_listing;
    uint64_t content_id;
    uint8_t apo_levels;
    /* Optional "metadata" (ms_metadata.h: title, creator, date, licence,
     * description, unit, from meshbake --metadata); NULL: none. Owned by the
     * entry; kept when the model is baked again without --metadata. */
    ms_metadata *metadata;
    /* Optional "thumbnail_bits": DIR/NAME.thumb.png exists, rendered from the
     * cut at this precision (the preview's, public_max_bits, for a preview
     * model: docs/SECURITY.md). A server offers the picture only while
     * thumbnail_bits <= public_max_bits. */
    bool has_thumbnail;
    uint8_t thumbnail_bits;
    uint8_t thumbnail_up;      /* "thumbnail_up": its world up, 0 x, 1 y, 2 z (default) */
    /* The reader's bookkeeping: FNV-1a 64 of the entry's text in the file it
     * was read from (0: not known), by which ms_catalog_reload recognises an
     * unchanged entry. Never written. */
    uint64_t text_hash;
} ms_catalog_entry;

typedef struct ms_catalog {
    ms_catalog_entry *entries; /* sorted by name */
    size_t count;
} ms_catalog;

/* True when name is a valid model name. */
bool ms_model_name_valid(const char *name);

/* Reads DIR/catalog.json. A missing file is an empty catalogue; a malformed one
 * (bad JSON, wrong version, missing or mistyped field, invalid name, duplicate
 * name, more than MS_CATALOG_MAX_ENTRIES) is MS_ERR_FORMAT with the reason. */
ms_status ms_catalog_load(const char *dir, ms_catalog *catalog, ms_error *err);

/* ms_catalog_load, parsing again only the entries whose text differs from an
 * entry of previous (may be NULL; a catalogue this reader loaded): the others
 * are copied. A reload after one bake in a collection of 10,000 parses one
 * entry instead of all. A file not in the writer's layout (hand-edited) is
 * parsed whole. Same results and errors as ms_catalog_load. */
ms_status ms_catalog_reload(const char *dir, const ms_catalog *previous, ms_catalog *catalog,
                            ms_error *err);
void ms_catalog_free(ms_catalog *catalog);

/* The entry named name, or NULL. */
const ms_catalog_entry *ms_catalog_find(const ms_catalog *catalog, const char *name);

/* Opens the archive at archive_path and records its listing figures in entry
 * (content_id, apo_levels, has_listing). Errors: the archive reader's. */
ms_status ms_catalog_entry_fill_listing(ms_catalog_entry *entry, const char *archive_path,
                                        ms_error *err);

/* Adds or replaces entry (copied) in DIR/catalog.json, under the lock. */
ms_status ms_catalog_update(const char *dir, const ms_catalog_entry *entry, ms_error *err);

/* Sets the thumbnail fields of the entry named name (has_thumbnail,
 * thumbnail_bits, thumbnail_up), under the lock, leaving the rest of the entry as it is.
 * MS_ERR_RANGE when there is no such entry. */
ms_status ms_catalog_update_thumbnail(const char *dir, const char *name, bool has_thumbnail,
                                      unsigned thumbnail_bits, unsigned thumbnail_up,
                                      ms_error *err);

/* Removes the entry named name, if any, under the lock. */
ms_status ms_catalog_remove(const char *dir, const char *name, ms_error *err);

/* Formats the current UTC time as ISO 8601 into out (at least 21 bytes). */
void ms_catalog_now(char *out, size_t size);

#endif
