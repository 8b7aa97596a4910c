/* No two files of the client core call into each other both ways (issue 35,
 * item 4), and no part of it (network, scheduler, decoder, docs/CLIENT.md "The
 * core's parts") uses what it may not, through tests/check-circles: it reads
 * `nm` of the core's object files (build/asan/client/core, built before the
 * tests). Runs from the repository root, like every test. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

static void test_no_circles_in_the_core(void **state)
{
    (void)state;
    static char out[65536];
    int rc = ms_test_run("tests/check-circles", out, sizeof out);
    if (rc != 0)
        fail_msg("tests/check-circles (exit %d):\n%s", rc, out);
    assert_non_null(strstr(out, "check-circles: 0 circles in "));
    assert_non_null(strstr(out, "check-circles: 0 crossings between the core's parts"));
}

static void write_file(const char *dir, const char *name, const char *text)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
}

/* The checker finds what it is for: of three files where a and b call each
 * other and c calls a only, the pair a <-> b is reported, a -> c is not; an
 * empty folder is an error of its own. */
static void test_checker_sees_a_circle(void **state)
{
    (void)state;
    char dir[512], cmd[2048];
    static char out[65536];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(cmd, sizeof cmd, "tests/check-circles '%s'", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "no object files"));
    write_file(dir, "a.c", "int b_two(void);\nint a_one(void) { return b_two(); }\n"
                           "int a_three(void) { return 3; }\n");
    write_file(dir, "b.c", "int a_one(void);\nint b_two(void) { return 2; }\n"
                           "int b_four(void) { return a_one(); }\n");
    write_file(dir, "c.c", "int a_three(void);\nint c_five(void) { return a_three(); }\n");
    snprintf(cmd, sizeof cmd, "cd '%s' && cc -c a.c b.c c.c", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "tests/check-circles '%s'", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "check-circles: a.c <-> b.c: a uses b_two; b uses a_one"));
    assert_null(strstr(out, "c.c"));
    assert_non_null(strstr(out, "check-circles: 1 circles in 3 files"));
    ms_test_rmdir(dir);
}

/* The borders of the parts: in a scratch tree laid out as the repository's,
 * a network file using a decoder file's symbol and a file in no part are
 * reported; the decoder using the scheduler is allowed. */
static void test_checker_sees_a_crossing(void **state)
{
    (void)state;
    char dir[512], src[600], obj[700], cmd[2600];
    static char out[65536];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(src, sizeof src, "%s/client/core", dir);
    snprintf(obj, sizeof obj, "%s/build/asan/client/core", dir);
    snprintf(cmd, sizeof cmd, "mkdir -p '%s' '%s' '%s/tests' && cp tests/check-circles '%s/tests/'",
             src, obj, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    write_file(src, "ms_client_core_net.c", "int rx_add(void);\nint net_main(void) { return rx_add(); }\n");
    write_file(src, "ms_core_rx.c", "int sched_plan(void);\nint rx_add(void) { return sched_plan(); }\n");
    write_file(src, "ms_core_sched.c", "int sched_plan(void) { return 1; }\n");
    write_file(src, "ms_core_extra.c", "int extra(void) { return 2; }\n");
    snprintf(cmd, sizeof cmd, "cd '%s' && for f in *.c; do cc -c $f -o '%s'/${f%%.c}.o || exit 1; done",
             src, obj);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(cmd, sizeof cmd, "cd '%s' && tests/check-circles", dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "check-circles: 0 circles in 4 files"));
    assert_non_null(strstr(out, "check-circles: ms_client_core_net.c (network) uses "
                                "ms_core_rx.c's rx_add (decoder)"));
    assert_non_null(strstr(out, "check-circles: ms_core_extra.c is in no part"));
    assert_null(strstr(out, "ms_core_rx.c (decoder) uses"));
    assert_non_null(strstr(out, "check-circles: 2 crossings between the core's parts"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_circles_in_the_core),
        cmocka_unit_test(test_checker_sees_a_circle),
        cmocka_unit_test(test_checker_sees_a_crossing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
