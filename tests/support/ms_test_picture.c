#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <png.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test_picture.h"

uint8_t *ms_test_png_read(const char *path, uint32_t *width, uint32_t *height)
{
    png_image image;
    memset(&image, 0, sizeof image);
    image.version = PNG_IMAGE_VERSION;
    if (!png_image_begin_read_from_file(&image, path))
        fail_msg("%s: %s", path, image.message);
    image.format = PNG_FORMAT_RGB;
    uint8_t *pixels = malloc(PNG_IMAGE_SIZE(image));
    assert_non_null(pixels);
    assert_true(png_image_finish_read(&image, NULL, pixels, 0, NULL));
    *width = image.width, *height = image.height;
    return pixels;
}

size_t ms_test_png_differing(const char *a_path, const char *b_path, int tolerance)
{
    uint32_t aw, ah, bw, bh;
    uint8_t *a = ms_test_png_read(a_path, &aw, &ah), *b = ms_test_png_read(b_path, &bw, &bh);
    assert_int_equal(aw, bw);
    assert_int_equal(ah, bh);
    size_t n = 0;
    for (size_t i = 0; i < (size_t)aw * ah; ++i)
        for (int c = 0; c < 3; ++c)
            if (abs(a[3 * i + c] - b[3 * i + c]) > tolerance) {
                ++n;
                break;
            }
    free(a);
    free(b);
    return n;
}

uint8_t *ms_test_silhouette(const char *path, uint32_t *width, uint32_t *height, size_t *covered)
{
    uint8_t *rgb = ms_test_png_read(path, width, height);
    size_t n = (size_t)*width * *height;
    uint8_t *mask = calloc(n ? n : 1, 1);
    assert_non_null(mask);
    *covered = 0;
    for (size_t i = 0; i < n; ++i) {
        for (int c = 0; c < 3; ++c)
            if (abs((int)rgb[3 * i + c] - (int)rgb[c]) > 8)
                mask[i] = 1;
        *covered += mask[i];
    }
    free(rgb);
    return mask;
}

double ms_test_silhouette_iou(const char *path, const char *ref_path, uint32_t width, uint32_t height,
                              size_t *covered, size_t *ref_covered)
{
    uint32_t w, h, rw, rh;
    uint8_t *mask = ms_test_silhouette(path, &w, &h, covered);
    uint8_t *ref_mask = ms_test_silhouette(ref_path, &rw, &rh, ref_covered);
    assert_int_equal(w, width);
    assert_int_equal(h, height);
    assert_int_equal(rw, width);
    assert_int_equal(rh, height);
    double iou = ms_test_mask_iou(mask, ref_mask, (size_t)w * h);
    free(mask);
    free(ref_mask);
    return iou;
}

double ms_test_mask_iou(const uint8_t *a, const uint8_t *b, size_t n)
{
    size_t both = 0, either = 0;
    for (size_t i = 0; i < n; ++i) {
        both += a[i] & b[i];
        either += a[i] | b[i];
    }
    return either ? (double)both / (double)either : 0.0;
}

double ms_test_png_psnr(const char *path, const char *ref_path, uint32_t width, uint32_t height)
{
    uint32_t w, h, rw, rh;
    uint8_t *a = ms_test_png_read(path, &w, &h), *b = ms_test_png_read(ref_path, &rw, &rh);
    assert_int_equal(w, width);
    assert_int_equal(h, height);
    assert_int_equal(rw, width);
    assert_int_equal(rh, height);
    size_t n = 3 * (size_t)w * h;
    double squares = 0;
    for (size_t i = 0; i < n; ++i) {
        double d = (double)a[i] - (double)b[i];
        squares += d * d;
    }
    free(a);
    free(b);
    double mse = n ? squares / (double)n : 0;
    return mse > 0 ? 10.0 * log10(255.0 * 255.0 / mse) : 99.0;
}

double ms_test_png_mean_chroma(const char *path)
{
    uint32_t w, h;
    size_t covered;
    uint8_t *mask = ms_test_silhouette(path, &w, &h, &covered);
    uint8_t *rgb = ms_test_png_read(path, &w, &h);
    double sum = 0;
    for (size_t i = 0; i < (size_t)w * h; ++i) {
        if (!mask[i])
            continue;
        const uint8_t *p = rgb + 3 * i;
        int hi = p[0] > p[1] ? p[0] : p[1], lo = p[0] < p[1] ? p[0] : p[1];
        hi = p[2] > hi ? p[2] : hi;
        lo = p[2] < lo ? p[2] : lo;
        sum += hi - lo;
    }
    free(mask);
    free(rgb);
    return covered ? sum / (double)covered : 0.0;
}
