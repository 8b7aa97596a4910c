/* The side door's Range, If-None-Match and Authorization parsing (server/serve/ms_http_parse.h),
 * case by case, with nginx's answers as the reference; and the replay of the
 * fuzz corpus tests/corpus/http_request/ through the fuzz target's checks. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <dirent.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_http_parse.h"

#define MS_FUZZ_NO_ENTRY_POINT
#include "fuzz/fuzz_http_request.c"

static void expect_range(const char *header, uint64_t length, ms_http_range_result result,
                         uint64_t first, uint64_t last)
{
    uint64_t a = 12345, b = 67890;
    ms_http_range_result got = ms_http_parse_range(header, length, &a, &b);
    if (got != result)
        fail_msg("Range '%s' on %llu bytes: result %d, expected %d", header ? header : "(none)",
                 (unsigned long long)length, (int)got, (int)result);
    if (result == MS_HTTP_RANGE_OK && (a != first || b != last))
        fail_msg("Range '%s': [%llu, %llu], expected [%llu, %llu]", header,
                 (unsigned long long)a, (unsigned long long)b, (unsigned long long)first,
                 (unsigned long long)last);
}

static void test_ranges(void **state)
{
    (void)state;
    const ms_http_range_result OK = MS_HTTP_RANGE_OK, BAD = MS_HTTP_RANGE_UNSATISFIABLE,
                               NONE = MS_HTTP_RANGE_NONE;
    expect_range(NULL, 100, NONE, 0, 0);
    expect_range("items=0-5", 100, NONE, 0, 0);
    /* Several ranges: 416, as docs/SECURITY.md says (issue 32, item 8). */
    expect_range("bytes=0-5,10-20", 100, BAD, 0, 0);
    expect_range("bytes=0-1,5-6", 100, BAD, 0, 0);
    expect_range("bytes=0-1, 5-6", 100, BAD, 0, 0);
    expect_range("bytes=0-5,", 100, BAD, 0, 0);
    expect_range("bytes=,0-5", 100, BAD, 0, 0);
    expect_range("bytes=-5,-5", 100, BAD, 0, 0);
    expect_range("items=0-1,5-6", 100, NONE, 0, 0);
    expect_range("bytes=5-9", 100, OK, 5, 9);
    expect_range("bytes= 5 - 9 ", 100, OK, 5, 9);
    expect_range("bytes=5-", 100, OK, 5, 99);
    expect_range("bytes=5-1000", 100, OK, 5, 99);
    expect_range("bytes=-4", 100, OK, 96, 99);
    expect_range("bytes=-1000", 100, OK, 0, 99);
    expect_range("bytes=-", 100, OK, 0, 99);
    expect_range("bytes=99-99", 100, OK, 99, 99);
    expect_range("bytes=9223372036854775807-", 100, BAD, 0, 0);
    const char *bad[] = {"bytes=5--3", "bytes=--1", "bytes=+1-2", "bytes=-18446744073709551616",
                         "bytes=18446744073709551616-", "bytes=9223372036854775808-1",
                         "bytes=9-5", "bytes=-0", "bytes=100-", "bytes=0x1-2", "bytes=5-9x",
                         "bytes=", "bytes=a-b", "bytes=5", "bytes=5 9", "bytes=-1-2"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i)
        expect_range(bad[i], 100, BAD, 0, 0);
    expect_range("bytes=0-", 0, BAD, 0, 0);
    expect_range("bytes=-1", 0, BAD, 0, 0);
}

/* Accept-Encoding as RFC 9110 section 12.5.3 reads it. */
static void test_accepts_coding(void **state)
{
    (void)state;
    assert_false(ms_http_accepts_coding(NULL, "deflate"));
    assert_false(ms_http_accepts_coding("", "deflate"));
    assert_true(ms_http_accepts_coding("deflate", "deflate"));
    assert_true(ms_http_accepts_coding("gzip, deflate, br, zstd", "deflate")); /* Chromium's */
    assert_true(ms_http_accepts_coding("GZIP , Deflate", "deflate"));
    assert_false(ms_http_accepts_coding("gzip, br", "deflate"));
    assert_false(ms_http_accepts_coding("deflatex, xdeflate", "deflate"));
    assert_true(ms_http_accepts_coding("deflate;q=0.5", "deflate"));
    assert_true(ms_http_accepts_coding("deflate; q=1.000", "deflate"));
    assert_true(ms_http_accepts_coding("deflate;Q=0.001", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=0", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=0.000", "deflate"));
    assert_true(ms_http_accepts_coding("*", "deflate"));
    assert_true(ms_http_accepts_coding("gzip;q=0, *;q=0.1", "deflate"));
    assert_false(ms_http_accepts_coding("*;q=0", "deflate"));
    assert_false(ms_http_accepts_coding("*, deflate;q=0", "deflate")); /* named beats the star */
    assert_true(ms_http_accepts_coding("*;q=0, deflate", "deflate"));
    /* malformed weights refuse: past 1, four decimals, a sign, text, other parameters */
    assert_false(ms_http_accepts_coding("deflate;q=1.5", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=2", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=0.1234", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=-1", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;level=9", "deflate"));
    assert_false(ms_http_accepts_coding("deflate;q=0.5x", "deflate"));
    assert_true(ms_http_accepts_coding(",,, deflate ,", "deflate"));
}

