/* meshview with an index by subtree (docs/CLIENT.md, "An index by subtree"),
 * the built program (build/asan/bin/meshview) under Xvfb with Mesa llvmpipe at
 * 160x120, streaming from meshserve on loopback a model baked into several
 * levels of one-group subtrees (80,000 triangles, 8,769 cells), along an
 * overview and a close-up:
 *   - by subtree (the default) and with --whole-index (as from a server without
 *     subtrees) it settles at both keyframes and draws the same pictures;
 *   - --json says which index it used, and by subtree it received fewer index
 *     bytes than the whole index and some subtrees beyond the head;
 *   - time_to_first_display is meshview's own (from opening to the first
 *     picture with a triangle): positive, after the core's first display (the
 *     core starts within the opening) and within the run;
 *   - over a slow link the first picture draws the core's first frame with a
 *     triangle (the renderer was ready for it, not behind);
 *   - --help lists --whole-index.
 * Nothing leaked (the program runs under LeakSanitizer). */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_bake.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define MODEL "demo"
#define TRIANGLES 80000
#define SIZE "160x120"

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600], log[600], port_file[600], bin[600], path_file[600];
    pid_t server;
    uint16_t port, http_port;
} fixture;

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    char why[256];
    if (!f)
        return -1;
    if (!ms_test_display_start(&f->display, why, sizeof why)) {
        fprintf(stderr, "no X display: %s\n", why);
        free(f);
        return -1;
    }
    *state = f;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    snprintf(f->log, sizeof f->log, "%s/meshserve.log", f->dir);
    snprintf(f->port_file, sizeof f->port_file, "%s/ports", f->dir);
    snprintf(f->path_file, sizeof f->path_file, "%s/overview-closeup.cam", f->dir);
    ms_test_bin_path(f->bin, 512, "meshview");
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    /* the first and last keyframes of scripts/paths/demo-closeup.cam */
    FILE *path = fopen(f->path_file, "w");
    if (!path)
        return -1;
    fputs("meshstream-camera-path 1\n"
          "0 3.5 0.5 0.4 0.6 0 0.1 0 0 1 40\n"
          "1 0.95 0.1 0.2 0.6 0 0.1 0 0 1 30\n",
          path);
    fclose(path);
    char ply[700];
    snprintf(ply, sizeof ply, "%s/demo.ply", f->dir);
    ms_nsp_test_demo_ply(ply, TRIANGLES);
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.input = ply;
    o.archive_dir = f->archives;
    o.name = MODEL;
    o.apo.enabled = false;   /* geometry is what the index decides */
    o.min_triangles = 300;   /* 4 levels of cells, one-group subtrees (n = 4): a close-up
                                needs a fraction of the index (42 KB of 116 KB zlib'd) */
    o.threads = 2;
    o.mem_mb = 64;
    ms_bake_report report;
    ms_error err;
    if (ms_bake(&o, &report, &err) != MS_OK) {
        fprintf(stderr, "bake: %s\n", err.text);
        return -1;
    }
    f->server = ms_test_meshserve_start(f->archives, NULL, 0, f->port_file, f->log, &f->port,
                                        &f->http_port);
    if (!f->server)
        return -1;
    return 0;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    if (!f)
        return 0;
    if (f->server)
        ms_test_stop(f->server, SIGTERM, 10.0);
    ms_test_display_stop(&f->display);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Runs meshview with args, stdout to out_file; returns its exit status. */
static int run_viewer(const fixture *f, const char *args, const char *out_file)
{
    char command[4096], ignored[64];
    snprintf(command, sizeof command, "%s %s > %s 2> %s/stderr.txt", f->bin, args, out_file, f->dir);
    return ms_test_run(command, ignored, sizeof ignored);
}

/* The scripted run's report along the test's path, shots in DIR/shots-LABEL. */
static json_t *stream(const fixture *f, const char *label, const char *extra)
{
    char args[2048], out[700];
    snprintf(out, sizeof out, "%s/%s.json", f->dir, label);
    snprintf(args, sizeof args,
             "--server 127.0.0.1:%u --model " MODEL " --path %s --size " SIZE
             " --frames 2 --screenshot-dir %s/shots-%s --json %s",
             f->port, f->path_file, f->dir, label, extra);
    assert_int_equal(run_viewer(f, args, out), 0);
    json_error_t jerr;
    json_t *report = json_load_file(out, 0, &jerr);
    if (!report)
        fail_msg("%s: %s", out, jerr.text);
    assert_true(json_is_true(json_object_get(report, "complete")));
    assert_int_equal(json_array_size(json_object_get(report, "keyframes")), 2);
    return report;
}

