/* Looking closely with meshview (docs/VIEWER.md, "Measuring", "Light",
 * "Shareable views"): the built program, scripted under Xvfb at 160x120, on
 * a unit cube baked at 20 bits without APO, seen head-on from -y (the face
 * y = 0 fills the middle of the picture):
 *   - --measure between two pixels of the face: both points on it; what the
 *     view held (6 bits at this size) and what the probe refined (20 bits,
 *     the model's) each within its precision of the distance computed here
 *     from the camera (the rays through the pixels met with the plane y = 0),
 *     the precision the grid step box_side / 2^bits at the bits held;
 *     with --hud the picture marks the points; a pixel off the model is a
 *     point not hit and no distance;
 *   - --light: the face's grey under az 60 equals az -60 and el 60 (the same
 *     angle to the normal) within one level, and against az 75 the linear
 *     intensities (sRGB decoded, the 5 % ambient taken off) go as meshview's
 *     lighting law says: Lambert's cosine times the self-shadowing cosine,
 *     cos^2, within 3 % (cos alone, 1.93, is far off the 3.73 of cos^2); the
 *     report's light as given;
 *   - --view: the report's view is the text given, its light and its
 *     measuring points are used (both points on the face);
 *   - usage errors: hostile --view texts, bad --light and --measure values and
 *     misplaced options are one line and exit status 2. */
#include <math.h>
#include <signal.h>
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

