/* Page files deflated once (see ms_page_cache.h). */
#include "ms_page_cache.h"

#include <event2/buffer.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>

/* A handful of files: the pages, their scripts, the two modules. */
#define PAGE_CACHE_ENTRIES 32

typedef struct page_entry {
    char *path;             /* NULL: a free slot */
    dev_t dev;
    ino_t ino;
    off_t size;
    struct timespec mtime;
    uint8_t *bytes;         /* NULL with length 0: the file would not shrink */
    size_t length;
    uint64_t stamp;         /* when it was stored: the oldest goes first */
} page_entry;

struct ms_page_cache {
    size_t max_bytes, held;
    uint64_t clock, hits, deflated;
    page_entry entries[PAGE_CACHE_ENTRIES];
};

ms_page_cache *ms_page_cache_new(size_t max_bytes)
{
    ms_page_cache *c = calloc(1, sizeof *c);
    if (c)
        c->max_bytes = max_bytes;
    return c;
}

static void entry_clear(ms_page_cache *c, page_entry *e)
{
    c->held -= e->length;
    free(e->path);
    free(e->bytes);
    memset(e, 0, sizeof *e);
}

void ms_page_cache_free(ms_page_cache *c)
{
    if (!c)
        return;
    for (size_t i = 0; i < PAGE_CACHE_ENTRIES; ++i)
        entry_clear(c, &c->entries[i]);
    free(c);
}

void ms_page_cache_counts(const ms_page_cache *c, uint64_t *hits, uint64_t *deflated)
{
    *hits = c->hits;
    *deflated = c->deflated;
}

static bool same_file(const page_entry *e, const char *path, const struct stat *st)
{
    return e->path && !strcmp(e->path, path) && e->dev == st->st_dev && e->ino == st->st_ino &&
           e->size == st->st_size && e->mtime.tv_sec == st->st_mtim.tv_sec &&
           e->mtime.tv_nsec == st->st_mtim.tv_nsec;
}

/* The file's bytes deflated into a new allocation (*packed, *packed_length;
 * *packed NULL when it would not shrink); false when it cannot be read or
 * there is no memory. */
static bool deflate_file(FILE *f, size_t size, uint8_t **packed, size_t *packed_length)
{
    *packed = NULL;
    *packed_length = 0;
    uLongf capacity = compressBound((uLong)size);
    uint8_t *raw = malloc(size), *out = malloc(capacity);
    bool ok = raw && out && fread(raw, 1, size, f) == size;
    if (ok && compress2(out, &capacity, raw, (uLong)size, 6) == Z_OK && capacity < size) {
        uint8_t *fitted = realloc(out, capacity);
        *packed = fitted ? fitted : out;
        *packed_length = capacity;
        out = NULL;
    }
    free(raw);
    free(out);
    return ok;
}

/* Keeps a copy of what path deflated to, the oldest entries making room. */
static void store(ms_page_cache *c, const char *path, const struct stat *st, const uint8_t *packed,
                  size_t length)
{
    if (length > c->max_bytes)
        return;
    page_entry *slot = NULL;
    for (size_t i = 0; i < PAGE_CACHE_ENTRIES; ++i)
        if (c->entries[i].path && !strcmp(c->entries[i].path, path))
            entry_clear(c, &c->entries[i]); /* its former contents */
    for (;;) {
        page_entry *oldest = NULL;
        slot = NULL;
        for (size_t i = 0; i < PAGE_CACHE_ENTRIES; ++i) {
            page_entry *e = &c->entries[i];
            if (!e->path)
                slot = slot ? slot : e;
            else if (!oldest || e->stamp < oldest->stamp)
                oldest = e;
        }
        if (slot && c->held + length <= c->max_bytes)
            break;
        if (!oldest)
            return;
        entry_clear(c, oldest);
    }
    page_entry e = {.path = strdup(path), .dev = st->st_dev, .ino = st->st_ino, .size = st->st_size,
                    .mtime = st->st_mtim, .length = length, .stamp = ++c->clock};
    if (length) {
        e.bytes = malloc(length);
        if (e.bytes)
            memcpy(e.bytes, packed, length);
    }
    if (!e.path || (length && !e.bytes)) {
        free(e.path);
        free(e.bytes);
        return;
    }
    *slot = e;
    c->held += length;
}

static struct evbuffer *buffer_of(const uint8_t *bytes, size_t length, uint64_t *out_length)
{
    struct evbuffer *body = evbuffer_new();
    if (body && evbuffer_add(body, bytes, length) != 0) {
        evbuffer_free(body);
        return NULL;
    }
    if (body)
        *out_length = length;
    return body;
}

struct evbuffer *ms_page_cache_deflated(ms_page_cache *c, const char *path, uint64_t *length)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    struct stat st;
    struct evbuffer *body = NULL;
    if (fstat(fileno(f), &st) != 0 || !S_ISREG(st.st_mode) || st.st_size <= 0 ||
        (uint64_t)st.st_size > MS_PAGE_CACHE_FILE_MAX)
        goto done;
    for (size_t i = 0; i < PAGE_CACHE_ENTRIES; ++i) {
        const page_entry *e = &c->entries[i];
        if (same_file(e, path, &st)) {
            c->hits++;
            body = e->bytes ? buffer_of(e->bytes, e->length, length) : NULL;
            goto done;
        }
    }
    uint8_t *packed;
    size_t packed_length;
    if (deflate_file(f, (size_t)st.st_size, &packed, &packed_length)) {
        c->deflated++;
        store(c, path, &st, packed, packed_length);
        if (packed)
            body = buffer_of(packed, packed_length, length);
        free(packed);
    }
done:
    fclose(f);
    return body;
}
