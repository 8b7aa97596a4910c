/* The accuracy study's error measures on cases with an exact answer: identical
 * meshes, a plane shifted by d (in model units and in projected pixels), a known
 * one-sided Hausdorff distance, the documented sample count, a known rotation of
 * a normal buffer, PSNR of identical images and of a uniform offset, SSIM of
 * identical images, and the silhouette mismatch of a shifted square. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_study_measure.h"
#include "ms_test.h"

/* A square grid of n x n quads (2 n^2 triangles) over [x0, x0 + size] x [y0, y0 +
 * size] at height z, in the plane z = const. Caller frees both arrays. */
static void grid(unsigned n, double x0, double y0, double size, double z, double **pos, uint32_t **tri,
                 size_t *vc, size_t *tc)
{
    *vc = (size_t)(n + 1) * (n + 1);
    *tc = 2 * (size_t)n * n;
    *pos = malloc(3 * *vc * sizeof **pos);
    *tri = malloc(3 * *tc * sizeof **tri);
    assert_non_null(*pos);
    assert_non_null(*tri);
    for (unsigned j = 0; j <= n; ++j)
        for (unsigned i = 0; i <= n; ++i) {
            double *p = &(*pos)[3 * (j * (n + 1) + i)];
            p[0] = x0 + size * i / n;
            p[1] = y0 + size * j / n;
            p[2] = z;
        }
    size_t t = 0;
    for (unsigned j = 0; j < n; ++j)
        for (unsigned i = 0; i < n; ++i) {
            uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            uint32_t q[6] = {a, b, d, a, d, c};
            memcpy(&(*tri)[3 * t], q, sizeof q);
            t += 2;
        }
}

