/* Colour in the CPU reference renderer and the study's measures (issue 34
 * item 3; ms_study_render.h, "Colour"; ms_study_measure.h, "Colour"). The
 * coloured trefoil of tests/data: its albedo picture is, at every covered
 * pixel, the barycentric interpolation of the hit triangle's vertex colours
 * (the barycentrics found here again, in doubles, from the pixel's ray),
 * within one level, the background elsewhere; without colours the albedo
 * picture is the viewer's grey. Lit, every covered pixel is the documented
 * law with the colour as the albedo, re-evaluated from the image's own
 * normal; white vertices light as the grey model within one level. The
 * colour PSNR on hand-made pictures: exact MSE, per channel, the largest
 * difference, the mask (given, by background colour, by hits). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_mesh_io.h"
#include "ms_study_measure.h"
#include "ms_study_render.h"
#include "ms_test.h"

#define WIDTH 160
#define HEIGHT 120

typedef struct trefoil {
    ms_mesh mesh;
    ms_study_scene *scene;
    ms_camera camera;
} trefoil;

static void trefoil_open(trefoil *t)
{
    memset(t, 0, sizeof *t);
    const char *path = "tests/data/trefoil_color.ply.gz"; /* in git: tests run from the root */
    ms_error err;
    if (ms_mesh_load(path, &t->mesh, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_non_null(t->mesh.colours);
    if (ms_study_scene_new(t->mesh.positions, t->mesh.vertex_count, t->mesh.triangles, t->mesh.triangle_count,
                           &t->scene, &err) != MS_OK)
        fail_msg("%s", err.text);
    /* from the side, so that the tube's walls are seen at every slant */
    const double eye[3] = {0.5, 0.2, 0.8}, target[3] = {0, -0.028, 0}, up[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(eye, target, up, 35, WIDTH, HEIGHT, 0.1, 10, &t->camera, NULL), MS_OK);
}

static void trefoil_close(trefoil *t)
{
    ms_study_scene_free(t->scene);
    ms_mesh_free(&t->mesh);
}

static void render(const trefoil *t, const uint8_t *colours, bool albedo, ms_study_image *im)
{
    ms_study_render_options o = {.threads = 2, .colours = colours, .albedo = albedo, .smooth = true};
    ms_error err;
    if (ms_study_render(t->scene, &t->camera, &o, im, &err) != MS_OK)
        fail_msg("%s", err.text);
}

/* The ray through pixel (i, j)'s centre (ms_study_render.h's projection). */
static void pixel_ray(const ms_camera *c, uint32_t i, uint32_t j, double dir[3])
{
    double ty = tan(c->fovy / 2), tx = ty * c->width / c->height;
    double x = (2.0 * (i + 0.5) / c->width - 1) * tx, y = (1 - 2.0 * (j + 0.5) / c->height) * ty;
    for (int k = 0; k < 3; ++k)
        dir[k] = c->forward[k] + x * c->right[k] + y * c->up[k];
}

/* Barycentrics (of corners 1 and 2) of the ray's crossing of triangle t's
 * plane (Moller-Trumbore, doubles). */
static void crossing(const ms_mesh *m, uint32_t t, const double o[3], const double d[3], double *u, double *v)
{
    const double *a = &m->positions[3 * m->triangles[3 * t]], *b = &m->positions[3 * m->triangles[3 * t + 1]],
                 *c = &m->positions[3 * m->triangles[3 * t + 2]];
    double e1[3], e2[3], s[3];
    for (int k = 0; k < 3; ++k)
        e1[k] = b[k] - a[k], e2[k] = c[k] - a[k], s[k] = o[k] - a[k];
    double p[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double q[3] = {s[1] * e1[2] - s[2] * e1[1], s[2] * e1[0] - s[0] * e1[2], s[0] * e1[1] - s[1] * e1[0]};
    double det = e1[0] * p[0] + e1[1] * p[1] + e1[2] * p[2];
    *u = (s[0] * p[0] + s[1] * p[1] + s[2] * p[2]) / det;
    *v = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) / det;
}

static void test_albedo_picture(void **state)
{
    (void)state;
    trefoil t;
    trefoil_open(&t);
    ms_study_image im = {0};
    render(&t, t.mesh.colours, true, &im);
    uint8_t bg = ms_study_srgb8(MS_STUDY_BACKGROUND);
    assert_int_equal(bg, 39);
    size_t covered = 0, exact = 0;
    for (uint32_t j = 0; j < HEIGHT; ++j)
        for (uint32_t i = 0; i < WIDTH; ++i) {
            size_t p = (size_t)j * WIDTH + i;
            const uint8_t *rgb = &im.rgb[3 * p];
            if (!ms_study_image_covered(&im, p)) {
                assert_true(rgb[0] == bg && rgb[1] == bg && rgb[2] == bg);
                continue;
            }
            covered++;
            double dir[3], u, v;
            pixel_ray(&t.camera, i, j, dir);
            uint32_t tri = im.triangle[p];
            crossing(&t.mesh, tri, t.camera.position, dir, &u, &v);
            assert_true(u > -1e-3 && v > -1e-3 && u + v < 1 + 1e-3); /* the hit lies on it */
            bool same = true;
            for (int k = 0; k < 3; ++k) {
                double want = (1 - u - v) * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri] + (size_t)k] +
                              u * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri + 1] + (size_t)k] +
                              v * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri + 2] + (size_t)k];
                if (fabs(rgb[k] - want) > 1.0)
                    fail_msg("pixel (%u, %u) channel %d: %u, the interpolation %.3f", i, j, k, rgb[k], want);
                same = same && rgb[k] == (uint8_t)lround(want);
            }
            exact += same;
        }
    print_message("albedo: %zu pixels covered, %zu the interpolation rounded exactly\n", covered, exact);
    assert_true(covered > (size_t)WIDTH * HEIGHT / 8);
    assert_true(exact > covered * 99 / 100); /* the rest sit within a rounding of a half level */
    /* without colours: the viewer's grey, sRGB-encoded */
    render(&t, NULL, true, &im);
    for (size_t p = 0; p < (size_t)WIDTH * HEIGHT; ++p)
        if (ms_study_image_covered(&im, p)) {
            assert_int_equal(im.rgb[3 * p], 221);
            assert_int_equal(im.rgb[3 * p + 1], 216);
            assert_int_equal(im.rgb[3 * p + 2], 209);
        }
    ms_study_image_free(&im);
    trefoil_close(&t);
}

