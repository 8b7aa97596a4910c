/* The size targets of the code (issue 22), through tests/check-structure: no
 * product source file over 800 lines and no function over 120, except those
 * tests/structure-known.txt still lists (a list that may only shrink). Runs
 * from the repository root, like every test. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_no_new_long_files_or_functions(void **state)
{
    (void)state;
    static char out[65536];
    int rc = ms_test_run("tests/check-structure", out, sizeof out);
    if (rc != 0)
        fail_msg("tests/check-structure (exit %d):\n%s", rc, out);
    assert_non_null(strstr(out, "check-structure: 0 new offenders"));
}

/* The checker finds what it is for: a function of 121 lines and a file of
 * 801 lines in a scratch tree are reported, a 120-line function is not. */
static void test_checker_sees_offenders(void **state)
{
    (void)state;
    char dir[512], cmd[2048], path[700];
    static char out[65536];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/tests' '%s/common' && cp tests/check-structure '%s/tests/'",
             dir, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(path, sizeof path, "%s/common/long.c", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "static int fits(void)\n{\n");
    for (int i = 0; i < 117; ++i)
        fprintf(f, "    (void)0;\n");
    fprintf(f, "}\n\nint too_long(int a,\n             int b)\n{\n");
    for (int i = 0; i < 117; ++i)
        fprintf(f, "    (void)0;\n");
    fprintf(f, "}\n");
    for (int i = 0; i < 560; ++i)
        fprintf(f, "/* filler */\n");
    fclose(f);
    snprintf(cmd, sizeof cmd, "'%s/tests/check-structure'", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "common/long.c:122: function too_long is 121 lines"));
    assert_non_null(strstr(out, "common/long.c:1: 802 lines (limit 800)"));
    assert_null(strstr(out, "fits"));
    assert_non_null(strstr(out, "check-structure: 2 new offenders, 0 known, 0 stale"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_new_long_files_or_functions),
        cmocka_unit_test(test_checker_sees_offenders),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