static ms_study_scene *grid_scene(unsigned n, double x0, double y0, double size, double z)
{
    double *pos;
    uint32_t *tri;
    size_t vc, tc;
    grid(n, x0, y0, size, z, &pos, &tri, &vc, &tc);
    ms_study_scene *s;
    ms_error err;
    if (ms_study_scene_new(pos, vc, tri, tc, &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    free(pos);
    free(tri);
    return s;
}

static void test_identical_meshes(void **state)
{
    (void)state;
    ms_study_scene *a = grid_scene(5, -1, -1, 2, 0.25), *b = grid_scene(5, -1, -1, 2, 0.25);
    ms_study_distance_params p = {.spacing = 0.05, .threads = 2};
    ms_study_distance d;
    ms_error err;
    assert_int_equal(ms_study_distance_measure(a, b, &p, &d, &err), MS_OK);
    assert_true(d.hausdorff == 0);
    assert_true(d.rms == 0);
    assert_true(d.samples_a > 0 && d.samples_a == d.samples_b);
    ms_study_scene_free(a);
    ms_study_scene_free(b);
}

/* Plane z = 0 against the same plane at z = d, at the origin and far from it. */
static void check_shifted_plane(double offset, double d)
{
    ms_study_scene *a = grid_scene(4, offset, offset, 1, offset), *b = grid_scene(4, offset, offset, 1, offset + d);
    ms_study_distance_params p = {.spacing = 0.1, .threads = 0};
    ms_study_distance r;
    ms_error err;
    assert_int_equal(ms_study_distance_measure(a, b, &p, &r, &err), MS_OK);
    double tol = 1e-12 * (1 + fabs(offset));
    assert_true(fabs(r.hausdorff - d) <= tol);
    assert_true(fabs(r.rms - d) <= tol);
    assert_true(fabs(r.hausdorff_ab - d) <= tol && fabs(r.hausdorff_ba - d) <= tol);
    assert_true(fabs(r.rms_ab - d) <= tol && fabs(r.rms_ba - d) <= tol);
    ms_study_scene_free(a);
    ms_study_scene_free(b);
}

static void test_shifted_plane(void **state)
{
    (void)state;
    check_shifted_plane(0, 0.125);
    check_shifted_plane(0, 1e-3);
    check_shifted_plane(1e7, 0.5);
}

/* Face-on camera at distance D from plane A (z = 0) and D - d from plane B (z =
 * d): every sample of A is d ppu / D pixels away, every one of B d ppu / (D - d). */
static void test_shifted_plane_pixels(void **state)
{
    (void)state;
    const double d = 0.1, D = 4;
    ms_study_scene *a = grid_scene(4, -0.5, -0.5, 1, 0), *b = grid_scene(4, -0.5, -0.5, 1, d);
    ms_camera cam;
    ms_error err;
    const double pos[3] = {0, 0, D}, target[3] = {0, 0, 0}, up[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(pos, target, up, 45, 200, 100, 0.1, 100, &cam, &err), MS_OK);
    ms_study_distance_params p = {.spacing = 0.1, .threads = 2, .camera = &cam};
    ms_study_distance r;
    assert_int_equal(ms_study_distance_measure(a, b, &p, &r, &err), MS_OK);
    double ppu = ms_camera_pixels_per_unit(&cam), pa = d * ppu / D, pb = d * ppu / (D - d);
    assert_int_equal(r.samples_px, r.samples_a + r.samples_b); /* the whole of both planes is in view */
    assert_true(fabs(r.hausdorff_px - pb) <= 1e-9 * pb);
    /* equal areas: rms^2 is the mean of the two squares */
    double rms = sqrt((pa * pa + pb * pb) / 2);
    assert_true(fabs(r.rms_px - rms) <= 1e-9 * rms);
    ms_study_scene_free(a);
    ms_study_scene_free(b);
}

/* A = unit square, B = its left half: h(B -> A) = 0, h(A -> B) = 0.5 exactly
 * (reached at A's right corners). */
static void test_one_sided(void **state)
{
    (void)state;
    ms_study_scene *a = grid_scene(2, 0, 0, 1, 0);
    double pos[12] = {0, 0, 0, 0.5, 0, 0, 0.5, 1, 0, 0, 1, 0};
    uint32_t tri[6] = {0, 1, 2, 0, 2, 3};
    ms_study_scene *b;
    ms_error err;
    assert_int_equal(ms_study_scene_new(pos, 4, tri, 2, &b, &err), MS_OK);
    ms_study_distance_params p = {.spacing = 0.3, .threads = 1};
    ms_study_distance r;
    assert_int_equal(ms_study_distance_measure(a, b, &p, &r, &err), MS_OK);
    assert_true(r.hausdorff_ab == 0.5);
    assert_true(r.hausdorff_ba == 0);
    assert_true(r.rms_ba == 0);
    assert_true(r.hausdorff == 0.5);
    assert_true(r.rms_ab > 0.1 && r.rms_ab < 0.5);
    ms_study_scene_free(a);
    ms_study_scene_free(b);
}

/* One right triangle with legs 1: longest edge sqrt 2, spacing 0.25 -> k =
 * ceil(5.657) = 6 steps, 36 centroids, + 3 vertices. Empty and bad input. */
static void test_sample_count_and_errors(void **state)
{
    (void)state;
    double pos[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    uint32_t tri[3] = {0, 1, 2};
    ms_study_scene *a, *empty;
    ms_error err;
    assert_int_equal(ms_study_scene_new(pos, 3, tri, 1, &a, &err), MS_OK);
    ms_study_distance_params p = {.spacing = 0.25, .threads = 1};
    ms_study_distance r;
    assert_int_equal(ms_study_distance_measure(a, a, &p, &r, &err), MS_OK);
    assert_int_equal(r.samples_a, 39);
    assert_int_equal(r.samples_b, 39);
    p.spacing = 0;
    assert_int_equal(ms_study_distance_measure(a, a, &p, &r, &err), MS_ERR_ARG);
    p.spacing = NAN;
    assert_int_equal(ms_study_distance_measure(a, a, &p, &r, &err), MS_ERR_ARG);
    p.spacing = 1;
    assert_int_equal(ms_study_scene_new(pos, 3, tri, 0, &empty, &err), MS_OK);
    assert_int_equal(ms_study_distance_measure(a, empty, &p, &r, &err), MS_ERR_EMPTY);
    ms_study_scene_free(empty);
    tri[2] = 3;
    assert_int_equal(ms_study_scene_new(pos, 3, tri, 1, &empty, &err), MS_ERR_ARG);
    assert_null(empty);
    tri[2] = 2;
    pos[4] = INFINITY;
    assert_int_equal(ms_study_scene_new(pos, 3, tri, 1, &empty, &err), MS_ERR_RANGE);
    /* closest point: above the triangle's interior, beyond an edge, beyond a corner */
    const double above[3] = {0.25, 0.25, 2}, beyond_edge[3] = {1, 1, 0}, corner[3] = {-3, -4, 0};
    uint32_t t;
    assert_true(fabs(ms_study_scene_closest(a, above, &t) - 2) < 1e-15);
    assert_int_equal(t, 0);
    assert_true(fabs(ms_study_scene_closest(a, beyond_edge, NULL) - sqrt(0.5)) < 1e-15);
    assert_true(fabs(ms_study_scene_closest(a, corner, NULL) - 5) < 1e-15);
    ms_study_scene_free(a);
}

static void make_image(ms_study_image *im, uint32_t w, uint32_t h)
{
    ms_error err;
    if (ms_study_image_alloc(im, w, h, &err) != MS_OK)
        fail_msg("%s", err.text);
}

static void cover(ms_study_image *im, size_t p, const float n[3], uint8_t grey)
{
    im->triangle[p] = 0;
    im->depth[p] = 1;
    memcpy(&im->normal[3 * p], n, 3 * sizeof *n);
    memset(&im->rgb[3 * p], grey, 3);
}

/* Normals in the xy plane turned by theta about z are theta away, whatever they are. */
static void test_normal_rotation(void **state)
{
    (void)state;
    const double theta = 17.5 * M_PI / 180;
    ms_study_image a, b;
    make_image(&a, 20, 10);
    make_image(&b, 20, 10);
    uint64_t rng = 99;
    for (size_t p = 0; p < 200; ++p) {
        double phi = (double)(ms_test_random(&rng) % 100000) / 100000 * 2 * M_PI;
        float n[3] = {(float)cos(phi), (float)sin(phi), 0}, m[3] = {(float)cos(phi + theta), (float)sin(phi + theta), 0};
        cover(&a, p, n, 128);
        cover(&b, p, m, 128);
    }
    ms_study_image_error e;
    ms_error err;
    assert_int_equal(ms_study_image_compare(&a, &b, &e, &err), MS_OK);
    assert_int_equal(e.both_covered, 200);
    assert_int_equal(e.silhouette_mismatch, 0);
    assert_true(fabs(e.normal_mean_deg - 17.5) < 1e-4);
    assert_true(fabs(e.normal_p95_deg - 17.5) < 1e-4);
    assert_true(fabs(e.normal_max_deg - 17.5) < 1e-4);
    /* identical: 0 degrees, infinite PSNR, SSIM exactly 1 */
    assert_int_equal(ms_study_image_compare(&a, &a, &e, &err), MS_OK);
    assert_true(e.normal_max_deg == 0 && e.normal_mean_deg == 0);
    assert_true(isinf(e.psnr_db) && e.psnr_db > 0);
    assert_true(e.mse == 0);
    assert_true(e.ssim == 1.0);
    /* a known 95th percentile: 100 pixels at 0 deg, then 1..100 deg? use 20 of 200
     * turned by 90 degrees: p95 = 90 (190th smallest of 200 is within the 20), mean 9 */
    for (size_t p = 0; p < 200; ++p) {
        float n[3] = {1, 0, 0}, m[3] = {p < 20 ? 0.0f : 1.0f, p < 20 ? 1.0f : 0.0f, 0};
        cover(&a, p, n, 128);
        cover(&b, p, m, 128);
    }
    assert_int_equal(ms_study_image_compare(&a, &b, &e, &err), MS_OK);
    assert_true(fabs(e.normal_p95_deg - 90) < 1e-12);
    assert_true(fabs(e.normal_mean_deg - 9) < 1e-12);
    /* 9 of 200 turned: the 190th smallest is 0 */
    for (size_t p = 9; p < 20; ++p)
        cover(&b, p, (const float[3]){1, 0, 0}, 128);
    assert_int_equal(ms_study_image_compare(&a, &b, &e, &err), MS_OK);
    assert_true(e.normal_p95_deg == 0);
    assert_true(fabs(e.normal_max_deg - 90) < 1e-12);
    ms_study_image_free(&a);
    ms_study_image_free(&b);
}

static void test_psnr_ssim(void **state)
{
    (void)state;
    ms_study_image a, b;
    make_image(&a, 40, 30);
    make_image(&b, 40, 30);
    memset(a.rgb, 100, 3 * 40 * 30);
    memset(b.rgb, 105, 3 * 40 * 30);
    ms_study_image_error e;
    ms_error err;
    assert_int_equal(ms_study_image_compare(&a, &b, &e, &err), MS_OK);
    assert_true(e.mse == 25);
    assert_true(fabs(e.psnr_db - 20 * log10(255.0 / 5)) < 1e-12);
    assert_int_equal(e.both_covered, 0);
    assert_true(e.ssim < 1);
    /* a textured image: SSIM with itself exactly 1, with noise added less */
    uint64_t rng = 7;
    for (size_t i = 0; i < 3 * 40 * 30; ++i)
        a.rgb[i] = (uint8_t)(ms_test_random(&rng) % 256);
    double ssim;
    assert_int_equal(ms_study_ssim_rgb(a.rgb, a.rgb, 40, 30, &ssim, &err), MS_OK);
    assert_true(ssim == 1.0);
    memcpy(b.rgb, a.rgb, 3 * 40 * 30);
    for (size_t i = 0; i < 3 * 40 * 30; i += 7)
        b.rgb[i] = (uint8_t)(255 - b.rgb[i]);
    assert_int_equal(ms_study_ssim_rgb(a.rgb, b.rgb, 40, 30, &ssim, &err), MS_OK);
    assert_true(ssim < 0.9 && ssim > -1);
    /* a small image: one whole-image window; identical gives 1 */
    assert_int_equal(ms_study_ssim_rgb(a.rgb, a.rgb, 5, 4, &ssim, &err), MS_OK);
    assert_true(ssim == 1.0);
    /* mismatched sizes */
    ms_study_image c;
    make_image(&c, 40, 29);
    assert_int_equal(ms_study_image_compare(&a, &c, &e, &err), MS_ERR_ARG);
    ms_study_image_free(&a);
    ms_study_image_free(&b);
    ms_study_image_free(&c);
}

/* A 6 x 6 square and the same shifted right by 3 pixels: 2 * 3 * 6 pixels differ;
 * normals are compared on the 3 x 6 overlap only. */
static void test_silhouette(void **state)
{
    (void)state;
    ms_study_image a, b;
    make_image(&a, 20, 16);
    make_image(&b, 20, 16);
    const float n[3] = {0, 0, 1};
    for (uint32_t y = 5; y < 11; ++y)
        for (uint32_t x = 5; x < 11; ++x) {
            cover(&a, (size_t)y * 20 + x, n, 200);
            cover(&b, (size_t)y * 20 + x + 3, n, 200);
        }
    ms_study_image_error e;
    ms_error err;
    assert_int_equal(ms_study_image_compare(&a, &b, &e, &err), MS_OK);
    assert_int_equal(e.silhouette_mismatch, 36);
    assert_int_equal(e.both_covered, 18);
    assert_int_equal(e.pixels, 320);
    ms_study_image_free(&a);
    ms_study_image_free(&b);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_identical_meshes),
        cmocka_unit_test(test_shifted_plane),
        cmocka_unit_test(test_shifted_plane_pixels),
        cmocka_unit_test(test_one_sided),
        cmocka_unit_test(test_sample_count_and_errors),
        cmocka_unit_test(test_normal_rotation),
        cmocka_unit_test(test_psnr_ssim),
        cmocka_unit_test(test_silhouette),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