static void test_lit_picture(void **state)
{
    (void)state;
    trefoil t;
    trefoil_open(&t);
    ms_study_image lit = {0}, grey = {0};
    render(&t, t.mesh.colours, false, &lit);
    size_t covered = 0;
    for (uint32_t j = 0; j < HEIGHT; ++j)
        for (uint32_t i = 0; i < WIDTH; ++i) {
            size_t p = (size_t)j * WIDTH + i;
            if (!ms_study_image_covered(&lit, p))
                continue;
            covered++;
            double dir[3], u, v, len = 0;
            pixel_ray(&t.camera, i, j, dir);
            for (int k = 0; k < 3; ++k)
                len += dir[k] * dir[k];
            double nl = 0;
            for (int k = 0; k < 3; ++k)
                nl -= lit.normal[3 * p + (size_t)k] * dir[k] / sqrt(len);
            nl = fmax(0, nl);
            uint32_t tri = lit.triangle[p];
            crossing(&t.mesh, tri, t.camera.position, dir, &u, &v);
            for (int k = 0; k < 3; ++k) {
                double c = ((1 - u - v) * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri] + (size_t)k] +
                            u * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri + 1] + (size_t)k] +
                            v * t.mesh.colours[4 * (size_t)t.mesh.triangles[3 * tri + 2] + (size_t)k]) /
                           255.0;
                double a = ms_study_srgb_decode(c);
                double want = a * (MS_STUDY_AMBIENT + nl * MS_STUDY_DIFFUSE * nl) +
                              nl * MS_STUDY_SPECULAR * pow(nl, MS_STUDY_SHININESS);
                if (abs((int)lit.rgb[3 * p + (size_t)k] - (int)ms_study_srgb8(want)) > 1)
                    fail_msg("pixel (%u, %u) channel %d: %u, the law gives %u", i, j, k, lit.rgb[3 * p + (size_t)k],
                             ms_study_srgb8(want));
            }
        }
    assert_true(covered > (size_t)WIDTH * HEIGHT / 8);
    /* white vertices: the grey model's picture (albedo 1), within a rounding */
    uint8_t *white = malloc(4 * t.mesh.vertex_count);
    assert_non_null(white);
    memset(white, 255, 4 * t.mesh.vertex_count);
    render(&t, white, false, &lit);
    render(&t, NULL, false, &grey);
    size_t same = 0;
    for (size_t p = 0; p < 3 * (size_t)WIDTH * HEIGHT; ++p) {
        assert_true(abs((int)lit.rgb[p] - (int)grey.rgb[p]) <= 1);
        same += lit.rgb[p] == grey.rgb[p];
    }
    assert_true(same > 3 * (size_t)WIDTH * HEIGHT * 99 / 100);
    free(white);
    ms_study_image_free(&lit);
    ms_study_image_free(&grey);
    trefoil_close(&t);
}

