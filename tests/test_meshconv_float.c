/* meshconv refuses to write float coordinates that a float cannot hold
 * (issue 19, item 13: it wrote Inf and exited 0); --double keeps them. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_too_large_for_float(void **state)
{
    (void)state;
    char dir[512], bin[4096], in[700], out_path[700], cmd[8192], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshconv");
    snprintf(in, sizeof in, "%s/huge.obj", dir);
    snprintf(out_path, sizeof out_path, "%s/huge.ply", dir);
    const char obj[] = "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n";
    ms_test_write_file(in, obj, sizeof obj - 1);
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s'", bin, in, out_path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_string_equal(out, "meshconv: vertex 1: coordinate 1e+39 does not fit a float; "
                             "use --double\n");
    assert_int_equal(access(out_path, F_OK), -1);
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --ascii", bin, in, out_path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --ascii --double", bin, in, out_path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    size_t size;
    unsigned char *ply = ms_test_read_file(out_path, &size);
    char *text = calloc(size + 1, 1);
    memcpy(text, ply, size);
    assert_non_null(strstr(text, "\n9.9999999999999994e+38 0 0\n"));
    assert_null(strstr(text, "inf"));
    free(text);
    free(ply);
    /* The largest float still fits. */
    const char edge[] = "v 0 0 0\nv 3.4028234e38 0 0\nv 0 1 0\nf 1 2 3\n";
    ms_test_write_file(in, edge, sizeof edge - 1);
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s'", bin, in, out_path);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_too_large_for_float),
    };
    return cmocka_run_group_tests_name("meshconv_float", tests, NULL, NULL);
}
