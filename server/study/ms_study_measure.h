/* Error measures of the accuracy study (docs/ACCURACY.md gives the definitions
 * and why): geometric distance between two meshes, and image error of a render
 * against a reference render.
 *
 * Geometric (ms_study_distance). Each mesh X of the pair is sampled
 * deterministically at a spacing s (model units):
 *   - every vertex referenced by a triangle, weight 0 (Hausdorff only);
 *   - every triangle is cut into k^2 congruent sub-triangles by the regular
 *     barycentric grid of k = min(MS_STUDY_MAX_SUBDIVISION, max(1, ceil(longest
 *     edge / s))) steps per edge; each sub-triangle's centroid is a sample of
 *     weight area / k^2 (the midpoint rule for integrals over the surface).
 * d(x, Y) is the exact distance from sample x to the closest point of Y's
 * triangles (Embree rtcPointQuery, distances in doubles). Then
 *   hausdorff_ab = max over A's samples of d(x, B)      (and _ba the other way)
 *   rms_ab       = sqrt(sum w d^2 / sum w) over A's samples
 *   hausdorff    = max(hausdorff_ab, hausdorff_ba)
 *   rms          = sqrt((sum_A w d^2 + sum_B w d^2) / (sum_A w + sum_B w))
 * With a camera, the same over the samples inside the view frustum, each
 * distance converted to pixels at the sample: d * pixels_per_unit / eye depth
 * (the size of d seen face-on there): hausdorff_px, rms_px.
 * Samples are split into fixed blocks of triangles / vertices and reduced in
 * block order: results do not depend on the thread count.
 *
 * Image (ms_study_image_compare), of a test render against a reference render of
 * the same size (ms_study_render.h):
 *   - normal angle, over the pixels covered in both: atan2(|n x m|, n . m), in
 *     degrees; mean, 95th percentile (nearest rank: the ceil(0.95 N)-th smallest)
 *     and max (0 when no pixel is covered in both);
 *   - PSNR of the shaded 8-bit sRGB images: 10 log10(255^2 / MSE), MSE over every
 *     channel of every pixel; +infinity when the images are identical;
 *   - SSIM (Wang et al. 2004) of the luma 0.299 R + 0.587 G + 0.114 B of the
 *     8-bit values, Gaussian window 11 x 11 with sigma 1.5, C1 = (0.01 * 255)^2,
 *     C2 = (0.03 * 255)^2, averaged over every window position wholly inside the
 *     image (one window of uniform weights over the whole image when it is
 *     smaller than 11 pixels either way);
 *   - silhouette mismatch: pixels covered in exactly one of the two.
 *
 * Colour (ms_study_colour_psnr), of two pictures of a coloured model, usually
 * albedo pictures (the unlit vertex colours: meshview's MS_SHADING_ALBEDO read
 * back, meshrender --albedo, ms_study_render with options.albedo), over the
 * pixels of a mask (those covered in either picture: the background, the same
 * in both, would only raise the figure):
 *   - PSNR of the 8-bit sRGB values, 10 log10(255^2 / MSE), MSE over the three
 *     channels of the pixels compared; per channel the same over its values;
 *     +infinity where they are identical;
 *   - the largest difference of one value.
 *
 * Thread-safety: pure functions of their inputs (scenes and images are read).
 */
#ifndef MS_STUDY_MEASURE_H
#define MS_STUDY_MEASURE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_camera.h"
#include "ms_error.h"
#include "ms_study_render.h"
#include "ms_study_scene.h"

#define MS_STUDY_MAX_SUBDIVISION 256u

typedef struct ms_study_distance_params {
    double spacing;           /* sample spacing s, model units, > 0 */
    unsigned threads;         /* 0: every core */
    const ms_camera *camera;  /* NULL: no projected figures */
} ms_study_distance_params;

typedef struct ms_study_distance {
    double hausdorff, rms;                 /* symmetric, model units */
    double hausdorff_ab, hausdorff_ba, rms_ab, rms_ba;
    uint64_t samples_a, samples_b;         /* vertices + sub-triangle centroids */
    double hausdorff_px, rms_px;           /* symmetric, projected (0 without camera) */
    uint64_t samples_px;                   /* samples inside the frustum */
} ms_study_distance;

/* Errors: MS_ERR_ARG for a spacing that is not positive and finite, MS_ERR_EMPTY
 * when either mesh has no triangle, MS_ERR_NOMEM. */
ms_status ms_study_distance_measure(const ms_study_scene *a, const ms_study_scene *b,
                                    const ms_study_distance_params *params, ms_study_distance *out,
                                    ms_error *err);

typedef struct ms_study_image_error {
    uint64_t pixels;               /* width * height */
    uint64_t both_covered;         /* pixels the normal angle is measured on */
    uint64_t silhouette_mismatch;  /* covered in exactly one image */
    double normal_mean_deg, normal_p95_deg, normal_max_deg;
    double mse;                    /* of the 8-bit values */
    double psnr_db;                /* +infinity for identical images */
    double ssim;
} ms_study_image_error;

/* test against reference (same size: MS_ERR_ARG otherwise); MS_ERR_NOMEM. */
ms_status ms_study_image_compare(const ms_study_image *test, const ms_study_image *reference,
                                 ms_study_image_error *out, ms_error *err);

typedef struct ms_study_colour_error {
    uint64_t pixels;         /* compared: the mask's */
    double mse;              /* of the 8-bit values, over the three channels */
    double psnr_db;          /* +infinity for identical pixels */
    double channel_psnr_db[3]; /* r, g, b alone */
    unsigned max_difference; /* of one value, 0 to 255 */
} ms_study_colour_error;

/* test against reference: two RGB pictures of `pixels` pixels (3 bytes each,
 * 8-bit sRGB, any row order as long as it is the same), over the pixels whose
 * mask byte is not 0 (mask NULL: every pixel). MS_ERR_ARG when no pixel is
 * compared or a buffer is missing. */
ms_status ms_study_colour_psnr(const uint8_t *test, const uint8_t *reference, size_t pixels, const uint8_t *mask,
                               ms_study_colour_error *out, ms_error *err);

/* The mask of the pixels covered in either picture (both false) or in both
 * (both true: the colours alone, the silhouette apart), known by their
 * colour: a pixel is covered in a picture where it differs from background
 * (r g b, the pictures' background colour: meshview's and meshrender's is
 * 39 39 39). mask holds `pixels` bytes, 1 or 0; returns how many are 1. */
size_t ms_study_colour_mask(const uint8_t *test, const uint8_t *reference, size_t pixels, const uint8_t background[3],
                            bool both, uint8_t *mask);

/* The same over two study images of one size (ms_study_render.h), the pixels
 * covered in either (by their hits, not their colours). MS_ERR_ARG for images
 * of different sizes or no pixel covered; MS_ERR_NOMEM. */
ms_status ms_study_image_colour_psnr(const ms_study_image *test, const ms_study_image *reference,
                                     ms_study_colour_error *out, ms_error *err);

/* The pieces, for callers with bare buffers: PSNR of two 8-bit buffers of count
 * values; SSIM of two RGB images (3 * width * height bytes each). */
double ms_study_psnr(const uint8_t *a, const uint8_t *b, size_t count, double *mse);
ms_status ms_study_ssim_rgb(const uint8_t *a, const uint8_t *b, uint32_t width, uint32_t height, double *ssim,
                            ms_error *err);

#endif
