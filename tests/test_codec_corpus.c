/* Replays the codec regression corpus (tests/corpus/codec): valid-* streams decode
 * to full precision with the declared counts and coarsen back; bad-* (truncated
 * or damaged) streams are refused with an error; every file, including fuzzer
 * finds (fuzz-*), also goes through the decoder with CRC checks off, which must
 * end with MS_OK or an error, never a crash, leak or hang. */
#include <dirent.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"

#define CORPUS "tests/corpus/codec"

static uint8_t *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    uint8_t *b = malloc((size_t)n + 1);
    assert_non_null(b);
    assert_int_equal(fread(b, 1, (size_t)n, f), (size_t)n);
    fclose(f);
    *size = (size_t)n;
    return b;
}

/* Full decode, then coarsen to the window start and refine again. */
static ms_status decode_all(const uint8_t *b, size_t n, bool skip_crc, ms_error *err)
{
    ms_codec_decoder_options opt = {.skip_crc = skip_crc};
    ms_codec_decoder *d;
    ms_status st = ms_codec_decoder_create(b, n, NULL, &opt, &d, err);
    if (st != MS_OK)
        return st;
    unsigned top = ms_codec_decoder_max_level(d);
    st = ms_codec_decoder_set_level(d, top, err);
    if (st == MS_OK) {
        const ms_codec_header *h = ms_codec_decoder_header(d);
        assert_int_equal(ms_codec_decoder_vertex_count(d), h->end_vertices);
        assert_int_equal(ms_codec_decoder_tri_count(d), h->end_tris);
        st = ms_codec_decoder_set_level(d, ms_codec_decoder_min_level(d), err);
        if (st == MS_OK)
            st = ms_codec_decoder_set_level(d, top, err);
    }
    ms_codec_decoder_destroy(d);
    return st;
}

static void test_corpus_replays(void **state)
{
    (void)state;
    DIR *dir = opendir(CORPUS);
    assert_non_null(dir);
    struct dirent *e;
    int valid = 0, bad = 0, other = 0;
    while ((e = readdir(dir)) != NULL) {
        if (e->d_name[0] == '.')
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", CORPUS, e->d_name);
        size_t n;
        uint8_t *b = slurp(path, &n);
        ms_error err;
        ms_status st = decode_all(b, n, false, &err);
        if (strncmp(e->d_name, "valid-", 6) == 0) {
            if (st != MS_OK)
                fail_msg("%s: %s", e->d_name, err.text);
            valid++;
        } else if (strncmp(e->d_name, "bad-", 4) == 0) {
            if (st == MS_OK)
                fail_msg("%s decoded without error", e->d_name);
            assert_true(strlen(err.text) > 0 && strchr(err.text, '\n') == NULL);
            bad++;
        } else {
            other++;
        }
        (void)decode_all(b, n, true, &err);
        free(b);
    }
    closedir(dir);
    print_message("corpus: %d valid, %d bad, %d other\n", valid, bad, other);
    assert_true(valid >= 6);
    assert_true(bad >= 12);
}

/* Deterministic random damage (byte flips, truncations, insertions) of every
 * valid corpus stream, decoded with CRC checks off so the damage reaches the
 * decoder logic: each run must end with MS_OK or an error, never a crash (ASan)
 * or an assertion. With CRC checks on, every damaged stream that differs from
 * the original within its declared bytes is refused. */
static void test_random_damage(void **state)
{
    (void)state;
    DIR *dir = opendir(CORPUS);
    assert_non_null(dir);
    struct dirent *e;
    uint32_t x = 0x2545F491u;
    int runs = 0, refused = 0;
    while ((e = readdir(dir)) != NULL) {
        if (strncmp(e->d_name, "valid-", 6) != 0)
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", CORPUS, e->d_name);
        size_t n;
        uint8_t *orig = slurp(path, &n);
        uint8_t *b = malloc(n + 64);
        assert_non_null(b);
        for (int k = 0; k < 150; ++k) {
            memcpy(b, orig, n);
            size_t m = n;
            int edits = 1 + k % 4;
            for (int j = 0; j < edits; ++j) {
                x ^= x << 13, x ^= x >> 17, x ^= x << 5;
                size_t pos = x % m;
                switch ((x >> 24) % 4) {
                case 0: b[pos] ^= (uint8_t)(1u << ((x >> 8) & 7)); break;
                case 1: b[pos] = (uint8_t)(x >> 16); break;
                case 2: m = pos + 1; break;
                default:
                    if (m < n + 60) {
                        memmove(b + pos + 1, b + pos, m - pos);
                        b[pos] = (uint8_t)x;
                        m++;
                    }
                }
            }
            ms_error err;
            (void)decode_all(b, m, true, &err);
            ms_status st = decode_all(b, m, false, &err);
            if (st != MS_OK)
                refused++;
            else
                assert_true(m >= n && memcmp(b, orig, n) == 0);
            runs++;
        }
        free(b);
        free(orig);
    }
    closedir(dir);
    print_message("damaged streams: %d runs, %d refused with CRC checks on\n", runs, refused);
    assert_true(runs >= 900);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_corpus_replays),
        cmocka_unit_test(test_random_damage),
    };
    return cmocka_run_group_tests_name("codec_corpus", tests, NULL, NULL);
}
