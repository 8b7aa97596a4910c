/* Reading stored subtrees (docs/ARCHIVE.md "Subtrees"): inflating one into
 * room bounded by its own header and the archive header, and checking it
 * against the tree: what the partial index (ms_archive_partial.c) and the
 * file reader share. Every failure is one line naming the subtree. */
#include "ms_subtree_read.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#define ZLIB_MAX_RATIO 1032u

/* The most members a subtree can have at this depth (and in this archive). */
static uint64_t max_members(const ms_archive_header *h, unsigned levels, bool root)
{
    uint64_t group = (uint64_t)h->n * h->n * h->n, total = 0, band = root ? 1 : group;
    for (unsigned l = 0; l < levels && total < h->cell_count; ++l) {
        total += band;
        band *= group;
        if (band > h->cell_count)
            band = h->cell_count;
    }
    return total < h->cell_count ? total : h->cell_count;
}

/* Feeds zlib until `out` is full, the stream ends or fails. */
static int inflate_into(z_stream *z, uint8_t *out, size_t size)
{
    z->next_out = out;
    z->avail_out = (uInt)size;
    int r = Z_OK;
    while (z->avail_out > 0 && r == Z_OK)
        r = inflate(z, Z_NO_FLUSH);
    return r;
}

static ms_status inflate_fail(const char *where, int r, const z_stream *z, ms_error *err)
{
    if (r == Z_MEM_ERROR)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory inflating", where);
    if (r == Z_BUF_ERROR || r == Z_STREAM_END || r == Z_OK)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: zlib stream ends before the blob (%lu bytes)",
                            where, (unsigned long)z->total_out);
    return ms_error_set(err, MS_ERR_CORRUPT, "%s: not a valid zlib stream: %s", where,
                        r == Z_NEED_DICT ? "it needs a preset dictionary"
                        : z->msg         ? z->msg
                                         : "bad data");
}

void ms_subtree_blob_free(ms_subtree_blob *b)
{
    free(b->raw);
    memset(b, 0, sizeof *b);
}

ms_status ms_subtree_blob_read(const char *where, const ms_archive_header *h, unsigned levels,
                               uint32_t id, const uint8_t *stored, size_t stored_size,
                               ms_subtree_blob *b, ms_error *err)
{
    memset(b, 0, sizeof *b);
    if (stored_size == 0 || stored_size > UINT32_MAX)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %zu stored bytes", where, stored_size);
    z_stream z;
    memset(&z, 0, sizeof z);
    if (inflateInit(&z) != Z_OK)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory inflating", where);
    z.next_in = (Bytef *)(uintptr_t)stored; /* zlib's API is not const-correct */
    z.avail_in = (uInt)stored_size;
    uint8_t head[MS_SUBTREE_HEADER_SIZE];
    int r = inflate_into(&z, head, sizeof head);
    ms_status st = MS_OK;
    /* zlib may fail while reading past the bytes it has just written. */
    if (z.avail_out > 0 || (r != Z_OK && r != Z_STREAM_END))
        st = inflate_fail(where, r, &z, err);
    uint32_t m = 0, t = 0;
    if (st == MS_OK) {
        m = ms_get_u32(head + 12);
        t = ms_get_u32(head + 16);
        uint64_t m_cap = max_members(h, levels, id == 0);
        uint64_t t_cap = m * (uint64_t)(h->bits + 1 + 2 * MS_ARCHIVE_MAX_APO_LEVELS +
                                          (h->has_colour ? h->bits + 2 : 0) + (h->bits + 4) / 4);
        if (t_cap > h->table_words)
            t_cap = h->table_words;
        if (memcmp(head, MS_SUBTREE_MAGIC, 4) != 0)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: not a subtree (bad magic)", where);
        else if (head[4] != MS_SUBTREE_VERSION || head[5] != 0)
            st = ms_error_set(err, MS_ERR_UNSUPPORTED, "%s: subtree version %u, this build reads %u",
                              where, head[4] | head[5] << 8, MS_SUBTREE_VERSION);
        else if (head[6] != levels || head[7] != 0)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: subtree of depth %u in an archive of depth %u",
                              where, head[6], levels);
        else if (ms_get_u32(head + 8) != id)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: the blob is subtree %u", where,
                              ms_get_u32(head + 8));
        else if (m < 1 || m > m_cap)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: %u members outside 1..%llu", where, m,
                              (unsigned long long)m_cap);
        else if (t > t_cap)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: %u table words, at most %llu", where, t,
                              (unsigned long long)t_cap);
    }
    size_t raw_size = 0;
    if (st == MS_OK) {
        raw_size = MS_SUBTREE_HEADER_SIZE + (4 + (size_t)MS_ARCHIVE_RECORD_SIZE) * m + 4 * (size_t)t;
        if ((uint64_t)stored_size * ZLIB_MAX_RATIO < raw_size)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: %zu stored bytes cannot inflate to %zu",
                              where, stored_size, raw_size);
    }
    if (st == MS_OK) {
        b->raw = malloc(raw_size);
        if (!b->raw)
            st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for %zu bytes", where,
                              raw_size);
    }
    if (st == MS_OK) {
        memcpy(b->raw, head, sizeof head);
        size_t rest = raw_size - sizeof head;
        r = rest ? inflate_into(&z, b->raw + sizeof head, rest) : Z_OK;
        if (z.avail_out > 0 || (r != Z_OK && r != Z_STREAM_END))
            st = inflate_fail(where, r, &z, err);
        else if (r == Z_OK) {
            /* Full: the stream must end here, with nothing after it. */
            uint8_t extra;
            r = inflate_into(&z, &extra, 1);
            if (z.avail_out == 0)
                st = ms_error_set(err, MS_ERR_FORMAT, "%s: inflates to more than %zu bytes",
                                  where, raw_size);
            else if (r != Z_STREAM_END)
                st = inflate_fail(where, r, &z, err);
        }
        if (st == MS_OK && z.avail_in > 0)
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: %u bytes follow the zlib stream", where,
                              z.avail_in);
    }
    inflateEnd(&z);
    if (st == MS_OK &&
        crc32_z(0L, b->raw + MS_SUBTREE_HEADER_SIZE, raw_size - MS_SUBTREE_HEADER_SIZE) !=
            ms_get_u32(b->raw + 20))
        st = ms_error_set(err, MS_ERR_CORRUPT, "%s: checksum mismatch", where);
    if (st == MS_OK) {
        b->id = id;
        b->count = m;
        b->table_words = t;
        b->raw_size = raw_size;
        b->ids = b->raw + MS_SUBTREE_HEADER_SIZE;
        b->records = b->ids + 4 * (size_t)m;
        b->tables = b->records + MS_ARCHIVE_RECORD_SIZE * (size_t)m;
        uint32_t previous = 0;
        for (uint32_t i = 0; st == MS_OK && i < m; ++i) {
            uint32_t cell = ms_get_u32(b->ids + 4 * (size_t)i);
            if (i == 0 ? cell != id : cell <= previous)
                st = ms_error_set(err, MS_ERR_FORMAT,
                                  "%s: member %u (cell %u) is not in ascending order from %u",
                                  where, i, cell, id);
            else if (cell >= h->cell_count)
                st = ms_error_set(err, MS_ERR_FORMAT, "%s: member cell %u of %u cells", where,
                                  cell, h->cell_count);
            previous = cell;
        }
    }
    if (st != MS_OK)
        ms_subtree_blob_free(b);
    return st;
}

