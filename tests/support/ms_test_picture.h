/* Pictures in tests: PNG files decoded and compared (libpng's simplified
 * reader). Every helper fails the test on error. Include after cmocka.h. */
#ifndef MS_TEST_PICTURE_H
#define MS_TEST_PICTURE_H

#include <stddef.h>
#include <stdint.h>

/* Decodes a PNG as RGB, 3 bytes per pixel, rows top-down (malloc'd; the
 * caller frees it). */
uint8_t *ms_test_png_read(const char *path, uint32_t *width, uint32_t *height);

/* Pixels of two PNGs of the same size whose colour differs by more than
 * tolerance in a channel. */
size_t ms_test_png_differing(const char *a_path, const char *b_path, int tolerance);

/* A PNG's silhouette: 1 where a pixel differs from the picture's top-left
 * pixel (the background) by more than 8 in a channel, else 0 (malloc'd, one
 * byte per pixel; the caller frees it); its size and the pixels set. */
uint8_t *ms_test_silhouette(const char *path, uint32_t *width, uint32_t *height, size_t *covered);

/* The intersection over union of two PNGs' silhouettes (ms_test_silhouette),
 * which must both be width x height (the test fails otherwise); their
 * covered pixels in *covered and *ref_covered. */
double ms_test_silhouette_iou(const char *path, const char *ref_path, uint32_t width, uint32_t height,
                              size_t *covered, size_t *ref_covered);

/* The intersection over union of two masks of n pixels (0 or 1 each); 0
 * when neither covers a pixel. */
double ms_test_mask_iou(const uint8_t *a, const uint8_t *b, size_t n);

/* The PSNR in dB (all three channels; 99 when equal) of two PNGs, which must
 * both be width x height (the test fails otherwise). */
double ms_test_png_psnr(const char *path, const char *ref_path, uint32_t width, uint32_t height);

/* The mean chroma (largest less smallest channel, 0..255) of a PNG's
 * covered pixels (ms_test_silhouette): about 10 for meshview's grey
 * material, far more for a model drawn in its colours; 0 when nothing is
 * covered. */
double ms_test_png_mean_chroma(const char *path);

#endif
