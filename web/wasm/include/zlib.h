/* The part of zlib's interface that the decoding sources use, for the
 * WebAssembly build only (make wasm; docs/BROWSER.md). Emscripten's zlib port
 * is not available offline: ms_wasm_zlib.c computes the CRC-32 and inflates
 * a zlib stream given whole (client/web/ms_web_inflate.h: the index head and
 * its subtrees); deflating is a stub that fails with a clear message. Native
 * builds use the real zlib.h. */
#ifndef MS_WASM_ZLIB_H
#define MS_WASM_ZLIB_H

#include <stddef.h>

typedef unsigned char Bytef;
typedef unsigned int uInt;
typedef unsigned long uLong;
typedef size_t z_size_t;
typedef long z_off_t;

#define Z_OK 0
#define Z_STREAM_END 1
#define Z_NEED_DICT 2
#define Z_ERRNO (-1)
#define Z_STREAM_ERROR (-2)
#define Z_DATA_ERROR (-3)
#define Z_MEM_ERROR (-4)
#define Z_BUF_ERROR (-5)
#define Z_NO_FLUSH 0
#define Z_FINISH 4
#define Z_FILTERED 1
#define Z_DEFLATED 8

typedef struct z_stream_s {
    Bytef *next_in;
    uInt avail_in;
    uLong total_in;
    Bytef *next_out;
    uInt avail_out;
    uLong total_out;
    const char *msg;
    void *zalloc, *zfree, *opaque;
    struct ms_wasm_inflate_state *state; /* ms_wasm_zlib.c's */
} z_stream;

uLong crc32(uLong crc, const Bytef *buf, uInt len);
uLong crc32_z(uLong crc, const Bytef *buf, z_size_t len);

int inflateInit(z_stream *strm);
int inflate(z_stream *strm, int flush);
int inflateEnd(z_stream *strm);
int deflateInit2(z_stream *strm, int level, int method, int window_bits, int mem_level,
                 int strategy);
uLong deflateBound(z_stream *strm, uLong source_length);
int deflate(z_stream *strm, int flush);
int deflateEnd(z_stream *strm);

#endif
