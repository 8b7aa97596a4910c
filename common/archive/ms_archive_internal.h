/* Inside the archive reader: the ms_archive structure and the record checks
 * that the whole-file reader (ms_archive.c), the subtree code (ms_subtree.c)
 * and the partial index (ms_archive_partial.c) share. Private to
 * common/archive's archive files. */
#ifndef MS_ARCHIVE_INTERNAL_H
#define MS_ARCHIVE_INTERNAL_H

#include <stdatomic.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"

/* One stored (zlib) subtree computed from an index blob on first request. */
typedef struct ms_stored_subtree {
    size_t size;
    uint8_t bytes[];
} ms_stored_subtree;

/* The partial index of a client (ms_archive_partial.c). */
typedef struct ms_partial_index ms_partial_index;

struct ms_archive {
    const uint8_t *map;
    size_t map_size;
    bool index_only; /* a malloc'd copy of header + index (or NULL), no payloads */
    /* The mapped file, kept open so that ms_archive_file_stat describes the
     * very file mapped, not whatever its path names now; -1 for an index. */
    int fd;
    ms_archive_header header;
    ms_archive_cell *cells; /* cell_count records; NULL on a partial index */
    /* The index blob (blob header + raw index): the start of map for an index
     * blob, else (a file) inflated_blob. */
    const uint8_t *blob;
    uint8_t *inflated_blob; /* a file's: malloc'd, MS_ARCHIVE_HEADER_SIZE + index_size */
    const uint8_t *tables;  /* table words, little-endian */
    const uint8_t *payload;
    uint64_t payload_size;
    uint64_t index_size; /* raw */

    /* Subtrees of a whole archive (ms_subtree.c), set up at open: the ids at
     * subtree_levels, ascending, and per id its stored bytes: a file's own
     * (file_subtree, file_subtree_size) or, for an archive opened from an
     * index blob, deflated on first request and published once (stored_cache). */
    unsigned subtree_levels;
    uint32_t subtree_count;
    uint32_t *subtree_ids;
    const uint8_t **file_subtree;
    uint32_t *file_subtree_size;
    uint32_t *file_subtree_ids; /* a file's: the directory's ids */
    uint32_t file_subtree_count;
    _Atomic(ms_stored_subtree *) *stored_cache;
    _Atomic(ms_stored_subtree *) head_cache; /* the index head, built on first request */

    /* A client's partial index (ms_archive_open_head), else NULL. */
    ms_partial_index *partial;
};

/* --- Little-endian field access ------------------------------------------- */

static inline uint32_t ms_get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static inline uint64_t ms_get_u64(const uint8_t *p)
{
    return ms_get_u32(p) | (uint64_t)ms_get_u32(p + 4) << 32;
}

static inline void ms_put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static inline void ms_put_u64(uint8_t *p, uint64_t v)
{
    ms_put_u32(p, (uint32_t)v);
    ms_put_u32(p + 4, (uint32_t)(v >> 32));
}

/* What a header heads: a file (version 3), an index blob (blob version 1,
 * followed by the raw index) or an index head (version 3, followed by the root
 * subtree). */
typedef enum ms_header_kind { MS_HEADER_FILE, MS_HEADER_BLOB, MS_HEADER_HEAD } ms_header_kind;

/* The header's sections, as ms_archive_parse_header reads them. */
typedef struct ms_archive_sections {
    uint64_t index_size;  /* raw: 80 * cells + 4 * table words */
    uint64_t stored_size; /* bytes of the index in the file (head: of the root subtree) */
    uint64_t payload_size;
    uint32_t index_crc;   /* of the raw index */
    uint32_t subtree_count;  /* file or head */
    unsigned subtree_levels; /* file or head */
} ms_archive_sections;

/* Parses and checks a header (docs/ARCHIVE.md) against the `size` bytes it
 * heads; one-line errors naming path. */
ms_status ms_archive_parse_header(const char *path, const uint8_t *p, size_t size,
                                  ms_header_kind kind, ms_archive_header *h,
                                  ms_archive_sections *sec, ms_error *err);

/* Decodes an 80-byte record (field-local, no checks). */
void ms_archive_decode_cell(const uint8_t *raw, ms_archive_cell *c);

