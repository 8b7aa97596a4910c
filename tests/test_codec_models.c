/* Codec on every shared model: lossless round trip at 12 and 16 bits, every
 * intermediate kd-level valid and equal to the independent reference coarsener
 * (all 36 levels at 12 bits, every 6th at 16 bits; for the 871k dragon every 9th
 * / 12th level, to keep the ASan run short), levels 0-2 always, refine after
 * coarsen identical, encoding deterministic (12 bits, all but the dragon); at
 * 12 bits with cell centres and with the default geometry ahead (the dragon:
 * ahead only), at 16 bits with the default geometry ahead. Also the meshcodec
 * CLI, its colour figures on the colour trefoil fixture included. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_mesh_io.h"
#include "support/ms_codec_check.h"
#include "support/ms_test.h"

static const char *const models[] = {
    "stanford_bunny_res3.ply.gz",  "stanford_dragon_vrip_res4.ply.gz",
    "stanford_dragon_vrip_res3.ply.gz", "stanford_dragon_vrip_res2.ply.gz",
    "glmark2_bunny.obj.gz",        "cgal_armadillo.off.gz",
    "torus_tristrips.ply.gz",      "trefoil_color.ply.gz",
    "snowden_bust_hi.ply.gz",      "stanford_dragon_vrip.ply.gz",
};

static void run_model(const char *file, unsigned bits, unsigned step, bool twice,
                      unsigned aheads)
{
    char path[4096];
    ms_test_model_path(path, sizeof path, file);
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_error err;
    if (ms_mesh_load(path, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_codec_check_result r;
    ms_codec_check_roundtrip_ex(&m, bits, step, twice, aheads, &r);
    print_message("%s at %u bits: %zu vertices, %zu triangles, %zu bytes, %.2f bits/vertex\n",
                  file, bits, r.vertices, r.triangles, r.bytes, 8.0 * r.bytes / r.vertices);
    assert_int_equal(r.vertices + r.weld.welded_vertices, m.vertex_count);
    assert_int_equal(r.triangles + r.weld.degenerate_triangles + r.weld.duplicate_triangles,
                     m.triangle_count);
    ms_mesh_free(&m);
}

static void test_models_12_bits(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof models / sizeof *models; ++i) {
        int dragon = strcmp(models[i], "stanford_dragon_vrip.ply.gz") == 0;
        run_model(models[i], 12, dragon ? 9 : 1, !dragon,
                  dragon ? MS_CHECK_AHEAD_DEFAULT : MS_CHECK_AHEAD_BOTH);
    }
}

static void test_models_16_bits(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof models / sizeof *models; ++i) {
        int dragon = strcmp(models[i], "stanford_dragon_vrip.ply.gz") == 0;
        run_model(models[i], 16, dragon ? 12 : 6, false, MS_CHECK_AHEAD_DEFAULT);
    }
}

static void test_cli(void **state)
{
    (void)state;
    char bin[1024], model[1024], dir[1024], cmd[8192], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshcodec");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    ms_test_tmpdir(dir, sizeof dir);

    snprintf(cmd, sizeof cmd, "%s roundtrip %s --bits 12 --json", bin, model);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"vertices\": 1889"));
    assert_non_null(strstr(out, "\"triangles\": 3768"));
    assert_non_null(strstr(out, "\"duplicate_triangles\": 83"));
    assert_non_null(strstr(out, "\"lossless\": true"));
    assert_non_null(strstr(out, "\"bits_per_vertex\": "));
    assert_non_null(strstr(out, "\"encode_seconds\": "));
    assert_non_null(strstr(out, "\"decode_seconds\": "));

    /* a model with colour: its colour stream too (docs/COLOUR.md) */
    snprintf(cmd, sizeof cmd, "%s roundtrip tests/data/trefoil_color.ply.gz --bits 12 --json", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"colour_alpha\": true"));
    assert_non_null(strstr(out, "\"colour_bytes\": 6862,"));
    assert_non_null(strstr(out, "\"colour_lossless\": true"));
    snprintf(cmd, sizeof cmd, "%s roundtrip tests/data/trefoil_color.ply.gz --bits 12 "
             "--colour-bits 4 --json", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"colour_bytes\": 2940,"));
    snprintf(cmd, sizeof cmd, "%s roundtrip %s --colour-bits 9", bin, model);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s roundtrip %s --bits 12 --json", bin, model);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_null(strstr(out, "colour_bytes")); /* no colour, no colour figures */

    snprintf(cmd, sizeof cmd, "%s encode %s -o %s/b.msgc --bits 12", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "%s decode %s/b.msgc -o %s/b.ply", bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_error err;
    snprintf(cmd, sizeof cmd, "%s/b.ply", dir);
    assert_int_equal(ms_mesh_load(cmd, &m, NULL, &err), MS_OK);
    assert_int_equal(m.vertex_count, 1889);
    assert_int_equal(m.triangle_count, 3768);
    ms_mesh_free(&m);
    /* level of detail at 4 bits: fewer points */
    snprintf(cmd, sizeof cmd, "%s decode %s/b.msgc -o %s/c.ply --bits 4", bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "%s/c.ply", dir);
    assert_int_equal(ms_mesh_load(cmd, &m, NULL, &err), MS_OK);
    assert_true(m.vertex_count > 10 && m.vertex_count < 1889);
    ms_mesh_free(&m);

    /* usage and input errors: one line on stderr, exit 2 / 1 */
    snprintf(cmd, sizeof cmd, "%s encode %s -o %s/x --bits 7", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "8..20"));
    snprintf(cmd, sizeof cmd, "%s decode %s/b.msgc -o %s/d.ply --bits 13", bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s frobnicate", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s decode %s -o %s/d.ply", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "magic"));
    assert_null(strchr(out, '\n') == out + strlen(out) - 1 ? NULL : strchr(out, '\n'));
    snprintf(cmd, sizeof cmd, "head -c 100 %s/b.msgc > %s/t.msgc && %s decode %s/t.msgc -o %s/t.ply",
             dir, dir, bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "truncated"));
    /* an empty mesh is a clear error */
    snprintf(cmd, sizeof cmd, "printf 'ply\\nformat ascii 1.0\\nelement vertex 0\\nproperty float x\\n"
             "property float y\\nproperty float z\\nend_header\\n' > %s/e.ply && "
             "%s encode %s/e.ply -o %s/e.msgc", dir, bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_true(strstr(out, "empty") || strstr(out, "no triangles"));
    const char *subs[] = {"encode", "decode", "roundtrip"};
    for (int i = 0; i < 3; ++i) {
        snprintf(cmd, sizeof cmd, "%s %s --help", bin, subs[i]);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
        assert_non_null(strstr(out, "usage: meshcodec"));
    }
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cli),
        cmocka_unit_test(test_models_12_bits),
        cmocka_unit_test(test_models_16_bits),
    };
    return cmocka_run_group_tests_name("codec_models", tests, NULL, NULL);
}
