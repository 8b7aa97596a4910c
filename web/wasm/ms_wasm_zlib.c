/* The WebAssembly build's stand-in for zlib (include/zlib.h): the CRC-32 of
 * zlib and PNG (reflected polynomial 0xEDB88320, initial and final complement),
 * computed a byte at a time from a table built at compile time; the stream
 * functions fail with a message saying where inflating happens instead. */
#include <zlib.h>

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

static const char *const not_here =
    "zlib streams are not inflated in the WebAssembly module (the page uses DecompressionStream)";

int inflateInit(z_stream *strm)
{
    strm->msg = NULL;
    strm->total_in = strm->total_out = 0;
    return Z_OK;
}

int inflate(z_stream *strm, int flush)
{
    (void)flush;
    strm->msg = not_here;
    return Z_DATA_ERROR;
}

int inflateEnd(z_stream *strm)
{
    (void)strm;
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
