/* libFuzzer target on the HTTP side door's request-header parsing
 * (server/serve/ms_http_parse.c: Range and If-None-Match), the functions the
 * server calls for every payload request.
 *
 * Input: 8 bytes of body length (little-endian; the top 24 bits are cleared,
 * so lengths stay within 2^40 and small ones are common), then the Range
 * header text, a NUL byte, and the If-None-Match header text (each may hold
 * any bytes; a missing NUL leaves If-None-Match absent).
 *
 * Besides the sanitizers, the target checks the contract and aborts when it
 * is broken: a range accepted lies inside the body (first <= last < length);
 * parsing is deterministic; a plain "bytes=A-B" of digits gives [A, min(B,
 * length - 1)] when A < length; "*" and the tag itself always match.
 *
 * tests/test_http_parse.c includes this file to replay
 * tests/corpus/http_request/ in `make test`; it then calls
 * ms_fuzz_http_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_http_parse.h"

#define MS_FUZZ_HTTP_CHECK(cond)                                                               \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_http_request: contract broken: %s (%s:%d)\n", #cond,        \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* "bytes=A-B" with A and B plain digit strings of at most 18 digits. */
static bool simple_range(const char *h, uint64_t *a, uint64_t *b)
{
    if (strncmp(h, "bytes=", 6) != 0)
        return false;
    const char *p = h + 6;
    uint64_t v[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        int digits = 0;
        while (*p >= '0' && *p <= '9' && digits < 19) {
            v[k] = v[k] * 10 + (uint64_t)(*p++ - '0');
            ++digits;
        }
        if (digits == 0 || digits > 18)
            return false;
        if (k == 0 && *p++ != '-')
            return false;
    }
    if (*p != '\0')
        return false;
    *a = v[0], *b = v[1];
    return true;
}

static void ms_fuzz_http_one(const uint8_t *data, size_t size)
{
    if (size < 8)
        return;
    uint64_t length = 0;
    for (int i = 0; i < 8; ++i)
        length |= (uint64_t)data[i] << (8 * i);
    length &= (1ull << 40) - 1;
    data += 8, size -= 8;
    const uint8_t *nul = memchr(data, 0, size);
    size_t range_size = nul ? (size_t)(nul - data) : size;
    char *range = malloc(range_size + 1);
    memcpy(range, data, range_size);
    range[range_size] = '\0';
    char *none_match = NULL;
    if (nul) {
        size_t n = size - range_size - 1;
        none_match = malloc(n + 1);
        memcpy(none_match, nul + 1, n);
        none_match[n] = '\0';
    }

    uint64_t first = 0, last = 0, first2 = 0, last2 = 0;
    ms_http_range_result r = ms_http_parse_range(range, length, &first, &last);
    MS_FUZZ_HTTP_CHECK(r == MS_HTTP_RANGE_NONE || r == MS_HTTP_RANGE_OK ||
                       r == MS_HTTP_RANGE_UNSATISFIABLE);
    MS_FUZZ_HTTP_CHECK(ms_http_parse_range(range, length, &first2, &last2) == r);
    if (r == MS_HTTP_RANGE_OK) {
        MS_FUZZ_HTTP_CHECK(first <= last && last < length);
        MS_FUZZ_HTTP_CHECK(first == first2 && last == last2);
    }
    uint64_t a, b;
    if (simple_range(range, &a, &b)) {
        if (a <= b && a < length) {
            MS_FUZZ_HTTP_CHECK(r == MS_HTTP_RANGE_OK);
            MS_FUZZ_HTTP_CHECK(first == a && last == (b < length ? b : length - 1));
        } else {
            MS_FUZZ_HTTP_CHECK(r == MS_HTTP_RANGE_UNSATISFIABLE);
        }
    }
    MS_FUZZ_HTTP_CHECK(ms_http_parse_range(NULL, length, &first, &last) == MS_HTTP_RANGE_NONE);
    if (!strncmp(range, "bytes=", 6) && strchr(range, ',')) /* several ranges: refused */
        MS_FUZZ_HTTP_CHECK(r == MS_HTTP_RANGE_UNSATISFIABLE);

    /* The same text as an Authorization header: a credential found lies
     * inside it, is visible ASCII without spaces, and follows the scheme. */
    const char *token = NULL;
    size_t token_length = 0;
    if (ms_http_bearer_credential(range, &token, &token_length)) {
        MS_FUZZ_HTTP_CHECK(token > range + 6 && token + token_length <= range + strlen(range));
        MS_FUZZ_HTTP_CHECK(token_length > 0);
        for (size_t i = 0; i < token_length; ++i)
            MS_FUZZ_HTTP_CHECK(token[i] > ' ' && token[i] < 0x7f);
    }

    const char *etag = "\"5-a-17-g12\"";
    bool matched = ms_http_none_match(none_match, etag);
    MS_FUZZ_HTTP_CHECK(matched == ms_http_none_match(none_match, etag));
    MS_FUZZ_HTTP_CHECK(ms_http_none_match("*", etag));
    MS_FUZZ_HTTP_CHECK(ms_http_none_match(etag, etag));
    if (none_match) {
        /* The input as a tag: a quoted string without commas matches itself. */
        size_t n = strlen(none_match);
        if (n >= 2 && none_match[0] == '"' && none_match[n - 1] == '"' &&
            !strpbrk(none_match, ", \t"))
            MS_FUZZ_HTTP_CHECK(ms_http_none_match(none_match, none_match));
    }
    free(range);
    free(none_match);
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_http_one(data, size);
    return 0;
}
#endif
