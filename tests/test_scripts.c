/* The scripts under scripts/ take no arguments: `--help` prints each one's
 * header comment (exit 0), anything else is refused with one line (exit 2).
 * Runs from the repository root, like every test. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <dirent.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

static const char *const SCRIPTS[] = {
    "attack",      "bench",       "bench-apo",  "bench-apo-bake", "bench-bake",   "bench-client",
    "bench-codec", "bench-codec-peer", "bench-read", "bench-serve", "bench-valence", "bench-viewer",
    "demo",        "install-deps", "run-tests", "screenshots",
};

static bool listed(const char *name)
{
    for (size_t i = 0; i < sizeof SCRIPTS / sizeof *SCRIPTS; ++i)
        if (strcmp(SCRIPTS[i], name) == 0)
            return true;
    return false;
}

/* Every shell script in the folder is in the list (the sourced helper, the
 * Python generator and the camera paths folder aside), so a new one is tested. */
static void test_every_script_is_listed(void **state)
{
    (void)state;
    DIR *dir = opendir("scripts");
    assert_non_null(dir);
    size_t seen = 0;
    for (struct dirent *e; (e = readdir(dir));) {
        const char *n = e->d_name;
        if (n[0] == '.' || strcmp(n, "paths") == 0 || strcmp(n, "script-usage.sh") == 0 ||
            strcmp(n, "gen-camera-paths.py") == 0)
            continue;
        if (!listed(n))
            fail_msg("scripts/%s is not in test_scripts.c's list", n);
        seen++;
    }
    closedir(dir);
    assert_int_equal(seen, sizeof SCRIPTS / sizeof *SCRIPTS);
}

/* The script's first header line, without the leading "# ". */
static void header_line(const char *path, char *line, size_t size)
{
    FILE *f = fopen(path, "r");
    assert_non_null(f);
    char buf[512];
    assert_non_null(fgets(buf, sizeof buf, f)); /* #! line */
    assert_non_null(fgets(buf, sizeof buf, f));
    fclose(f);
    assert_true(strncmp(buf, "# ", 2) == 0);
    snprintf(line, size, "%s", buf + 2);
}

static void test_help_prints_the_header(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof SCRIPTS / sizeof *SCRIPTS; ++i) {
        char path[256], cmd[512], out[8192], first[512];
        snprintf(path, sizeof path, "scripts/%s", SCRIPTS[i]);
        header_line(path, first, sizeof first);
        for (int form = 0; form < 2; ++form) {
            snprintf(cmd, sizeof cmd, "%s %s", path, form ? "-h" : "--help");
            assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
            if (strncmp(out, first, strlen(first)) != 0)
                fail_msg("%s --help starts with '%.60s', not its header '%.60s'", path, out,
                         first);
            /* the header only: never the script's code */
            assert_null(strstr(out, "script_usage"));
            assert_null(strstr(out, "set -"));
        }
    }
}

static void test_arguments_are_refused(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof SCRIPTS / sizeof *SCRIPTS; ++i) {
        char cmd[512], out[1024], want[512];
        snprintf(cmd, sizeof cmd, "scripts/%s --frobnicate", SCRIPTS[i]);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
        snprintf(want, sizeof want,
                 "%s: unknown argument '--frobnicate' (it takes none; try '%s --help')\n",
                 SCRIPTS[i], SCRIPTS[i]);
        assert_string_equal(out, want);
    }
}

static void test_python_generator(void **state)
{
    (void)state;
    char out[4096];
    assert_int_equal(ms_test_run("python3 scripts/gen-camera-paths.py --help", out, sizeof out),
                     0);
    assert_non_null(strstr(out, "Writes the shipped camera paths"));
    assert_int_equal(ms_test_run("python3 scripts/gen-camera-paths.py --frobnicate", out,
                                 sizeof out),
                     2);
    assert_non_null(strstr(out, "unrecognized arguments: --frobnicate"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_script_is_listed),
        cmocka_unit_test(test_help_prints_the_header),
        cmocka_unit_test(test_arguments_are_refused),
        cmocka_unit_test(test_python_generator),
    };
    return cmocka_run_group_tests_name("scripts", tests, NULL, NULL);
}
