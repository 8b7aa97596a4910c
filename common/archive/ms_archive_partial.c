/* A client's partial index (ms_subtree.h): the subtrees held, each with its
 * decoded records and table words, and a hash map from cell id to its record,
 * so that memory follows the subtrees held, never the model's cell count. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive_internal.h"
#include "ms_subtree.h"
#include "ms_subtree_read.h"

typedef struct held_subtree {
    uint32_t id, count, table_words;
    uint32_t *ids;          /* member cell ids, ascending */
    ms_archive_cell *cells; /* their records; table_first is the subtree's own */
    uint8_t *tables;        /* table words, little-endian */
    size_t raw_size;        /* of the blob: what the budget counts */
} held_subtree;

/* Open addressing with linear probing; key MS_ARCHIVE_NONE marks a free slot
 * (cell ids stay below 2^24). */
typedef struct map_slot {
    uint32_t key;
    uint32_t member; /* index in the subtree (cell map) */
    held_subtree *subtree;
} map_slot;

typedef struct cell_map {
    map_slot *slots;
    size_t capacity; /* a power of two, or 0 */
    size_t count;
} cell_map;

struct ms_partial_index {
    unsigned levels;
    uint32_t subtree_count; /* of the model, from the head */
    cell_map cells;         /* cell id -> (subtree, member) */
    cell_map subtrees;      /* subtree id -> subtree */
    size_t bytes_held;
};

static size_t slot_of(uint32_t key, size_t capacity)
{
    return (size_t)((key * 2654435761u) & (capacity - 1));
}

static const map_slot *map_find(const cell_map *m, uint32_t key)
{
    if (!m->capacity)
        return NULL;
    for (size_t i = slot_of(key, m->capacity);; i = (i + 1) & (m->capacity - 1)) {
        if (m->slots[i].key == key)
            return &m->slots[i];
        if (m->slots[i].key == MS_ARCHIVE_NONE)
            return NULL;
    }
}

static void map_put_slot(map_slot *slots, size_t capacity, map_slot s)
{
    size_t i = slot_of(s.key, capacity);
    while (slots[i].key != MS_ARCHIVE_NONE)
        i = (i + 1) & (capacity - 1);
    slots[i] = s;
}

static bool map_resize(cell_map *m, size_t capacity)
{
    map_slot *slots = malloc(capacity * sizeof *slots);
    if (!slots)
        return false;
    for (size_t i = 0; i < capacity; ++i)
        slots[i].key = MS_ARCHIVE_NONE;
    for (size_t i = 0; i < m->capacity; ++i)
        if (m->slots[i].key != MS_ARCHIVE_NONE)
            map_put_slot(slots, capacity, m->slots[i]);
    free(m->slots);
    m->slots = slots;
    m->capacity = capacity;
    return true;
}

/* Room for `more` keys at a load of at most one half. */
static bool map_reserve(cell_map *m, size_t more)
{
    size_t capacity = m->capacity ? m->capacity : 16;
    while (2 * (m->count + more) > capacity)
        capacity *= 2;
    return capacity == m->capacity || map_resize(m, capacity);
}

static void map_put(cell_map *m, uint32_t key, uint32_t member, held_subtree *subtree)
{
    map_put_slot(m->slots, m->capacity, (map_slot){key, member, subtree});
    m->count++;
}

/* Removes key (backward-shift deletion, so no tombstones), and shrinks the
 * table when it is mostly empty. */
static void map_remove(cell_map *m, uint32_t key)
{
    map_slot *found = (map_slot *)map_find(m, key);
    if (!found)
        return;
    size_t mask = m->capacity - 1, hole = (size_t)(found - m->slots);
    for (size_t i = (hole + 1) & mask; m->slots[i].key != MS_ARCHIVE_NONE; i = (i + 1) & mask) {
        size_t home = slot_of(m->slots[i].key, m->capacity);
        /* Move it into the hole unless its home lies cyclically in (hole, i]. */
        bool stays = hole <= i ? (hole < home && home <= i) : (hole < home || home <= i);
        if (!stays) {
            m->slots[hole] = m->slots[i];
            hole = i;
        }
    }
    m->slots[hole].key = MS_ARCHIVE_NONE;
    m->count--;
    if (m->capacity > 64 && 8 * m->count < m->capacity)
        map_resize(m, m->capacity / 2); /* on failure it simply stays larger */
}

