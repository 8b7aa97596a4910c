/* Stored APO chunk: header, level table, zlib-compressed words, CRC32s. */
#include "ms_apo_blob.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

static void put_u16(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}
static void put_u32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}
static uint32_t get_u16(const uint8_t *p) { return (uint32_t)p[0] | (uint32_t)p[1] << 8; }
static uint32_t get_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* The words as little-endian bytes, whatever the host order. */
static uint8_t *words_to_bytes(const uint32_t *words, size_t count)
{
    uint8_t *b = malloc(count * 4 + 1);
    if (b)
        ms_apo_words_to_bytes(words, count, b);
    return b;
}

static uint32_t crc_of(const uint8_t *p, size_t n)
{
    uLong c = crc32(0L, Z_NULL, 0);
    while (n > 0) {
        uInt step = n > (1u << 30) ? (1u << 30) : (uInt)n;
        c = crc32(c, p, step);
        p += step;
        n -= step;
    }
    return (uint32_t)c;
}

ms_status ms_apo_blob_write(const ms_apo_chunk *chunk, int level, uint8_t **out, size_t *out_size, ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    if (chunk->level_count > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_ARG, "apo blob: %u levels", chunk->level_count);
    uint64_t total = 0;
    for (uint32_t d = 0; d < chunk->level_count; ++d)
        total += chunk->level_texels[d];
    if (total != chunk->texel_count || total > MS_APO_MAX_TEXELS)
        return ms_error_set(err, MS_ERR_ARG, "apo blob: chunk holds %zu of %llu words", chunk->texel_count,
                            (unsigned long long)total);
    size_t raw_size = chunk->texel_count * 4;
    uint8_t *raw = words_to_bytes(chunk->texels, chunk->texel_count);
    size_t head = MS_APO_BLOB_HEADER_BYTES + 4u * chunk->level_count;
    uLongf bound = compressBound((uLong)raw_size);
    uint8_t *blob = malloc(head + bound);
    if (!raw || !blob) {
        free(raw);
        free(blob);
        return ms_error_set(err, MS_ERR_NOMEM, "apo blob: no memory for %zu bytes", raw_size);
    }
    uLongf csize = bound;
    if (compress2(blob + head, &csize, raw, (uLong)raw_size, level < -1 || level > 9 ? -1 : level) != Z_OK) {
        free(raw);
        free(blob);
        return ms_error_set(err, MS_ERR_NOMEM, "apo blob: zlib compression failed");
    }
    memcpy(blob, "MSAP", 4);
    put_u16(blob + 4, MS_APO_BLOB_VERSION);
    put_u16(blob + 6, chunk->level_count);
    put_u32(blob + 8, (uint32_t)chunk->texel_count);
    put_u32(blob + 12, (uint32_t)csize);
    put_u32(blob + 16, crc_of(raw, raw_size));
    for (uint32_t d = 0; d < chunk->level_count; ++d)
        put_u32(blob + MS_APO_BLOB_HEADER_BYTES + 4 * d, chunk->level_texels[d]);
    /* The header CRC covers bytes 0..19 and the table (bytes 24..head). */
    uLong c = crc32(0L, Z_NULL, 0);
    c = crc32(c, blob, 20);
    c = crc32(c, blob + MS_APO_BLOB_HEADER_BYTES, (uInt)(head - MS_APO_BLOB_HEADER_BYTES));
    put_u32(blob + 20, (uint32_t)c);
    free(raw);
    *out = blob;
    *out_size = head + csize;
    return MS_OK;
}

ms_status ms_apo_blob_read(const uint8_t *data, size_t size, ms_apo_chunk *chunk, ms_error *err)
{
    memset(chunk, 0, sizeof *chunk);
    if (size < MS_APO_BLOB_HEADER_BYTES || memcmp(data, "MSAP", 4) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "apo blob: no APO chunk header (%zu bytes)", size);
    uint32_t version = get_u16(data + 4);
    if (version != MS_APO_BLOB_VERSION)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "apo blob: version %u (this reader knows only %u)", version,
                            MS_APO_BLOB_VERSION);
    uint32_t levels = get_u16(data + 6);
    if (levels > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_FORMAT, "apo blob: %u levels (max %u)", levels, MS_APO_MAX_LEVELS);
    size_t head = MS_APO_BLOB_HEADER_BYTES + 4u * levels;
    uint32_t texels = get_u32(data + 8), csize = get_u32(data + 12);
    if (size < head || size - head != csize)
        return ms_error_set(err, MS_ERR_FORMAT, "apo blob: %zu bytes, header declares %zu", size,
                            head + (size_t)csize);
    uLong c = crc32(0L, Z_NULL, 0);
    c = crc32(c, data, 20);
    c = crc32(c, data + MS_APO_BLOB_HEADER_BYTES, (uInt)(head - MS_APO_BLOB_HEADER_BYTES));
    if ((uint32_t)c != get_u32(data + 20))
        return ms_error_set(err, MS_ERR_CORRUPT, "apo blob: header CRC mismatch");
    uint32_t table[MS_APO_MAX_LEVELS];
    uint64_t total = 0;
    for (uint32_t d = 0; d < levels; ++d) {
        table[d] = get_u32(data + MS_APO_BLOB_HEADER_BYTES + 4 * d);
        total += table[d];
    }
    if (total != texels || total > MS_APO_MAX_TEXELS)
        return ms_error_set(err, MS_ERR_FORMAT, "apo blob: table sums to %llu words, header says %u",
                            (unsigned long long)total, texels);
    size_t raw_size = (size_t)texels * 4;
    uint8_t *raw = malloc(raw_size + 1);
    uint32_t *words = malloc((size_t)texels * sizeof *words + 1);
    if (!raw || !words) {
        free(raw);
        free(words);
        return ms_error_set(err, MS_ERR_NOMEM, "apo blob: no memory for %zu bytes", raw_size);
    }
    uLongf got = (uLongf)raw_size;
    int zr = uncompress(raw, &got, data + head, csize);
    ms_status st = MS_OK;
    if (zr != Z_OK || got != raw_size)
        st = ms_error_set(err, MS_ERR_CORRUPT, "apo blob: zlib stream is damaged or has the wrong length");
    else if (crc_of(raw, raw_size) != get_u32(data + 16))
        st = ms_error_set(err, MS_ERR_CORRUPT, "apo blob: texel CRC mismatch");
    if (st == MS_OK) {
        ms_apo_words_from_bytes(raw, texels, words);
        ms_apo_view view;
        st = ms_apo_view_init(&view, table, levels, words, texels, err);
    }
    free(raw);
    if (st != MS_OK)
        free(words);
    else
        ms_apo_chunk_adopt(chunk, words, texels, levels, table);
    return st;
}
