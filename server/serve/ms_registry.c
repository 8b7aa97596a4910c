/* Model registry: see ms_registry.h. */
#include "ms_registry.h"

#include <stdbool.h>
#if defined(__GLIBC__)
#include <malloc.h>
#endif
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

#include "ms_progress.h"
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
    /* Truncated in place? Then the mapping's pages past the end are gone.
     * fstat of the mapped file: no path lookup for every payload served. */
    uint64_t end = MS_ARCHIVE_HEADER_SIZE + ms_archive_get_header(m->archive)->index_stored_size +
                   (apo ? c->apo_offset + c->apo_length
                        : c->geometry_offset + c->geometry_length +
                              (colour ? ms_archive_colour_length(m->archive, cell) : 0));
    struct stat now;
    if (ms_archive_file_stat(m->archive, &now, NULL) == MS_OK && (uint64_t)now.st_size < end) {
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


/* One catalogue entry and, once asked for, its open model. */
typedef struct registry_slot {
    ms_catalog_entry *entry;  /* in the registry's catalogue; public_max_bits clamped to bits */
    ms_model *model;          /* the open model (one reference), or NULL */
    uint64_t file_inode, file_size;
    int64_t file_mtime_ns;    /* the file as the scan found it */
    bool broken;              /* its file did not open: not tried again until it changes */
    /* the open slots, most recently used first (indices; NO_SLOT ends) */
    size_t newer, older;
    double last_use;          /* ms_now_seconds at its last find (or open) */
    uint64_t requests, bytes_sent; /* the counters of its closed versions */
} registry_slot;

struct ms_registry {
    char *dir;
    ms_catalog catalog;   /* the scan's catalogue: the slots' entries, and the next
                           * scan's reference for what did not change */
    registry_slot *slots; /* sorted by name */
    size_t count;
    size_t open_count, max_open;
    size_t newest, oldest;  /* the open slots' use list (NO_SLOT: empty) */
    ms_registry_warn_fn warn;
    void *warn_arg;
};

#define NO_SLOT SIZE_MAX

static size_t slot_index(const ms_registry *r, const registry_slot *slot)
{
    return (size_t)(slot - r->slots);
}

static void use_list_remove(ms_registry *r, registry_slot *slot)
{
    if (slot->newer != NO_SLOT)
        r->slots[slot->newer].older = slot->older;
    else
        r->newest = slot->older;
    if (slot->older != NO_SLOT)
        r->slots[slot->older].newer = slot->newer;
    else
        r->oldest = slot->newer;
    slot->newer = slot->older = NO_SLOT;
}

static void use_list_push_newest(ms_registry *r, registry_slot *slot)
{
    size_t i = slot_index(r, slot);
    slot->older = r->newest;
    slot->newer = NO_SLOT;
    if (r->newest != NO_SLOT)
        r->slots[r->newest].newer = i;
    else
        r->oldest = i;
    r->newest = i;
}

/* A slot whose model was just opened or reused: newest in the use list. */
static void slot_opened(ms_registry *r, registry_slot *slot, ms_model *model)
{
    slot->model = model;
    r->open_count++;
    use_list_push_newest(r, slot);
}

/* Closes a slot's model: the registry's reference goes, the counters stay. */
static void slot_close(ms_registry *r, registry_slot *slot)
{
    if (!slot->model)
        return;
    slot->requests = slot->model->requests;
    slot->bytes_sent = slot->model->bytes_sent;
    ms_model_unref(slot->model);
    slot->model = NULL;
    r->open_count--;
    use_list_remove(r, slot);
}

void ms_registry_free(ms_registry *r)
{
    if (!r)
        return;
    for (size_t i = 0; i < r->count; ++i) {
        ms_model_unref(r->slots[i].model);
    }
    free(r->slots);
    ms_catalog_free(&r->catalog);
    free(r->dir);
    free(r);
}

size_t ms_registry_count(const ms_registry *r) { return r->count; }

size_t ms_registry_open_count(const ms_registry *r) { return r->open_count; }

const ms_catalog_entry *ms_registry_entry(const ms_registry *r, size_t i)
{
    return r->slots[i].entry;
}

ms_model *ms_registry_open_model_at(const ms_registry *r, size_t i) { return r->slots[i].model; }

static registry_slot *find_slot(const ms_registry *r, const char *name)
{
    if (!ms_model_name_valid(name))
        return NULL;
    size_t lo = 0, hi = r->count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        int c = strcmp(r->slots[mid].entry->name, name);
        if (c == 0)
            return &r->slots[mid];
        if (c < 0)
            lo = mid + 1;
        else
            hi = mid;
    }
    return NULL;
}

