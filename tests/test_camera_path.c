/* Camera path files: parsing, interpolation, and every kind of bad line. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <stdlib.h>
#include <cmocka.h>

#include "ms_camera_path.h"

static const char good[] =
    "meshstream-camera-path 1\n"
    "# orbit start\n"
    "0    0 0 10   0 0 0   0 1 0   60\n"
    "\n"
    "2.0  10 0 0   0 0 0   0 1 0   30   # quarter turn, zoom\r\n"
    "4.5  10 0 0   0 0 0   0 1 0   30\n";

static void test_parse_and_sample(void **state)
{
    (void)state;
    ms_camera_path p;
    ms_error err;
    assert_int_equal(ms_camera_path_parse(good, strlen(good), "orbit.cam", &p, &err), MS_OK);
    assert_int_equal(p.count, 3);
    assert_true(ms_camera_path_duration(&p) == 4.5);
    ms_camera c;
    assert_int_equal(ms_camera_path_sample(&p, 1.0, 640, 480, 0.1, 100, &c, &err), MS_OK);
    assert_float_equal(c.position[0], 5.0, 1e-12);
    assert_float_equal(c.position[2], 5.0, 1e-12);
    assert_float_equal(c.fovy, 45.0 * M_PI / 180.0, 1e-12);
    /* Clamped before the start and after the end. */
    assert_int_equal(ms_camera_path_sample(&p, -3.0, 640, 480, 0.1, 100, &c, &err), MS_OK);
    assert_float_equal(c.position[2], 10.0, 1e-12);
    assert_int_equal(ms_camera_path_sample(&p, 99.0, 640, 480, 0.1, 100, &c, &err), MS_OK);
    assert_float_equal(c.position[0], 10.0, 1e-12);
    assert_float_equal(c.fovy, 30.0 * M_PI / 180.0, 1e-12);
    ms_camera_path_free(&p);
}

static void expect_error(const char *text, ms_status code, const char *message)
{
    ms_camera_path p;
    ms_error err;
    assert_int_equal(ms_camera_path_parse(text, strlen(text), "bad.cam", &p, &err), code);
    if (!strstr(err.text, message))
        fail_msg("'%s' does not mention '%s'", err.text, message);
    assert_null(p.keys);
}

