/* Reading a file's index (docs/ARCHIVE.md "The stored index"): the subtree
 * directory, every stored subtree inflated and checked on its own, and the raw
 * index assembled from them, which ms_archive.c then checks as any other. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ms_archive_internal.h"
#include "ms_subtree.h"
#include "ms_subtree_read.h"

/* The cells decoded so far, for the parent look-up of ms_subtree_blob_check. */
typedef struct assembly {
    ms_archive_cell *cells;
    uint8_t *placed;
} assembly;

static const ms_archive_cell *placed_cell(const void *context, uint32_t cell)
{
    const assembly *s = context;
    return s->placed[cell] ? &s->cells[cell] : NULL;
}

/* Reads the directory into a->file_subtree*; checks its CRC, ids ascending
 * from 0, offsets following each other from the end of the directory, and
 * lengths filling the index section exactly. */
static ms_status read_directory(const char *path, ms_archive *a, const ms_archive_sections *sec,
                                ms_error *err)
{
    const uint8_t *section = a->map + MS_ARCHIVE_HEADER_SIZE;
    uint64_t count = sec->subtree_count, directory = 12 * count + 4;
    if (directory > sec->stored_size)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: a directory of %llu subtrees does not fit the %llu-byte index",
                            path, (unsigned long long)count,
                            (unsigned long long)sec->stored_size);
    if ((uint32_t)crc32_z(0L, section, 12 * count) != ms_get_u32(section + 12 * count))
        return ms_error_set(err, MS_ERR_CORRUPT, "%s: subtree directory checksum mismatch", path);
    a->file_subtree = malloc(count * sizeof *a->file_subtree);
    a->file_subtree_size = malloc(count * sizeof *a->file_subtree_size);
    a->file_subtree_ids = malloc(count * sizeof *a->file_subtree_ids);
    if (!a->file_subtree || !a->file_subtree_size || !a->file_subtree_ids)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for %llu subtrees", path,
                            (unsigned long long)count);
    uint64_t next = 0;
    for (uint64_t i = 0; i < count; ++i) {
        const uint8_t *e = section + 12 * i;
        uint32_t id = ms_get_u32(e), offset = ms_get_u32(e + 4), length = ms_get_u32(e + 8);
        if (i == 0 ? id != 0 : id <= a->file_subtree_ids[i - 1])
            return ms_error_set(err, MS_ERR_FORMAT,
                                "%s: subtree directory entry %llu: id %u out of order", path,
                                (unsigned long long)i, id);
        if (offset != next || length == 0 || length > sec->stored_size - directory - next)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "%s: subtree directory entry %llu: bytes %u+%u outside the index",
                                path, (unsigned long long)i, offset, length);
        a->file_subtree_ids[i] = id;
        a->file_subtree[i] = section + directory + offset;
        a->file_subtree_size[i] = length;
        a->file_subtree_count = (uint32_t)i + 1;
        next += length;
    }
    if (directory + next != sec->stored_size)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: the subtrees fill %llu of the index's %llu bytes", path,
                            (unsigned long long)(directory + next),
                            (unsigned long long)sec->stored_size);
    return MS_OK;
}

/* Checks one subtree and writes its records into raw (table_first still the
 * subtree's own); the tables are placed once every cell is known. */