const ms_catalog_entry *ms_registry_entry_named(const ms_registry *r, const char *name)
{
    registry_slot *slot = find_slot(r, name);
    return slot ? slot->entry : NULL;
}

ms_model *ms_registry_peek(const ms_registry *r, const char *name)
{
    registry_slot *slot = find_slot(r, name);
    return slot ? slot->model : NULL;
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
    m->entry.metadata = NULL; /* the catalogue's, not the model's: /catalog shows it */
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
    m->max_apo_levels = ms_archive_max_apo_levels(m->archive);
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
    m->content_id = ms_archive_content_id(m->archive);
    m->refs = 1;
    /* the file mapped, which a rename since the stat above may have replaced */
    (void)ms_archive_file_stat(m->archive, &st, NULL);
    m->file_inode = (uint64_t)st.st_ino;
    m->file_size = (uint64_t)st.st_size;
    m->file_mtime_ns = (int64_t)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec;
    *out = m;
    return MS_OK;
}


/* Closes, least recently used first, models only the registry holds, until at
 * most keep are open; never the slot spared (the one just opened). */
static void close_over_limit(ms_registry *r, size_t keep, const registry_slot *spared)
{
    size_t i = r->oldest;
    while (r->open_count > keep && i != NO_SLOT) {
        registry_slot *slot = &r->slots[i];
        i = slot->newer;
        if (slot->model->refs == 1 && slot != spared)
            slot_close(r, slot);
    }
}

/* Opens a slot's archive (its first request since the scan or since it was
 * closed). A file that does not open marks the slot broken, so that it is not
 * tried again until a rescan finds it changed; err says why. */
static ms_model *slot_open(ms_registry *r, registry_slot *slot, ms_error *err)
{
    ms_model *m;
    if (ms_model_open(r->dir, slot->entry, &m, err) != MS_OK) {
        slot->broken = true;
        return NULL;
    }
    /* Replaced since the scan (a bake without SIGHUP yet): the file there now
     * is what is served, under the entry the scan read. */
    slot->file_inode = m->file_inode;
    slot->file_size = m->file_size;
    slot->file_mtime_ns = m->file_mtime_ns;
    m->requests = slot->requests;
    m->bytes_sent = slot->bytes_sent;
    slot_opened(r, slot, m);
    close_over_limit(r, r->max_open, slot);
    return m;
}

ms_model *ms_registry_find(ms_registry *r, const char *name)
{
    registry_slot *slot = find_slot(r, name);
    if (!slot)
        return NULL;
    slot->last_use = ms_now_seconds();
    if (slot->model) {
        use_list_remove(r, slot);
        use_list_push_newest(r, slot);
        return slot->model;
    }
    if (slot->broken)
        return NULL;
    ms_error err;
    ms_model *m = slot_open(r, slot, &err);
    if (!m) /* once: the slot is broken now */
        warn_model(r->warn, r->warn_arg, "model '%s' cannot be served: %s", slot->entry->name,
                   err.text);
    return m;
}

void ms_registry_close_idle(ms_registry *r, double now, double idle_s)
{
    size_t i = r->oldest;
    while (i != NO_SLOT && r->slots[i].last_use <= now - idle_s) {
        registry_slot *slot = &r->slots[i];
        i = slot->newer;
        if (slot->model->refs == 1)
            slot_close(r, slot);
    }
}

/* True when the catalogue says the same of a model as when it was loaded: its
 * access rule (public_max_bits, clamped) and what /catalog shows. */
static bool entry_unchanged(const ms_catalog_entry *was, const ms_catalog_entry *e)
{
    unsigned public_bits = e->public_max_bits > e->bits ? e->bits : e->public_max_bits;
    return was->public_max_bits == public_bits && was->vertices == e->vertices &&
           was->triangles == e->triangles && was->cells == e->cells && was->bits == e->bits &&
           was->apo == e->apo && was->archive_bytes == e->archive_bytes &&
           !strcmp(was->baked_at, e->baked_at) &&
           !strcmp(was->source ? was->source : "", e->source ? e->source : "");
}

/* Fills a slot for one catalogue entry: its file's identity, and from the
 * previous registry what still holds. A model open there is kept when neither
 * its file nor its entry changed; when its file changed it is opened again now
 * (work in proportion to what changed), and a broken replacement keeps the
 * verified version being served. Every other model opens on first request.
 * False when the file is missing (warned). */
