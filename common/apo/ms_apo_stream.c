/* APO chunks in the archive: zlib with a flush per level (see ms_apo_stream.h). */
#include "ms_apo_stream.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

ms_status ms_apo_stream_compress(const ms_apo_chunk *chunk, int zlib_level, uint8_t **out, size_t *out_size,
                                 uint32_t level_table[2 * MS_APO_MAX_LEVELS], ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    uint64_t total = 0;
    for (uint32_t d = 0; d < chunk->level_count && d < MS_APO_MAX_LEVELS; ++d)
        total += chunk->level_texels[d];
    if (chunk->level_count > MS_APO_MAX_LEVELS || total != chunk->texel_count || total > MS_APO_MAX_TEXELS)
        return ms_error_set(err, MS_ERR_ARG, "apo stream: chunk holds %zu words of %llu", chunk->texel_count,
                            (unsigned long long)total);
    if (chunk->level_count == 0)
        return MS_OK;
    size_t raw_size = chunk->texel_count * 4;
    uint8_t *raw = malloc(raw_size);
    z_stream z;
    memset(&z, 0, sizeof z);
    if (!raw || deflateInit(&z, zlib_level < -1 || zlib_level > 9 ? -1 : zlib_level) != Z_OK) {
        free(raw);
        return ms_error_set(err, MS_ERR_NOMEM, "apo stream: no memory for %zu bytes", raw_size);
    }
    ms_apo_words_to_bytes(chunk->texels, chunk->texel_count, raw);
    /* deflateBound covers one stream of raw_size bytes. A sync flush per level
     * can end a block early (worst case: one more stored-block header, 5 bytes,
     * as a level's few incompressible bytes start a stored block of their own),
     * then appends an empty stored block (5 bytes) after up to 7 bits of
     * padding: 11 bytes a level beyond the bound; 16 kept. (6 was too few: the
     * dragon baked with --apo-tol 0.4 ran out at a chunk's level 8.) */
    size_t cap = deflateBound(&z, (uLong)raw_size) + 16u * chunk->level_count + 16;
    uint8_t *buf = malloc(cap);
    ms_status st = buf ? MS_OK : ms_error_set(err, MS_ERR_NOMEM, "apo stream: no memory for %zu bytes", cap);
    size_t start = 0;
    uint64_t texels = 0;
    z.next_out = buf;
    z.avail_out = (uInt)cap;
    for (uint32_t d = 0; st == MS_OK && d < chunk->level_count; ++d) {
        size_t n = (size_t)chunk->level_texels[d] * 4;
        z.next_in = raw + start;
        z.avail_in = (uInt)n;
        bool last = d + 1 == chunk->level_count;
        int rc = deflate(&z, last ? Z_FINISH : Z_SYNC_FLUSH);
        if (rc != (last ? Z_STREAM_END : Z_OK) || z.avail_in != 0)
            st = ms_error_set(err, MS_ERR_NOMEM, "apo stream: zlib failed at level %u", d);
        start += n;
        texels += chunk->level_texels[d];
        if (z.total_out > UINT32_MAX)
            st = ms_error_set(err, MS_ERR_RANGE, "apo stream: chunk over 4 GiB");
        level_table[2 * d] = (uint32_t)z.total_out;
        level_table[2 * d + 1] = (uint32_t)texels;
    }
    *out_size = z.total_out;
    deflateEnd(&z);
    free(raw);
    if (st != MS_OK) {
        free(buf);
        *out_size = 0;
        return st;
    }
    *out = buf;
    return MS_OK;
}

ms_status ms_apo_stream_inflate(const uint8_t *data, size_t size, const uint32_t *level_table, uint32_t levels,
                                ms_apo_chunk *chunk, ms_error *err)
{
    memset(chunk, 0, sizeof *chunk);
    if (levels > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_FORMAT, "apo stream: %u levels", levels);
    uint32_t per_level[MS_APO_MAX_LEVELS], complete = 0, prev_bytes = 0, prev_texels = 0;
    for (uint32_t d = 0; d < levels; ++d) {
        uint32_t bytes = level_table[2 * d], texels = level_table[2 * d + 1];
        if (bytes <= prev_bytes || texels <= prev_texels || texels > MS_APO_MAX_TEXELS)
            return ms_error_set(err, MS_ERR_FORMAT, "apo stream: level table is not increasing at level %u", d);
        per_level[d] = texels - prev_texels;
        if (bytes <= size)
            complete = d + 1;
        prev_bytes = bytes, prev_texels = texels;
    }
    if (levels && size > prev_bytes)
        return ms_error_set(err, MS_ERR_FORMAT, "apo stream: %zu bytes for a chunk of %u", size, prev_bytes);
    size_t want_bytes = complete ? level_table[2 * (complete - 1)] : 0;
    size_t want_words = complete ? level_table[2 * (complete - 1) + 1] : 0;
    uint8_t *raw = malloc(want_words * 4 + 1);
    uint32_t *words = malloc(want_words * sizeof *words + 1);
    if (!raw || !words) {
        free(raw);
        free(words);
        return ms_error_set(err, MS_ERR_NOMEM, "apo stream: no memory for %zu words", want_words);
    }
    ms_status st = MS_OK;
    if (complete) {
        z_stream z;
        memset(&z, 0, sizeof z);
        if (inflateInit(&z) != Z_OK) {
            free(raw);
            free(words);
            return ms_error_set(err, MS_ERR_NOMEM, "apo stream: zlib could not start");
        }
        z.next_in = (Bytef *)(uintptr_t)data;
        z.avail_in = (uInt)want_bytes;
        z.next_out = raw;
        z.avail_out = (uInt)(want_words * 4);
        int rc = inflate(&z, Z_SYNC_FLUSH);
        bool whole = complete == levels;
        /* A whole chunk ends its stream (and so checks zlib's Adler-32); a prefix
         * must yield exactly its levels' words from exactly its bytes. */
        bool ok = whole ? rc == Z_STREAM_END : (rc == Z_OK || rc == Z_BUF_ERROR);
        if (ok && !whole && z.avail_out == 0 && z.avail_in == 0) {
            uint8_t extra;
            z.next_out = &extra;
            z.avail_out = 1;
            rc = inflate(&z, Z_SYNC_FLUSH);
            ok = z.avail_out == 1 && (rc == Z_OK || rc == Z_BUF_ERROR);
        }
        if (!ok || z.avail_in != 0 || z.total_out != want_words * 4)
            st = ms_error_set(err, MS_ERR_CORRUPT, "apo stream: zlib data is damaged or does not match the "
                              "level table (%u of %u levels)", complete, levels);
        inflateEnd(&z);
    }
    if (st == MS_OK)
        ms_apo_words_from_bytes(raw, want_words, words);
    free(raw);
    if (st != MS_OK)
        free(words);
    else
        ms_apo_chunk_adopt(chunk, words, want_words, levels, per_level);
    return st;
}
