/* Inflating one zlib stream (RFC 1950 around RFC 1951) in one call, for the
 * WebAssembly build, which has no zlib (docs/BROWSER.md, "Build"): the index
 * head and its subtrees are stored deflated (docs/ARCHIVE.md, "Subtrees"),
 * and the page reads them through the very reader the native client uses
 * (common/archive's ms_archive_open_head, ms_archive_add_subtree), whose
 * inflate calls web/wasm/ms_wasm_zlib.c answers with this. Built natively
 * too, so that tests/test_web_view.c checks it against zlib under the
 * sanitizers. Written from the RFCs: canonical Huffman codes decoded a bit at
 * a time (the streams here are tens of kilobytes). */
#ifndef MS_WEB_INFLATE_H
#define MS_WEB_INFLATE_H

#include <stddef.h>
#include <stdint.h>

typedef enum ms_web_inflate_result {
    MS_WEB_INFLATE_OK = 0,      /* the stream ended, its Adler-32 right */
    MS_WEB_INFLATE_SHORT = 1,   /* the input ends before the stream does */
    MS_WEB_INFLATE_BAD = 2,     /* not a valid zlib stream (why says how) */
    MS_WEB_INFLATE_DICT = 3,    /* the stream needs a preset dictionary */
    MS_WEB_INFLATE_TOO_BIG = 4, /* it inflates to more than max_out bytes */
    MS_WEB_INFLATE_NOMEM = 5
} ms_web_inflate_result;

/* Inflates the zlib stream at the start of in[0 .. in_size) into a malloc'd
 * buffer (*out, *out_size; the caller frees it, also on failure, where it
 * holds what was inflated before the stream failed or ended early; NULL when
 * nothing was). *used: the input bytes the stream took (header, blocks and
 * Adler-32; what follows is not read). *why: a constant line for a failure. */
ms_web_inflate_result ms_web_inflate(const uint8_t *in, size_t in_size, size_t max_out,
                                     uint8_t **out, size_t *out_size, size_t *used,
                                     const char **why);

#endif
