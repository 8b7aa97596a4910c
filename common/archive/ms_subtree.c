/* Subtrees of a whole archive: listing, encoding, the stored bytes a server
 * sends and the index head (ms_subtree.h, docs/ARCHIVE.md "Subtrees"), and the
 * raw blob reader shared with archive files and the partial index. */
#include "ms_subtree.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ms_archive_internal.h"

/* Deflate's densest code gives at most 1032 bytes out for every byte in. */
#define ZLIB_MAX_RATIO 1032u

unsigned ms_subtree_default_levels(unsigned n) { return n == 2 ? 2u : 1u; }

static uint32_t group_size(const ms_archive_header *h) { return (uint32_t)h->n * h->n * h->n; }

/* Whether `id` starts a subtree at depth `levels` of a whole archive. */
static bool is_subtree_id(const ms_archive *a, unsigned levels, uint32_t id)
{
    if (id == 0)
        return true;
    if (id >= a->header.cell_count)
        return false;
    const ms_archive_cell *c = &a->cells[id];
    const ms_archive_cell *p = &a->cells[c->parent]; /* validated: parent < id */
    return p->first_child == id && (p->level + 1u) % levels == 0;
}

static ms_status check_whole(const ms_archive *a, unsigned levels, ms_error *err)
{
    if (a->partial || !a->cells)
        return ms_error_set(err, MS_ERR_ARG, "subtrees are listed from a whole archive only");
    if (levels < MS_SUBTREE_MIN_LEVELS || levels > MS_SUBTREE_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_ARG, "subtree depth %u outside %u..%u", levels,
                            MS_SUBTREE_MIN_LEVELS, MS_SUBTREE_MAX_LEVELS);
    return MS_OK;
}

ms_status ms_subtree_list(const ms_archive *a, unsigned levels, uint32_t **ids, size_t *count,
                          ms_error *err)
{
    *ids = NULL;
    *count = 0;
    ms_status st = check_whole(a, levels, err);
    if (st != MS_OK)
        return st;
    size_t n = 0;
    for (uint32_t id = 0; id < a->header.cell_count; ++id)
        n += is_subtree_id(a, levels, id);
    uint32_t *out = malloc(n * sizeof *out);
    if (!out)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu subtree ids", n);
    size_t k = 0;
    for (uint32_t id = 0; id < a->header.cell_count; ++id)
        if (is_subtree_id(a, levels, id))
            out[k++] = id;
    *ids = out;
    *count = n;
    return MS_OK;
}

static int compare_u32(const void *x, const void *y)
{
    uint32_t a = *(const uint32_t *)x, b = *(const uint32_t *)y;
    return (a > b) - (a < b);
}

ms_status ms_subtree_members(const ms_archive *a, unsigned levels, uint32_t id,
                             uint32_t **members, size_t *count, ms_error *err)
{
    *members = NULL;
    *count = 0;
    ms_status st = check_whole(a, levels, err);
    if (st != MS_OK)
        return st;
    if (!is_subtree_id(a, levels, id))
        return ms_error_set(err, MS_ERR_RANGE, "cell %u does not start a subtree", id);
    const ms_archive_header *h = &a->header;
    uint32_t group = id == 0 ? 1 : group_size(h);
    size_t capacity = group, n = 0;
    uint32_t *out = malloc(capacity * sizeof *out);
    if (!out)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for subtree %u", id);
    for (uint32_t k = 0; k < group; ++k)
        out[n++] = id + k;
    /* Breadth-first inside the subtree: a member's children are members unless
     * the member ends a band of `levels` levels. */
    for (size_t i = 0; i < n; ++i) {
        const ms_archive_cell *c = &a->cells[out[i]];
        if (c->first_child == MS_ARCHIVE_NONE || (c->level + 1u) % levels == 0)
            continue;
        if (n + group_size(h) > capacity) {
            size_t grown = 2 * capacity + group_size(h);
            uint32_t *bigger = realloc(out, grown * sizeof *out);
            if (!bigger) {
                free(out);
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory for subtree %u", id);
            }
            out = bigger;
            capacity = grown;
        }
        for (uint32_t k = 0; k < group_size(h); ++k)
            out[n++] = c->first_child + k;
    }
    /* Breadth-first files list them ascending already; the format only
     * promises parents before children, so sort when needed. */
    for (size_t i = 1; i < n; ++i)
        if (out[i - 1] > out[i]) {
            qsort(out, n, sizeof *out, compare_u32);
            break;
        }
    *members = out;
    *count = n;
    return MS_OK;
}

