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
    uint64_t n = 0;
    if (ms_test_metric(http_port, "meshstream_model_requests_total{model=\"" MODEL "\"}", &n) != 0)
        n = 0; /* no line before the first request */
    return n;
}

/* A served archive directory with the dragon at 16 bits, a staged 14-bit bake
 * of it beside, and meshserve on ephemeral ports. */
typedef struct {
    char dir[512], live[600], stage[600];
    pid_t server;
    uint16_t port, http_port;
    char address[64];
} replacement;

static void replacement_start(replacement *r)
{
    char input[512];
    ms_test_tmpdir(r->dir, sizeof r->dir);
    snprintf(r->live, sizeof r->live, "%s/live", r->dir);
    snprintf(r->stage, sizeof r->stage, "%s/stage", r->dir);
    assert_int_equal(mkdir(r->live, 0755), 0);
    assert_int_equal(mkdir(r->stage, 0755), 0);
    ms_test_model_path(input, sizeof input, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_report report;
    ms_nsp_test_bake(input, r->live, MODEL, 16, 2000, &report);
    ms_nsp_test_bake(input, r->stage, MODEL, 14, 2000, &report);

    char serve[512], ports[700], serve_log[700];
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    snprintf(ports, sizeof ports, "%s/ports", r->dir);
    snprintf(serve_log, sizeof serve_log, "%s/meshserve.log", r->dir);
    char *serve_argv[] = {serve, r->live, "--port", "0", "--http-port", "0", "--port-file", ports,
                          NULL};
    r->server = ms_test_spawn(serve_argv, serve_log);
    assert_int_equal(ms_test_wait_ports(ports, 15.0, &r->port, &r->http_port), 0);
    snprintf(r->address, sizeof r->address, "127.0.0.1:%u", r->port);
}

/* Publishes the staged bake over the served one and applies it (SIGHUP). */
static void replacement_publish(const replacement *r)
{
    char from[700], to[700];
    snprintf(from, sizeof from, "%s/" MODEL ".msa", r->stage);
    snprintf(to, sizeof to, "%s/" MODEL ".msa", r->live);
    assert_int_equal(rename(from, to), 0);
    assert_int_equal(kill(r->server, SIGHUP), 0);
}

static void replacement_stop(const replacement *r)
{
    assert_int_equal(ms_test_stop(r->server, SIGTERM, 15.0), 0);
    ms_test_rmdir(r->dir);
}

static void test_meshload_streams_the_new_version(void **state)
{
    (void)state;
    replacement r;
    replacement_start(&r);
    char load[512], load_log[700];
    ms_test_bin_path(load, sizeof load, "meshload");
    snprintf(load_log, sizeof load_log, "%s/meshload.json", r.dir);
    uint64_t before = model_requests(r.http_port);

    char clients[8];
    snprintf(clients, sizeof clients, "%d", CLIENTS);
    char *load_argv[] = {load, "--server", r.address, "--model", MODEL, "--path", PATH_FILE,
                         "--clients", clients, "--bandwidth", "320kbit", "--duration", "90",
                         "--json", NULL};
    pid_t loader = ms_test_spawn(load_argv, load_log);
    /* both clients streaming: their opens and at least one cell request each */
    for (int tries = 0; tries < 600 && model_requests(r.http_port) < before + 2 * CLIENTS; ++tries)
        usleep(10000);
    assert_true(model_requests(r.http_port) >= before + 2 * CLIENTS);
    replacement_publish(&r);

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
    replacement_stop(&r);
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
    replacement r;
    replacement_start(&r);
    char view[512], view_log[700];
    ms_test_bin_path(view, sizeof view, "meshview");
    snprintf(view_log, sizeof view_log, "%s/meshview.log", r.dir);
    uint64_t before = model_requests(r.http_port);
    char *view_argv[] = {view, "--server", r.address, "--model", MODEL, "--bandwidth", "40000",
                         "--size", "160x120", NULL};
    pid_t viewer = ms_test_spawn(view_argv, view_log);
    /* streaming: the index fetch of the window's model source, the core's open
     * and at least one cell request */
    for (int tries = 0; tries < 3000 && model_requests(r.http_port) < before + 3; ++tries)
        usleep(10000);
    assert_true(model_requests(r.http_port) >= before + 3);
    uint64_t at_replace = model_requests(r.http_port);
    replacement_publish(&r);

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
    for (int tries = 0; tries < 3000 && model_requests(r.http_port) < at_replace + 2; ++tries)
        usleep(10000);
    assert_true(model_requests(r.http_port) >= at_replace + 2);
    assert_int_equal(ms_test_stop(viewer, SIGTERM, 20.0), 0);
    replacement_stop(&r);
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
