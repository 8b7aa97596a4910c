#include "ms_png.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

static void put_be32(uint8_t *out, uint32_t v)
{
    out[0] = (uint8_t)(v >> 24);
    out[1] = (uint8_t)(v >> 16);
    out[2] = (uint8_t)(v >> 8);
    out[3] = (uint8_t)v;
}

/* Writes one chunk: length, type, data, CRC over type and data. */
static int write_chunk(FILE *f, const char type[4], const uint8_t *data, uint32_t size)
{
    uint8_t head[8];
    put_be32(head, size);
    memcpy(head + 4, type, 4);
    uLong crc = crc32(0L, (const Bytef *)type, 4);
    if (size)
        crc = crc32(crc, data, size);
    uint8_t tail[4];
    put_be32(tail, (uint32_t)crc);
    return fwrite(head, 1, 8, f) != 8 || (size && fwrite(data, 1, size, f) != size) ||
           fwrite(tail, 1, 4, f) != 4;
}

ms_status ms_png_write(const char *path, const uint8_t *pixels, uint32_t width, uint32_t height,
                       int channels, ms_error *err)
{
    if (width < 1 || width > 65535 || height < 1 || height > 65535 ||
        (channels != 1 && channels != 3))
        return ms_error_set(err, MS_ERR_ARG, "%s: bad PNG size %ux%u x%d", path, width, height,
                            channels);
    size_t row = (size_t)width * (size_t)channels + 1; /* filter byte + samples */
    size_t raw_size = row * height;
    uint8_t *raw = malloc(raw_size);
    uLongf packed_size = compressBound((uLong)raw_size);
    uint8_t *packed = malloc(packed_size);
    if (!raw || !packed) {
        free(raw);
        free(packed);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    for (uint32_t y = 0; y < height; ++y) {
        raw[y * row] = 0; /* filter: none */
        memcpy(raw + y * row + 1, pixels + (size_t)y * (row - 1), row - 1);
    }
    int zst = compress2(packed, &packed_size, raw, (uLong)raw_size, 6);
    free(raw);
    if (zst != Z_OK) {
        free(packed);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: zlib compression failed", path);
    }
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        free(packed);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", tmp, strerror(errno));
    }
    static const uint8_t signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    uint8_t ihdr[13];
    put_be32(ihdr, width);
    put_be32(ihdr + 4, height);
    ihdr[8] = 8;                       /* bit depth */
    ihdr[9] = channels == 3 ? 2 : 0;   /* colour type: RGB or grey */
    ihdr[10] = ihdr[11] = ihdr[12] = 0; /* deflate, adaptive filter, no interlace */
    int failed = fwrite(signature, 1, 8, f) != 8 || write_chunk(f, "IHDR", ihdr, 13) ||
                 write_chunk(f, "IDAT", packed, (uint32_t)packed_size) ||
                 write_chunk(f, "IEND", NULL, 0);
    free(packed);
    failed |= fclose(f) != 0;
    if (failed || rename(tmp, path) != 0) {
        remove(tmp);
        return ms_error_set(err, MS_ERR_IO, "%s: write failed", path);
    }
    return MS_OK;
}
