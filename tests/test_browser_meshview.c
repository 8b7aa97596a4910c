/* The browser's pictures against meshview's (docs/BROWSER.md "Pictures"):
 * the demo model along the close-up path (scripts/paths/demo-closeup.cam,
 * three of its keyframes: the overview, the middle, the carved relief), the
 * page in headless Chromium following the path through its #cam= (one page,
 * the camera moved by the URL's hash) and meshview's scripted run of the
 * same path, same size, same tolerance, both from one meshserve. At every
 * keyframe: the page reaches view complete with no console error, and its
 * screenshot matches meshview's picture: silhouette intersection over union
 * >= 0.98 and PSNR >= 30 dB (the page shades with meshview's lit law in its
 * geometry mode). The colour trefoil fixture (tests/data) likewise at one
 * camera: the page draws its scanned colours (docs/BROWSER.md, "Colour") as
 * meshview does, not the default grey. Skips, saying why, without
 * chromium-headless-shell or emscripten; needs an X display for meshview
 * (Xvfb, ms_test_display). */
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define WIDTH 320
#define HEIGHT 240
#define KEYS 3

/* Keyframes 0, 4 and 8 of scripts/paths/demo-closeup.cam, one second apart. */
static const char *const KEYFRAMES[KEYS] = {
    "3.5 0.5 0.4 0.6 0 0.1 0 0 1 40",
    "1.26875 0.15 0.225 0.6 0 0.1 0 0 1 35",
    "0.95 0.1 0.2 0.6 0 0.1 0 0 1 30",
};

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600];
    pid_t server;
    uint16_t port, http_port;
    char why_skip[256];
} fixture;

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    char why[256];
    if (!f || !ms_test_display_start(&f->display, why, sizeof why)) {
        fprintf(stderr, "no X display: %s\n", why);
        free(f);
        return -1;
    }
    *state = f;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char meshgen[600], meshbake[600], trefoil[1024], command[8192], out[4096];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    ms_test_model_path(trefoil, sizeof trefoil, "trefoil_color.ply.gz");
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 && "
             "%s %s -o %s --name trefoil --min-tris 2000 --no-apo --threads 2",
             meshgen, f->dir, meshbake, f->dir, f->archives, meshbake, trefoil, f->archives);
    if (ms_test_run(command, out, sizeof out) != 0) {
        fprintf(stderr, "%s: %s\n", command, out);
        return -1;
    }
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    f->server = ms_test_browser_serve(f->dir, f->archives, &f->port, &f->http_port);
    return f->server ? 0 : -1;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    if (!f)
        return 0;
    if (f->server)
        ms_test_stop(f->server, SIGTERM, 10.0);
    ms_test_rmdir(f->dir);
    ms_test_display_stop(&f->display);
    free(f);
    return 0;
}

/* IoU of the silhouettes and PSNR (dB, all three channels) of two pictures
 * of WIDTH x HEIGHT. */
static void compare(const char *a_path, const char *b_path, double *iou, double *psnr)
{
    size_t covered, ref_covered;
    *iou = ms_test_silhouette_iou(a_path, b_path, WIDTH, HEIGHT, &covered, &ref_covered);
    *psnr = ms_test_png_psnr(a_path, b_path, WIDTH, HEIGHT);
}