/* Index of cell among the blob's ids, or -1. */
static long member_index(const ms_subtree_blob *b, uint32_t cell)
{
    size_t lo = 0, hi = b->count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (ms_get_u32(b->ids + 4 * mid) < cell)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < b->count && ms_get_u32(b->ids + 4 * lo) == cell ? (long)lo : -1;
}

ms_status ms_subtree_blob_check(const char *where, const ms_archive_header *h, unsigned levels,
                                uint64_t payload_size, const ms_subtree_blob *b,
                                ms_cell_lookup held, const void *context, ms_archive_cell *cells,
                                ms_error *err)
{
    uint32_t group = b->id == 0 ? 1 : (uint32_t)h->n * h->n * h->n;
    for (uint32_t i = 0; i < b->count; ++i)
        ms_archive_decode_cell(b->records + MS_ARCHIVE_RECORD_SIZE * (size_t)i, &cells[i]);
    if (b->count < group)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %u members, fewer than its first group",
                            where, b->count);
    /* The first group: the children of a held cell at the end of a band. */
    const ms_archive_cell *outer = NULL;
    if (b->id != 0) {
        outer = held(context, cells[0].parent);
        if (!outer || outer->first_child != b->id || (outer->level + 1u) % levels != 0 ||
            cells[0].parent >= b->id)
            return ms_error_set(err, MS_ERR_RANGE,
                                "%s: not the children of a held cell at the end of a band", where);
    }
    uint64_t next_table = 0, claimed = 0;
    for (uint32_t i = 0; i < b->count; ++i) {
        uint32_t cell = ms_get_u32(b->ids + 4 * (size_t)i);
        ms_archive_cell *c = &cells[i];
        const ms_archive_cell *parent = NULL;
        if (i < group) {
            if (cell != b->id + i)
                return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u is not in its first group",
                                    where, cell);
            parent = outer; /* NULL for the root, which has none */
            if (b->id != 0 && c->parent != cells[0].parent)
                return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u: not a sibling of cell %u",
                                    where, cell, b->id);
        } else {
            long k = c->parent < cell ? member_index(b, c->parent) : -1;
            if (k < 0 || (cells[k].level + 1u) % levels == 0)
                return ms_error_set(err, MS_ERR_FORMAT,
                                    "%s: cell %u: its parent %u is not a member above it", where,
                                    cell, c->parent);
            parent = &cells[k];
        }
        ms_status st = ms_archive_check_record(where, h, payload_size, cell,
                                               b->records + MS_ARCHIVE_RECORD_SIZE * (size_t)i, c,
                                               parent, b->tables, b->table_words, &next_table,
                                               err);
        if (st != MS_OK)
            return st;
        if (c->first_child != MS_ARCHIVE_NONE && (c->level + 1u) % levels != 0) {
            /* Its children belong here: every one must be a member naming it. */
            uint32_t children = (uint32_t)h->n * h->n * h->n;
            for (uint32_t k = 0; k < children; ++k) {
                long j = member_index(b, c->first_child + k);
                if (j < 0 || cells[j].parent != cell)
                    return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u: child %u is missing",
                                        where, cell, c->first_child + k);
            }
            claimed += children;
        }
    }
    if (claimed + group != b->count)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %u members, the tree gives %llu", where,
                            b->count, (unsigned long long)(claimed + group));
    if (next_table != b->table_words)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: the members' tables use %llu of %u words",
                            where, (unsigned long long)next_table, b->table_words);
    return MS_OK;
}
