/* meshgen command line: help, argument errors, and the file it writes. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_help_and_usage_errors(void **state)
{
    (void)state;
    char bin[512], cmd[2048], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshgen");
    snprintf(cmd, sizeof cmd, "%s --help", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "Usage: meshgen"));
    snprintf(cmd, sizeof cmd, "%s", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_string_equal(out, "meshgen: missing -o OUT.ply (see meshgen --help)\n");
    snprintf(cmd, sizeof cmd, "%s -o /tmp/x.ply --triangles 12abc", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--triangles wants an integer"));
    snprintf(cmd, sizeof cmd, "%s -o /tmp/x.ply --triangles 999999999999", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s -o /nonexistent-dir/x.ply", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "meshgen: /nonexistent-dir/x.ply"));
}

static void test_writes_requested_size(void **state)
{
    (void)state;
    char bin[512], dir[512], cmd[2048], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshgen");
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(cmd, sizeof cmd, "%s -o %s/d.ply --triangles 10000 --json --ascii", bin, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    /* 12 * 29^2 = 10092 is the nearest count the grid allows. */
    assert_non_null(strstr(out, "\"grid\": 29, \"seed\": 0, \"vertices\": 5048, \"triangles\": 10092"));
    char path[700], head[512];
    snprintf(path, sizeof path, "%s/d.ply", dir);
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    size_t n = fread(head, 1, sizeof head - 1, f);
    fclose(f);
    head[n] = '\0';
    assert_non_null(strstr(head, "format ascii 1.0\n"));
    assert_non_null(strstr(head, "element vertex 5048\n"));
    assert_non_null(strstr(head, "element face 10092\n"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help_and_usage_errors),
        cmocka_unit_test(test_writes_requested_size),
    };
    return cmocka_run_group_tests_name("meshgen", tests, NULL, NULL);
}