static void test_closeup_path_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char path_file[700], text[1024], command[4096], meshview[600];
    size_t used = (size_t)snprintf(text, sizeof text, "meshstream-camera-path 1\n");
    for (int k = 0; k < KEYS; ++k)
        used += (size_t)snprintf(text + used, sizeof text - used, "%d %s\n", k, KEYFRAMES[k]);
    snprintf(path_file, sizeof path_file, "%s/closeup.cam", f->dir);
    ms_test_write_file(path_file, text, used);
    /* meshview's pictures: lit, geometry normals, 1 px, from the same server */
    ms_test_bin_path(meshview, sizeof meshview, "meshview");
    snprintf(command, sizeof command,
             "%s --server 127.0.0.1:%u --model demo --path %s --size %dx%d --screenshot-dir %s/mv "
             "--shading geometry --tolerance 1 --frames 1 --json",
             meshview, f->port, path_file, WIDTH, HEIGHT, f->dir);
    json_t *mv = ms_test_run_json(command, 0);
    json_t *mv_keys = json_object_get(mv, "keyframes");
    assert_int_equal(json_array_size(mv_keys), KEYS);
    /* the page along the same path: one page, its #cam= moved keyframe by keyframe */
    char first[256];
    snprintf(first, sizeof first, "%s", KEYFRAMES[0]);
    for (char *c = first; *c; ++c)
        *c = *c == ' ' ? ',' : *c;
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/demo#cam=%s&tol=1&hud=0' --size %dx%d "
             "--out %s/page.png --keyframes %s --timeout 120",
             f->http_port, first, WIDTH, HEIGHT, f->dir, path_file);
    json_t *page = ms_test_run_json(command, 0);
    json_t *page_keys = json_object_get(page, "keyframes");
    assert_int_equal(json_array_size(page_keys), KEYS);
    assert_int_equal(json_array_size(json_object_get(page, "console")), 0);
    for (int k = 0; k < KEYS; ++k) {
        json_t *p = json_array_get(page_keys, (size_t)k), *m = json_array_get(mv_keys, (size_t)k);
        char shot[700], ref[700];
        snprintf(shot, sizeof shot, "%s/page-%02d.png", f->dir, k);
        snprintf(ref, sizeof ref, "%s/mv/keyframe-%02d.png", f->dir, k);
        double iou, psnr;
        compare(shot, ref, &iou, &psnr);
        printf("keyframe %d: page %s, %lld triangles in %lld cells, settled %lld ms after its "
               "camera; meshview complete %s, %lld triangles; IoU %.4f, PSNR %.2f dB\n",
               k, json_string_value(json_object_get(p, "state")),
               (long long)json_integer_value(json_object_get(p, "triangles")),
               (long long)json_integer_value(json_object_get(p, "cells")),
               (long long)json_integer_value(json_object_get(p, "settleMs")),
               json_is_true(json_object_get(m, "complete")) ? "yes" : "no",
               (long long)json_integer_value(json_object_get(m, "triangles_drawn")), iou, psnr);
        assert_string_equal(json_string_value(json_object_get(p, "state")), "complete");
        assert_true(json_is_true(json_object_get(m, "complete")));
        assert_true(iou >= 0.98);
        assert_true(psnr >= 30.0);
    }
    json_decref(page);
    json_decref(mv);
}

static void test_colour_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char camera[] = "0.6 0.5 3.4 0 0 0 0 1 0 40";
    char path_file[700], text[256], command[4096], meshview[600], page_cam[64];
    int used = snprintf(text, sizeof text, "meshstream-camera-path 1\n0 %s\n", camera);
    snprintf(path_file, sizeof path_file, "%s/trefoil.cam", f->dir);
    ms_test_write_file(path_file, text, (size_t)used);
    ms_test_bin_path(meshview, sizeof meshview, "meshview");
    snprintf(command, sizeof command,
             "%s --server 127.0.0.1:%u --model trefoil --path %s --size %dx%d --screenshot-dir %s/mvc "
             "--shading geometry --tolerance 1 --frames 1 --json",
             meshview, f->port, path_file, WIDTH, HEIGHT, f->dir);
    json_t *mv = ms_test_run_json(command, 0);
    assert_int_equal(json_array_size(json_object_get(mv, "keyframes")), 1);
    assert_true(json_is_true(json_object_get(json_array_get(json_object_get(mv, "keyframes"), 0), "complete")));
    snprintf(page_cam, sizeof page_cam, "%s", camera);
    for (char *c = page_cam; *c; ++c)
        *c = *c == ' ' ? ',' : *c;
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/trefoil#cam=%s&tol=1&hud=0' --size %dx%d "
             "--out %s/trefoil.png --timeout 120",
             f->http_port, page_cam, WIDTH, HEIGHT, f->dir);
    json_t *page = ms_test_run_json(command, 0);
    assert_int_equal(json_array_size(json_object_get(page, "console")), 0);
    char shot[700], ref[700];
    snprintf(shot, sizeof shot, "%s/trefoil.png", f->dir);
    snprintf(ref, sizeof ref, "%s/mvc/keyframe-00.png", f->dir);
    double iou, psnr;
    compare(shot, ref, &iou, &psnr);
    double chroma = ms_test_png_mean_chroma(shot), ref_chroma = ms_test_png_mean_chroma(ref);
    json_t *figures = json_object_get(page, "page");
    printf("trefoil: page %s, %lld triangles, %lld colour bytes; IoU %.4f, PSNR %.2f dB; mean chroma %.1f "
           "(meshview %.1f)\n",
           json_string_value(json_object_get(page, "state")),
           (long long)json_integer_value(json_object_get(figures, "triangles")),
           (long long)json_integer_value(json_object_get(json_object_get(figures, "timing"), "colourBytes")), iou,
           psnr, chroma, ref_chroma);
    assert_string_equal(json_string_value(json_object_get(page, "state")), "complete");
    assert_true(iou >= 0.98);
    assert_true(psnr >= 30.0);
    /* coloured, as meshview's (the default grey has a chroma of about 10) */
    assert_true(ref_chroma > 40.0);
    assert_true(fabs(chroma - ref_chroma) < 0.1 * ref_chroma);
    json_decref(page);
    json_decref(mv);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_closeup_path_against_meshview),
        cmocka_unit_test(test_colour_against_meshview),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
