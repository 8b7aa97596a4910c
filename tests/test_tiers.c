/* The test tiers (tests/tiers.txt, scripts/run-tests, `make check`), through
 * tests/check-tiers: every test program is in exactly one tier, and none in a
 * tier below what its source does (a program that starts a server is not a
 * unit test), so that a new program cannot be forgotten by `make check` and
 * `make test` alike. Runs from the repository root. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_every_program_has_its_tier(void **state)
{
    (void)state;
    static char out[65536];
    int rc = ms_test_run("tests/check-tiers", out, sizeof out);
    if (rc != 0)
        fail_msg("tests/check-tiers (exit %d):\n%s", rc, out);
    assert_non_null(strstr(out, " programs ("));
    assert_non_null(strstr(out, "), 0 problems"));
}

static void put(const char *dir, const char *name, const char *text)
{
    char path[700];
    snprintf(path, sizeof path, "%s/tests/%s", dir, name);
    ms_test_write_file(path, text, strlen(text));
}

/* The checker on a scratch tree: a program in no tier, a listed program with
 * no source, an unknown tier, a server test listed as unit and a GL test
 * listed as system are each reported, one line each; a slow unit test listed
 * as system is not. */
static void test_checker_sees_what_is_wrong(void **state)
{
    (void)state;
    char dir[512], cmd[2048];
    static char out[65536];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s/tests' && cp tests/check-tiers '%s/tests/'", dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    put(dir, "tiers.txt", "# a comment\n"
                          "test_pure      unit     # in-process\n"
                          "test_slow      system   # pure, but slow\n"
                          "test_server    unit     # wrongly\n"
                          "test_window    system   # wrongly\n"
                          "test_gone      unit\n"
                          "test_odd       fast\n");
    put(dir, "test_pure.c", "int main(void) { return 0; }\n");
    put(dir, "test_slow.c", "int main(void) { return 0; }\n");
    put(dir, "test_server.c", "pid_t p = ms_test_meshserve_start(a, NULL, 0, f, l, &p1, &p2);\n");
    put(dir, "test_window.c", "ms_test_gl_start(&gl);\n");
    put(dir, "test_odd.c", "int main(void) { return 0; }\n");
    put(dir, "test_new.c", "int main(void) { return 0; }\n");
    snprintf(cmd, sizeof cmd, "'%s/tests/check-tiers'", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    const char *want[] = {
        "tests/tiers.txt:7: test_odd: unknown tier 'fast' (unit, system, display)\n",
        "tests/test_new.c: in no tier: add it to tests/tiers.txt\n",
        "tests/tiers.txt:4: test_server is unit, but its source needs system\n",
        "tests/tiers.txt:5: test_window is system, but its source needs display\n",
        "tests/tiers.txt:6: test_gone: no tests/test_gone.c\n",
        "check-tiers: 6 programs (3 unit, 2 system, 0 display), 5 problems\n",
    };
    for (size_t i = 0; i < sizeof want / sizeof *want; ++i)
        if (!strstr(out, want[i]))
            fail_msg("no line '%s' in:\n%s", want[i], out);
    assert_null(strstr(out, "test_slow"));
    assert_null(strstr(out, "test_pure"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_program_has_its_tier),
        cmocka_unit_test(test_checker_sees_what_is_wrong),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