static bool slot_fill(ms_registry *r, registry_slot *slot, ms_catalog_entry *entry,
                      const ms_registry *previous)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.msa", r->dir, entry->name);
    struct stat st;
    if (stat(path, &st) != 0) {
        warn_model(r->warn, r->warn_arg, "model '%s' skipped: %s", entry->name,
                   "archive file missing");
        return false;
    }
    slot->newer = slot->older = NO_SLOT;
    slot->entry = entry;
    slot->file_inode = (uint64_t)st.st_ino;
    slot->file_size = (uint64_t)st.st_size;
    slot->file_mtime_ns = (int64_t)st.st_mtim.tv_sec * 1000000000 + st.st_mtim.tv_nsec;
    const registry_slot *old = previous ? find_slot(previous, entry->name) : NULL;
    if (!old)
        return true;
    bool same_file = old->file_inode == slot->file_inode && old->file_size == slot->file_size &&
                     old->file_mtime_ns == slot->file_mtime_ns;
    slot->requests = old->model ? old->model->requests : old->requests;
    slot->bytes_sent = old->model ? old->model->bytes_sent : old->bytes_sent;
    slot->last_use = old->last_use;
    if (same_file)
        slot->broken = old->broken;
    if (!old->model)
        return true;
    if (same_file && entry_unchanged(old->entry, entry)) {
        ms_model_ref(old->model);
        slot_opened(r, slot, old->model);
        return true;
    }
    ms_error err;
    if (slot_open(r, slot, &err))
        return true;
    /* A broken replacement: the verified mapping goes on. */
    warn_model(r->warn, r->warn_arg, "model '%s': keeping the version being served: %s",
               entry->name, err.text);
    slot->broken = false;
    ms_model_ref(old->model);
    slot_opened(r, slot, old->model);
    return true;
}

typedef struct use_order {
    double last_use;
    size_t slot;
} use_order;

static int compare_use(const void *a, const void *b)
{
    const use_order *x = a, *y = b;
    if (x->last_use != y->last_use)
        return x->last_use < y->last_use ? -1 : 1;
    return (x->slot > y->slot) - (x->slot < y->slot);
}

/* The open slots' use list in the order of their last use (a scan links the
 * models it keeps in name order), so that idleness and the limit close the
 * least recently used first across rescans. */
static void use_list_by_last_use(ms_registry *r)
{
    use_order *open = malloc((r->open_count ? r->open_count : 1) * sizeof *open);
    size_t n = 0;
    if (!open)
        return; /* the name order stays: only the closing order differs */
    for (size_t i = r->oldest; i != NO_SLOT && n < r->open_count; i = r->slots[i].newer)
        open[n++] = (use_order){r->slots[i].last_use, i};
    qsort(open, n, sizeof *open, compare_use);
    r->newest = r->oldest = NO_SLOT;
    for (size_t k = 0; k < n; ++k) {
        registry_slot *slot = &r->slots[open[k].slot];
        slot->newer = slot->older = NO_SLOT;
        use_list_push_newest(r, slot);
    }
    free(open);
}

ms_status ms_registry_scan(const char *dir, const ms_registry *previous, size_t max_open,
                           ms_registry **result, ms_registry_warn_fn warn, void *warn_arg,
                           ms_error *err)
{
    *result = NULL;
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return ms_error_set(err, MS_ERR_IO, "%s: not a directory", dir);
    ms_registry *out = calloc(1, sizeof *out);
    if (!out || !(out->dir = strdup(dir))) {
        free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", dir);
    }
    /* Only the entries whose text changed since the previous scan are parsed
     * again: a reload after one bake costs one entry's parse. */
    ms_status status =
        ms_catalog_reload(dir, previous ? &previous->catalog : NULL, &out->catalog, err);
    out->slots = calloc(out->catalog.count ? out->catalog.count : 1, sizeof *out->slots);
    out->max_open = max_open ? max_open : 1;
    out->warn = warn;
    out->warn_arg = warn_arg;
    out->newest = out->oldest = NO_SLOT;
    if (status == MS_OK && !out->slots)
        status = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", dir);
    if (status != MS_OK) {
        ms_registry_free(out);
        return status;
    }
    /* The catalogue is sorted by name, so the registry is too. */
    for (size_t i = 0; i < out->catalog.count; ++i) {
        ms_catalog_entry *entry = &out->catalog.entries[i];
        if (entry->public_max_bits > entry->bits)
            entry->public_max_bits = entry->bits;
        registry_slot *slot = &out->slots[out->count];
        if (slot_fill(out, slot, entry, previous))
            out->count++;
        else
            memset(slot, 0, sizeof *slot);
    }
#if defined(__GLIBC__)
    /* The catalogue's transient text and JSON (megabytes at 10,000 models)
     * were freed: give the pages back rather than hold them as idle heap. */
    malloc_trim(0);
#endif
    use_list_by_last_use(out);
    close_over_limit(out, out->max_open, NULL);
    *result = out;
    return MS_OK;
}
