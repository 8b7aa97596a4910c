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
#include <jansson.h>
#include <libgen.h>

#include "ms_test.h"

static const char *const SCRIPTS[] = {
    "attack",       "bake-gallery", "bench",       "bench-apo",    "bench-apo-bake", "bench-bake", "bench-browser",
    "bench-bake-scale", "bench-client", "bench-client-scale", "bench-codec", "bench-collection",  "bench-codec-peer", "bench-limits", "bench-read", "bench-scene-link", "bench-scenes", "bench-serve",
    "bench-valence", "bench-viewer", "cluster",    "demo",         "fetch-models",   "fuzz-seeds",     "install-deps",   "run-tests",
    "screenshots",  "study",
};

static bool listed(const char *name)
{
    for (size_t i = 0; i < sizeof SCRIPTS / sizeof *SCRIPTS; ++i)
        if (strcmp(SCRIPTS[i], name) == 0)
            return true;
    return false;
}

/* Every shell script in the folder is in the list (the sourced helpers, the
 * Python generator and report writer and the camera paths, scenes and
 * metadata and annotations sidecar folders aside), so a new one is tested. */
static void test_every_script_is_listed(void **state)
{
    (void)state;
    DIR *dir = opendir("scripts");
    assert_non_null(dir);
    size_t seen = 0;
    for (struct dirent *e; (e = readdir(dir));) {
        const char *n = e->d_name;
        if (n[0] == '.' || strcmp(n, "paths") == 0 || strcmp(n, "scenes") == 0 ||
            strcmp(n, "metadata") == 0 || strcmp(n, "annotations") == 0 ||
            strcmp(n, "script-usage.sh") == 0 || strcmp(n, "models.sh") == 0 ||
            strcmp(n, "gen-camera-paths.py") == 0 ||
            strcmp(n, "study-report.py") == 0)
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

/* scripts/cluster's short form: two meshserve instances behind HAProxy (from
 * deploy/), one killed with SIGKILL while meshload's clients play a camera
 * path: every client fails over and completes with every byte verified;
 * nginx's second pass with the same requests is answered from its cache, and
 * a token's answers never are. */
static void test_cluster_short_form(void **state)
{
    (void)state;
    char bin[512], dir[256], json_path[320], cmd[1200];
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(json_path, sizeof json_path, "%s/cluster.json", dir);
    snprintf(cmd, sizeof cmd, "CLUSTER_SHORT=1 CLUSTER_JSON=%s MESHSTREAM_BIN=%s scripts/cluster",
             json_path, dirname(bin));
    static char out[65536];
    int status = ms_test_run(cmd, out, sizeof out);
    if (status != 0)
        fail_msg("scripts/cluster exited %d: %s", status, out);
    json_error_t jerr;
    json_t *report = json_load_file(json_path, 0, &jerr);
    assert_non_null(report);
    assert_true(json_is_true(json_object_get(report, "ok")));
    json_t *scaling = json_object_get(report, "scaling");
    assert_int_equal(json_array_size(scaling), 1);
    json_t *two = json_array_get(scaling, 0);
    assert_int_equal(json_integer_value(json_object_get(two, "instances")), 2);
    assert_int_equal(json_integer_value(json_object_get(two, "errors")), 0);
    assert_true(json_number_value(json_object_get(two, "throughput_MBps")) > 0);
    json_t *failover = json_object_get(report, "failover");
    assert_int_equal(json_integer_value(json_object_get(failover, "clients")), 4);
    assert_int_equal(json_integer_value(json_object_get(failover, "requests_lost")), 0);
    assert_int_equal(json_integer_value(json_object_get(failover, "meshload_exit")), 0);
    /* the instance killed held at least one client, which came back */
    assert_true(json_integer_value(json_object_get(failover, "reconnects")) >= 1);
    double failover_s = json_number_value(json_object_get(failover, "failover_seconds_max"));
    assert_true(failover_s > 0); /* how long: make bench (scripts/cluster's full form) */
    json_t *cache = json_object_get(report, "cache");
    /* both passes ask the same 4 x 100 cell requests (same seed) */
    json_t *second = json_object_get(cache, "second_pass");
    assert_int_equal(json_integer_value(json_object_get(second, "HIT")), 400);
    assert_int_equal(json_object_size(second), 1);
    json_t *tokens = json_object_get(cache, "token_answers");
    assert_int_equal(json_array_size(tokens), 2);
    for (size_t i = 0; i < 2; ++i)
        assert_string_equal(json_string_value(json_array_get(tokens, i)), "BYPASS");
    json_decref(report);
    ms_test_rmdir(dir);
}

/* deploy/fill: the one way the deploy/ templates are filled (scripts/cluster,
 * docs/DEPLOY.md); a field left without a value is refused, by name. */
static void test_deploy_fill(void **state)
{
    (void)state;
    static char out[16384];
    assert_int_equal(ms_test_run("deploy/fill --help", out, sizeof out), 0);
    assert_non_null(strstr(out, "Fills a deploy/ template"));
    assert_int_equal(ms_test_run("deploy/fill deploy/nginx.conf.in - BIND=127.0.0.1", out,
                                 sizeof out),
                     1);
    assert_non_null(strstr(out, "no value for @CACHE_DIR@, @CACHE_MAX_SIZE@, @CACHE_PORT@"));
    assert_int_equal(ms_test_run("deploy/fill deploy/nginx.conf.in - bind=x", out, sizeof out), 2);
    assert_int_equal(ms_test_run("deploy/fill deploy/meshserve.conf.in - INSTANCE=1 "
                                 "ARCHIVE_DIR=/srv/a BIND=127.0.0.1 PORT=7810 HTTP_PORT=7811 "
                                 "MAX_CLIENTS=1024 HTTP_MAX_CONNECTIONS=256 TOKEN=t0k "
                                 "ACCESS_LOG=/var/log/a.log",
                                 out, sizeof out),
                     0);
    assert_non_null(strstr(out, "\narchive_dir = /srv/a\n"));
    assert_non_null(strstr(out, "\nport = 7810\n"));
    assert_null(strchr(out, '@'));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_script_is_listed),
        cmocka_unit_test(test_help_prints_the_header),
        cmocka_unit_test(test_arguments_are_refused),
        cmocka_unit_test(test_python_generator),
        cmocka_unit_test(test_deploy_fill),
        cmocka_unit_test(test_cluster_short_form),
    };
    return cmocka_run_group_tests_name("scripts", tests, NULL, NULL);
}
