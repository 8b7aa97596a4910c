/* meshload's near and far planes come from the model's bounds (issue 32,
 * item 3): a model in micrometres (scaled by 1e-6) and one in thousands of
 * kilometres (1e6), each with its camera path scaled alike, are displayed
 * and complete through meshload (with fixed planes at 1e-4 and 1e4 units the
 * first lay wholly before the near plane and the second beyond the far one:
 * time_to_first_display -1, "complete", exit 0). A path that looks away from
 * the model displays nothing: exit 1 with one line saying so. Models are
 * bumpy spheres of 2,256 triangles written as OFF, baked with meshbake and
 * read with meshload --archive (no server). Runs from the repository root. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_test.h"

typedef struct fixture {
    char dir[512];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f || !ms_test_tmpdir(f->dir, sizeof f->dir))
        return -1;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* DIR/NAME.off: a bumpy sphere of radius about `scale`, baked into
 * DIR/archives/NAME.msa. */
static void bake_sphere(const fixture *f, const char *name, double scale)
{
    char off[700], bin[512], cmd[2000], out[4096];
    snprintf(off, sizeof off, "%s/%s.off", f->dir, name);
    assert_int_equal(ms_test_write_bumpy_sphere(off, scale), 0);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s %s -o %s/archives --name %s --min-tris 200 2>&1", bin, off,
             f->dir, name);
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("%s: %s", cmd, out);
}

/* DIR/NAME.cam: two keyframes on the z axis at 3 and 2.5 radii, looking at
 * `target_z` radii (0: the centre; 2: away, the model behind the eye). */
static void write_path(const fixture *f, const char *name, double scale, double target_z)
{
    char path[700], text[600];
    snprintf(path, sizeof path, "%s/%s.cam", f->dir, name);
    int n = snprintf(text, sizeof text,
                     "meshstream-camera-path 1\n"
                     "0 0 0 %.17g 0 0 %.17g 0 1 0 40\n1 0 0 %.17g 0 0 %.17g 0 1 0 40\n",
                     3 * scale, target_z * 4 * scale, 2.5 * scale, target_z * 4 * scale);
    ms_test_write_file(path, text, (size_t)n);
}

static void expect_displayed(const fixture *f, const char *name, double scale)
{
    bake_sphere(f, name, scale);
    write_path(f, name, scale, 0);
    char bin[512], cmd[2000];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd,
             "%s --archive %s/archives/%s.msa --path %s/%s.cam --duration 60 --json", bin,
             f->dir, name, f->dir, name);
    json_t *report = ms_test_run_json(cmd, 0);
    json_t *client = json_array_get(json_object_get(report, "per_client"), 0);
    assert_non_null(client);
    assert_true(json_number_value(json_object_get(client, "time_to_first_display")) >= 0);
    assert_true(json_number_value(json_object_get(client, "time_to_view_complete")) >= 0);
    assert_string_equal(json_string_value(json_object_get(client, "error")), "");
    json_t *keys = json_object_get(client, "keyframes");
    assert_int_equal(json_array_size(keys), 2);
    for (size_t k = 0; k < 2; ++k)
        assert_true(json_is_true(json_object_get(json_array_get(keys, k), "complete")));
    json_decref(report);
}

static void test_micrometre_model(void **state) { expect_displayed(*state, "tiny", 1e-6); }
static void test_megametre_model(void **state) { expect_displayed(*state, "huge", 1e6); }

/* Nothing in view: not a success. */
static void test_nothing_displayed_fails(void **state)
{
    fixture *f = *state;
    bake_sphere(f, "away", 1e-6);
    write_path(f, "away", 1e-6, 2);
    char bin[512], cmd[2000], out[4096];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd,
             "%s --archive %s/archives/away.msa --path %s/away.cam --duration 60 2>&1 >/dev/null",
             bin, f->dir, f->dir);
    int status = ms_test_run(cmd, out, sizeof out);
    if (status != 1)
        fail_msg("%s: exit %d, '%s'", cmd, status, out);
    assert_string_equal(out, "meshload: client 0: nothing of the model is in view at the path's "
                             "last keyframe (t=1 s)\n");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_micrometre_model, setup, teardown),
        cmocka_unit_test_setup_teardown(test_megametre_model, setup, teardown),
        cmocka_unit_test_setup_teardown(test_nothing_displayed_fails, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