ms_status ms_subtree_encode(const ms_archive *a, unsigned levels, uint32_t id, uint8_t **raw,
                            size_t *size, ms_error *err)
{
    *raw = NULL;
    *size = 0;
    uint32_t *members;
    size_t m;
    ms_status st = ms_subtree_members(a, levels, id, &members, &m, err);
    if (st != MS_OK)
        return st;
    uint64_t t = 0;
    for (size_t i = 0; i < m; ++i)
        t += ms_archive_cell_table_words(&a->header, &a->cells[members[i]]);
    size_t total = MS_SUBTREE_HEADER_SIZE + (4 + MS_ARCHIVE_RECORD_SIZE) * m + 4 * (size_t)t;
    uint8_t *out = malloc(total);
    if (!out) {
        free(members);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory encoding subtree %u", id);
    }
    memcpy(out, MS_SUBTREE_MAGIC, 4);
    out[4] = (uint8_t)MS_SUBTREE_VERSION;
    out[5] = 0;
    out[6] = (uint8_t)levels;
    out[7] = 0;
    ms_put_u32(out + 8, id);
    ms_put_u32(out + 12, (uint32_t)m);
    ms_put_u32(out + 16, (uint32_t)t);
    uint8_t *ids = out + MS_SUBTREE_HEADER_SIZE;
    uint8_t *records = ids + 4 * m;
    uint8_t *tables = records + MS_ARCHIVE_RECORD_SIZE * m;
    uint32_t next = 0;
    for (size_t i = 0; i < m; ++i) {
        ms_archive_cell c = a->cells[members[i]];
        uint64_t words = ms_archive_cell_table_words(&a->header, &c);
        memcpy(tables + 4 * (size_t)next, a->tables + 4 * (size_t)c.table_first, 4 * words);
        c.table_first = next;
        next += (uint32_t)words;
        ms_put_u32(ids + 4 * i, members[i]);
        ms_archive_encode_cell(&c, records + MS_ARCHIVE_RECORD_SIZE * i);
    }
    ms_put_u32(out + 20, (uint32_t)crc32_z(0L, out + MS_SUBTREE_HEADER_SIZE,
                                           total - MS_SUBTREE_HEADER_SIZE));
    free(members);
    *raw = out;
    *size = total;
    return MS_OK;
}

ms_status ms_subtree_deflate(const uint8_t *raw, size_t size, uint8_t **stored,
                             size_t *stored_size, ms_error *err)
{
    *stored = NULL;
    *stored_size = 0;
    if (size > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "a %zu-byte subtree is too large", size);
    z_stream z;
    memset(&z, 0, sizeof z);
    if (deflateInit2(&z, 9, Z_DEFLATED, 15, 8, Z_FILTERED) != Z_OK)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory compressing a subtree");
    uLong bound = deflateBound(&z, (uLong)size);
    uint8_t *out = malloc(bound);
    if (!out) {
        deflateEnd(&z);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory compressing a subtree");
    }
    z.next_in = (Bytef *)(uintptr_t)raw; /* zlib's API is not const-correct */
    z.avail_in = (uInt)size;
    z.next_out = out;
    z.avail_out = (uInt)bound;
    int r = deflate(&z, Z_FINISH);
    size_t produced = z.total_out;
    deflateEnd(&z);
    if (r != Z_STREAM_END) {
        free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "compressing a subtree failed (zlib %d)", r);
    }
    *stored = out;
    *stored_size = produced;
    return MS_OK;
}

/* --- The subtrees of an open archive -------------------------------------- */

ms_status ms_archive_subtrees_init(ms_archive *a, unsigned levels, ms_error *err)
{
    size_t count;
    ms_status st = ms_subtree_list(a, levels, &a->subtree_ids, &count, err);
    if (st != MS_OK)
        return st;
    a->subtree_levels = levels;
    a->subtree_count = (uint32_t)count;
    a->stored_cache = malloc(count * sizeof *a->stored_cache);
    if (!a->stored_cache)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu subtrees", count);
    for (size_t i = 0; i < count; ++i)
        atomic_init(&a->stored_cache[i], NULL);
    atomic_init(&a->head_cache, NULL);
    return MS_OK;
}

