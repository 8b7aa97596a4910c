/* libFuzzer target `web_inflate` (corpus tests/corpus/web_inflate): the
 * browser build's own inflater (client/web/ms_web_inflate.h), written from the
 * RFCs because the WebAssembly build has no zlib, against zlib itself on the
 * same bytes. A server, a CDN or anything between them may send the page any
 * bytes as an index head or subtree; the inflater must take them as zlib does.
 *
 * Two checks per input, each aborting when the contract is broken:
 *  - the bytes as a zlib stream: ms_web_inflate accepts them exactly when
 *    zlib's inflate ends the stream (Adler-32 checked) within the same output
 *    limit, with the same output and the same input used; it says DICT
 *    exactly when zlib asks for a dictionary, TOO_BIG exactly when zlib
 *    inflates past the limit, BAD when zlib finds a data error, and SHORT
 *    when zlib wants more input, or BAD there when it found the stream
 *    broken where zlib had not looked yet (then zlib accepts neither 4 KiB of
 *    zeros nor of 0xFF after it); whatever it inflated before failing is
 *    what zlib inflated before it (the common prefix agrees);
 *  - the bytes deflated by zlib (level and strategy from the input, so that
 *    stored, fixed and dynamic blocks all come), with garbage after the
 *    stream: ms_web_inflate gives the bytes back and uses the stream alone.
 *
 * tests/test_fuzz_replay.c includes this file to replay
 * tests/corpus/web_inflate/ in `make test`; it then calls
 * ms_fuzz_web_inflate_one() directly (true: the bytes are a zlib stream that
 * both inflaters accept). */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

#include "ms_web_inflate.h"

#define MS_FUZZ_WEB_INFLATE_CHECK(cond)                                                        \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_web_inflate: contract broken: %s (%s:%d)\n", #cond,          \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* The output limit of both inflaters (a subtree is tens of kilobytes; small
 * enough that a stream inflating past it is easy for the fuzzer to make). */
#define MS_FUZZ_WEB_INFLATE_MAX (1u << 18)

/* What zlib makes of in[0 .. size): its verdict as ms_web_inflate's, the bytes
 * it inflated (at most max + 1: one past the limit tells TOO_BIG) and the
 * input it used. */
static ms_web_inflate_result ms_fuzz_zlib_inflate(const uint8_t *in, size_t size, uint8_t *out, size_t max,
                                                  size_t *out_size, size_t *used)
{
    z_stream z;
    memset(&z, 0, sizeof z);
    MS_FUZZ_WEB_INFLATE_CHECK(inflateInit(&z) == Z_OK);
    z.next_in = (Bytef *)(uintptr_t)in;
    z.avail_in = (uInt)size;
    z.next_out = out;
    z.avail_out = (uInt)(max + 1);
    int r = inflate(&z, Z_FINISH);
    *out_size = (size_t)z.total_out;
    *used = (size_t)z.total_in;
    inflateEnd(&z);
    if (*out_size > max)
        return MS_WEB_INFLATE_TOO_BIG;
    switch (r) {
    case Z_STREAM_END:
        return MS_WEB_INFLATE_OK;
    case Z_NEED_DICT:
        return MS_WEB_INFLATE_DICT;
    case Z_DATA_ERROR:
        return MS_WEB_INFLATE_BAD;
    case Z_BUF_ERROR: /* Z_FINISH with the input spent and the stream not ended */
        return MS_WEB_INFLATE_SHORT;
    default:
        MS_FUZZ_WEB_INFLATE_CHECK(!"zlib answered something else");
        return MS_WEB_INFLATE_BAD;
    }
}

/* Whether zlib accepts in[0 .. size) followed by 4096 bytes `fill` (the
 * stream ending within them). */
static bool ms_fuzz_zlib_accepts_any_continuation(const uint8_t *in, size_t size, int fill)
{
    enum { MORE = 4096 };
    uint8_t *longer = malloc(size + MORE), *out = malloc(MS_FUZZ_WEB_INFLATE_MAX + 1);
    MS_FUZZ_WEB_INFLATE_CHECK(longer != NULL && out != NULL);
    if (size)
        memcpy(longer, in, size);
    memset(longer + size, fill, MORE);
    size_t out_size, used;
    bool ok = ms_fuzz_zlib_inflate(longer, size + MORE, out, MS_FUZZ_WEB_INFLATE_MAX, &out_size, &used) ==
              MS_WEB_INFLATE_OK;
    free(longer);
    free(out);
    return ok;
}

