/* catalog.json reading and locked updating. See ms_catalog.h. */
#include "ms_catalog.h"

#include "ms_archive.h"
#include "ms_catalog_internal.h"
#include "ms_input_file.h"

#include <errno.h>
#include <inttypes.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <time.h>
#include <unistd.h>

bool ms_model_name_valid(const char *name)
{
    size_t len = 0;
    for (const char *c = name; *c; ++c, ++len) {
        bool ok = (*c >= 'a' && *c <= 'z') || (*c >= 'A' && *c <= 'Z') ||
                  (*c >= '0' && *c <= '9') || *c == '_' || *c == '-';
        if (!ok || len >= MS_MODEL_NAME_MAX)
            return false;
    }
    return len > 0;
}

void ms_catalog_now(char *out, size_t size)
{
    time_t now = time(NULL);
    struct tm tm;
    gmtime_r(&now, &tm);
    strftime(out, size, "%Y-%m-%dT%H:%M:%SZ", &tm);
}

void ms_catalog_free(ms_catalog *c)
{
    if (!c)
        return;
    for (size_t i = 0; i < c->count; ++i) {
        free(c->entries[i].source);
        ms_metadata_free(c->entries[i].metadata);
    }
    free(c->entries);
    c->entries = NULL;
    c->count = 0;
}

static int compare_entries(const void *a, const void *b)
{
    return strcmp(((const ms_catalog_entry *)a)->name, ((const ms_catalog_entry *)b)->name);
}

const ms_catalog_entry *ms_catalog_find(const ms_catalog *c, const char *name)
{
    ms_catalog_entry key;
    if (c->count == 0 || !ms_model_name_valid(name))
        return NULL;
    snprintf(key.name, sizeof key.name, "%s", name);
    return bsearch(&key, c->entries, c->count, sizeof key, compare_entries);
}

static void catalog_path(const char *dir, const char *file, char *out, size_t size)
{
    snprintf(out, size, "%s/%s", dir, file);
}

/* --- JSON to entries ------------------------------------------------------- */

/* Reads an unsigned integer field in [0, max]. */
static bool get_uint(json_t *obj, const char *key, uint64_t max, uint64_t *out)
{
    json_t *v = json_object_get(obj, key);
    if (!json_is_integer(v) || json_integer_value(v) < 0 ||
        (uint64_t)json_integer_value(v) > max)
        return false;
    *out = (uint64_t)json_integer_value(v);
    return true;
}

