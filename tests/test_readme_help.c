/* The README and the programs agree, through tests/check-readme: a section
 * for every program, --help exiting 0, and every option of a synopsis in
 * that program's --help. Needs every program built (make tests builds them).
 * Runs from the repository root, like every test. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_readme_and_help_agree(void **state)
{
    (void)state;
    static char out[65536], cmd[4200], bin[4096];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    char *slash = strrchr(bin, '/');
    assert_non_null(slash);
    *slash = '\0';
    snprintf(cmd, sizeof cmd, "tests/check-readme '%s'", bin);
    int rc = ms_test_run(cmd, out, sizeof out);
    if (rc != 0)
        fail_msg("tests/check-readme (exit %d):\n%s", rc, out);
    assert_non_null(strstr(out, " 0 disagreements"));
}

/* The checker sees a disagreement: a README that promises an option the
 * program's --help does not know. */
static void test_checker_sees_a_missing_option(void **state)
{
    (void)state;
    char dir[512], cmd[8192], bin[4096];
    static char out[65536];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    *strrchr(bin, '/') = '\0';
    snprintf(cmd, sizeof cmd,
             "mkdir -p '%s/tests' && cp tests/check-readme '%s/tests/' && cp -r common protocol "
             "server client '%s/' && sed 's/^    meshgen -o OUT.ply/    meshgen --frobnicate -o "
             "OUT.ply/' README.md > '%s/README.md'",
             dir, dir, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "'%s/tests/check-readme' '%s'", dir, bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "meshgen: README gives --frobnicate, --help does not"));
    assert_non_null(strstr(out, " 1 disagreements"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_readme_and_help_agree),
        cmocka_unit_test(test_checker_sees_a_missing_option),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