static void held_free(held_subtree *s)
{
    if (!s)
        return;
    free(s->ids);
    free(s->cells);
    free(s->tables);
    free(s);
}

void ms_partial_free(ms_partial_index *p)
{
    if (!p)
        return;
    for (size_t i = 0; i < p->subtrees.capacity; ++i)
        if (p->subtrees.slots[i].key != MS_ARCHIVE_NONE)
            held_free(p->subtrees.slots[i].subtree);
    free(p->subtrees.slots);
    free(p->cells.slots);
    free(p);
}

const ms_archive_cell *ms_partial_get_cell(const ms_archive *a, uint32_t cell,
                                           const uint8_t **tables)
{
    const map_slot *s = map_find(&a->partial->cells, cell);
    if (tables)
        *tables = s ? s->subtree->tables : NULL;
    return s ? &s->subtree->cells[s->member] : NULL;
}

static const ms_archive_cell *held_lookup(const void *context, uint32_t cell)
{
    const ms_archive *a = context;
    return cell < a->header.cell_count ? ms_partial_get_cell(a, cell, NULL) : NULL;
}

ms_status ms_archive_add_subtree(ms_archive *a, uint32_t id, const uint8_t *stored,
                                 size_t stored_size, ms_error *err)
{
    ms_partial_index *p = a->partial;
    if (!p)
        return ms_error_set(err, MS_ERR_ARG, "subtree %u: the archive is whole, not partial", id);
    if (map_find(&p->subtrees, id))
        return MS_OK;
    char where[96];
    snprintf(where, sizeof where, "subtree %u", id);
    if (id >= a->header.cell_count)
        return ms_error_set(err, MS_ERR_RANGE, "%s: beyond the %u cells", where,
                            a->header.cell_count);
    if (id != 0 && !p->subtrees.count)
        return ms_error_set(err, MS_ERR_RANGE, "%s: the root subtree is not held", where);
    ms_subtree_blob blob;
    ms_status st = ms_subtree_blob_read(where, &a->header, p->levels, id, stored, stored_size,
                                        &blob, err);
    if (st != MS_OK)
        return st;
    held_subtree *s = calloc(1, sizeof *s);
    if (s) {
        s->ids = malloc(blob.count * sizeof *s->ids);
        s->cells = malloc(blob.count * sizeof *s->cells);
        s->tables = malloc(4 * (size_t)blob.table_words + 1);
    }
    if (!s || !s->ids || !s->cells || !s->tables)
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    if (st == MS_OK)
        st = ms_subtree_blob_check(where, &a->header, p->levels, a->payload_size, &blob,
                                   held_lookup, a, s->cells, err);
    for (uint32_t i = 0; st == MS_OK && i < blob.count; ++i) {
        s->ids[i] = ms_get_u32(blob.ids + 4 * (size_t)i);
        /* A lying ancestor could make two subtrees claim one id: refuse. */
        if (map_find(&p->cells, s->ids[i]))
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u is already held", where,
                              s->ids[i]);
    }
    if (st == MS_OK && (!map_reserve(&p->cells, blob.count) || !map_reserve(&p->subtrees, 1)))
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    if (st != MS_OK) {
        held_free(s);
        ms_subtree_blob_free(&blob);
        return st;
    }
    s->id = id;
    s->count = blob.count;
    s->table_words = blob.table_words;
    s->raw_size = blob.raw_size;
    memcpy(s->tables, blob.tables, 4 * (size_t)blob.table_words);
    for (uint32_t i = 0; i < blob.count; ++i)
        map_put(&p->cells, s->ids[i], i, s);
    map_put(&p->subtrees, id, 0, s);
    p->bytes_held += s->raw_size;
    ms_subtree_blob_free(&blob);
    return MS_OK;
}