#include "ms_archive.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define WIDTH 160
#define HEIGHT 120
#define FOVY 40.0

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600], cam[700], bin[600];
    double box_side;
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
    /* the unit cube, 12 triangles wound outwards */
    char ply[700], command[4096], bake[600];
    snprintf(ply, sizeof ply, "%s/cube.ply", f->dir);
    FILE *out = fopen(ply, "w");
    if (!out)
        return -1;
    fprintf(out, "ply\nformat ascii 1.0\nelement vertex 8\nproperty double x\nproperty double y\n"
                 "property double z\nelement face 12\nproperty list uchar int vertex_indices\nend_header\n");
    for (int i = 0; i < 8; ++i)
        fprintf(out, "%d %d %d\n", i & 1, (i >> 1) & 1, (i >> 2) & 1);
    static const int quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int q = 0; q < 6; ++q)
        fprintf(out, "3 %d %d %d\n3 %d %d %d\n", quads[q][0], quads[q][1], quads[q][2], quads[q][0], quads[q][2],
                quads[q][3]);
    fclose(out);
    ms_test_bin_path(bake, sizeof bake, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name cube --bits 20 --no-apo --json", bake, ply, f->archives);
    json_decref(ms_test_run_json(command, 0));
    char file[700];
    snprintf(file, sizeof file, "%s/cube.msa", f->archives);
    ms_archive *archive;
    ms_error err;
    if (ms_archive_open(file, &archive, &err) != MS_OK)
        return -1;
    f->box_side = ms_archive_get_header(archive)->box_side;
    ms_archive_close(archive);
    /* head-on: from -y at the face's middle, up z */
    snprintf(f->cam, sizeof f->cam, "%s/front.cam", f->dir);
    out = fopen(f->cam, "w");
    if (!out)
        return -1;
    fprintf(out, "meshstream-camera-path 1\n0 0.5 -2.5 0.5 0.5 0.5 0.5 0 0 1 %g\n", FOVY);
    fclose(out);
    ms_test_bin_path(f->bin, sizeof f->bin, "meshview");
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

/* meshview on model from source (the archive directory, or "--server
 * HOST:PORT") with extra options (along the front path unless `extra` gives a
 * view); the report, the keyframe's PNG into png. */
static json_t *view_at(const fixture *f, const char *source, const char *model, const char *tag, const char *extra,
                       bool path, char *png, size_t size)
{
    char command[8192];
    snprintf(command, sizeof command,
             "%s %s --model %s %s%s --size %dx%d --shading geometry --frames 1 --screenshot-dir %s/%s --json %s",
             f->bin, source, model, path ? "--path " : "", path ? f->cam : "", WIDTH, HEIGHT, f->dir, tag, extra);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    if (png)
        snprintf(png, size, "%s", json_string_value(json_object_get(key, "png")));
    return report;
}

/* The cube from the archive directory. */
static json_t *view(const fixture *f, const char *tag, const char *extra, bool path, char *png, size_t size)
{
    return view_at(f, f->archives, "cube", tag, extra, path, png, size);
}

/* The point of the plane y = 0 seen at framebuffer point (x, y), computed
 * here: eye (0.5, -2.5, 0.5), forward +y, right +x, up +z. */
static void face_point(double x, double y, double p[3])
{
    double th = tan(FOVY * M_PI / 360.0), sx = (2 * x / WIDTH - 1) * th * WIDTH / HEIGHT, sy = (1 - 2 * y / HEIGHT) * th;
    double t = 2.5; /* to y = 0 along (sx, 1, sy) */
    p[0] = 0.5 + t * sx, p[1] = 0, p[2] = 0.5 + t * sy;
}

static double number(const json_t *o, const char *key)
{
    const json_t *v = json_object_get(o, key);
    if (!json_is_number(v))
        fail_msg("no number '%s'", key);
    return json_number_value(v);
}

static void test_measure_on_the_face(void **state)
{
    fixture *f = *state;
    json_t *report = view(f, "measure", "--measure 52.25,40.5:111.5,77.75", true, NULL, 0);
    json_t *m = json_object_get(report, "measure");
    assert_non_null(m);
    json_t *points = json_object_get(m, "points");
    assert_int_equal(json_array_size(points), 2);
    double a[3], b[3];
    face_point(52.25, 40.5, a);
    face_point(111.5, 77.75, b);
    double expected = sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[2] - b[2]) * (a[2] - b[2]));
    double step_max = 0;
    for (size_t i = 0; i < 2; ++i) {
        json_t *p = json_array_get(points, i);
        assert_true(json_is_true(json_object_get(p, "hit")));
        int bits = (int)json_integer_value(json_object_get(p, "bits"));
        double step = number(p, "step");
        assert_true(bits > 0 && bits <= 20);
        assert_true(step == ldexp(f->box_side, -bits));
        step_max = step > step_max ? step : step_max;
        /* on the face y = 0, within the step */
        assert_true(fabs(json_real_value(json_array_get(json_object_get(p, "point"), 1))) <= step);
    }
    double length = number(m, "length"), precision = number(m, "precision");
    double view_length = number(m, "view_length"), view_precision = number(m, "view_precision");
    int view_bits = (int)json_integer_value(json_object_get(m, "view_bits_min"));
    printf("the view (%d bits): %.9f +- %.3g; refined (%lld bits): %.9f +- %.3g; computed %.9f\n", view_bits,
           view_length, view_precision, (long long)json_integer_value(json_object_get(m, "bits_min")), length,
           precision, expected);
    /* what the view held: coarser, still within its own precision */
    assert_true(view_bits > 0 && view_bits < 20);
    assert_true(view_precision == ldexp(f->box_side, -view_bits));
    assert_true(fabs(view_length - expected) <= view_precision);
    /* refined by the probe to the model's 20 bits */
    assert_true(json_is_true(json_object_get(m, "refined_to_full")));
    assert_int_equal(json_integer_value(json_object_get(m, "bits_min")), 20);
    assert_true(precision == step_max && precision == ldexp(f->box_side, -20));
    assert_true(fabs(length - expected) <= precision);
    assert_string_equal(json_string_value(json_object_get(m, "unit")), "model units");
    const char *text = json_string_value(json_object_get(m, "text"));
    assert_non_null(strstr(text, " model units (20 bits, full)"));
    assert_int_equal(strlen(strstr(text, " model units (20 bits, full)")), strlen(" model units (20 bits, full)"));
    json_decref(report);

    /* with --hud the keyframe's picture marks the points (yellow squares) */
    char png[800];
    report = view(f, "measure-hud", "--hud --measure 52.25,90.5:111.5,77.75", true, png, sizeof png);
    json_decref(report);
    uint32_t w, h;
    uint8_t *rgb = ms_test_png_read(png, &w, &h);
    const uint8_t *at = &rgb[3 * (90 * w + 52)];
    printf("marker pixel: %d %d %d\n", at[0], at[1], at[2]);
    assert_true(at[0] >= 240 && at[1] >= 200 && at[1] <= 230 && at[2] <= 80);
    free(rgb);

    /* a pixel off the model: not hit, no distance */
    report = view(f, "miss", "--measure 80,60:2,2", true, NULL, 0);
    m = json_object_get(report, "measure");
    assert_true(json_is_true(json_object_get(json_array_get(json_object_get(m, "points"), 0), "hit")));
    assert_false(json_is_true(json_object_get(json_array_get(json_object_get(m, "points"), 1), "hit")));
    assert_true(json_is_null(json_object_get(m, "length")));
    json_decref(report);
}

