/* Reading a meshstream archive file (docs/ARCHIVE.md: version 3, whose index is
 * stored as compressed subtrees, ms_subtree.h; any other version is refused
 * with MS_ERR_UNSUPPORTED naming it).
 *
 * ms_archive_open maps the file read-only and validates the header, inflates
 * every subtree of the index into memory (into exactly the sizes declared),
 * checks the index CRC, every cell record, the tree structure and the per-cell tables
 * before returning; afterwards every accessor is a bounds-safe look-up. Payload CRCs are checked on
 * demand by ms_archive_verify_payload (the server checks once, the client checks
 * what it receives).
 *
 * Ownership: the ms_archive owns the mapping (and a file's inflated index); pointers it returns stay valid until ms_archive_close. Thread-safety:
 * after open, any number of threads may read the same archive concurrently
 * (a partial archive of ms_subtree.h only while no subtree is added or dropped).
 */
#ifndef MS_ARCHIVE_H
#define MS_ARCHIVE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

struct stat;

/* The file version meshbake writes and the reader reads (the only one): the
 * index is stored as subtrees (ms_subtree.h). */
#define MS_ARCHIVE_VERSION 4u
/* The version of the index blob (ms_archive_index_bytes, what the server sends):
 * a 128-byte blob header followed by the raw index. */
#define MS_ARCHIVE_BLOB_VERSION 2u
/* Header byte 120 of a file or index head: the index in subtrees. */
#define MS_ARCHIVE_INDEX_SUBTREES 2u
#define MS_ARCHIVE_HEADER_SIZE 128u
#define MS_ARCHIVE_RECORD_SIZE 80u
#define MS_ARCHIVE_MAX_CELLS (1u << 24)
#define MS_ARCHIVE_MAX_TABLE_WORDS (1u << 28)
#define MS_ARCHIVE_MAX_APO_LEVELS 32u
#define MS_ARCHIVE_NONE 0xFFFFFFFFu
/* The most bits a cell's window spans (bits_max - bits_min + 1; p <= 20). */
#define MS_ARCHIVE_MAX_WINDOW 21u

typedef struct ms_archive_header {
    double box_origin[3];  /* world units */
    double box_side;       /* world units, > 0 */
    uint8_t bits;          /* p */
    uint8_t n;             /* nSP children per axis */
    uint8_t root_bits;     /* p_r */
    bool has_apo;
    uint8_t apo_lead;
    uint8_t apo_max_depth;
    /* Per-vertex colour (docs/ARCHIVE.md, "Colour streams"): flags bit 1; every
     * cell's tables then end with its colour prefix table and colour CRC, and
     * its colour stream (docs/COLOUR.md) follows its geometry payload. */
    bool has_colour;
    uint8_t colour_bits;   /* 1..8 bits per channel with colour, else 0 */
    bool colour_alpha;     /* the colour streams code alpha */
    /* How a client draws a coarse vertex (docs/CODEC.md §4.4): at a precision
     * below smooth_bits, at its point after smooth_rounds rounds of
     * ms_codec_state_smooth over its cell's complex; both 0: no smoothing
     * (bytes 122 and 123; rounds 1..MS_CODEC_SMOOTH_ROUNDS_MAX with bits in
     * 1..bits, else both 0). The error tables measure those points. */
    uint8_t smooth_rounds;
    uint8_t smooth_bits;
    uint32_t cell_count;
    uint32_t table_words;
    uint32_t min_triangles; /* N_min used by the baker */
    uint64_t vertex_count;
    uint64_t triangle_count;
    uint64_t file_size;
    /* Set by the reader, ignored by the writer: the version read (3 for a file,
     * 1 for an index blob) and the bytes the index occupies there (a file's
     * directory and stored subtrees; a blob's raw index, 80 * cell_count + 4 *
     * table_words). */
    uint32_t version;
    uint64_t index_stored_size;
} ms_archive_header;

typedef struct ms_archive_cell {
    uint32_t parent;       /* MS_ARCHIVE_NONE for the root */
    uint32_t first_child;  /* MS_ARCHIVE_NONE for a leaf; else n^3 consecutive cells */
    uint8_t level;
    uint8_t bits_min, bits_max;
    uint32_t position[3];  /* in cells of this level, each < n^level */
    uint32_t vertex_count, triangle_count; /* at bits_max */
    uint64_t geometry_offset;  /* relative to the payload area */
    uint32_t geometry_length, geometry_crc;
    uint64_t apo_offset;
    uint32_t apo_length, apo_crc, apo_raw_length;
    uint32_t table_first;  /* first word of this cell's tables */
    uint8_t apo_levels;
    /* In memory only, filled by the reader from the cell's tables: its surface
     * error table (ms_archive_cell_error), error[b - bits_min] for bit b. */
    uint8_t error[MS_ARCHIVE_MAX_WINDOW];
} ms_archive_cell;