static json_int_t index_figure(json_t *report, const char *name)
{
    json_t *value = json_object_get(json_object_get(report, "index"), name);
    assert_true(json_is_integer(value));
    return json_integer_value(value);
}

static void check_first_display(json_t *report)
{
    double mine = json_real_value(json_object_get(report, "time_to_first_display"));
    double core = json_real_value(json_object_get(report, "core_first_display"));
    double run = json_real_value(json_object_get(report, "seconds"));
    assert_true(core > 0);
    assert_true(mine >= core);
    assert_true(mine < run);
}

static void test_by_subtree_draws_as_whole(void **state)
{
    fixture *f = *state;
    json_t *subtree = stream(f, "subtree", "");
    json_t *whole = stream(f, "whole", "--whole-index");
    json_t *index = json_object_get(subtree, "index");
    assert_true(json_is_true(json_object_get(index, "by_subtree")));
    assert_true(json_is_false(json_object_get(json_object_get(whole, "index"), "by_subtree")));
    assert_int_equal(index_figure(whole, "subtrees_received"), 0);
    /* the close-up needed subtrees beyond the head, and less than the whole index */
    assert_true(index_figure(subtree, "subtrees_received") > 0);
    assert_true(index_figure(subtree, "index_bytes_received") > 0);
    assert_true(index_figure(subtree, "index_bytes_received") < index_figure(whole, "index_bytes_received"));
    check_first_display(subtree);
    check_first_display(whole);
    /* the same settled views, drawn the same way */
    json_t *a_keys = json_object_get(subtree, "keyframes"), *b_keys = json_object_get(whole, "keyframes");
    for (size_t k = 0; k < 2; ++k) {
        json_t *a = json_array_get(a_keys, k), *b = json_array_get(b_keys, k);
        assert_true(json_is_true(json_object_get(a, "complete")));
        assert_true(json_integer_value(json_object_get(a, "triangles_drawn")) > 0);
        assert_int_equal(json_integer_value(json_object_get(a, "triangles_drawn")),
                         json_integer_value(json_object_get(b, "triangles_drawn")));
        size_t differing = ms_test_png_differing(json_string_value(json_object_get(a, "png")),
                                                 json_string_value(json_object_get(b, "png")), 2);
        if (differing > 160 * 120 / 500)
            fail_msg("keyframe %zu: %zu pixels differ", k, differing);
    }
    json_decref(subtree);
    json_decref(whole);
}

/* meshview's first picture draws the core's first frame with a triangle in
 * view: the renderer was ready for it (its programs compiled and its pipeline
 * warmed while the index head came, before the first camera), so it did not
 * have to catch up to a later frame. Over a slow
 * link (4 KB/s) the root's bits come a few at a time, frames apart; the home
 * view (no path) shows the whole model, so both count the same triangles. The
 * view need not complete in the 2 s given (exit status 0 or 1). */
static void test_first_picture_is_first_display(void **state)
{
    fixture *f = *state;
    char args[2048], out[700];
    snprintf(out, sizeof out, "%s/first.json", f->dir);
    snprintf(args, sizeof args,
             "--server 127.0.0.1:%u --model " MODEL " --size " SIZE " --bandwidth 4000"
             " --keyframe-timeout 2 --screenshot-dir %s/shots-first --json",
             f->port, f->dir);
    int status = run_viewer(f, args, out);
    assert_true(status == 0 || status == 1);
    json_error_t jerr;
    json_t *report = json_load_file(out, 0, &jerr);
    if (!report)
        fail_msg("%s: %s", out, jerr.text);
    json_int_t mine = json_integer_value(json_object_get(report, "first_frame_generation"));
    json_int_t core = json_integer_value(json_object_get(report, "core_first_display_generation"));
    print_message("first picture: core frame %lld; the core's first display: frame %lld\n",
                  (long long)mine, (long long)core);
    assert_true(core > 0);
    assert_int_equal(mine, core);
    check_first_display(report);
    json_decref(report);
}

static void test_help_lists_whole_index(void **state)
{
    fixture *f = *state;
    char out[700];
    snprintf(out, sizeof out, "%s/help.txt", f->dir);
    assert_int_equal(run_viewer(f, "--help", out), 0);
    size_t length;
    unsigned char *text = ms_test_read_file(out, &length);
    char *help = calloc(length + 1, 1);
    assert_non_null(help);
    memcpy(help, text, length);
    free(text);
    assert_non_null(strstr(help, "--whole-index"));
    free(help);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help_lists_whole_index),
        cmocka_unit_test(test_by_subtree_draws_as_whole),
        cmocka_unit_test(test_first_picture_is_first_display),
    };
    return cmocka_run_group_tests_name("meshview_subtrees", tests, group_setup, group_teardown);
}
