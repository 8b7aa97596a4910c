/* meshload against a model replaced while it streams (issue 20, item 4): the
 * dragon baked at 16 bits is served, two meshload clients stream it at
 * 320 kbit/s, and a bake of it at 14 bits is renamed over the archive and
 * applied with SIGHUP. Each client's core hears MODEL_CHANGED, stops with
 * stats.model_changed, and meshload starts a fresh core that streams the new
 * version: both clients end with every keyframe complete, no failed cell (each
 * payload verified against its CRC), no reconnect, and model_changes 1.
 * meshview's window, on the same replacement, opens the new version by name and
 * goes on (one line saying so, exit 0 on SIGTERM); under Xvfb when no display.
 * Runs from the repository root; needs meshserve, meshload and meshview. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_net.h"

#define MODEL "dragon"
#define PATH_FILE "scripts/paths/dragon-closeup.cam"
#define CLIENTS 2

/* The dragon's request counter in /metrics (opens and cell requests). */
static uint64_t model_requests(uint16_t http_port)
{
    ms_test_http_response r;
    if (ms_test_http_get(http_port, "/metrics", NULL, &r) != 0)
        fail_msg("no answer to /metrics");
    const char *key = "meshstream_model_requests_total{model=\"" MODEL "\"} ";
    const char *at = r.body ? strstr((const char *)r.body, key) : NULL;
    uint64_t n = at ? strtoull(at + strlen(key), NULL, 10) : 0;
    ms_test_http_free(&r);
    return n;
}

static void test_meshload_streams_the_new_version(void **state)
{
    (void)state;
    char dir[512], live[600], stage[600], input[512];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(live, sizeof live, "%s/live", dir);
    snprintf(stage, sizeof stage, "%s/stage", dir);
    assert_int_equal(mkdir(live, 0755), 0);
    assert_int_equal(mkdir(stage, 0755), 0);
    ms_test_model_path(input, sizeof input, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_report report;
    ms_nsp_test_bake(input, live, MODEL, 16, 2000, &report);
    ms_nsp_test_bake(input, stage, MODEL, 14, 2000, &report);

    char serve[512], load[512], ports[700], serve_log[700], load_log[700];
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    ms_test_bin_path(load, sizeof load, "meshload");
    snprintf(ports, sizeof ports, "%s/ports", dir);
    snprintf(serve_log, sizeof serve_log, "%s/meshserve.log", dir);
    snprintf(load_log, sizeof load_log, "%s/meshload.json", dir);
    char *serve_argv[] = {serve, live, "--port", "0", "--http-port", "0", "--port-file", ports,
                          NULL};
    pid_t server = ms_test_spawn(serve_argv, serve_log);
    uint16_t port, http_port;
    assert_int_equal(ms_test_wait_ports(ports, 15.0, &port, &http_port), 0);
    uint64_t before = model_requests(http_port);

    char address[64], clients[8];
    snprintf(address, sizeof address, "127.0.0.1:%u", port);
    snprintf(clients, sizeof clients, "%d", CLIENTS);
    char *load_argv[] = {load, "--server", address, "--model", MODEL, "--path", PATH_FILE,
                         "--clients", clients, "--bandwidth", "320kbit", "--duration", "90",
                         "--json", NULL};
    pid_t loader = ms_test_spawn(load_argv, load_log);
    /* both clients streaming: their opens and at least one cell request each */
    for (int tries = 0; tries < 600 && model_requests(http_port) < before + 2 * CLIENTS; ++tries)
        usleep(10000);
    assert_true(model_requests(http_port) >= before + 2 * CLIENTS);
    char from[700], to[700];
    snprintf(from, sizeof from, "%s/" MODEL ".msa", stage);
    snprintf(to, sizeof to, "%s/" MODEL ".msa", live);
    assert_int_equal(rename(from, to), 0);
    assert_int_equal(kill(server, SIGHUP), 0);

    assert_int_equal(ms_test_stop(loader, 0, 120.0), 0);
    size_t size;
    char *text = (char *)ms_test_read_file(load_log, &size);
    json_error_t jerr;
    json_t *j = json_loadb(text, size, 0, &jerr);
    if (!j)
        fail_msg("meshload's output is not JSON (%s): %.*s", jerr.text,
                 (int)(size < 2000 ? size : 2000), text);
    free(text);
    json_t *per_client = json_object_get(j, "per_client");
    assert_int_equal(json_array_size(per_client), CLIENTS);
    for (size_t i = 0; i < CLIENTS; ++i) {
        json_t *c = json_array_get(per_client, i);
        assert_string_equal(json_string_value(json_object_get(c, "error")), "");
        assert_int_equal(json_integer_value(json_object_get(c, "model_changes")), 1);
        assert_int_equal(json_integer_value(json_object_get(c, "reconnects")), 0);
        assert_int_equal(json_integer_value(json_object_get(c, "failed_cells")), 0);
        assert_true(json_number_value(json_object_get(c, "time_to_view_complete")) > 0);
        json_t *keys = json_object_get(c, "keyframes");
        assert_true(json_array_size(keys) > 1);
        for (size_t k = 0; k < json_array_size(keys); ++k)
            assert_true(json_is_true(json_object_get(json_array_get(keys, k), "complete")));
    }
    json_decref(j);
    assert_int_equal(ms_test_stop(server, SIGTERM, 15.0), 0);
    ms_test_rmdir(dir);
}

/* Whether file `path` contains `needle` (a log being written by a child). */
static bool log_contains(const char *path, const char *needle)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return false;
    char line[1024];
    bool found = false;
    while (!found && fgets(line, sizeof line, f))
        found = strstr(line, needle) != NULL;
    fclose(f);
    return found;
}

