/* The side door's deflated page files (server/serve/ms_page_cache.h): the
 * bytes zlib gives, deflated once and then answered from the cache; a file
 * rewritten (or replaced) deflated again; the oldest kept files making room
 * within the byte bound; files that would not shrink, are missing, empty,
 * not regular or too large give NULL, every time. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <cmocka.h>
#include <event2/buffer.h>
#include <zlib.h>

#include "ms_page_cache.h"
#include "ms_test.h"

/* A compressible text of `size` bytes, varied by `seed`. */
static char *text_of(size_t size, unsigned seed)
{
    char *t = malloc(size);
    assert_non_null(t);
    for (size_t i = 0; i < size; ++i)
        t[i] = "meshstream page "[(i + seed) % 16];
    return t;
}

/* The cache's answer for path inflates to exactly `want`; returns its length. */
static uint64_t assert_inflates_to(ms_page_cache *c, const char *path, const char *want, size_t size)
{
    uint64_t length = 0;
    struct evbuffer *body = ms_page_cache_deflated(c, path, &length);
    assert_non_null(body);
    assert_int_equal(evbuffer_get_length(body), length);
    unsigned char *packed = evbuffer_pullup(body, -1);
    uLongf out_size = size;
    char *out = malloc(size + 1);
    assert_non_null(out);
    assert_int_equal(uncompress((Bytef *)out, &out_size, packed, (uLong)length), Z_OK);
    assert_int_equal(out_size, size);
    assert_memory_equal(out, want, size);
    free(out);
    evbuffer_free(body);
    return length;
}

static void counts_are(const ms_page_cache *c, uint64_t hits, uint64_t deflated)
{
    uint64_t h, d;
    ms_page_cache_counts(c, &h, &d);
    assert_int_equal(h, hits);
    assert_int_equal(d, deflated);
}

static void test_deflated_once_then_from_the_cache(void **state)
{
    (void)state;
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/view.js", dir);
    char *text = text_of(50000, 0);
    ms_test_write_file(path, text, 50000);
    ms_page_cache *c = ms_page_cache_new(1u << 20);
    assert_non_null(c);
    uint64_t first = assert_inflates_to(c, path, text, 50000);
    counts_are(c, 0, 1);
    assert_int_equal(assert_inflates_to(c, path, text, 50000), first);
    counts_are(c, 1, 1);
    /* rewritten with other bytes, the same size: its modification time
     * changes (set a second ahead: a rewrite within the clock's grain) */
    char *other = text_of(50000, 5);
    ms_test_write_file(path, other, 50000);
    struct stat st;
    assert_int_equal(stat(path, &st), 0);
    struct timespec times[2] = {st.st_atim, {.tv_sec = st.st_mtim.tv_sec + 1, .tv_nsec = st.st_mtim.tv_nsec}};
    assert_int_equal(utimensat(0, path, times, 0), 0);
    assert_inflates_to(c, path, other, 50000);
    counts_are(c, 1, 2);
    assert_inflates_to(c, path, other, 50000);
    counts_are(c, 2, 2);
    ms_page_cache_free(c);
    free(text);
    free(other);
    ms_test_rmdir(dir);
}

/* Within the byte bound: the oldest file deflated goes first; a bound of 0
 * keeps nothing (every lookup deflates, the same bytes). */
static void test_oldest_make_room(void **state)
{
    (void)state;
    char dir[512], paths[3][600];
    ms_test_tmpdir(dir, sizeof dir);
    char *texts[3];
    uint64_t sizes[3];
    ms_page_cache *probe = ms_page_cache_new(1u << 20);
    for (int i = 0; i < 3; ++i) {
        snprintf(paths[i], sizeof paths[i], "%s/page%d.js", dir, i);
        texts[i] = text_of(40000, (unsigned)i);
        ms_test_write_file(paths[i], texts[i], 40000);
        evbuffer_free(ms_page_cache_deflated(probe, paths[i], &sizes[i]));
    }
    ms_page_cache_free(probe);
    /* room for two of them */
    ms_page_cache *c = ms_page_cache_new((size_t)(sizes[0] + sizes[1] + sizes[2] - 1));
    for (int i = 0; i < 3; ++i)
        assert_inflates_to(c, paths[i], texts[i], 40000);
    counts_are(c, 0, 3);
    /* the third's arrival pushed the first out; the other two are held */
    assert_inflates_to(c, paths[2], texts[2], 40000);
    assert_inflates_to(c, paths[1], texts[1], 40000);
    counts_are(c, 2, 3);
    assert_inflates_to(c, paths[0], texts[0], 40000);
    counts_are(c, 2, 4);
    ms_page_cache_free(c);
    c = ms_page_cache_new(0);
    for (int k = 0; k < 2; ++k)
        assert_inflates_to(c, paths[0], texts[0], 40000);
    counts_are(c, 0, 2);
    ms_page_cache_free(c);
    for (int i = 0; i < 3; ++i)
        free(texts[i]);
    ms_test_rmdir(dir);
}

/* NULL for what is not sent deflated, the first time and after. */
static void test_what_is_not_deflated(void **state)
{
    (void)state;
    char dir[512], noise[600], empty[600], missing[600], big[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(noise, sizeof noise, "%s/noise.wasm", dir);
    snprintf(empty, sizeof empty, "%s/empty.js", dir);
    snprintf(missing, sizeof missing, "%s/missing.js", dir);
    snprintf(big, sizeof big, "%s/big.wasm", dir);
    uint8_t random[4096];
    uint32_t x = 12345;
    for (size_t i = 0; i < sizeof random; ++i) {
        x = x * 1664525u + 1013904223u;
        random[i] = (uint8_t)(x >> 24);
    }
    ms_test_write_file(noise, random, sizeof random); /* would not shrink */
    ms_test_write_file(empty, "", 0);
    char *large = text_of(MS_PAGE_CACHE_FILE_MAX + 1, 0);
    ms_test_write_file(big, large, MS_PAGE_CACHE_FILE_MAX + 1);
    free(large);
    ms_page_cache *c = ms_page_cache_new(1u << 20);
    const char *paths[] = {noise, empty, missing, big, dir};
    for (int k = 0; k < 2; ++k)
        for (size_t i = 0; i < sizeof paths / sizeof *paths; ++i) {
            uint64_t length = 77;
            assert_null(ms_page_cache_deflated(c, paths[i], &length));
            assert_int_equal(length, 77);
        }
    /* the incompressible file deflated once, then known not to shrink */
    counts_are(c, 1, 1);
    ms_page_cache_free(c);
    ms_page_cache_free(NULL);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_deflated_once_then_from_the_cache),
        cmocka_unit_test(test_oldest_make_room),
        cmocka_unit_test(test_what_is_not_deflated),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
