/* Writing a meshstream archive file (docs/ARCHIVE.md, version 3: the index
 * stored as a directory and its subtrees, each one zlib stream with fixed
 * parameters).
 *
 * Usage: open with the header fields and the tree topology (for each cell in
 * breadth-first order, the index of its first child or MS_ARCHIVE_NONE), put each
 * cell's geometry payload (and APO chunk when the header says so) in any order —
 * the baker produces them in post-order, from several threads — then finish.
 * Payloads are spooled to an unlinked temporary file, so memory stays bounded by
 * the index; finish writes `path.partial`, flushes it to disk and renames it to
 * `path`. Abort, any error, or a killed process never leaves a file at `path`
 * that looks complete. While it writes `path.partial` the writer holds an
 * exclusive flock on it, so that ms_archive_writer_remove_stale can tell the
 * leftovers of a killed writer from the file of one at work.
 *
 * Ownership: the writer copies what it is given. Thread-safety: calls on one
 * writer must be serialised by the caller.
 */
#ifndef MS_ARCHIVE_WRITER_H
#define MS_ARCHIVE_WRITER_H

#include <stdint.h>

#include "ms_archive.h"
#include "ms_error.h"

typedef struct ms_archive_writer ms_archive_writer;

/* header: every field but table_words, file_size, version and index_stored_size
 * is used (the writer sets those); cell_count gives
 * the length of first_child. The topology is checked against the breadth-first
 * rules (MS_ERR_ARG when it breaks them). */
ms_status ms_archive_writer_open(const char *path, const ms_archive_header *header,
                                 const uint32_t *first_child, ms_archive_writer **writer,
                                 ms_error *err);

/* prefix_table has bits_max - bits_min + 1 entries (see docs/ARCHIVE.md); counts
 * are the cell's vertices and triangles at bits_max. Once per cell. */
ms_status ms_archive_writer_put_geometry(ms_archive_writer *writer, uint32_t cell,
                                         const uint8_t *data, uint32_t length,
                                         const uint32_t *prefix_table, uint32_t vertex_count,
                                         uint32_t triangle_count, ms_error *err);

/* The cell's surface error table (ms_archive.h, MS_ARCHIVE_ERROR_SCALE): one
 * byte per bit of its window (copied), each at most MS_ARCHIVE_ERROR_MAX and
 * at most twice the one before (never growing in world units); MS_ERR_ARG
 * otherwise. Optional, at most once per cell: a cell without one gets its
 * kd-cells' half-diagonals. */
ms_status ms_archive_writer_put_error(ms_archive_writer *writer, uint32_t cell,
                                      const uint8_t *error_table, ms_error *err);

/* level_table has 2 * levels words (compressed bytes, texels per complete level
 * prefix). At most once per cell; only when the header has has_apo. */
ms_status ms_archive_writer_put_apo(ms_archive_writer *writer, uint32_t cell,
                                    const uint8_t *data, uint32_t length, uint32_t raw_length,
                                    const uint32_t *level_table, uint8_t levels, ms_error *err);

/* The APO chunk put for a cell, read back: *data (malloc'd, caller frees; NULL
 * for an empty one), its length and its level table (2 * levels words, borrowed
 * until the chunk is dropped or the writer finishes); levels 0 and *data NULL
 * when the cell has none. MS_ERR_ARG for a bad cell, MS_ERR_IO, MS_ERR_NOMEM. */
ms_status ms_archive_writer_get_apo(ms_archive_writer *writer, uint32_t cell, uint8_t **data,
                                    uint32_t *length, const uint32_t **level_table, uint8_t *levels,
                                    ms_error *err);

/* Forgets a cell's APO chunk (its bytes stay in the spool, unused), so that
 * ms_archive_writer_put_apo may give it another, or it keeps none. */
void ms_archive_writer_drop_apo(ms_archive_writer *writer, uint32_t cell);

/* The cell's colour stream (docs/COLOUR.md) over its window: prefix_table has
 * bits_max - bits_min + 1 entries, entry k the bytes that decode its colour to
 * bits_min + k bits (entry 0: the stream header and base chunk), the last the
 * length. Exactly once for each cell with vertices, only when the header has
 * has_colour (and colour_bits, colour_alpha). */
ms_status ms_archive_writer_put_colour(ms_archive_writer *writer, uint32_t cell,
                                       const uint8_t *data, uint32_t length,
                                       const uint32_t *prefix_table, ms_error *err);

/* The precision window the writer expects for a cell (from the topology). */
void ms_archive_writer_window(const ms_archive_writer *writer, uint32_t cell, uint8_t *bits_min,
                              uint8_t *bits_max);

/* Sets the welded input counts of the header (the baker knows them only after
 * encoding). */
void ms_archive_writer_set_counts(ms_archive_writer *writer, uint64_t vertex_count,
                                  uint64_t triangle_count);

/* Chooses the index's subtree depth S (1..8; 0: ms_subtree_default_levels of
 * the header's n, the default). MS_ERR_ARG otherwise. The records, payloads
 * and content id do not depend on it. */
ms_status ms_archive_writer_set_subtree_levels(ms_archive_writer *writer, unsigned subtree_levels,
                                               ms_error *err);

/* The threads finish may encode and deflate the index's subtrees on (0 or 1, the
 * default: the calling thread alone); the file's bytes are the same for any
 * value. */
void ms_archive_writer_set_threads(ms_archive_writer *writer, unsigned threads);

/* Writes the file. Every cell must have its geometry. Frees the writer, whatever
 * the outcome. */
ms_status ms_archive_writer_finish(ms_archive_writer *writer, ms_error *err);

/* Drops everything written so far. Accepts NULL. */
void ms_archive_writer_abort(ms_archive_writer *writer);

/* Called with the file name (not the path) of each leftover removed. */
typedef void (*ms_archive_stale_fn)(void *arg, const char *file_name);

/* Removes every *.msa.partial in dir that no writer holds (left by a killed
 * bake); a file whose lock cannot be taken at once belongs to a bake at work
 * and stays. Returns how many were removed; a directory that cannot be read
 * removes nothing. */
unsigned ms_archive_writer_remove_stale(const char *dir, ms_archive_stale_fn removed, void *arg);

#endif