static ms_status parse_entry(const char *path, size_t index, json_t *obj, ms_catalog_entry *e,
                             ms_error *err)
{
    memset(e, 0, sizeof *e);
    json_t *name = json_object_get(obj, "name"), *source = json_object_get(obj, "source"),
           *baked = json_object_get(obj, "baked_at"), *apo = json_object_get(obj, "apo"),
           *tol = json_object_get(obj, "apo_tolerance");
    if (!json_is_object(obj) || !json_is_string(name) || !json_is_string(source) ||
        !json_is_string(baked) || !json_is_boolean(apo) || !json_is_number(tol))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: missing or mistyped field", path,
                            index);
    if (!ms_model_name_valid(json_string_value(name)))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: invalid name", path, index);
    if (strlen(json_string_value(baked)) >= sizeof e->baked_at)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: bad baked_at", path, index);
    uint64_t vertices, triangles, bytes, cells, bits, n, root_bits, min_tris, lead, depth, pub;
    if (!get_uint(obj, "vertices", UINT32_MAX + 1ull, &vertices) ||
        !get_uint(obj, "triangles", 1ull << 34, &triangles) ||
        !get_uint(obj, "archive_bytes", UINT64_MAX >> 1, &bytes) ||
        !get_uint(obj, "cells", 1u << 24, &cells) || !get_uint(obj, "bits", 20, &bits) ||
        !get_uint(obj, "n", 8, &n) || !get_uint(obj, "root_bits", 20, &root_bits) ||
        !get_uint(obj, "min_triangles", UINT32_MAX, &min_tris) ||
        !get_uint(obj, "apo_lead", 16, &lead) || !get_uint(obj, "apo_max_depth", 24, &depth) ||
        !get_uint(obj, "public_max_bits", 20, &pub))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: numeric field missing or out of range",
                            path, index);
    e->source = strdup(json_string_value(source));
    if (!e->source)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    snprintf(e->name, sizeof e->name, "%s", json_string_value(name));
    snprintf(e->baked_at, sizeof e->baked_at, "%s", json_string_value(baked));
    e->vertices = vertices, e->triangles = triangles, e->archive_bytes = bytes;
    e->cells = (uint32_t)cells, e->bits = (uint8_t)bits, e->n = (uint8_t)n;
    e->root_bits = (uint8_t)root_bits, e->min_triangles = (uint32_t)min_tris;
    e->apo = json_is_true(apo), e->apo_lead = (uint8_t)lead, e->apo_max_depth = (uint8_t)depth;
    e->apo_tolerance = json_number_value(tol);
    e->public_max_bits = (uint8_t)pub;
    json_t *crease = json_object_get(obj, "crease_angle");
    if (crease) {
        double deg = json_is_number(crease) ? json_number_value(crease) : -1.0;
        if (!(deg >= 0.0 && deg <= 180.0)) {
            free(e->source);
            e->source = NULL;
            return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: crease_angle is not a number of degrees from 0 to 180",
                                path, index);
        }
        e->has_crease_angle = true;
        e->crease_angle_deg = deg;
    }
    json_t *id = json_object_get(obj, "content_id");
    if (id) {
        const char *hex = json_is_string(id) ? json_string_value(id) : "";
        char *end = NULL;
        uint64_t levels;
        if (strlen(hex) != 16 || strspn(hex, "0123456789abcdef") != 16 ||
            !get_uint(obj, "apo_levels", 64, &levels)) {
            free(e->source);
            e->source = NULL;
            return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: content_id is not 16 "
                                "lower-case hex digits with an apo_levels of 0..64", path, index);
        }
        e->content_id = strtoull(hex, &end, 16);
        e->apo_levels = (uint8_t)levels;
        e->has_listing = true;
    }
    uint64_t thumb_bits;
    if (json_object_get(obj, "thumbnail_bits")) {
        if (!get_uint(obj, "thumbnail_bits", 20, &thumb_bits)) {
            free(e->source);
            e->source = NULL;
            return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: thumbnail_bits is not an "
                                "integer in 0..20", path, index);
        }
        e->has_thumbnail = true;
        e->thumbnail_bits = (uint8_t)thumb_bits;
        e->thumbnail_up = 2;
        json_t *up = json_object_get(obj, "thumbnail_up");
        const char *axis = json_is_string(up) ? json_string_value(up) : "";
        if (up && (strlen(axis) != 1 || axis[0] < 'x' || axis[0] > 'z')) {
            free(e->source);
            e->source = NULL;
            return ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: thumbnail_up is not "
                                "\"x\", \"y\" or \"z\"", path, index);
        }
        if (up)
            e->thumbnail_up = (uint8_t)(axis[0] - 'x');
    }
    json_t *meta = json_object_get(obj, "metadata");
    if (meta) {
        char where[4200];
        snprintf(where, sizeof where, "%s: model %zu", path, index);
        ms_status st = ms_metadata_from_json(meta, where, &e->metadata, err);
        if (st != MS_OK) {
            free(e->source);
            e->source = NULL;
            return st;
        }
    }
    return MS_OK;
}

/* Sorts the entries by name and refuses a name listed twice. */
static ms_status finish_catalog(const char *path, ms_catalog *c, ms_error *err)
{
    qsort(c->entries, c->count, sizeof *c->entries, compare_entries);
    for (size_t i = 1; i < c->count; ++i)
        if (!strcmp(c->entries[i].name, c->entries[i - 1].name))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: model '%s' listed twice", path,
                                c->entries[i].name);
    return MS_OK;
}

