/* The index blob's wire encoding (PROTOCOL.md section 4.8): see ms_proto.h.
 * The decoded size is declared before any byte arrives and inflating never
 * goes past it, so a hostile stream costs at most that declared buffer. */
#include <stdlib.h>
#include <zlib.h>

#include "ms_proto.h"

ms_status ms_proto_index_deflate(const uint8_t *blob, size_t size, uint8_t **encoded,
                                 size_t *encoded_size, ms_error *err)
{
    *encoded = NULL;
    *encoded_size = 0;
    if (!blob || size == 0 || size > MS_PROTO_MAX_INDEX_SIZE)
        return ms_error_set(err, MS_ERR_ARG, "index blob of %zu bytes", size);
    uLongf capacity = compressBound((uLong)size);
    uint8_t *z = malloc(capacity);
    if (!z)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory compressing a %zu-byte index", size);
    int r = compress2(z, &capacity, blob, (uLong)size, Z_BEST_COMPRESSION);
    if (r != Z_OK) {
        free(z);
        return ms_error_set(err, r == Z_MEM_ERROR ? MS_ERR_NOMEM : MS_ERR_ARG,
                            "zlib could not compress the index (%d)", r);
    }
    if (capacity >= size) {
        free(z);
        return ms_error_set(err, MS_ERR_RANGE, "the index does not compress (%lu >= %zu bytes)",
                            (unsigned long)capacity, size);
    }
    uint8_t *shrunk = realloc(z, capacity);
    *encoded = shrunk ? shrunk : z;
    *encoded_size = capacity;
    return MS_OK;
}

/* Runs the whole inflate into out[0..declared) and classifies how it ended. */
static ms_status inflate_bounded(z_stream *z, uint32_t declared, ms_error *err)
{
    int r = inflate(z, Z_FINISH);
    if (r == Z_MEM_ERROR)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory inflating the index");
    if (r == Z_NEED_DICT || r == Z_DATA_ERROR || r == Z_STREAM_ERROR)
        return ms_error_set(err, MS_ERR_FORMAT, "compressed index is not a valid zlib stream: %s",
                            z->msg ? z->msg : "bad data");
    if (r != Z_STREAM_END && z->avail_out == 0) {
        /* The declared room is full and the stream goes on: one byte more
         * tells whether it had more to give (too long) or just its trailer. */
        uint8_t extra;
        z->next_out = &extra;
        z->avail_out = 1;
        r = inflate(z, Z_FINISH);
        if (z->avail_out == 0)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "compressed index inflates to more than the declared %u bytes",
                                (unsigned)declared);
        if (r == Z_NEED_DICT || r == Z_DATA_ERROR || r == Z_STREAM_ERROR)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "compressed index is not a valid zlib stream: %s",
                                z->msg ? z->msg : "bad data");
    }
    if (r != Z_STREAM_END)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "compressed index is truncated (%lu bytes inflated of %u)",
                            (unsigned long)z->total_out, (unsigned)declared);
    if (z->total_out != declared)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "compressed index inflates to %lu bytes, not the declared %u",
                            (unsigned long)z->total_out, (unsigned)declared);
    if (z->avail_in != 0)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%u bytes follow the end of the compressed index",
                            (unsigned)z->avail_in);
    return MS_OK;
}

ms_status ms_proto_index_inflate(const uint8_t *encoded, size_t encoded_size,
                                 uint32_t declared_size, uint32_t index_crc32, uint8_t *out,
                                 ms_error *err)
{
    if (declared_size == 0 || declared_size > MS_PROTO_MAX_INDEX_SIZE)
        return ms_error_set(err, MS_ERR_RANGE, "declared index size %u outside [1, %u]",
                            (unsigned)declared_size, MS_PROTO_MAX_INDEX_SIZE);
    if (encoded_size == 0 || encoded_size >= declared_size)
        return ms_error_set(err, MS_ERR_RANGE,
                            "compressed index of %zu bytes is not shorter than the declared %u",
                            encoded_size, (unsigned)declared_size);
    if (!encoded || !out)
        return ms_error_set(err, MS_ERR_ARG, "no compressed index or no output buffer");
    z_stream z = {0};
    if (inflateInit(&z) != Z_OK)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory inflating the index");
    z.next_in = (Bytef *)(uintptr_t)encoded; /* zlib's API is not const-correct */
    z.avail_in = (uInt)encoded_size;
    z.next_out = out;
    z.avail_out = declared_size;
    ms_status st = inflate_bounded(&z, declared_size, err);
    inflateEnd(&z);
    if (st != MS_OK)
        return st;
    if ((uint32_t)crc32_z(0L, out, declared_size) != index_crc32)
        return ms_error_set(err, MS_ERR_CORRUPT, "inflated model index fails its CRC-32");
    return MS_OK;
}