/* The bytes as a zlib stream, both inflaters; true when both accept them. */
static bool ms_fuzz_web_inflate_stream(const uint8_t *data, size_t size)
{
    uint8_t *ours = NULL;
    size_t ours_size = 0, ours_used = 0;
    const char *why = NULL;
    ms_web_inflate_result r =
        ms_web_inflate(data, size, MS_FUZZ_WEB_INFLATE_MAX, &ours, &ours_size, &ours_used, &why);
    uint8_t *theirs = malloc(MS_FUZZ_WEB_INFLATE_MAX + 1);
    MS_FUZZ_WEB_INFLATE_CHECK(theirs != NULL);
    size_t theirs_size = 0, theirs_used = 0;
    ms_web_inflate_result z =
        ms_fuzz_zlib_inflate(data, size, theirs, MS_FUZZ_WEB_INFLATE_MAX, &theirs_size, &theirs_used);
    /* zlib stops at the first place it wants more input; ours may have found
     * the stream broken before that (an empty or incomplete code read,
     * which zlib reads on as zero lengths until it runs out): then no bytes
     * that could follow make it a stream zlib accepts. */
    bool earlier = r == MS_WEB_INFLATE_BAD && z == MS_WEB_INFLATE_SHORT;
    if (r != z && !earlier)
        fprintf(stderr, "fuzz_web_inflate: ours %d (%s), zlib %d\n", (int)r, why ? why : "", (int)z);
    MS_FUZZ_WEB_INFLATE_CHECK(r == z || earlier);
    if (earlier)
        for (int fill = 0; fill <= 0xFF; fill += 0xFF)
            MS_FUZZ_WEB_INFLATE_CHECK(!ms_fuzz_zlib_accepts_any_continuation(data, size, fill));
    MS_FUZZ_WEB_INFLATE_CHECK(r == MS_WEB_INFLATE_OK || (why != NULL && why[0] != '\0' && !strchr(why, '\n')));
    MS_FUZZ_WEB_INFLATE_CHECK(ours_size <= MS_FUZZ_WEB_INFLATE_MAX);
    MS_FUZZ_WEB_INFLATE_CHECK(ours_size == 0 || ours != NULL);
    if (r == MS_WEB_INFLATE_OK) {
        MS_FUZZ_WEB_INFLATE_CHECK(ours_size == theirs_size);
        MS_FUZZ_WEB_INFLATE_CHECK(ours_used == theirs_used);
    }
    size_t common = ours_size < theirs_size ? ours_size : theirs_size;
    MS_FUZZ_WEB_INFLATE_CHECK(common == 0 || memcmp(ours, theirs, common) == 0);
    free(ours);
    free(theirs);
    return r == MS_WEB_INFLATE_OK;
}

/* The bytes deflated by zlib, then garbage: back as they were. */
static void ms_fuzz_web_inflate_round_trip(const uint8_t *data, size_t size)
{
    if (size == 0 || size > 65536)
        return;
    static const int strategies[] = {Z_DEFAULT_STRATEGY, Z_FILTERED, Z_HUFFMAN_ONLY, Z_RLE, Z_FIXED};
    int level = data[0] % 10, strategy = strategies[(data[size - 1] >> 4) % 5];
    z_stream z;
    memset(&z, 0, sizeof z);
    MS_FUZZ_WEB_INFLATE_CHECK(deflateInit2(&z, level, Z_DEFLATED, 15, 8, strategy) == Z_OK);
    uLong bound = deflateBound(&z, (uLong)size);
    uint8_t *packed = malloc(bound + 7);
    MS_FUZZ_WEB_INFLATE_CHECK(packed != NULL);
    z.next_in = (Bytef *)(uintptr_t)data;
    z.avail_in = (uInt)size;
    z.next_out = packed;
    z.avail_out = (uInt)bound;
    MS_FUZZ_WEB_INFLATE_CHECK(deflate(&z, Z_FINISH) == Z_STREAM_END);
    size_t packed_size = (size_t)z.total_out;
    deflateEnd(&z);
    memcpy(packed + packed_size, "garbage", 7);
    uint8_t *out = NULL;
    size_t out_size = 0, used = 0;
    const char *why = NULL;
    MS_FUZZ_WEB_INFLATE_CHECK(ms_web_inflate(packed, packed_size + 7, MS_FUZZ_WEB_INFLATE_MAX, &out, &out_size,
                                             &used, &why) == MS_WEB_INFLATE_OK);
    MS_FUZZ_WEB_INFLATE_CHECK(used == packed_size);
    MS_FUZZ_WEB_INFLATE_CHECK(out_size == size && memcmp(out, data, size) == 0);
    free(out);
    free(packed);
}

static bool ms_fuzz_web_inflate_one(const uint8_t *data, size_t size)
{
    bool accepted = ms_fuzz_web_inflate_stream(data, size);
    ms_fuzz_web_inflate_round_trip(data, size);
    return accepted;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_web_inflate_one(data, size);
    return 0;
}
#endif