static void test_colour_psnr(void **state)
{
    (void)state;
    /* four pixels; the second differs by 3 in red and 4 in blue, the fourth
     * by 10 in green; the mask leaves the fourth out */
    const uint8_t a[12] = {10, 20, 30, 100, 100, 100, 0, 0, 0, 255, 255, 255};
    const uint8_t b[12] = {10, 20, 30, 103, 100, 96, 0, 0, 0, 255, 245, 255};
    const uint8_t mask[4] = {1, 1, 1, 0};
    ms_study_colour_error e;
    ms_error err;
    assert_int_equal(ms_study_colour_psnr(a, b, 4, mask, &e, &err), MS_OK);
    assert_int_equal(e.pixels, 3);
    assert_true(fabs(e.mse - 25.0 / 9.0) < 1e-12);
    assert_true(fabs(e.psnr_db - 10 * log10(255.0 * 255.0 * 9.0 / 25.0)) < 1e-9);
    assert_true(fabs(e.channel_psnr_db[0] - 10 * log10(255.0 * 255.0 * 3.0 / 9.0)) < 1e-9);
    assert_true(isinf(e.channel_psnr_db[1]));
    assert_true(fabs(e.channel_psnr_db[2] - 10 * log10(255.0 * 255.0 * 3.0 / 16.0)) < 1e-9);
    assert_int_equal(e.max_difference, 4);
    assert_int_equal(ms_study_colour_psnr(a, b, 4, NULL, &e, &err), MS_OK);
    assert_int_equal(e.pixels, 4);
    assert_int_equal(e.max_difference, 10);
    assert_true(fabs(e.mse - 125.0 / 12.0) < 1e-12);
    assert_int_equal(ms_study_colour_psnr(a, a, 4, NULL, &e, &err), MS_OK);
    assert_true(isinf(e.psnr_db) && e.mse == 0 && e.max_difference == 0);
    const uint8_t none[4] = {0, 0, 0, 0};
    assert_int_equal(ms_study_colour_psnr(a, b, 4, none, &e, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "colour PSNR: no pixel to compare");
    /* the mask by colour: the third pixel is background in both */
    uint8_t by_colour[4];
    const uint8_t black[3] = {0, 0, 0};
    assert_int_equal(ms_study_colour_mask(a, b, 4, black, false, by_colour), 3);
    assert_true(by_colour[0] && by_colour[1] && !by_colour[2] && by_colour[3]);
    const uint8_t c[12] = {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0}; /* only the second covered */
    assert_int_equal(ms_study_colour_mask(a, c, 4, black, true, by_colour), 1);
    assert_true(!by_colour[0] && by_colour[1] && !by_colour[2] && !by_colour[3]);
    assert_int_equal(ms_study_colour_mask(a, c, 4, black, false, by_colour), 3);

    /* two renders of the trefoil, every vertex's green 8 levels up (at most
     * 255): over the pixels covered, as the bare function gives it */
    trefoil t;
    trefoil_open(&t);
    uint8_t *shifted = malloc(4 * t.mesh.vertex_count);
    assert_non_null(shifted);
    memcpy(shifted, t.mesh.colours, 4 * t.mesh.vertex_count);
    for (size_t v = 0; v < t.mesh.vertex_count; ++v)
        shifted[4 * v + 1] = (uint8_t)(shifted[4 * v + 1] > 247 ? 255 : shifted[4 * v + 1] + 8);
    ms_study_image x = {0}, y = {0};
    render(&t, t.mesh.colours, true, &x);
    render(&t, shifted, true, &y);
    assert_int_equal(ms_study_image_colour_psnr(&x, &y, &e, &err), MS_OK);
    size_t n = (size_t)WIDTH * HEIGHT;
    uint8_t *covered = malloc(n);
    assert_non_null(covered);
    size_t count = 0;
    for (size_t p = 0; p < n; ++p)
        count += covered[p] = ms_study_image_covered(&x, p) != 0;
    assert_int_equal(e.pixels, count);
    ms_study_colour_error bare;
    assert_int_equal(ms_study_colour_psnr(x.rgb, y.rgb, n, covered, &bare, &err), MS_OK);
    assert_true(e.psnr_db == bare.psnr_db && e.max_difference == bare.max_difference);
    assert_true(isinf(e.channel_psnr_db[0]) && isinf(e.channel_psnr_db[2]));
    print_message("green 8 up: %llu pixels, PSNR %.2f dB (green %.2f), largest difference %u\n",
                  (unsigned long long)e.pixels, e.psnr_db, e.channel_psnr_db[1], e.max_difference);
    assert_true(e.max_difference <= 9 && e.channel_psnr_db[1] > 30 && e.channel_psnr_db[1] < 31);
    /* by the background colour: the same pixels (no surface pixel is 39 39 39 here) */
    const uint8_t bg[3] = {39, 39, 39};
    assert_int_equal(ms_study_colour_mask(x.rgb, y.rgb, n, bg, false, covered), count);
    assert_int_equal(ms_study_colour_mask(x.rgb, y.rgb, n, bg, true, covered), count); /* one silhouette */
    ms_study_image z = {0};
    ms_study_image_alloc(&z, 2, 2, &err);
    assert_int_equal(ms_study_image_colour_psnr(&x, &z, &e, &err), MS_ERR_ARG);
    ms_study_image_free(&z);
    free(covered);
    free(shifted);
    ms_study_image_free(&x);
    ms_study_image_free(&y);
    trefoil_close(&t);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_albedo_picture),
        cmocka_unit_test(test_lit_picture),
        cmocka_unit_test(test_colour_psnr),
    };
    return cmocka_run_group_tests_name("study_colour", tests, NULL, NULL);
}
