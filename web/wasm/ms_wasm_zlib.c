/* The WebAssembly build's stand-in for zlib (include/zlib.h): the CRC-32 of
 * zlib and PNG (reflected polynomial 0xEDB88320, initial and final complement),
 * computed a byte at a time from a table built at compile time; inflating by
 * client/web's ms_web_inflate; deflating fails with a message saying so. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ms_web_inflate.h"

#define POLY 0xEDB88320u
#define R1(c) (((c) >> 1) ^ (POLY & (0u - ((c) & 1u))))
#define R8(c) R1(R1(R1(R1(R1(R1(R1(R1(c))))))))
#define T4(n) R8((n) + 0u), R8((n) + 1u), R8((n) + 2u), R8((n) + 3u)
#define T16(n) T4(n), T4((n) + 4u), T4((n) + 8u), T4((n) + 12u)
#define T64(n) T16(n), T16((n) + 16u), T16((n) + 32u), T16((n) + 48u)

static const unsigned int table[256] = {T64(0u), T64(64u), T64(128u), T64(192u)};

uLong crc32_z(uLong crc, const Bytef *buf, z_size_t len)
{
    if (!buf)
        return 0;
    unsigned int c = ~(unsigned int)crc;
    for (z_size_t i = 0; i < len; ++i)
        c = table[(c ^ buf[i]) & 0xFFu] ^ (c >> 8);
    return ~c;
}

uLong crc32(uLong crc, const Bytef *buf, uInt len) { return crc32_z(crc, buf, len); }

static const char *const not_here = "zlib streams are not deflated in the WebAssembly module";

/* Inflating: the whole stream is inflated at the first call
 * (ms_web_inflate: the callers, common/archive's subtree reader, give it
 * whole), then handed out as the caller's room allows; the result comes with
 * the last byte (Z_STREAM_END, or the failure, as zlib would say it after
 * the bytes it could give). */
struct ms_wasm_inflate_state {
    int started;
    uint8_t *out;
    size_t size, at;
    int result;
};

int inflateInit(z_stream *strm)
{
    strm->msg = NULL;
    strm->total_in = strm->total_out = 0;
    strm->state = calloc(1, sizeof *strm->state);
    return strm->state ? Z_OK : Z_MEM_ERROR;
}

int inflate(z_stream *strm, int flush)
{
    (void)flush;
    struct ms_wasm_inflate_state *s = strm->state;
    if (!s)
        return Z_STREAM_ERROR;
    if (!s->started) {
        s->started = 1;
        size_t used;
        const char *why;
        /* the most zlib's format can give a byte in (docs/ARCHIVE.md) */
        size_t max = (size_t)strm->avail_in * 1032u + 64u;
        ms_web_inflate_result r = ms_web_inflate(strm->next_in, strm->avail_in, max, &s->out, &s->size,
                                                 &used, &why);
        strm->next_in += used;
        strm->avail_in -= (uInt)used;
        strm->total_in += used;
        s->result = r == MS_WEB_INFLATE_OK      ? Z_STREAM_END
                    : r == MS_WEB_INFLATE_SHORT ? Z_BUF_ERROR
                    : r == MS_WEB_INFLATE_DICT  ? Z_NEED_DICT
                    : r == MS_WEB_INFLATE_NOMEM ? Z_MEM_ERROR
                                                : Z_DATA_ERROR;
        if (r != MS_WEB_INFLATE_OK)
            strm->msg = why;
    }
    size_t n = s->size - s->at;
    if (n > strm->avail_out)
        n = strm->avail_out;
    if (n)
        memcpy(strm->next_out, s->out + s->at, n);
    s->at += n;
    strm->next_out += n;
    strm->avail_out -= (uInt)n;
    strm->total_out += n;
    return s->at < s->size ? Z_OK : s->result;
}

int inflateEnd(z_stream *strm)
{
    if (strm->state) {
        free(strm->state->out);
        free(strm->state);
        strm->state = NULL;
    }
    return Z_OK;
}

int deflateInit2(z_stream *strm, int level, int method, int window_bits, int mem_level,
                 int strategy)
{
    (void)level, (void)method, (void)window_bits, (void)mem_level, (void)strategy;
    strm->msg = not_here;
    return Z_STREAM_ERROR;
}

uLong deflateBound(z_stream *strm, uLong source_length)
{
    (void)strm;
    return source_length + 64;
}

int deflate(z_stream *strm, int flush)
{
    (void)flush;
    strm->msg = not_here;
    return Z_STREAM_ERROR;
}

int deflateEnd(z_stream *strm)
{
    (void)strm;
    return Z_OK;
}
