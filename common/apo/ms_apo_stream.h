/* APO chunks as the archive stores them (docs/ARCHIVE.md, "Per-cell tables"):
 * the texel words as little-endian bytes, deflated into one zlib stream with a
 * sync flush after every level, so that the bytes up to any level boundary
 * inflate on their own; and a level table of two words per level L: the
 * compressed length at which levels 0..L are complete, and the texels in levels
 * 0..L. A client may fetch a prefix of whole levels and inflate it alone.
 *
 * Ownership: *out buffers are malloc'd and owned by the caller. Thread-safety:
 * pure functions, no shared state.
 */
#ifndef MS_APO_STREAM_H
#define MS_APO_STREAM_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_chunk.h"
#include "ms_error.h"

/* Compresses a complete chunk (texel_count must equal the sum of its table;
 * MS_ERR_ARG otherwise) at zlib level 0..9 (-1 = default). level_table receives
 * 2 * level_count words. An empty chunk (0 levels) gives 0 bytes and *out NULL.
 * MS_ERR_NOMEM when memory or zlib fails; MS_ERR_RANGE beyond 4 GiB. */
ms_status ms_apo_stream_compress(const ms_apo_chunk *chunk, int zlib_level, uint8_t **out, size_t *out_size,
                                 uint32_t level_table[2 * MS_APO_MAX_LEVELS], ms_error *err);

/* Inflates data[0..size), the whole stored chunk or any prefix of it, given its
 * level table (2 * levels words, as stored). *chunk (zeroed by the caller)
 * receives the complete chunk's per-level word counts and the words of every
 * level whose compressed end is within size, ready for ms_apo_view_init.
 * Errors: MS_ERR_FORMAT for a table that is not monotone, has an empty level,
 * too many levels or more bytes than its end; MS_ERR_CORRUPT when zlib fails or
 * the stream does not inflate to exactly the table's words at a level boundary;
 * MS_ERR_NOMEM. On error *chunk stays zeroed. */
ms_status ms_apo_stream_inflate(const uint8_t *data, size_t size, const uint32_t *level_table, uint32_t levels,
                                ms_apo_chunk *chunk, ms_error *err);

#endif
