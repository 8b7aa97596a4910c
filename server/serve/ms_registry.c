/* Model registry: see ms_registry.h. */
#include "ms_registry.h"

#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "ms_proto.h"
#include "ms_subtree.h"

void ms_model_ref(ms_model *m) { m->refs++; }

void ms_model_unref(ms_model *m)
{
    if (!m || --m->refs > 0)
        return;
    ms_archive_close(m->archive);
    free(m->index_zlib);
    free(m->payload_checks);
    free(m->file_path);
    free(m->entry.source);
    free(m);
}

ms_status ms_model_check_payload(ms_model *m, uint32_t cell, uint8_t stream, bool *first_report,
                                 ms_error *err)
{
    *first_report = false;
    const ms_archive_cell *c = ms_archive_get_cell(m->archive, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u does not exist", cell);
    bool apo = stream == MS_PROTO_STREAM_APO, colour = stream == MS_PROTO_STREAM_COLOUR;
    uint16_t checked = apo ? MS_PAYLOAD_APO_CHECKED : colour ? MS_PAYLOAD_COLOUR_CHECKED : MS_PAYLOAD_GEOMETRY_CHECKED;
    uint16_t bad = apo ? MS_PAYLOAD_APO_BAD : colour ? MS_PAYLOAD_COLOUR_BAD : MS_PAYLOAD_GEOMETRY_BAD;
    uint16_t gone = apo ? MS_PAYLOAD_APO_GONE : colour ? MS_PAYLOAD_COLOUR_GONE : MS_PAYLOAD_GEOMETRY_GONE;
    const char *what = apo ? "APO chunk" : colour ? "colour stream" : "geometry payload";
    uint16_t *state = &m->payload_checks[cell];
    /* Truncated in place? Then the mapping's pages past the end are gone. */
    uint64_t end = MS_ARCHIVE_HEADER_SIZE + ms_archive_get_header(m->archive)->index_stored_size +
                   (apo ? c->apo_offset + c->apo_length
                        : c->geometry_offset + c->geometry_length +
                              (colour ? ms_archive_colour_length(m->archive, cell) : 0));
    struct stat now;
    if (stat(m->file_path, &now) == 0 && (uint64_t)now.st_ino == m->file_inode &&
        (uint64_t)now.st_size < end) {
        *first_report = !(*state & gone);
        *state |= gone;
        return ms_error_set(err, MS_ERR_IO,
                            "cell %u: the archive file shrank to %llu bytes under the server; "
                            "the %s ended at %llu", cell, (unsigned long long)now.st_size,
                            what, (unsigned long long)end);
    }
    if (!(*state & checked)) {
        size_t length;
        const uint8_t *data = apo      ? ms_archive_apo(m->archive, cell, &length)
                              : colour ? ms_archive_colour(m->archive, cell, &length)
                                       : ms_archive_geometry(m->archive, cell, &length);
        ms_status st = colour ? ms_archive_check_colour(m->archive, cell, data, length, err)
                              : ms_archive_check_payload(m->archive, cell, apo, data, length, err);
        *state |= checked | (st != MS_OK ? bad : 0);
        *first_report = st != MS_OK;
        return st;
    }
    if (*state & bad)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: %s checksum mismatch", cell, what);
    return MS_OK;
}

struct ms_registry {
    char *dir;
    ms_model **models; /* sorted by name, each holding one reference */
    size_t count;
};

void ms_registry_free(ms_registry *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->count; ++i)
        ms_model_unref(r->models[i]);
    free(r->models);
    free(r->dir);
    free(r);
}

size_t ms_registry_count(const ms_registry *r) { return r->count; }

ms_model *ms_registry_model(const ms_registry *r, size_t i) { return r->models[i]; }