void ms_archive_subtrees_free(ms_archive *a)
{
    if (a->stored_cache)
        for (uint32_t i = 0; i < a->subtree_count; ++i)
            free(atomic_load(&a->stored_cache[i]));
    free(a->stored_cache);
    free(atomic_load(&a->head_cache));
    free(a->subtree_ids);
    free(a->file_subtree);
    free(a->file_subtree_size);
    free(a->file_subtree_ids);
}

/* Index of id in subtree_ids, or -1. */
long ms_archive_subtree_slot(const ms_archive *a, uint32_t id)
{
    size_t lo = 0, hi = a->subtree_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (a->subtree_ids[mid] < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < a->subtree_count && a->subtree_ids[lo] == id ? (long)lo : -1;
}

/* Publishes `fresh` in *slot unless another thread did first; returns the one
 * that stays. */
static ms_stored_subtree *publish(_Atomic(ms_stored_subtree *) *slot, ms_stored_subtree *fresh)
{
    ms_stored_subtree *expected = NULL;
    if (atomic_compare_exchange_strong(slot, &expected, fresh))
        return fresh;
    free(fresh);
    return expected;
}

static ms_stored_subtree *stored_copy(const uint8_t *prefix, size_t prefix_size,
                                      const uint8_t *bytes, size_t size)
{
    ms_stored_subtree *s = malloc(sizeof *s + prefix_size + size);
    if (!s)
        return NULL;
    s->size = prefix_size + size;
    if (prefix_size)
        memcpy(s->bytes, prefix, prefix_size);
    memcpy(s->bytes + prefix_size, bytes, size);
    return s;
}

const uint8_t *ms_archive_subtree(const ms_archive *a, uint32_t id, size_t *stored_size)
{
    *stored_size = 0;
    long slot = a->partial || !a->stored_cache ? -1 : ms_archive_subtree_slot(a, id);
    if (slot < 0)
        return NULL;
    if (a->file_subtree) {
        *stored_size = a->file_subtree_size[slot];
        return a->file_subtree[slot];
    }
    ms_stored_subtree *s = atomic_load(&a->stored_cache[slot]);
    if (!s) {
        uint8_t *raw, *stored;
        size_t raw_size, size;
        ms_error err;
        if (ms_subtree_encode(a, a->subtree_levels, id, &raw, &raw_size, &err) != MS_OK)
            return NULL;
        ms_status st = ms_subtree_deflate(raw, raw_size, &stored, &size, &err);
        free(raw);
        if (st != MS_OK)
            return NULL;
        s = stored_copy(NULL, 0, stored, size);
        free(stored);
        if (!s)
            return NULL;
        s = publish((_Atomic(ms_stored_subtree *) *)&a->stored_cache[slot], s);
    }
    *stored_size = s->size;
    return s->bytes;
}

unsigned ms_archive_subtree_levels(const ms_archive *a) { return a->subtree_levels; }

uint32_t ms_archive_subtree_count(const ms_archive *a) { return a->subtree_count; }

const uint8_t *ms_archive_index_head(const ms_archive *a, size_t *size)
{
    *size = 0;
    if (a->partial || !a->blob)
        return NULL;
    ms_stored_subtree *s = atomic_load(&a->head_cache);
    if (!s) {
        size_t root_size;
        const uint8_t *root = ms_archive_subtree(a, 0, &root_size);
        if (!root)
            return NULL;
        uint8_t header[MS_ARCHIVE_HEADER_SIZE];
        /* The head's file size is the index blob's (128 + raw index +
         * payloads), so that the head is the same from a file or a blob. */
        ms_archive_encode_header(&a->header, a->index_size, (uint32_t)root_size, a->payload_size,
                                 MS_ARCHIVE_HEADER_SIZE + a->index_size + a->payload_size,
                                 ms_get_u32(a->blob + 108), a->subtree_levels, a->subtree_count,
                                 header);
        s = stored_copy(header, sizeof header, root, root_size);
        if (!s)
            return NULL;
        s = publish((_Atomic(ms_stored_subtree *) *)&a->head_cache, s);
    }
    *size = s->size;
    return s->bytes;
}