/* The mean linear intensity over a 20 x 20 block at the face's middle,
 * ambient taken off: (linear / albedo - 0.05) / 0.95 per channel, averaged;
 * and the mean 8-bit level. */
static double face_lambert(const char *png, double *level)
{
    static const double albedo[3] = {0.72, 0.69, 0.64};
    uint32_t w, h;
    uint8_t *rgb = ms_test_png_read(png, &w, &h);
    assert_int_equal(w, WIDTH);
    double sum = 0, levels = 0;
    int n = 0;
    for (uint32_t y = HEIGHT / 2 - 10; y < HEIGHT / 2 + 10; ++y)
        for (uint32_t x = WIDTH / 2 - 10; x < WIDTH / 2 + 10; ++x)
            for (int c = 0; c < 3; ++c) {
                double s = rgb[3 * (y * w + x) + c] / 255.0;
                double lin = s <= 0.04045 ? s / 12.92 : pow((s + 0.055) / 1.055, 2.4);
                sum += (lin / albedo[c] - 0.05) / 0.95;
                levels += rgb[3 * (y * w + x) + c];
                n++;
            }
    free(rgb);
    *level = levels / n;
    return sum / n;
}

static void test_light_follows_lambert(void **state)
{
    fixture *f = *state;
    static const char *const lights[] = {"60,0", "-60,0", "0,60", "75,0"};
    double lambert[4], level[4];
    for (int i = 0; i < 4; ++i) {
        char extra[64], tag[32], png[800];
        snprintf(extra, sizeof extra, "--light %s", lights[i]);
        snprintf(tag, sizeof tag, "light%d", i);
        json_t *report = view(f, tag, extra, true, png, sizeof png);
        json_t *light = json_object_get(report, "light");
        double az, el;
        sscanf(lights[i], "%lf,%lf", &az, &el);
        assert_true(number(light, "azimuth_deg") == az && number(light, "elevation_deg") == el);
        json_decref(report);
        lambert[i] = face_lambert(png, &level[i]);
    }
    double want = pow(cos(M_PI / 3) / cos(75 * M_PI / 180), 2);
    printf("face grey: az 60 %.2f, az -60 %.2f, el 60 %.2f, az 75 %.2f; ratio %.3f (cos^2 law %.3f)\n", level[0],
           level[1], level[2], level[3], lambert[0] / lambert[3], want);
    assert_true(fabs(level[0] - level[1]) <= 1 && fabs(level[0] - level[2]) <= 1);
    assert_true(fabs(lambert[0] / lambert[3] / want - 1) <= 0.03);
    /* absolute: cos^2 60 = 0.25 within 3 % */
    assert_true(fabs(lambert[0] / 0.25 - 1) <= 0.03);
    /* the default is the head light */
    json_t *report = view(f, "head", "", true, NULL, 0);
    assert_true(json_is_true(json_object_get(json_object_get(report, "light"), "head")));
    json_decref(report);
}

static void test_view_text(void **state)
{
    fixture *f = *state;
    /* the front view (yaw: looking along +y with up z) with a light and two points on the face */
    const char *text = "mv1:t=0.5,0.5,0.5:d=3:o=3.141592653589793,0:f=40:u=z:l=60,0"
                       ":m=0.25,0,0.5,0,1,0/0.75,0,0.25,0,1,0";
    char extra[600];
    snprintf(extra, sizeof extra, "--view %s", text);
    json_t *report = view(f, "view", extra, false, NULL, 0);
    assert_string_equal(json_string_value(json_object_get(report, "view")), text);
    json_t *light = json_object_get(report, "light");
    assert_true(number(light, "azimuth_deg") == 60 && number(light, "elevation_deg") == 0);
    json_t *m = json_object_get(report, "measure");
    json_t *points = json_object_get(m, "points");
    assert_int_equal(json_array_size(points), 2);
    for (size_t i = 0; i < 2; ++i)
        assert_true(json_is_true(json_object_get(json_array_get(points, i), "hit")));
    double length = number(m, "length");
    printf("the view's chain: %.9f +- %.3g\n", length, number(m, "precision"));
    assert_true(fabs(length - sqrt(0.25 + 0.0625)) <= number(m, "precision"));
    json_decref(report);
}