void ms_archive_drop_subtree(ms_archive *a, uint32_t id)
{
    ms_partial_index *p = a->partial;
    const map_slot *found = p && id != 0 ? map_find(&p->subtrees, id) : NULL;
    if (!found)
        return;
    held_subtree *s = found->subtree;
    /* Subtrees below first: they hang off members that end a band. */
    for (uint32_t i = 0; i < s->count; ++i) {
        const ms_archive_cell *c = &s->cells[i];
        if (c->first_child != MS_ARCHIVE_NONE && (c->level + 1u) % p->levels == 0)
            ms_archive_drop_subtree(a, c->first_child);
    }
    for (uint32_t i = 0; i < s->count; ++i)
        map_remove(&p->cells, s->ids[i]);
    map_remove(&p->subtrees, id);
    p->bytes_held -= s->raw_size;
    held_free(s);
}

ms_status ms_archive_open_head(const uint8_t *head, size_t size, const char *name,
                               ms_archive **out, ms_error *err)
{
    *out = NULL;
    ms_archive_header h;
    ms_archive_sections sec;
    ms_status st = ms_archive_parse_header(name, head, size, MS_HEADER_HEAD, &h, &sec, err);
    if (st != MS_OK)
        return st;
    ms_archive *a = calloc(1, sizeof *a);
    ms_partial_index *p = calloc(1, sizeof *p);
    if (!a || !p) {
        free(a);
        free(p);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", name);
    }
    a->index_only = true;
    a->header = h;
    a->index_size = sec.index_size;
    a->payload_size = sec.payload_size;
    a->subtree_levels = sec.subtree_levels;
    a->subtree_count = sec.subtree_count;
    a->partial = p;
    p->levels = sec.subtree_levels;
    p->subtree_count = sec.subtree_count;
    atomic_init(&a->head_cache, NULL);
    st = ms_archive_add_subtree(a, 0, head + MS_ARCHIVE_HEADER_SIZE, size - MS_ARCHIVE_HEADER_SIZE,
                                err);
    if (st != MS_OK) {
        ms_error inner = *err;
        ms_error_set(err, st, "%s: %s", name, inner.text);
        ms_archive_close(a);
        return st;
    }
    *out = a;
    return MS_OK;
}

uint32_t ms_archive_subtree_of(const ms_archive *a, uint32_t cell)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    if (!c)
        return MS_ARCHIVE_NONE;
    if (a->partial)
        return map_find(&a->partial->cells, cell)->subtree->id;
    /* Up to the first level of its band; its group starts the subtree. */
    unsigned band = c->level / a->subtree_levels * a->subtree_levels;
    if (band == 0)
        return 0;
    while (c->level > band)
        cell = c->parent, c = ms_archive_get_cell(a, cell);
    return ms_archive_get_cell(a, c->parent)->first_child;
}

uint32_t ms_archive_children_subtree(const ms_archive *a, uint32_t cell)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    if (!c || c->first_child == MS_ARCHIVE_NONE)
        return MS_ARCHIVE_NONE;
    if ((c->level + 1u) % a->subtree_levels == 0)
        return c->first_child;
    return ms_archive_subtree_of(a, cell);
}

bool ms_archive_is_partial(const ms_archive *a) { return a->partial != NULL; }

bool ms_archive_subtree_held(const ms_archive *a, uint32_t id)
{
    if (!a->partial)
        return ms_archive_subtree_slot(a, id) >= 0;
    return map_find(&a->partial->subtrees, id) != NULL;
}

bool ms_archive_held_subtree(const ms_archive *a, uint32_t id, const uint32_t **ids,
                             const ms_archive_cell **records, size_t *count)
{
    const map_slot *slot = a->partial ? map_find(&a->partial->subtrees, id) : NULL;
    *ids = slot ? slot->subtree->ids : NULL;
    *records = slot ? slot->subtree->cells : NULL;
    *count = slot ? slot->subtree->count : 0;
    return slot != NULL;
}

size_t ms_archive_subtrees_held(const ms_archive *a)
{
    return a->partial ? a->partial->subtrees.count : a->subtree_count;
}

size_t ms_archive_index_bytes_held(const ms_archive *a)
{
    return a->partial ? a->partial->bytes_held : (size_t)a->index_size;
}