typedef struct ms_archive ms_archive;

/* Opens and validates path. On failure *archive is NULL and err says what is
 * wrong and where (byte offset or cell number). */
ms_status ms_archive_open(const char *path, ms_archive **archive, ms_error *err);
void ms_archive_close(ms_archive *archive);

/* fstat of the file an archive opened by ms_archive_open maps, through the
 * descriptor it keeps open until ms_archive_close: the mapped file itself
 * (its inode, its size now), whatever its path names since; no path lookup,
 * so cheap enough for every payload served. MS_ERR_ARG for an index
 * (ms_archive_open_index*), MS_ERR_IO when fstat fails. Thread-safe. */
ms_status ms_archive_file_stat(const ms_archive *archive, struct stat *st, ms_error *err);

/* Validates and copies an index blob (blob header + raw cell index, as
 * ms_archive_index_bytes gives it and the server sends it); name is used in
 * errors. The result has no payloads: ms_archive_geometry/apo return NULL (with
 * the stored lengths) and the prefix look-ups work as usual. */
ms_status ms_archive_open_index(const uint8_t *blob, size_t size, const char *name,
                                ms_archive **archive, ms_error *err);

/* The same from an index saved in a file (meshexport's NAME.index, or a
 * /models/NAME answer of the HTTP door); at most 256 MiB. Every error names
 * path (MS_ERR_IO when it cannot be read). */
ms_status ms_archive_open_index_file(const char *path, const char *name, ms_archive **archive,
                                     ms_error *err);

const ms_archive_header *ms_archive_get_header(const ms_archive *archive);
/* NULL when cell >= cell_count, and on a partial archive (ms_subtree.h) when
 * the cell's subtree is not held. */
const ms_archive_cell *ms_archive_get_cell(const ms_archive *archive, uint32_t cell);

/* The whole index blob, for sending: a blob header (docs/ARCHIVE.md, "The
 * index blob") followed by the raw index (records + tables), the one the
 * file's subtrees assemble. NULL (size 0) on a partial archive. */
const uint8_t *ms_archive_index_bytes(const ms_archive *archive, size_t *size);

/* The archive's content identity: FNV-1a 64 of the index blob, which holds
 * every payload's CRC-32, so that two archives with the same id serve the same
 * bytes (clients key their caches on it; the catalogue records it at bake). */
uint64_t ms_archive_content_id(const ms_archive *archive);

/* The most APO levels any cell stores (0: no APO). O(cells). */
uint8_t ms_archive_max_apo_levels(const ms_archive *archive);

/* Payload bytes (not yet CRC-checked). Zero length for an absent APO chunk; NULL
 * on an index-only archive. */
const uint8_t *ms_archive_geometry(const ms_archive *archive, uint32_t cell, size_t *length);
const uint8_t *ms_archive_apo(const ms_archive *archive, uint32_t cell, size_t *length);

/* Byte length of the geometry prefix complete at `bits` (clamped to the cell's
 * window), and of the APO prefix complete at `level` (clamped to the levels
 * stored); *texels (may be NULL) receives the texel count of that APO prefix.
 * The APO `level` is a depth, from 0: the prefix holds levels 0 .. level, that
 * is level + 1 levels (so the first L levels end at level L - 1). */
uint32_t ms_archive_geometry_prefix(const ms_archive *archive, uint32_t cell, unsigned bits);

/* The surface error table (docs/ARCHIVE.md, "Per-cell tables"): one byte per
 * bit of a cell's window, four to a table word (its first bit in the first
 * word's low byte, the bytes after its last 0): the measured error of the
 * cell drawn at that precision (docs/CODEC.md §4.3), in 1/MS_ARCHIVE_ERROR_SCALE
 * of its kd-cell's half-diagonal at that bit (sqrt(3) / 2 * box_side / 2^bits),
 * rounded up; at most MS_ARCHIVE_ERROR_MAX (the whole diagonal), and in world
 * units never growing with the bits (a byte is at most twice the one before).
 * The writer's default, for a cell it was given no measurement of, is the
 * half-diagonal itself. */
#define MS_ARCHIVE_ERROR_SCALE 100u
#define MS_ARCHIVE_ERROR_MAX 200u
/* The error of cell record c drawn at `bits` (clamped to its window), world
 * units. Thread-safe. */
