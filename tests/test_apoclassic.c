/* meshbake --apo-classic (the whole-model mode): help, argument errors, a whole
 * run with --json, the stored chunk it writes (loaded back and validated), a
 * saved and reused simplified mesh, and a missing input. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_apo_blob.h"
#include "ms_apo_traverse.h"
#include "ms_test.h"

static void test_help_and_usage_errors(void **state)
{
    (void)state;
    char bin[512], cmd[2048], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s --help", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "meshbake IN --apo-classic --simplify N"));
    snprintf(cmd, sizeof cmd, "%s --apo-classic --help", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "--apo-init-depth D"));
    /* usage errors: exit status 2 and exactly this line */
    static const struct {
        const char *args, *message;
    } usage[] = {
        {"--apo-classic",
         "meshbake: missing input file (see meshbake --help)\n"},
        {"demo:1000 demo:2000 --apo-classic",
         "meshbake: expected one input, got more (see meshbake --help)\n"},
        {"demo:1000 --apo-classic --frobnicate",
         "meshbake: unknown option: --frobnicate (see meshbake --help)\n"},
        {"demo:1000 --apo-classic --simplify",
         "meshbake: option needs a value: --simplify (see meshbake --help)\n"},
        {"demo:1000 --apo-classic --apo-max-depth 31",
         "meshbake: --apo-max-depth wants an integer in [0, 30], got '31'\n"},
    };
    for (size_t i = 0; i < sizeof usage / sizeof *usage; ++i) {
        snprintf(cmd, sizeof cmd, "%s %s", bin, usage[i].args);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
        assert_string_equal(out, usage[i].message);
    }
    snprintf(cmd, sizeof cmd, "%s demo:1000 --apo-classic --apo-tol -1", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s demo:1000 --apo-classic --apo-measure fancy", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_int_equal(strchr(out, '\n') - out + 1, (long)strlen(out)); /* one line */
    snprintf(cmd, sizeof cmd, "%s /nonexistent/model.ply --apo-classic --simplify 100", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "meshbake: "));
    assert_non_null(strstr(out, "/nonexistent/model.ply"));
    assert_int_equal(strchr(out, '\n') - out + 1, (long)strlen(out)); /* one line */
}

static long json_number(const char *json, const char *key)
{
    char pattern[128];
    snprintf(pattern, sizeof pattern, "\"%s\":", key);
    const char *p = strstr(json, pattern);
    assert_non_null(p);
    return strtol(p + strlen(pattern), NULL, 10);
}

static void test_run_json_and_chunk(void **state)
{
    (void)state;
    char bin[512], dir[512], cmd[2048], out[8192], first[8192];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(cmd, sizeof cmd,
             "%s demo:12000 --apo-classic --simplify 400 --apo-tol 0.5 --apo-init-depth 3 --apo-max-depth 8 "
             "--json -o %s/c.apo --save-simplified %s/m.ply",
             bin, dir, dir);
    assert_int_equal(ms_test_run(cmd, first, sizeof first), 0);
    long internal = json_number(first, "internal_nodes"), leaves = json_number(first, "leaves");
    long texels = json_number(first, "texels"), bytes = json_number(first, "bytes");
    assert_true(internal > 0 && leaves > internal);
    assert_int_equal(texels, leaves + 2 * internal);
    assert_int_equal(bytes, 4 * texels);
    assert_int_equal(json_number(first, "simplified_triangles"), 400);
    assert_int_equal(json_number(first, "levels"), 9);
    assert_non_null(strstr(first, "\"seconds\":"));
    assert_non_null(strstr(first, "\"phases\":{\"load\":"));
    /* The stored chunk loads, validates and answers lookups. */
    char path[700];
    snprintf(path, sizeof path, "%s/c.apo", dir);
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    static uint8_t blob[1 << 22];
    size_t size = fread(blob, 1, sizeof blob, f);
    fclose(f);
    assert_int_equal(size, json_number(first, "stored_bytes"));
    ms_apo_chunk chunk;
    assert_int_equal(ms_apo_blob_read(blob, size, &chunk, NULL), MS_OK);
    assert_int_equal(chunk.texel_count, texels);
    ms_apo_view view;
    assert_int_equal(ms_apo_view_of_chunk(&view, &chunk, NULL), MS_OK);
    ms_apo_lookup_result r;
    float centre[3] = {0.5f, 0.5f, 0.5f};
    ms_apo_lookup(&view, centre, 30, MS_APO_MISSING_NEAREST, &r);
    assert_true(r.stop == MS_APO_STOP_LEAF);
    ms_apo_chunk_free(&chunk);
    /* Reusing the saved simplified mesh gives the same octree. */
    snprintf(cmd, sizeof cmd,
             "%s demo:12000 --apo-classic --simplified %s/m.ply --apo-tol 0.5 --apo-init-depth 3 --apo-max-depth 8 --json", bin,
             dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_int_equal(json_number(out, "internal_nodes"), internal);
    assert_int_equal(json_number(out, "leaves"), leaves);
    /* The text report. */
    snprintf(cmd, sizeof cmd, "%s demo:2000 --apo-classic --simplify 100 --apo-max-depth 6", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "octree "));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help_and_usage_errors),
        cmocka_unit_test(test_run_json_and_chunk),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