static ms_status place_subtree(const char *path, ms_archive *a, const ms_archive_sections *sec,
                               uint32_t i, assembly *s, ms_subtree_blob *blob, uint8_t *raw,
                               ms_error *err)
{
    char where[600];
    snprintf(where, sizeof where, "%s: subtree %u", path, a->file_subtree_ids[i]);
    ms_status st = ms_subtree_blob_read(where, &a->header, sec->subtree_levels,
                                        a->file_subtree_ids[i], a->file_subtree[i],
                                        a->file_subtree_size[i], blob, err);
    if (st != MS_OK)
        return st;
    ms_archive_cell *cells = malloc(blob->count * sizeof *cells);
    if (!cells)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    st = ms_subtree_blob_check(where, &a->header, sec->subtree_levels, sec->payload_size, blob,
                               placed_cell, s, cells, err);
    for (uint32_t k = 0; st == MS_OK && k < blob->count; ++k) {
        uint32_t cell = ms_get_u32(blob->ids + 4 * (size_t)k);
        if (s->placed[cell])
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u is in two subtrees", where, cell);
        else {
            s->placed[cell] = 1;
            s->cells[cell] = cells[k];
            memcpy(raw + (size_t)cell * MS_ARCHIVE_RECORD_SIZE,
                   blob->records + (size_t)k * MS_ARCHIVE_RECORD_SIZE, MS_ARCHIVE_RECORD_SIZE);
        }
    }
    free(cells);
    return st;
}

ms_status ms_archive_v3_assemble(const char *path, ms_archive *a, const ms_archive_sections *sec,
                                 uint8_t *raw, ms_error *err)
{
    ms_status st = read_directory(path, a, sec, err);
    if (st != MS_OK)
        return st;
    uint32_t cells = a->header.cell_count, count = sec->subtree_count;
    assembly s = {calloc(cells, sizeof *s.cells), calloc(cells, 1)};
    ms_subtree_blob *blobs = calloc(count, sizeof *blobs);
    /* Per cell: which subtree holds its tables. */
    uint32_t *holder = malloc(cells * sizeof *holder);
    if (!s.cells || !s.placed || !blobs || !holder)
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for %u cells", path, cells);
    for (uint32_t i = 0; st == MS_OK && i < count; ++i) {
        st = place_subtree(path, a, sec, i, &s, &blobs[i], raw, err);
        for (uint32_t k = 0; st == MS_OK && k < blobs[i].count; ++k)
            holder[ms_get_u32(blobs[i].ids + 4 * (size_t)k)] = i;
    }
    for (uint32_t c = 0; st == MS_OK && c < cells; ++c)
        if (!s.placed[c])
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u is in no subtree", path, c);
    /* The tables in cell order, as an index blob lays them out. */
    uint8_t *words = raw + (size_t)cells * MS_ARCHIVE_RECORD_SIZE;
    uint64_t next = 0;
    for (uint32_t c = 0; st == MS_OK && c < cells; ++c) {
        const ms_archive_cell *cell = &s.cells[c];
        uint64_t n = ms_archive_cell_table_words(&a->header, cell);
        if (n > a->header.table_words - next) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%s: the subtrees hold more than %u table words",
                              path, a->header.table_words);
            break;
        }
        /* Inside its blob's words: checked by ms_subtree_blob_check. */
        memcpy(words + 4 * next, blobs[holder[c]].tables + 4 * (size_t)cell->table_first, 4 * n);
        ms_put_u32(raw + (size_t)c * MS_ARCHIVE_RECORD_SIZE + 68, (uint32_t)next);
        next += n;
    }
    if (st == MS_OK && next != a->header.table_words)
        st = ms_error_set(err, MS_ERR_FORMAT, "%s: the subtrees hold %llu of %u table words", path,
                          (unsigned long long)next, a->header.table_words);
    for (uint32_t i = 0; blobs && i < count; ++i)
        ms_subtree_blob_free(&blobs[i]);
    free(blobs);
    free(holder);
    free(s.cells);
    free(s.placed);
    return st;
}

ms_status ms_archive_v3_check_directory(const char *path, ms_archive *a, ms_error *err)
{
    /* The directory must list exactly the subtrees of the (now checked) tree;
     * each was checked to hold exactly its members when it was placed. */
    bool same = a->subtree_count == a->file_subtree_count;
    for (uint32_t i = 0; same && i < a->subtree_count; ++i)
        same = a->file_subtree_ids[i] == a->subtree_ids[i];
    if (!same)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: the subtree directory does not list the tree's %u subtrees", path,
                            a->subtree_count);
    return MS_OK;
}