double ms_archive_cell_error(const ms_archive_header *header, const ms_archive_cell *c, unsigned bits);
/* The root's precision a selection wants at least while the model's box is in
 * the frustum, whatever the tolerance or a budget's factor: its coarsest
 * picture (a few dozen vertices, a few hundred bytes), so no model in view
 * vanishes (a client's budget loads it past its ceiling, as the index). */
#define MS_ARCHIVE_ROOT_FLOOR_BITS 3u

/* The precision, as a real number of bits, at which c's error seen at
 * px_per_unit pixels per world unit (the camera's pixels per unit over the
 * distance) is tolerance_px: between two bits of its window, where the error
 * interpolated geometrically between them reaches it; below the window,
 * doubling per bit from its first; above, halving per bit from its last (the
 * cell then wants its children). +INFINITY for an infinite px_per_unit. The
 * selection's need (ms_view_select, the client core's scheduler) in place of
 * the half-diagonal's ms_screen_bits_needed, which it equals on the writer's
 * default table. Thread-safe. */
double ms_archive_bits_needed(const ms_archive_header *header, const ms_archive_cell *c,
                              double px_per_unit, double tolerance_px);
uint32_t ms_archive_apo_prefix(const ms_archive *archive, uint32_t cell, unsigned level,
                               uint32_t *texels);

/* ---- colour streams (ms_archive_colour.c; docs/ARCHIVE.md, "Colour
 * streams"). On an archive without colour: length 0, prefix 0, NULL. */

/* The cell's colour stream: it follows the geometry payload; its length is the
 * last entry of its colour prefix table. NULL on an index-only archive. */
const uint8_t *ms_archive_colour(const ms_archive *archive, uint32_t cell, size_t *length);
uint32_t ms_archive_colour_length(const ms_archive *archive, uint32_t cell);
/* Byte length of the colour prefix that decodes the cell's colour to `bits`
 * (clamped to the cell's window; at bits_min: the stream header and its base
 * chunk). */
uint32_t ms_archive_colour_prefix(const ms_archive *archive, uint32_t cell, unsigned bits);
/* Checks a whole colour stream received from elsewhere (length and CRC32):
 * MS_ERR_CORRUPT on mismatch, MS_ERR_RANGE for a cell not held. */
ms_status ms_archive_check_colour(const ms_archive *archive, uint32_t cell, const uint8_t *data,
                                  size_t length, ms_error *err);

/* Checks both payload CRCs of a cell (and its colour stream's): MS_ERR_CORRUPT naming the cell on mismatch;
 * MS_ERR_ARG on an index-only archive. */
ms_status ms_archive_verify_payload(const ms_archive *archive, uint32_t cell, ms_error *err);

/* Checks a whole payload received from elsewhere against the index (length and
 * CRC32): MS_ERR_CORRUPT on mismatch. */
ms_status ms_archive_check_payload(const ms_archive *archive, uint32_t cell, bool apo,
                                   const uint8_t *data, size_t length, ms_error *err);

/* --- Shared with the writer (server/bake/ms_archive_writer.c) ------------------- */

/* Encodes / decodes the fixed-size parts. Decoding checks only field-local
 * ranges; cross-checks are done by ms_archive_open. Headers are encoded from
 * h's model fields (h->version, h->index_stored_size and h->file_size are not
 * used); index_size is the raw index (80 * cells + 4 * table words), index_crc
 * its CRC32.
 * ms_archive_encode_header: a file's (or an index head's) version-3 header;
 * stored_size is what follows the header before the payloads (the directory
 * and the stored subtrees of a file; the root subtree in an index head),
 * file_size is written as given.
 * ms_archive_encode_blob_header: an index blob's header (version 1, the raw
 * index follows; file size 128 + index_size + payload_size). */
void ms_archive_encode_header(const ms_archive_header *h, uint64_t index_size,
                              uint32_t stored_size, uint64_t payload_size, uint64_t file_size,
                              uint32_t index_crc, unsigned subtree_levels,
                              uint32_t subtree_count, uint8_t out[MS_ARCHIVE_HEADER_SIZE]);
void ms_archive_encode_blob_header(const ms_archive_header *h, uint64_t index_size,
                                   uint64_t payload_size, uint32_t index_crc,
                                   uint8_t out[MS_ARCHIVE_HEADER_SIZE]);
void ms_archive_encode_cell(const ms_archive_cell *c, uint8_t out[MS_ARCHIVE_RECORD_SIZE]);

/* Window rules of docs/ARCHIVE.md: the precision window of a cell at `level`. */
void ms_archive_cell_window(const ms_archive_header *h, unsigned level, bool leaf,
                            uint8_t *bits_min, uint8_t *bits_max);

#endif