ms_model *ms_registry_find(const ms_registry *r, const char *name)
{
    if (!ms_model_name_valid(name))
        return NULL;
    size_t lo = 0, hi = r->count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        int c = strcmp(r->models[mid]->entry.name, name);
        if (c == 0)
            return r->models[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

static void warn_model(ms_registry_warn_fn warn, void *arg, const char *fmt, const char *name,
                       const char *detail)
{
    if (!warn)
        return;
    char line[MS_ERROR_TEXT_MAX + 128];
    snprintf(line, sizeof line, fmt, name, detail);
    warn(arg, line);
}

ms_status ms_model_open(const char *dir, const ms_catalog_entry *entry, ms_model **out,
                        ms_error *err)
{
    *out = NULL;
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.msa", dir, entry->name);
    struct stat st;
    if (stat(path, &st) != 0)
        return ms_error_set(err, MS_ERR_IO, "%s: archive file missing", path);
    ms_model *m = calloc(1, sizeof *m);
    if (!m)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    ms_status status = ms_archive_open(path, &m->archive, err);
    if (status != MS_OK) {
        free(m);
        return status;
    }
    m->entry = *entry;
    m->entry.source = strdup(entry->source ? entry->source : "");
    m->file_path = strdup(path);
    if (!m->entry.source || !m->file_path) {
        free(m->entry.source);
        free(m->file_path);
        ms_archive_close(m->archive);
        free(m);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    const ms_archive_header *h = ms_archive_get_header(m->archive);
    m->payload_checks = calloc(h->cell_count ? h->cell_count : 1, sizeof *m->payload_checks);
    if (!m->payload_checks) {
        ms_archive_close(m->archive);
        free(m->file_path);
        free(m->entry.source);
        free(m);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    if (m->entry.public_max_bits > h->bits)
        m->entry.public_max_bits = h->bits;
    for (uint32_t cell = 0; cell < h->cell_count; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(m->archive, cell);
        if (c->apo_levels > m->max_apo_levels)
            m->max_apo_levels = c->apo_levels;
    }
    size_t index_size;
    const uint8_t *index = ms_archive_index_bytes(m->archive, &index_size);
    m->index_crc32 = (uint32_t)crc32_z(0L, index, index_size);
    /* Not shrinking, or no memory: the blob simply goes out raw. */
    if (ms_proto_index_deflate(index, index_size, &m->index_zlib, &m->index_zlib_size, NULL) !=
        MS_OK)
        m->index_zlib = NULL, m->index_zlib_size = 0;
    m->index_head = ms_archive_index_head(m->archive, &m->index_head_size);
    if (m->index_head && m->index_head_size >= 1 && m->index_head_size <= MS_PROTO_MAX_INDEX_SIZE)
        m->index_head_crc32 = (uint32_t)crc32_z(0L, m->index_head, m->index_head_size);
    else
        m->index_head = NULL, m->index_head_size = 0;
    uint64_t hash = 1469598103934665603ull;
    for (size_t i = 0; i < index_size; ++i)
        hash = (hash ^ index[i]) * 1099511628211ull;
    m->content_id = hash;
    m->refs = 1;
    m->file_inode = (uint64_t)st.st_ino;
    m->file_size = (uint64_t)st.st_size;
    m->file_mtime_ns = (int64_t)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec;
    *out = m;
    return MS_OK;
}

/* True when the catalogue says the same of a model as when it was loaded: its
 * access rule (public_max_bits, clamped as loaded) and what /catalog shows. */
static bool entry_unchanged(const ms_model *m, const ms_catalog_entry *e)
{
    unsigned bits = ms_archive_get_header(m->archive)->bits;
    unsigned public_bits = e->public_max_bits > bits ? bits : e->public_max_bits;
    return m->entry.public_max_bits == public_bits && m->entry.vertices == e->vertices &&
           m->entry.triangles == e->triangles && m->entry.cells == e->cells &&
           m->entry.bits == e->bits && m->entry.apo == e->apo &&
           m->entry.archive_bytes == e->archive_bytes &&
           !strcmp(m->entry.baked_at, e->baked_at) &&
           !strcmp(m->entry.source, e->source ? e->source : "");
}

/* Opens (or reuses from previous) the archive of one catalogue entry. A model
 * is reused only when neither its file nor its catalogue entry changed, so a
 * rescan applies a new preview to every later request. */
static ms_model *load_model(const char *dir, const ms_catalog_entry *entry,
                            const ms_registry *previous, ms_registry_warn_fn warn, void *warn_arg)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.msa", dir, entry->name);
    struct stat st;
    if (stat(path, &st) != 0) {
        warn_model(warn, warn_arg, "model '%s' skipped: %s", entry->name, "archive file missing");
        return NULL;
    }
    int64_t mtime_ns = (int64_t)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec;
    ms_model *old = previous ? ms_registry_find(previous, entry->name) : NULL;
    if (old && old->file_inode == (uint64_t)st.st_ino && old->file_size == (uint64_t)st.st_size &&
        old->file_mtime_ns == mtime_ns && entry_unchanged(old, entry)) {
        ms_model_ref(old);
        return old;
    }
    ms_model *m;
    ms_error err;
    if (ms_model_open(dir, entry, &m, &err) != MS_OK) {
        if (old) { /* a broken replacement: the verified mapping goes on */
            warn_model(warn, warn_arg, "model '%s': keeping the version being served: %s",
                       entry->name, err.text);
            ms_model_ref(old);
            return old;
        }
        warn_model(warn, warn_arg, "model '%s' skipped: %s", entry->name, err.text);
        return NULL;
    }
    if (old) { /* the model's counters go on across versions */
        m->requests = old->requests;
        m->bytes_sent = old->bytes_sent;
    }
    return m;
}

ms_status ms_registry_scan(const char *dir, const ms_registry *previous, ms_registry **result,
                           ms_registry_warn_fn warn, void *warn_arg, ms_error *err)
{
    *result = NULL;
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return ms_error_set(err, MS_ERR_IO, "%s: not a directory", dir);
    ms_catalog catalog;
    ms_status status = ms_catalog_load(dir, &catalog, err);
    if (status != MS_OK)
        return status;
    ms_registry *out = calloc(1, sizeof *out);
    if (out) {
        out->dir = strdup(dir);
        out->models = calloc(catalog.count ? catalog.count : 1, sizeof *out->models);
    }
    if (!out || !out->dir || !out->models) {
        ms_catalog_free(&catalog);
        ms_registry_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", dir);
    }
    /* The catalogue is sorted by name, so the registry is too. */
    for (size_t i = 0; i < catalog.count; ++i) {
        ms_model *m = load_model(dir, &catalog.entries[i], previous, warn, warn_arg);
        if (m)
            out->models[out->count++] = m;
    }
    ms_catalog_free(&catalog);
    *result = out;
    return MS_OK;
}