/* Checks one record (raw: its 80 bytes, c: decoded) on its own and against its
 * parent (NULL for cell 0, or when the parent is not known: an error), with
 * its tables in `tables` (table_words words), and fills its surface error
 * table (ms_archive_cell.error) from them. *next_table is where its tables
 * must start (tables lie in record order without gaps); it is advanced past
 * them. Errors are MS_ERR_FORMAT, one line starting with `where`. */
ms_status ms_archive_check_record(const char *where, const ms_archive_header *h,
                                  uint64_t payload_size, uint32_t id, const uint8_t *raw,
                                  ms_archive_cell *c, const ms_archive_cell *parent,
                                  const uint8_t *tables, uint64_t table_words,
                                  uint64_t *next_table, ms_error *err);

/* Table words of one cell: the record and where its tables are (full or
 * partial archive); false when the cell is not held. */
bool ms_archive_cell_tables(const ms_archive *a, uint32_t cell, const ms_archive_cell **c,
                            const uint8_t **tables);

/* Words of a cell's tables: its geometry prefix table, its APO level table,
 * with colour its colour prefix table and colour CRC, then its surface error
 * table. */
static inline uint64_t ms_archive_cell_table_words(const ms_archive_header *h,
                                                   const ms_archive_cell *c)
{
    uint64_t window = (uint64_t)c->bits_max - c->bits_min + 1;
    return window + 2ull * c->apo_levels + (h->has_colour ? window + 1 : 0) + (window + 3) / 4;
}

/* The first of a cell's surface error table words (a byte per bit of its
 * window, four to a word). */
static inline uint64_t ms_archive_error_table_first(const ms_archive_header *h,
                                                    const ms_archive_cell *c)
{
    return (uint64_t)c->table_first + ms_archive_cell_table_words(h, c) -
           ((uint64_t)c->bits_max - c->bits_min + 4) / 4;
}

/* The first of a cell's colour table words (its prefix table; the CRC follows). */
static inline uint64_t ms_archive_colour_table_first(const ms_archive_cell *c)
{
    return (uint64_t)c->table_first + (c->bits_max - c->bits_min + 1u) + 2ull * c->apo_levels;
}

/* ms_archive_colour.c: the colour fields of a header (flags bit 1, bytes 106
 * and 107) checked together; and a record's colour tables checked (prefix
 * table monotone, the stream inside the payload area right after the
 * geometry). One line starting with `where`, MS_ERR_FORMAT. */
ms_status ms_archive_check_colour_header(const char *where, const uint8_t *p,
                                         ms_archive_header *h, ms_error *err);
ms_status ms_archive_check_colour_tables(const char *where, const ms_archive_header *h,
                                         uint64_t payload_size, uint32_t id,
                                         const ms_archive_cell *c, const uint8_t *tables,
                                         ms_error *err);

/* ms_subtree.c: sets up the subtree ids of an archive validated as a whole
 * (levels: the file's S, or the default for an index blob), and frees them. */
ms_status ms_archive_subtrees_init(ms_archive *a, unsigned levels, ms_error *err);
void ms_archive_subtrees_free(ms_archive *a);
/* Index of id in subtree_ids of a whole archive, or -1. */
long ms_archive_subtree_slot(const ms_archive *a, uint32_t id);
/* A file (ms_archive_v3.c): reads the directory and inflates every stored
 * subtree of a->map into the raw index at `raw` (sec->index_size bytes, table
 * words renumbered as in an index blob), checking each subtree on its own;
 * the whole index is then checked as any other. After that check,
 * ms_archive_v3_check_directory checks that the directory lists exactly the
 * subtrees of the tree, each with exactly its members. */
ms_status ms_archive_v3_assemble(const char *path, ms_archive *a, const ms_archive_sections *sec,
                                 uint8_t *raw, ms_error *err);
ms_status ms_archive_v3_check_directory(const char *path, ms_archive *a, ms_error *err);

/* ms_archive_partial.c */
const ms_archive_cell *ms_partial_get_cell(const ms_archive *a, uint32_t cell,
                                           const uint8_t **tables);
void ms_partial_free(ms_partial_index *p);

#endif
