/* PNG writer: the file parses back (signature, chunk CRCs, IHDR fields) and the
 * inflated pixels equal what was written. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_png.h"
#include "ms_test.h"

static uint32_t be32(const uint8_t *p)
{
    return (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3];
}

static void roundtrip(int channels)
{
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/img.png", dir);
    const uint32_t w = 7, h = 5;
    uint8_t pixels[7 * 5 * 3];
    for (size_t i = 0; i < sizeof pixels; ++i)
        pixels[i] = (uint8_t)(i * 37 + 11);
    assert_int_equal(ms_png_write(path, pixels, w, h, channels, NULL), MS_OK);

    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    uint8_t file[4096];
    size_t size = fread(file, 1, sizeof file, f);
    fclose(f);
    assert_memory_equal(file, "\x89PNG\r\n\x1a\n", 8);
    size_t pos = 8;
    uint8_t idat[4096];
    size_t idat_size = 0;
    int saw_end = 0;
    while (pos + 12 <= size) {
        uint32_t len = be32(file + pos);
        assert_true(pos + 12 + len <= size);
        const uint8_t *type = file + pos + 4;
        uLong crc = crc32(0L, type, 4 + len);
        assert_int_equal(be32(file + pos + 8 + len), (uint32_t)crc);
        if (!memcmp(type, "IHDR", 4)) {
            assert_int_equal(be32(type + 4), w);
            assert_int_equal(be32(type + 8), h);
            assert_int_equal(type[12], 8);
            assert_int_equal(type[13], channels == 3 ? 2 : 0);
        } else if (!memcmp(type, "IDAT", 4)) {
            memcpy(idat + idat_size, type + 4, len);
            idat_size += len;
        } else if (!memcmp(type, "IEND", 4)) {
            saw_end = 1;
        }
        pos += 12 + len;
    }
    assert_true(saw_end);
    assert_int_equal(pos, size);
    uint8_t raw[4096];
    uLongf raw_size = sizeof raw;
    assert_int_equal(uncompress(raw, &raw_size, idat, idat_size), Z_OK);
    size_t row = w * (size_t)channels;
    assert_int_equal(raw_size, (row + 1) * h);
    for (uint32_t y = 0; y < h; ++y) {
        assert_int_equal(raw[y * (row + 1)], 0);
        assert_memory_equal(raw + y * (row + 1) + 1, pixels + y * row, row);
    }
    ms_test_rmdir(dir);
}

static void test_rgb_roundtrip(void **state) { (void)state; roundtrip(3); }
static void test_grey_roundtrip(void **state) { (void)state; roundtrip(1); }

static void test_bad_arguments(void **state)
{
    (void)state;
    uint8_t px[3] = {0};
    ms_error err;
    assert_int_equal(ms_png_write("/tmp/never.png", px, 0, 1, 3, &err), MS_ERR_ARG);
    assert_int_equal(ms_png_write("/tmp/never.png", px, 1, 1, 2, &err), MS_ERR_ARG);
    assert_int_equal(ms_png_write("/nonexistent-dir/x.png", px, 1, 1, 3, &err), MS_ERR_IO);
    assert_non_null(strstr(err.text, "/nonexistent-dir/x.png"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_rgb_roundtrip),
        cmocka_unit_test(test_grey_roundtrip),
        cmocka_unit_test(test_bad_arguments),
    };
    return cmocka_run_group_tests_name("png", tests, NULL, NULL);
}
