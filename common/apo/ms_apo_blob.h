/* The stored form of an APO chunk: a small header with the level table, then the
 * texel words compressed with zlib, protected by two CRC32s (docs/APO.md, "Stored
 * chunk"). Every integer is little-endian.
 *
 *   0  4  magic "MSAP"
 *   4  2  version (2: texels are corrections of the smooth normal, docs/APO.md;
 *         version 1, whose missing nodes meant "the nearest texel", was never
 *         released and is refused)
 *   6  2  level_count L (0..MS_APO_MAX_LEVELS)
 *   8  4  texel_count (sum of the level table)
 *  12  4  compressed_size C
 *  16  4  CRC32 of the uncompressed words (4*texel_count bytes, little-endian)
 *  20  4  CRC32 of bytes 0..19 followed by the level table
 *  24  4L level table (words per level)
 *  24+4L  C bytes: zlib stream of the words
 *
 * Thread-safety: pure functions; the caller owns every buffer.
 */
#ifndef MS_APO_BLOB_H
#define MS_APO_BLOB_H

#include <stddef.h>
#include <stdint.h>

#include "ms_apo_chunk.h"
#include "ms_error.h"

#define MS_APO_BLOB_VERSION 2u
#define MS_APO_BLOB_HEADER_BYTES 24u

/* Serialises a complete chunk (texel_count must equal the table's total) into a
 * new malloc'd buffer *out of *out_size bytes (the caller frees it). level:
 * zlib level 0..9 (-1 = default). MS_ERR_ARG for a partial chunk, MS_ERR_NOMEM. */
ms_status ms_apo_blob_write(const ms_apo_chunk *chunk, int level, uint8_t **out, size_t *out_size,
                            ms_error *err);

/* Parses and fully validates a stored chunk: size, magic, version, both CRCs, the
 * zlib stream (exact length), then the loader's structural checks. *chunk must be
 * zeroed; on success it owns the words. Errors: MS_ERR_FORMAT (bad size, magic or
 * table), MS_ERR_UNSUPPORTED (version), MS_ERR_CORRUPT (CRC, zlib, structure),
 * MS_ERR_NOMEM. On error *chunk is left zeroed. */
ms_status ms_apo_blob_read(const uint8_t *data, size_t size, ms_apo_chunk *chunk, ms_error *err);

#endif