static void test_none_match(void **state)
{
    (void)state;
    const char *etag = "\"abc-1\"";
    assert_false(ms_http_none_match(NULL, etag));
    assert_true(ms_http_none_match("*", etag));
    assert_true(ms_http_none_match(" * ", etag));
    assert_true(ms_http_none_match("\"abc-1\"", etag));
    assert_true(ms_http_none_match("W/\"abc-1\"", etag));
    assert_true(ms_http_none_match("\"x\", \"abc-1\"", etag));
    assert_true(ms_http_none_match("\"x\",\"abc-1\" ,\"y\"", etag));
    assert_false(ms_http_none_match("\"abc-12\"", etag));
    assert_false(ms_http_none_match("\"abc\"", etag));
    assert_false(ms_http_none_match("abc-1", etag));
    assert_false(ms_http_none_match("*x", etag));
    assert_false(ms_http_none_match("", etag));
    assert_false(ms_http_none_match(",,,", etag));
}

static void expect_bearer(const char *header, const char *credential)
{
    const char *token = "untouched";
    size_t length = 9;
    bool found = ms_http_bearer_credential(header, &token, &length);
    if (!credential) {
        if (found)
            fail_msg("Authorization '%s': credential '%.*s', expected none", header,
                     (int)length, token);
        assert_string_equal(token, "untouched");
        return;
    }
    if (!found)
        fail_msg("Authorization '%s': no credential, expected '%s'", header, credential);
    if (length != strlen(credential) || memcmp(token, credential, length) != 0)
        fail_msg("Authorization '%s': credential '%.*s', expected '%s'", header, (int)length,
                 token, credential);
}

/* Issue 32, item 8: the scheme in any case, spaces as RFC 9110 allows them. */
static void test_bearer_credential(void **state)
{
    (void)state;
    expect_bearer("Bearer s3cret", "s3cret");
    expect_bearer("bearer s3cret", "s3cret");
    expect_bearer("BEARER s3cret", "s3cret");
    expect_bearer("bEaReR s3cret", "s3cret");
    expect_bearer("Bearer   s3cret", "s3cret");   /* 1*SP */
    expect_bearer("Bearer s3cret  \t", "s3cret"); /* trailing OWS */
    expect_bearer(" \tBearer s3cret", "s3cret");  /* leading OWS */
    expect_bearer("Bearer abc-._~+/==", "abc-._~+/=="); /* token68 */
    expect_bearer("Bearer s3cret!#", "s3cret!#"); /* what the config allows */
    expect_bearer(NULL, NULL);
    expect_bearer("", NULL);
    expect_bearer("Bearer", NULL);
    expect_bearer("Bearer ", NULL);
    expect_bearer("Bearer    ", NULL);
    expect_bearer("Bearers3cret", NULL);
    expect_bearer("Bearer\ts3cret", NULL);
    expect_bearer("Basic czNjcmV0", NULL);
    expect_bearer("Bearer s3cret extra", NULL);
    expect_bearer("Bearer s3c\x01ret", NULL);
    expect_bearer("Bearer s3c\xc3\xa9ret", NULL);
    expect_bearer("Bear s3cret", NULL);
    expect_bearer("Bearer@ s3cret", NULL);
}

static void test_corpus_replay(void **state)
{
    (void)state;
    const char *dir_path = "tests/corpus/http_request";
    DIR *dir = opendir(dir_path);
    if (!dir)
        fail_msg("cannot open %s (run the tests from the repository root)", dir_path);
    unsigned files = 0;
    static uint8_t data[1 << 16];
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        if (entry->d_name[0] == '.')
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir_path, entry->d_name);
        FILE *f = fopen(path, "rb");
        assert_non_null(f);
        size_t n = fread(data, 1, sizeof data, f);
        fclose(f);
        ms_fuzz_http_one(data, n); /* aborts on a broken contract */
        ++files;
    }
    closedir(dir);
    assert_true(files >= 12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ranges),
        cmocka_unit_test(test_none_match),
        cmocka_unit_test(test_accepts_coding),
        cmocka_unit_test(test_bearer_credential),
        cmocka_unit_test(test_corpus_replay),
    };
    return cmocka_run_group_tests_name("http_parse", tests, NULL, NULL);
}