static void test_meshview_opens_the_new_version(void **state)
{
    (void)state;
    char dir[512], live[600], stage[600], input[512];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(live, sizeof live, "%s/live", dir);
    snprintf(stage, sizeof stage, "%s/stage", dir);
    assert_int_equal(mkdir(live, 0755), 0);
    assert_int_equal(mkdir(stage, 0755), 0);
    ms_test_model_path(input, sizeof input, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_report report;
    ms_nsp_test_bake(input, live, MODEL, 16, 2000, &report);
    ms_nsp_test_bake(input, stage, MODEL, 14, 2000, &report);

    char serve[512], view[512], ports[700], serve_log[700], view_log[700];
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    ms_test_bin_path(view, sizeof view, "meshview");
    snprintf(ports, sizeof ports, "%s/ports", dir);
    snprintf(serve_log, sizeof serve_log, "%s/meshserve.log", dir);
    snprintf(view_log, sizeof view_log, "%s/meshview.log", dir);
    char *serve_argv[] = {serve, live, "--port", "0", "--http-port", "0", "--port-file", ports,
                          NULL};
    pid_t server = ms_test_spawn(serve_argv, serve_log);
    uint16_t port, http_port;
    assert_int_equal(ms_test_wait_ports(ports, 15.0, &port, &http_port), 0);
    uint64_t before = model_requests(http_port);

    char address[64];
    snprintf(address, sizeof address, "127.0.0.1:%u", port);
    char *view_argv[] = {view, "--server", address, "--model", MODEL, "--bandwidth", "40000",
                         "--size", "160x120", NULL};
    pid_t viewer = ms_test_spawn(view_argv, view_log);
    /* streaming: the index fetch of the window's model source, the core's open
     * and at least one cell request */
    for (int tries = 0; tries < 3000 && model_requests(http_port) < before + 3; ++tries)
        usleep(10000);
    assert_true(model_requests(http_port) >= before + 3);
    char from[700], to[700];
    snprintf(from, sizeof from, "%s/" MODEL ".msa", stage);
    snprintf(to, sizeof to, "%s/" MODEL ".msa", live);
    assert_int_equal(rename(from, to), 0);
    uint64_t at_replace = model_requests(http_port);
    assert_int_equal(kill(server, SIGHUP), 0);

    /* The window says it opens the new version, and then streams it. */
    for (int tries = 0; tries < 3000 && !log_contains(view_log, "opening the new version"); ++tries)
        usleep(10000);
    if (!log_contains(view_log, "opening the new version")) {
        static char printed[2000];
        size_t length;
        char *text = (char *)ms_test_read_file(view_log, &length);
        snprintf(printed, sizeof printed, "%.*s", (int)(length < 1999 ? length : 1999), text);
        free(text);
        fail_msg("meshview did not reopen; it printed: %s", printed);
    }
    for (int tries = 0; tries < 3000 && model_requests(http_port) < at_replace + 2; ++tries)
        usleep(10000);
    assert_true(model_requests(http_port) >= at_replace + 2);
    assert_int_equal(ms_test_stop(viewer, SIGTERM, 20.0), 0);
    assert_int_equal(ms_test_stop(server, SIGTERM, 15.0), 0);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_meshload_streams_the_new_version),
        cmocka_unit_test(test_meshview_opens_the_new_version),
    };
    ms_test_display display;
    char why[256];
    if (!ms_test_display_start(&display, why, sizeof why)) {
        fprintf(stderr, "test_meshload_changed: no X display for meshview: %s\n", why);
        return 1;
    }
    int failed = cmocka_run_group_tests(tests, NULL, NULL);
    ms_test_display_stop(&display);
    return failed;
}