/* The whole document through jansson: any layout (entries get no text hash). */
static ms_status parse_catalog(const char *path, const char *text, size_t size, ms_catalog *c,
                               ms_error *err)
{
    json_error_t jerr;
    json_t *root = json_loadb(text, size, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: line %d: %s", path, jerr.line, jerr.text);
    json_t *version = json_object_get(root, "version"), *models = json_object_get(root, "models");
    ms_status st = MS_OK;
    size_t count = json_array_size(models);
    if (!json_is_object(root) || !json_is_integer(version) || !json_is_array(models))
        st = ms_error_set(err, MS_ERR_FORMAT, "%s: not a meshstream catalogue", path);
    else if (json_integer_value(version) != MS_CATALOG_VERSION)
        st = ms_error_set(err, MS_ERR_UNSUPPORTED, "%s: catalogue version %lld, this build reads %d",
                          path, (long long)json_integer_value(version), MS_CATALOG_VERSION);
    else if (count > MS_CATALOG_MAX_ENTRIES)
        st = ms_error_set(err, MS_ERR_RANGE, "%s: %zu models exceed the limit", path, count);
    else if (!(c->entries = calloc(count ? count : 1, sizeof *c->entries)))
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    for (size_t i = 0; st == MS_OK && i < count; ++i)
        if ((st = parse_entry(path, i, json_array_get(models, i), &c->entries[i], err)) == MS_OK)
            c->count++;
    json_decref(root);
    return st;
}

/* Open-addressing table of a previous catalogue's entries by text hash. */
typedef struct hash_index {
    size_t *slots; /* entry index + 1; 0 empty */
    size_t mask;
} hash_index;

static bool hash_index_build(hash_index *h, const ms_catalog *previous)
{
    size_t size = 16;
    while (previous && size < 2 * previous->count)
        size *= 2;
    h->slots = calloc(size, sizeof *h->slots);
    h->mask = size - 1;
    if (!h->slots)
        return false;
    for (size_t i = 0; previous && i < previous->count; ++i) {
        uint64_t key = previous->entries[i].text_hash;
        if (!key)
            continue;
        size_t at = (size_t)key & h->mask;
        while (h->slots[at])
            at = (at + 1) & h->mask;
        h->slots[at] = i + 1;
    }
    return true;
}

static const ms_catalog_entry *hash_index_find(const hash_index *h, const ms_catalog *previous,
                                               uint64_t key)
{
    for (size_t at = (size_t)key & h->mask; h->slots[at]; at = (at + 1) & h->mask)
        if (previous->entries[h->slots[at] - 1].text_hash == key)
            return &previous->entries[h->slots[at] - 1];
    return NULL;
}

/* The writer's layout, entry by entry: an entry whose text previous already
 * parsed is copied, the others parsed. */
static ms_status parse_spans(const char *path, const char *text, const ms_catalog_span *spans,
                             size_t count, const ms_catalog *previous, ms_catalog *c,
                             ms_error *err)
{
    hash_index index;
    c->entries = calloc(count ? count : 1, sizeof *c->entries);
    if (!c->entries || !hash_index_build(&index, previous))
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    ms_status st = MS_OK;
    for (size_t i = 0; st == MS_OK && i < count; ++i) {
        ms_catalog_entry *e = &c->entries[i];
        uint64_t key = ms_catalog_span_hash(text, spans[i]);
        const ms_catalog_entry *known = previous ? hash_index_find(&index, previous, key) : NULL;
        if (known) {
            *e = *known;
            bool failed = false;
            e->source = strdup(known->source ? known->source : "");
            e->metadata = ms_metadata_dup(known->metadata, &failed);
            if (!e->source || failed) {
                free(e->source);
                ms_metadata_free(e->metadata);
                e->source = NULL, e->metadata = NULL;
                st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
            }
        } else {
            json_error_t jerr;
            json_t *obj = json_loadb(text + spans[i].offset, spans[i].length,
                                     JSON_REJECT_DUPLICATES, &jerr);
            st = obj ? parse_entry(path, i, obj, e, err)
                     : ms_error_set(err, MS_ERR_FORMAT, "%s: model %zu: %s", path, i, jerr.text);
            json_decref(obj);
        }
        e->text_hash = key;
        if (st == MS_OK)
            c->count++;
    }
    free(index.slots);
    return st;
}

/* Reads DIR/catalog.json whole into *text (malloc'ed); *text NULL and MS_OK
 * when there is no catalogue yet. */
static ms_status read_catalog_text(const char *path, char **text, size_t *size, ms_error *err)
{
    *text = NULL;
    *size = 0;
    if (access(path, F_OK) != 0 && errno == ENOENT)
        return MS_OK;
    char *buffer;
    size_t got;
    ms_status st = ms_input_read_most(path, MS_CATALOG_MAX_BYTES, &buffer, &got, err);
    if (st != MS_OK)
        return st;
    if (got > MS_CATALOG_MAX_BYTES) {
        free(buffer);
        return ms_error_set(err, MS_ERR_RANGE, "%s: larger than 64 MiB", path);
    }
    *text = buffer;
    *size = got;
    return MS_OK;
}

ms_status ms_catalog_reload(const char *dir, const ms_catalog *previous, ms_catalog *c,
                            ms_error *err)
{
    memset(c, 0, sizeof *c);
    char path[4096];
    catalog_path(dir, "catalog.json", path, sizeof path);
    char *text;
    size_t size;
    ms_status st = read_catalog_text(path, &text, &size, err);
    if (st != MS_OK || !text)
        return st; /* no catalogue yet: an empty collection */
    ms_catalog_span *spans;
    size_t count;
    if (ms_catalog_cut_spans(text, size, MS_CATALOG_MAX_ENTRIES, &spans, &count) == 0) {
        st = parse_spans(path, text, spans, count, previous, c, err);
        free(spans);
    } else {
        st = parse_catalog(path, text, size, c, err);
    }
    free(text);
    if (st == MS_OK)
        st = finish_catalog(path, c, err);
    if (st != MS_OK)
        ms_catalog_free(c);
    return st;
}

ms_status ms_catalog_load(const char *dir, ms_catalog *c, ms_error *err)
{
    return ms_catalog_reload(dir, NULL, c, err);
}

ms_status ms_catalog_entry_fill_listing(ms_catalog_entry *e, const char *archive_path,
                                        ms_error *err)
{
    ms_archive *a;
    ms_status st = ms_archive_open(archive_path, &a, err);
    if (st != MS_OK)
        return st;
    e->content_id = ms_archive_content_id(a);
    e->apo_levels = ms_archive_max_apo_levels(a);
    e->has_listing = true;
    ms_archive_close(a);
    return MS_OK;
}

/* --- Entries to JSON ------------------------------------------------------- */

static json_t *entry_to_json(const ms_catalog_entry *e)
{
    json_t *obj = json_pack("{s:s, s:s, s:s, s:I, s:I, s:I, s:I, s:i, s:i, s:i, s:I, s:b, s:i, s:i, s:f, s:i}",
                     "name", e->name, "source", e->source ? e->source : "", "baked_at", e->baked_at,
                     "vertices", (json_int_t)e->vertices, "triangles", (json_int_t)e->triangles,
                     "archive_bytes", (json_int_t)e->archive_bytes, "cells", (json_int_t)e->cells,
                     "bits", (int)e->bits, "n", (int)e->n, "root_bits", (int)e->root_bits,
                     "min_triangles", (json_int_t)e->min_triangles, "apo", (int)e->apo,
                     "apo_lead", (int)e->apo_lead, "apo_max_depth", (int)e->apo_max_depth,
                     "apo_tolerance", isfinite(e->apo_tolerance) ? e->apo_tolerance : 0.0,
                     "public_max_bits", (int)e->public_max_bits);
    if (obj && e->has_crease_angle)
        json_object_set_new(obj, "crease_angle", json_real(e->crease_angle_deg));
    if (obj && e->has_listing) {
        char hex[17];
        snprintf(hex, sizeof hex, "%016" PRIx64, e->content_id);
        json_object_set_new(obj, "content_id", json_string(hex));
        json_object_set_new(obj, "apo_levels", json_integer(e->apo_levels));
    }
    if (obj && e->has_thumbnail) {
        char axis[2] = {(char)('x' + (e->thumbnail_up <= 2 ? e->thumbnail_up : 2)), 0};
        json_object_set_new(obj, "thumbnail_bits", json_integer(e->thumbnail_bits));
        json_object_set_new(obj, "thumbnail_up", json_string(axis));
    }
    if (obj && e->metadata) {
        json_t *meta = ms_metadata_to_json(e->metadata);
        if (!meta || json_object_set_new(obj, "metadata", meta) != 0) {
            json_decref(obj);
            return NULL;
        }
    }
    return obj;
}

static ms_status catalog_save(const char *dir, const ms_catalog *c, ms_error *err)
{
    char path[4096], tmp[4200];
    catalog_path(dir, "catalog.json", path, sizeof path);
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    json_t *models = json_array();
    json_t *root = json_pack("{s:i, s:o}", "version", MS_CATALOG_VERSION, "models", models);
    int failed = !root;
    for (size_t i = 0; !failed && i < c->count; ++i) {
        json_t *e = entry_to_json(&c->entries[i]);
        failed = !e || json_array_append_new(models, e) != 0;
    }
    if (failed) {
        json_decref(root);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory building JSON", path);
    }
    failed = json_dump_file(root, tmp, JSON_INDENT(2) | JSON_SORT_KEYS) != 0;
    json_decref(root);
    if (!failed) {
        int fd = open(tmp, O_RDONLY);
        failed = fd < 0 || fsync(fd) != 0;
        if (fd >= 0)
            close(fd);
    }
    if (failed || rename(tmp, path) != 0) {
        remove(tmp);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot write the catalogue", path);
    }
    return MS_OK;
}

/* Takes DIR/catalog.lock exclusively: its descriptor, or -1 with err set. */
static int lock_catalog(const char *dir, ms_error *err)
{
    char lock_path[4096];
    catalog_path(dir, "catalog.lock", lock_path, sizeof lock_path);
    int lock = open(lock_path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (lock < 0) {
        ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", lock_path, strerror(errno));
        return -1;
    }
    if (flock(lock, LOCK_EX) != 0) {
        ms_error_set(err, MS_ERR_IO, "%s: cannot lock: %s", lock_path, strerror(errno));
        close(lock);
        return -1;
    }
    return lock;
}

static void unlock_catalog(int lock)
{
    flock(lock, LOCK_UN);
    close(lock);
}

ms_status ms_catalog_update_thumbnail(const char *dir, const char *name, bool has_thumbnail,
                                      unsigned thumbnail_bits, unsigned thumbnail_up,
                                      ms_error *err)
{
    int lock = lock_catalog(dir, err);
    if (lock < 0)
        return err ? err->code : MS_ERR_IO;
    ms_catalog c;
    ms_status st = ms_catalog_load(dir, &c, err);
    if (st == MS_OK) {
        ms_catalog_entry *e = (ms_catalog_entry *)ms_catalog_find(&c, name);
        if (!e) {
            st = ms_error_set(err, MS_ERR_RANGE, "no model '%s' in %s/catalog.json", name, dir);
        } else {
            e->has_thumbnail = has_thumbnail;
            e->thumbnail_bits = has_thumbnail ? (uint8_t)thumbnail_bits : 0;
            e->thumbnail_up = (uint8_t)(thumbnail_up <= 2 ? thumbnail_up : 2);
            st = catalog_save(dir, &c, err);
        }
        ms_catalog_free(&c);
    }
    unlock_catalog(lock);
    return st;
}

/* Runs the read-modify-write under DIR/catalog.lock. */
static ms_status catalog_change(const char *dir, const ms_catalog_entry *add,
                                const char *remove_name, ms_error *err)
{
    int lock = lock_catalog(dir, err);
    if (lock < 0)
        return err ? err->code : MS_ERR_IO;
    ms_catalog c;
    ms_status st = ms_catalog_load(dir, &c, err);
    if (st == MS_OK) {
        const char *name = add ? add->name : remove_name;
        ms_catalog_entry *found = (ms_catalog_entry *)ms_catalog_find(&c, name);
        /* a model baked again keeps the crease angle and metadata set for it */
        bool keep_crease = add && found && found->has_crease_angle && !add->has_crease_angle;
        double crease = keep_crease ? found->crease_angle_deg : 0.0;
        bool failed = false;
        ms_metadata *metadata = !add ? NULL
                                : add->metadata ? ms_metadata_dup(add->metadata, &failed)
                                : found ? ms_metadata_dup(found->metadata, &failed) : NULL;
        if (found) { /* drop the old entry, keeping the array sorted */
            free(found->source);
            ms_metadata_free(found->metadata);
            size_t at = (size_t)(found - c.entries);
            memmove(found, found + 1, (c.count - at - 1) * sizeof *found);
            c.count--;
        }
        if (add) {
            ms_catalog_entry *grown = realloc(c.entries, (c.count + 1) * sizeof *grown);
            char *source = strdup(add->source ? add->source : "");
            if (!grown || !source || failed) {
                free(source);
                ms_metadata_free(metadata);
                if (grown)
                    c.entries = grown;
                st = ms_error_set(err, MS_ERR_NOMEM, "catalogue: out of memory");
            } else {
                c.entries = grown;
                c.entries[c.count] = *add;
                c.entries[c.count].source = source;
                c.entries[c.count].metadata = metadata;
                if (keep_crease) {
                    c.entries[c.count].has_crease_angle = true;
                    c.entries[c.count].crease_angle_deg = crease;
                }
                c.count++;
                qsort(c.entries, c.count, sizeof *c.entries, compare_entries);
            }
        }
        if (st == MS_OK)
            st = catalog_save(dir, &c, err);
        ms_catalog_free(&c);
    }
    unlock_catalog(lock);
    return st;
}

ms_status ms_catalog_update(const char *dir, const ms_catalog_entry *entry, ms_error *err)
{
    if (!ms_model_name_valid(entry->name))
        return ms_error_set(err, MS_ERR_ARG, "invalid model name '%s' (use 1-64 of A-Z a-z 0-9 _ -)",
                            entry->name);
    return catalog_change(dir, entry, NULL, err);
}

ms_status ms_catalog_remove(const char *dir, const char *name, ms_error *err)
{
    if (!ms_model_name_valid(name))
        return ms_error_set(err, MS_ERR_ARG, "invalid model name '%s'", name);
    return catalog_change(dir, NULL, name, err);
}
