/* The key file's page cache: see ms_nsp_key_cache.h. */
#include "ms_nsp_key_cache.h"

#include <errno.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define WAYS 8 /* pages a set holds (at least 3: ms_nsp_key_cache_triangle) */
_Static_assert(WAYS >= 3, "a triangle's three pages must fit in a set");

struct ms_nsp_key_cache {
    int fd;
    uint64_t vertex_count;
    size_t sets, slots;  /* slots = WAYS * sets */
    uint64_t *keys;      /* slots * MS_NSP_KEY_PAGE_KEYS */
    int64_t *page_of;    /* page held by each slot, -1 for none */
    uint64_t *used_at;   /* tick of the slot's last use (least recent goes first) */
    bool *dirty;         /* the slot's marks are not on disk yet */
    uint64_t tick;
    size_t last_slot;    /* the slot of the last lookup (a triangle's corners share pages) */
    ms_nsp_io *io;
    uint64_t *page_misses;
};

ms_status ms_nsp_key_cache_new(int fd, uint64_t vertex_count, size_t bytes, ms_nsp_io *io,
                               uint64_t *page_misses, ms_nsp_key_cache **out, ms_error *err)
{
    *out = NULL;
    ms_nsp_key_cache *c = calloc(1, sizeof *c);
    if (!c)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the key cache");
    c->fd = fd;
    c->vertex_count = vertex_count;
    c->io = io;
    c->page_misses = page_misses;
    if (bytes < MS_NSP_KEY_CACHE_MIN)
        bytes = MS_NSP_KEY_CACHE_MIN;
    uint64_t pages = (vertex_count + MS_NSP_KEY_PAGE_KEYS - 1) / MS_NSP_KEY_PAGE_KEYS;
    c->sets = bytes / (WAYS * MS_NSP_KEY_PAGE_KEYS * sizeof *c->keys);
    if (c->sets > pages / WAYS + 1)
        c->sets = (size_t)(pages / WAYS + 1); /* a small model fits whole */
    c->slots = WAYS * c->sets;
    c->keys = malloc(c->slots * MS_NSP_KEY_PAGE_KEYS * sizeof *c->keys);
    c->page_of = malloc(c->slots * sizeof *c->page_of);
    c->used_at = calloc(c->slots, sizeof *c->used_at);
    c->dirty = calloc(c->slots, sizeof *c->dirty);
    if (!c->keys || !c->page_of || !c->used_at || !c->dirty) {
        ms_nsp_key_cache_free(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the key cache");
    }
    for (size_t i = 0; i < c->slots; ++i)
        c->page_of[i] = -1;
    *out = c;
    return MS_OK;
}

static size_t page_keys(const ms_nsp_key_cache *c, uint64_t page)
{
    uint64_t left = c->vertex_count - page * MS_NSP_KEY_PAGE_KEYS;
    return left < MS_NSP_KEY_PAGE_KEYS ? (size_t)left : MS_NSP_KEY_PAGE_KEYS;
}

static off_t page_offset(uint64_t page)
{
    return (off_t)(page * MS_NSP_KEY_PAGE_KEYS * sizeof(uint64_t));
}

static ms_status write_back_slot(ms_nsp_key_cache *c, size_t slot, ms_error *err)
{
    if (!c->dirty[slot])
        return MS_OK;
    uint64_t page = (uint64_t)c->page_of[slot];
    size_t bytes = page_keys(c, page) * sizeof *c->keys;
    if (pwrite(c->fd, c->keys + slot * MS_NSP_KEY_PAGE_KEYS, bytes, page_offset(page)) !=
        (ssize_t)bytes)
        return ms_error_set(err, MS_ERR_IO, "cannot write the key file: %s", strerror(errno));
    c->dirty[slot] = false;
    c->io->spilled += bytes;
    return MS_OK;
}

/* Vertex v's entry (key and mark), valid until the next call; *slot_out its slot.
 * A page goes to the set its hashed number picks (so that strided access, as a
 * column of a grid walks, spreads over the sets), in the way least recently
 * used. */
static ms_status entry(ms_nsp_key_cache *c, uint64_t v, uint64_t **out, size_t *slot_out,
                       ms_error *err)
{
    uint64_t page = v / MS_NSP_KEY_PAGE_KEYS;
    /* A page lives in one slot only: finding it where the last lookup was is
     * what the search of its set would find. */
    size_t slot = c->last_slot;
    if (c->page_of[slot] != (int64_t)page) {
        size_t first = (size_t)((page * UINT64_C(0x9E3779B97F4A7C15)) >> 17) % c->sets * WAYS;
        slot = first;
        for (size_t w = 0; w < WAYS; ++w) {
            if (c->page_of[first + w] == (int64_t)page) {
                slot = first + w;
                break;
            }
            if (c->used_at[first + w] < c->used_at[slot])
                slot = first + w;
        }
    }
    uint64_t *keys = c->keys + slot * MS_NSP_KEY_PAGE_KEYS;
    if (c->page_of[slot] != (int64_t)page) {
        ms_status s = c->page_of[slot] >= 0 ? write_back_slot(c, slot, err) : MS_OK;
        if (s != MS_OK)
            return s;
        size_t bytes = page_keys(c, page) * sizeof *keys;
        if (pread(c->fd, keys, bytes, page_offset(page)) != (ssize_t)bytes)
            return ms_error_set(err, MS_ERR_IO, "cannot read the key file: %s", strerror(errno));
        c->page_of[slot] = (int64_t)page;
        c->io->read_back += bytes;
        (*c->page_misses)++;
    }
    c->used_at[slot] = ++c->tick;
    c->last_slot = slot;
    *out = &keys[v % MS_NSP_KEY_PAGE_KEYS];
    *slot_out = slot;
    return MS_OK;
}

ms_status ms_nsp_key_cache_triangle(ms_nsp_key_cache *c, const uint32_t v[3], uint64_t keys[3],
                                    ms_error *err)
{
    uint64_t *e[3];
    size_t slot[3];
    for (int j = 0; j < 3; ++j) {
        ms_status s = entry(c, v[j], &e[j], &slot[j], err);
        if (s != MS_OK)
            return s;
        keys[j] = *e[j] & ~MS_NSP_KEY_USED;
    }
    if (keys[0] == keys[1] || keys[1] == keys[2] || keys[0] == keys[2])
        return MS_OK;
    /* The three entries are still in place: a lookup takes its set's least
     * recently used slot, never one of the two just used (WAYS >= 3). Each mark
     * counts as a use, in order, as three more lookups would: the cache evicts
     * what it evicted when the marks were looked up again. */
    for (int j = 0; j < 3; ++j) {
        c->used_at[slot[j]] = ++c->tick;
        c->last_slot = slot[j];
        if (!(*e[j] & MS_NSP_KEY_USED)) {
            *e[j] |= MS_NSP_KEY_USED;
            c->dirty[slot[j]] = true;
        }
    }
    return MS_OK;
}

ms_status ms_nsp_key_cache_write_back(ms_nsp_key_cache *c, ms_error *err)
{
    ms_status s = MS_OK;
    for (size_t slot = 0; slot < c->slots && s == MS_OK; ++slot)
        if (c->page_of[slot] >= 0)
            s = write_back_slot(c, slot, err);
    return s;
}

void ms_nsp_key_cache_free(ms_nsp_key_cache *c)
{
    if (!c)
        return;
    free(c->keys);
    free(c->page_of);
    free(c->used_at);
    free(c->dirty);
    free(c);
}
