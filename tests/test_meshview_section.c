/* Section planes in meshview against meshrender (docs/VIEWER.md, "Sections";
 * docs/RENDERER.md, "Sections"): the dragon (res3) baked without APO,
 * streamed by the built meshview scripted under Xvfb at 200x150 to a 0.5 px
 * tolerance (at 1 px the coarser cut's section IoU is 0.951), and ray cast
 * whole by meshrender with the same --section planes from the same camera:
 *   - one axis plane (z = -0.005, the half towards the eye cut away), then
 *     that plane and a free one: the pixels in the section colour (the
 *     dragon's inside seen through the cut, MS_SECTION_R G B within 3 a
 *     channel) cover the same region in both pictures, IoU >= 0.95, and so
 *     does the model's silhouette (every pixel not the background);
 *   - the view text carries the planes: --view with s= draws the picture of
 *     the same view without s= given --section, to the byte, and the report's
 *     "sections" are the planes;
 *   - usage errors: hostile --section values to meshview and meshrender are
 *     one line and exit status 2. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_camera.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_picture.h"

#define WIDTH 200
#define HEIGHT 150

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600], cam[700], model[4096], view_bin[600], render_bin[600];
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
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char bake[600], command[8192];
    ms_test_model_path(f->model, sizeof f->model, "stanford_dragon_vrip_res3.ply.gz");
    ms_test_bin_path(bake, sizeof bake, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name dragon --no-apo --min-tris 1500 --json", bake, f->model,
             f->archives);
    json_decref(ms_test_run_json(command, 0));
    snprintf(f->cam, sizeof f->cam, "%s/dragon.cam", f->dir);
    FILE *out = fopen(f->cam, "w");
    if (!out)
        return -1;
    fprintf(out, "meshstream-camera-path 1\n0 0.10 0.20 0.28 -0.006 0.125 -0.005 0 1 0 40\n");
    fclose(out);
    ms_test_bin_path(f->view_bin, sizeof f->view_bin, "meshview");
    ms_test_bin_path(f->render_bin, sizeof f->render_bin, "meshrender");
    *state = f;
    return 0;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    if (!f)
        return 0;
    ms_test_display_stop(&f->display);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* meshview on the dragon (along the camera path unless `extra` has a view):
 * the report; the keyframe's PNG into png. */
static json_t *view(const fixture *f, const char *tag, const char *extra, bool path, char *png, size_t size)
{
    char command[8192];
    snprintf(command, sizeof command,
             "%s %s --model dragon %s%s --size %dx%d --shading geometry --tolerance 0.5 --frames 1 "
             "--screenshot-dir %s/%s --json %s",
             f->view_bin, f->archives, path ? "--path " : "", path ? f->cam : "", WIDTH, HEIGHT, f->dir, tag, extra);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    snprintf(png, size, "%s", json_string_value(json_object_get(key, "png")));
    return report;
}

static bool section_pixel(const uint8_t *p)
{
    static const int want[3] = {MS_SECTION_R, MS_SECTION_G, MS_SECTION_B};
    for (int k = 0; k < 3; ++k)
        if (abs((int)p[k] - want[k]) > 3)
            return false;
    return true;
}

/* IoU of the section-coloured pixels and of the silhouettes (pixels not the
 * background, the top-left corner's colour) of two pictures; the section
 * pixels' count in a. */
static void compare(const char *a_path, const char *b_path, double *section_iou, double *silhouette_iou,
                    size_t *section_pixels)
{
    uint32_t wa, ha, wb, hb;
    uint8_t *a = ms_test_png_read(a_path, &wa, &ha), *b = ms_test_png_read(b_path, &wb, &hb);
    assert_int_equal(wa, wb);
    assert_int_equal(ha, hb);
    size_t s_and = 0, s_or = 0, m_and = 0, m_or = 0, sa = 0;
    for (size_t i = 0; i < (size_t)wa * ha; ++i) {
        const uint8_t *x = &a[3 * i], *y = &b[3 * i];
        bool xs = section_pixel(x), ys = section_pixel(y);
        bool xm = memcmp(x, a, 3) != 0, ym = memcmp(y, b, 3) != 0;
        s_and += xs && ys, s_or += xs || ys, sa += xs;
        m_and += xm && ym, m_or += xm || ym;
    }
    *section_iou = s_or ? (double)s_and / (double)s_or : 0;
    *silhouette_iou = m_or ? (double)m_and / (double)m_or : 0;
    *section_pixels = sa;
    free(a);
    free(b);
}