static void test_bad_files(void **state)
{
    (void)state;
    const char *magic = "meshstream-camera-path 1\n";
    char text[4096];
    expect_error("", MS_ERR_FORMAT, "bad.cam: empty file");
    expect_error("meshstream-camera-path 2\n0 0 0 1 0 0 0 0 1 0 60\n", MS_ERR_FORMAT,
                 "bad.cam:1: not a camera path");
    expect_error(magic, MS_ERR_EMPTY, "no keyframe");
    /* a keyframe line after the magic line, and the error it gives */
    static const struct {
        const char *keyframes;
        ms_status code;
        const char *where;
    } cases[] = {
        {"0 0 0 1 0 0 0 0 1 0\n", MS_ERR_FORMAT, "bad.cam:2: expected 11 finite numbers"},
        {"0 0 0 1 0 0 0 0 1 0 60 7\n", MS_ERR_FORMAT, "bad.cam:2:"},
        {"0 0 0 1 0 0 0 0 1 0 60x\n", MS_ERR_FORMAT, "expected 11"},
        {"0 nan 0 1 0 0 0 0 1 0 60\n", MS_ERR_FORMAT, "finite"},
        {"0 1e999 0 1 0 0 0 0 1 0 60\n", MS_ERR_FORMAT, "finite"},
        {"1 0 0 1 0 0 0 0 1 0 60\n1 0 0 2 0 0 0 0 1 0 60\n", MS_ERR_RANGE,
         "bad.cam:3: times must start at >= 0 and increase"},
        {"-1 0 0 1 0 0 0 0 1 0 60\n", MS_ERR_RANGE, "times must"},
        {"0 1 1 1 1 1 1 0 1 0 60\n", MS_ERR_RANGE, "bad.cam:2: camera: position and target coincide"},
        {"0 0 0 1 0 0 0 0 0 1 60\n", MS_ERR_RANGE, "up is parallel"},
        {"0 0 0 1 0 0 0 0 1 0 180\n", MS_ERR_RANGE, "field of view"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        snprintf(text, sizeof text, "%s%s", magic, cases[i].keyframes);
        expect_error(text, cases[i].code, cases[i].where);
    }
    char *longline = malloc(3000);
    memset(longline, ' ', 2999);
    longline[2999] = '\0';
    snprintf(text, sizeof text, "%s%.2000s0\n", magic, longline);
    expect_error(text, MS_ERR_FORMAT, "line longer");
    free(longline);
    ms_camera_path p;
    ms_error err;
    assert_int_equal(ms_camera_path_load("/nonexistent.cam", &p, &err), MS_ERR_IO);
    char with_nul[] = "meshstream-camera-path 1\n0 0 0 1 0\0 0 0 0 1 0 60\n";
    assert_int_equal(ms_camera_path_parse(with_nul, sizeof with_nul - 1, "nul.cam", &p, &err),
                     MS_ERR_FORMAT);
}

/* The six shipped paths parse, and their durations are the documented ones. */
static void test_shipped_paths(void **state)
{
    (void)state;
    const struct {
        const char *file;
        double seconds;
    } shipped[] = {
        {"scripts/paths/demo-overview.cam", 12}, {"scripts/paths/demo-closeup.cam", 8},
        {"scripts/paths/demo-flythrough.cam", 12}, {"scripts/paths/dragon-overview.cam", 12},
        {"scripts/paths/dragon-closeup.cam", 8}, {"scripts/paths/dragon-flythrough.cam", 10},
    };
    for (size_t i = 0; i < sizeof shipped / sizeof *shipped; ++i) {
        ms_camera_path p;
        ms_error err;
        if (ms_camera_path_load(shipped[i].file, &p, &err) != MS_OK)
            fail_msg("%s", err.text);
        assert_true(ms_camera_path_duration(&p) == shipped[i].seconds);
        ms_camera c;
        for (double t = 0; t <= shipped[i].seconds; t += 0.25)
            assert_int_equal(ms_camera_path_sample(&p, t, 800, 600, 0.001, 100, &c, &err), MS_OK);
        ms_camera_path_free(&p);
    }
}

/* The interpolated keyframe (the one interpolation every path user goes
 * through) and the path time nearest a point. */
static void test_key_at_and_nearest_time(void **state)
{
    (void)state;
    ms_camera_path p;
    ms_error err;
    assert_int_equal(ms_camera_path_parse(good, strlen(good), "orbit.cam", &p, &err), MS_OK);
    ms_camera_key k;
    ms_camera_path_key_at(&p, 0.5, &k); /* a quarter of the way to the second keyframe */
    assert_true(k.time == 0.5);
    assert_true(k.position[0] == 2.5 && k.position[1] == 0 && k.position[2] == 7.5);
    assert_true(k.target[0] == 0 && k.up[1] == 1 && k.fovy_degrees == 52.5);
    ms_camera from_key, sampled;
    assert_int_equal(ms_camera_look_at(k.position, k.target, k.up, k.fovy_degrees, 640, 480, 0.1, 100,
                                       &from_key, &err), MS_OK);
    assert_int_equal(ms_camera_path_sample(&p, 0.5, 640, 480, 0.1, 100, &sampled, &err), MS_OK);
    assert_memory_equal(&from_key, &sampled, sizeof sampled);
    ms_camera_path_key_at(&p, 9, &k); /* held at the end */
    assert_true(k.time == 4.5 && k.position[0] == 10 && k.fovy_degrees == 30);
    ms_camera_path_key_at(&p, -1, &k); /* and before the start */
    assert_true(k.time == 0 && k.position[2] == 10);
    /* nearest: the segment (0 0 10) - (10 0 0) at its middle, t = 1 */
    double above_middle[3] = {5, 3, 5};
    assert_true(ms_camera_path_nearest_time(&p, above_middle) == 1.0);
    /* the still end (keyframes 2 and 3 at the same place): the earliest, 2 */
    double beyond_end[3] = {20, 0, -1};
    assert_true(ms_camera_path_nearest_time(&p, beyond_end) == 2.0);
    double before_start[3] = {-3, 0, 12};
    assert_true(ms_camera_path_nearest_time(&p, before_start) == 0.0);
    ms_camera_path_free(&p);
    ms_camera_path empty = {0};
    assert_true(ms_camera_path_nearest_time(&empty, above_middle) == 0.0);
    ms_camera_path_key_at(&empty, 1, &k);
    assert_true(k.time == 0 && k.fovy_degrees == 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse_and_sample),
        cmocka_unit_test(test_key_at_and_nearest_time),
        cmocka_unit_test(test_bad_files),
        cmocka_unit_test(test_shipped_paths),
    };
    return cmocka_run_group_tests_name("camera_path", tests, NULL, NULL);
}