/* The measurement's unit and its text, for the front pixels on model. */
static void assert_unit(const fixture *f, const char *source, const char *model, const char *tag, const char *unit)
{
    json_t *report = view_at(f, source, model, tag, "--measure 52.25,40.5:111.5,77.75", true, NULL, 0);
    json_t *m = json_object_get(report, "measure");
    assert_string_equal(json_string_value(json_object_get(m, "unit")), unit);
    char want[200];
    double precision = number(m, "precision");
    int decimals = 1 - (int)floor(log10(precision)); /* its first significant digit and one more */
    snprintf(want, sizeof want, "measure 2 points: %.*f +- %.*f %s (20 bits, full)", decimals, number(m, "length"),
             decimals, precision, unit);
    printf("%s: %s\n", tag, json_string_value(json_object_get(m, "text")));
    assert_string_equal(json_string_value(json_object_get(m, "text")), want);
    json_decref(report);
}

/* A model baked with a sidecar that declares "unit": "mm" is measured in mm,
 * from the archive directory and from a server (its METADATA document);
 * the cube without metadata in "model units". */
static void test_measure_in_the_declared_unit(void **state)
{
    fixture *f = *state;
    char sidecar[700], ply[700], bake[600], command[4096], out[4096];
    snprintf(sidecar, sizeof sidecar, "%s/mm.json", f->dir);
    const char *mm = "{\"title\": \"cube\", \"unit\": \"mm\"}";
    ms_test_write_file(sidecar, mm, strlen(mm));
    snprintf(ply, sizeof ply, "%s/cube.ply", f->dir);
    ms_test_bin_path(bake, sizeof bake, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name cube_mm --bits 20 --no-apo --no-thumbnail --metadata %s",
             bake, ply, f->archives, sidecar);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    assert_unit(f, f->archives, "cube_mm", "unit-local", "mm");
    char log[700], ports[700], source[64];
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    uint16_t port, http_port;
    pid_t server = ms_test_meshserve_start(f->archives, NULL, 0, ports, log, &port, &http_port);
    assert_true(server > 0);
    snprintf(source, sizeof source, "--server 127.0.0.1:%u", port);
    assert_unit(f, source, "cube_mm", "unit-server", "mm");
    assert_unit(f, source, "cube", "unit-server-none", "model units");
    ms_test_stop(server, SIGTERM, 10.0);
}

static void test_usage_errors(void **state)
{
    fixture *f = *state;
    static const char *const bad[] = {
        "--model cube --view mv1:t=0,0,0:d=0:o=0,0:f=40:u=z",
        "--model cube --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=q",
        "--model cube --view 'mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:x=1'",
        "--model cube --view ''",
        "--model cube --view mv1:t=nan,0,0:d=1:o=0,0:f=40:u=z",
        "--model cube --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0,0",
        "--model cube --light 200,0",
        "--model cube --light 10",
        "--model cube --light 'a,b'",
        "--model cube --screenshot-dir /tmp/x --measure 1,2",
        "--model cube --screenshot-dir /tmp/x --measure 1,2:3",
        "--model cube --screenshot-dir /tmp/x --measure 1,2:3,4:",
        "--model cube --measure 1,2:3,4",                /* a scripted run's */
        "--model cube --screenshot-dir /tmp/x --size 160x120 --measure 1,2:170,4", /* outside */
        "--light 10,10",                                 /* needs --model */
        "--model cube --screenshot-dir /tmp/x --path /tmp/p.cam --view mv1:t=0,0,0:d=1:o=0,0:f=40:u=z",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        char command[2048], out[4096];
        snprintf(command, sizeof command, "%s %s %s", f->bin, f->archives, bad[i]);
        int status = ms_test_run(command, out, sizeof out);
        size_t lines = 0;
        for (const char *p = out; *p; ++p)
            lines += *p == '\n';
        if (status != 2 || lines != 1 || strncmp(out, "meshview: ", 10))
            fail_msg("'%s': status %d, output '%s'", bad[i], status, out);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_measure_on_the_face),
        cmocka_unit_test(test_light_follows_lambert),
        cmocka_unit_test(test_view_text),
        cmocka_unit_test(test_measure_in_the_declared_unit),
        cmocka_unit_test(test_usage_errors),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