static void test_sections_against_embree(void **state)
{
    fixture *f = *state;
    static const struct {
        const char *tag, *planes;
    } cases[] = {
        {"axis", "--section z=-0.005"},
        {"two", "--section z=-0.005 --section -0.02,0.12,0,0.8,0.6,0"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        char png[800], ref[800], command[8192];
        json_t *report = view(f, cases[i].tag, cases[i].planes, true, png, sizeof png);
        assert_int_equal(json_array_size(json_object_get(report, "sections")), i + 1);
        json_decref(report);
        snprintf(command, sizeof command, "%s %s -p %s -o %s/%s-ref --width %d --height %d %s --json", f->render_bin,
                 f->model, f->cam, f->dir, cases[i].tag, WIDTH, HEIGHT, cases[i].planes);
        json_decref(ms_test_run_json(command, 0));
        snprintf(ref, sizeof ref, "%s/%s-ref/frame_000.png", f->dir, cases[i].tag);
        double section, silhouette;
        size_t pixels;
        compare(png, ref, &section, &silhouette, &pixels);
        printf("dragon, %s: section IoU %.4f over %zu pixels, silhouette IoU %.4f against Embree of the full "
               "model\n",
               cases[i].planes, section, pixels, silhouette);
        assert_true(pixels >= 1000);
        assert_true(section >= 0.95);
        assert_true(silhouette >= 0.95);
    }
}

static void test_view_text_carries_sections(void **state)
{
    fixture *f = *state;
    static const char camera[] = "mv1:t=-0.006,0.125,-0.005:d=0.3:o=0.4,0.3:f=40:u=y";
    char extra[1024], with[800], without[800], ref[800];
    snprintf(extra, sizeof extra, "--view %s:s=0,0,-0.005,0,0,1/-0.02,0.12,0,0.8,0.6,0", camera);
    json_t *a = view(f, "view-s", extra, false, with, sizeof with);
    snprintf(extra, sizeof extra, "--view %s --section z=-0.005 --section -0.02,0.12,0,0.8,0.6,0", camera);
    json_t *b = view(f, "view-flags", extra, false, without, sizeof without);
    assert_true(json_equal(json_object_get(a, "sections"), json_object_get(b, "sections")));
    json_t *second = json_array_get(json_object_get(a, "sections"), 1);
    assert_true(json_real_value(json_array_get(json_object_get(second, "normal"), 0)) == 0.8);
    assert_int_equal(ms_test_png_differing(with, without, 0), 0);
    snprintf(extra, sizeof extra, "--view %s", camera);
    json_decref(view(f, "view-none", extra, false, ref, sizeof ref));
    double section, silhouette;
    size_t pixels, none;
    compare(with, ref, &section, &silhouette, &pixels);
    compare(ref, ref, &section, &silhouette, &none);
    printf("the view text's sections: %zu section pixels, %zu without\n", pixels, none);
    assert_true(pixels >= 500);
    assert_int_equal(none, 0);
    json_decref(a);
    json_decref(b);
}

static void test_usage_errors(void **state)
{
    fixture *f = *state;
    static const char *const bad[] = {
        "V --model dragon --section x=",
        "V --model dragon --section 'x=1 '",
        "V --model dragon --section 0,0,0,0,0,0",
        "V --model dragon --section 0,0,0,1,1",
        "V --model dragon --section z=1e309",
        "V --model dragon --section x=1 --section y=1 --section z=1 --section -x=0",
        "V --section x=0",
        "R --section x=",
        "R --section 0,0,0,0,0,0",
        "R --section w=1",
        "R --section x=1 --section y=1 --section z=1 --section -x=0",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        char command[8192], out[4096];
        bool meshview = bad[i][0] == 'V';
        if (meshview)
            snprintf(command, sizeof command, "%s %s %s", f->view_bin, f->archives, bad[i] + 2);
        else
            snprintf(command, sizeof command, "%s %s -p %s -o %s/bad %s", f->render_bin, f->model, f->cam, f->dir,
                     bad[i] + 2);
        int status = ms_test_run(command, out, sizeof out);
        size_t lines = 0;
        for (const char *p = out; *p; ++p)
            lines += *p == '\n';
        if (status != 2 || lines != 1 || strncmp(out, meshview ? "meshview: " : "meshrender: ", meshview ? 10 : 12))
            fail_msg("'%s': status %d, output '%s'", bad[i], status, out);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sections_against_embree),
        cmocka_unit_test(test_view_text_carries_sections),
        cmocka_unit_test(test_usage_errors),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
