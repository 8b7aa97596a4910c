/* meshview, the built program (build/asan/bin/meshview), under Xvfb with Mesa
 * llvmpipe at 160x120:
 *   - streaming from meshserve on loopback along scripts/paths/demo-closeup.cam
 *     settles (view complete, nothing left to upload) at every keyframe, no
 *     frame uploads more than --upload-budget, and the coarse first frame
 *     differs from the final one;
 *   - the local-archive mode draws the same pictures (with --compare-apo, which
 *     times both shadings of each frame and still pictures the run's own);
 *   - the catalogue screen lists the model, and its panel shows the model's
 *     thumbnail from a local directory and from a server (binary door, by
 *     the catalogue's worker: "loading" first), and draws on against a server
 *     that never answers the documents ("loading", then "no picture");
 *   - a model small on screen (400 down to 15 px tall) is drawn at every size,
 *     its silhouette that of meshrender's picture of the full mesh;
 *   - bad input: --help (0), bad options (2), no display (1), unknown model (1),
 *     no server (1), server gone mid-stream (1): one line on stderr each, and
 *     nothing leaked (the program runs under LeakSanitizer). */
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"
#include "ms_test_quiet.h"

#define MODEL "demo"
#define PATH_FILE "scripts/paths/demo-closeup.cam"
#define TRIANGLES 20000
#define BUDGET 65536
#define SIZE "160x120"

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600], log[600], port_file[600], bin[600];
    pid_t server;
    uint16_t port, http_port;
} fixture;

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    char why[256];
    if (!f || !ms_test_display_start(&f->display, why, sizeof why)) {
        fprintf(stderr, "no X display: %s\n", why);
        free(f);
        return -1;
    }
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    snprintf(f->log, sizeof f->log, "%s/meshserve.log", f->dir);
    snprintf(f->port_file, sizeof f->port_file, "%s/ports", f->dir);
    ms_test_bin_path(f->bin, 512, "meshview");
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    if (ms_nsp_test_bake_demo(f->dir, TRIANGLES, f->archives, MODEL, 1500, false) != 0)
        return -1;
    f->server = ms_test_meshserve_start(f->archives, NULL, 0, f->port_file, f->log, &f->port,
                                        &f->http_port);
    if (!f->server)
        return -1;
    *state = f;
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

/* Runs meshview with args; stdout to out_file (when given), stderr captured. */
static int run_viewer(const fixture *f, const char *args, const char *out_file, char *err_text,
                      size_t size)
{
    char command[4096], err_file[700];
    snprintf(err_file, sizeof err_file, "%s/stderr.txt", f->dir);
    snprintf(command, sizeof command, "%s %s > %s 2> %s", f->bin, args,
             out_file ? out_file : "/dev/null", err_file);
    char ignored[64];
    int status = ms_test_run(command, ignored, sizeof ignored);
    size_t length;
    unsigned char *text = ms_test_read_file(err_file, &length);
    snprintf(err_text, size, "%.*s", (int)length, (const char *)text);
    free(text);
    return status;
}

/* A whole file as a NUL-terminated string (the caller frees it). */
static char *read_text(const char *path)
{
    size_t length;
    unsigned char *data = ms_test_read_file(path, &length);
    char *text = malloc(length + 1);
    assert_non_null(text);
    memcpy(text, data, length);
    text[length] = 0;
    free(data);
    return text;
}

static size_t count_lines(const char *text)
{
    size_t n = 0;
    for (const char *p = text; *p; ++p)
        n += *p == '\n';
    return n;
}

static json_t *load_report(const char *path)
{
    json_error_t jerr;
    json_t *report = json_load_file(path, 0, &jerr);
    if (!report)
        fail_msg("%s: %s", path, jerr.text);
    return report;
}

/* Checks a scripted run's report: every keyframe settled with a PNG of the
 * right size, no frame above the budget. Returns the keyframe count. */
static size_t check_streaming_report(json_t *report)
{
    assert_true(json_is_true(json_object_get(report, "complete")));
    json_t *keys = json_object_get(report, "keyframes");
    size_t count = json_array_size(keys);
    assert_int_equal(count, 9); /* demo-closeup.cam */
    for (size_t k = 0; k < count; ++k) {
        json_t *key = json_array_get(keys, k);
        assert_true(json_is_true(json_object_get(key, "complete")));
        assert_true(json_integer_value(json_object_get(key, "triangles_drawn")) > 0);
        uint32_t w, h;
        free(ms_test_png_read(json_string_value(json_object_get(key, "png")), &w, &h));
        assert_int_equal(w, 160);
        assert_int_equal(h, 120);
    }
    json_t *frames = json_object_get(report, "frames");
    assert_true(json_integer_value(json_object_get(frames, "frames")) >= (json_int_t)count);
    assert_true(json_integer_value(json_object_get(frames, "upload_bytes_max")) > 0);
    assert_true(json_integer_value(json_object_get(frames, "upload_bytes_max")) <= BUDGET);
    assert_true(json_integer_value(json_object_get(report, "geometry_bytes")) > 0);
    /* memory (issue 32 item 5): the GL storage holds at least the offscreen
     * framebuffer (8 bytes a pixel) and the texel buffer's first 64 Ki words;
     * the process's RSS grew from its start through the GL context */
    json_int_t gl = json_integer_value(json_object_get(report, "gl_bytes"));
    assert_true(gl > 160 * 120 * 8 + 4 * 65536);
    assert_true(json_integer_value(json_object_get(report, "gl_bytes_peak")) >= gl);
    json_int_t core = json_integer_value(json_object_get(report, "core_memory"));
    assert_true(core > 0);
    assert_true(json_integer_value(json_object_get(report, "core_peak_memory")) >= core);
    json_int_t rss = json_integer_value(json_object_get(report, "rss_bytes"));
    assert_true(rss > 0);
    assert_true(json_integer_value(json_object_get(report, "rss_peak_bytes")) >= rss);
    json_t *stages = json_object_get(report, "rss_stages");
    json_int_t start = json_integer_value(json_object_get(stages, "start"));
    assert_true(start > 0);
    assert_true(json_integer_value(json_object_get(stages, "context")) > start);
    assert_true(json_integer_value(json_object_get(stages, "shaders")) > 0);
    assert_true(json_integer_value(json_object_get(stages, "first_frame")) > 0);
    assert_int_equal(json_integer_value(json_object_get(stages, "end")) > 0, 1);
    return count;
}

static void test_streaming_and_local_archive(void **state)
{
    fixture *f = *state;
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/server.json", f->dir);
    snprintf(args, sizeof args,
             "--server 127.0.0.1:%u --model " MODEL " --path " PATH_FILE " --size " SIZE
             " --upload-budget %d --screenshot-dir %s/server --json",
             f->port, BUDGET, f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *server = load_report(out);
    size_t count = check_streaming_report(server);

    /* The coarse first frame and the final one are different pictures. */
    const char *first = json_string_value(json_object_get(server, "first_frame_png"));
    assert_non_null(first);
    json_t *keys = json_object_get(server, "keyframes");
    const char *last = json_string_value(json_object_get(json_array_get(keys, count - 1), "png"));
    assert_true(ms_test_png_differing(first, last, 8) > 160 * 120 / 10);

    /* The same path from the archive directory, without a server. */
    snprintf(out, sizeof out, "%s/local.json", f->dir);
    snprintf(args, sizeof args,
             "%s --model " MODEL " --path " PATH_FILE " --size " SIZE
             " --upload-budget %d --screenshot-dir %s/local --compare-apo --json",
             f->archives, BUDGET, f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *local = load_report(out);
    assert_int_equal(check_streaming_report(local), count);
    assert_string_equal(json_string_value(json_object_get(local, "source")), "archive");
    /* --compare-apo timed both shadings of every frame and still pictured the
     * run's own (the pictures below equal the server run's). */
    json_t *compare = json_object_get(local, "compare_apo");
    assert_true(json_integer_value(json_object_get(compare, "draws")) > 0);
    assert_true(json_real_value(json_object_get(compare, "apo_draw_ms_p50")) > 0);
    assert_true(json_real_value(json_object_get(compare, "plain_draw_ms_p50")) > 0);
    assert_null(json_object_get(server, "compare_apo"));
    json_t *local_keys = json_object_get(local, "keyframes");
    for (size_t k = 0; k < count; ++k) {
        const char *a = json_string_value(json_object_get(json_array_get(keys, k), "png"));
        const char *b = json_string_value(json_object_get(json_array_get(local_keys, k), "png"));
        /* The same settled view, drawn the same way: at most a few pixels where
         * a rounding differs. */
        assert_true(ms_test_png_differing(a, b, 2) <= 160 * 120 / 500);
    }
    json_decref(server);
    json_decref(local);
}

/* A model seen from ever farther, 400 down to 15 px tall: meshview draws it
 * at every distance (the clipping planes frame the model, not a fixed range
 * of its size: it vanished behind the far plane at 8 box sides), and down to
 * 30 px its silhouette overlaps meshrender's picture of the full mesh with an
 * intersection over union of at least 0.9; at 1 px it draws at most 8
 * triangles a covered pixel (3.4 to 4.6 below 400 px, CLIENT.md). */
static void test_small_on_screen_never_vanishes(void **state)
{
    fixture *f = *state;
    static const double heights_px[] = {400, 120, 60, 30, 15};
    enum { SIDE = 480, KEYS = sizeof heights_px / sizeof *heights_px };
    char archive_path[700], path_file[700], text[4096], args[2048], out[700], err_text[4096];
    snprintf(archive_path, sizeof archive_path, "%s/" MODEL ".msa", f->archives);
    ms_archive *archive;
    ms_error err;
    assert_int_equal(ms_archive_open(archive_path, &archive, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(archive);
    double side = h->box_side, centre[3];
    for (int a = 0; a < 3; ++a)
        centre[a] = h->box_origin[a] + 0.5 * side;
    ms_archive_close(archive);
    /* distance at which the box's side spans height px of SIDE at fovy 40 */
    size_t used = (size_t)snprintf(text, sizeof text, "meshstream-camera-path 1\n");
    for (int k = 0; k < KEYS; ++k) {
        double d = side * SIDE / (heights_px[k] * 2.0 * tan(20.0 * M_PI / 180.0));
        used += (size_t)snprintf(text + used, sizeof text - used, "%d %.9g %.9g %.9g %.9g %.9g %.9g 0 1 0 40\n",
                                 k, centre[0], centre[1], centre[2] + d, centre[0], centre[1], centre[2]);
    }
    snprintf(path_file, sizeof path_file, "%s/far.cam", f->dir);
    FILE *pf = fopen(path_file, "w");
    assert_non_null(pf);
    fputs(text, pf);
    fclose(pf);

    snprintf(out, sizeof out, "%s/far.json", f->dir);
    snprintf(args, sizeof args,
             "%s --model " MODEL " --path %s --size %dx%d --no-apo --frames 1 "
             "--screenshot-dir %s/far --json", f->archives, path_file, SIDE, SIDE, f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *report = load_report(out);
    char meshrender[600], command[4096];
    ms_test_bin_path(meshrender, sizeof meshrender, "meshrender");
    snprintf(command, sizeof command, "%s %s/demo.ply -p %s -o %s/far-ref --width %d --height %d --json",
             meshrender, f->dir, path_file, f->dir, SIDE, SIDE);
    json_decref(ms_test_run_json(command, 0));
    json_t *keys = json_object_get(report, "keyframes");
    assert_int_equal(json_array_size(keys), KEYS);
    for (int k = 0; k < KEYS; ++k) {
        json_t *key = json_array_get(keys, k);
        assert_true(json_is_true(json_object_get(key, "complete")));
        json_int_t triangles = json_integer_value(json_object_get(key, "triangles_drawn"));
        char ref[800];
        snprintf(ref, sizeof ref, "%s/far-ref/frame_%03d.png", f->dir, k);
        uint32_t w, h2, rw, rh;
        size_t covered, ref_covered;
        uint8_t *mask = ms_test_silhouette(json_string_value(json_object_get(key, "png")), &w, &h2, &covered);
        uint8_t *ref_mask = ms_test_silhouette(ref, &rw, &rh, &ref_covered);
        assert_int_equal(w, rw);
        assert_int_equal(h2, rh);
        double iou = ms_test_mask_iou(mask, ref_mask, (size_t)w * h2);
        printf("%g px tall: %lld triangles, %zu px covered (meshrender %zu), IoU %.3f, %.1f triangles "
               "per covered pixel\n", heights_px[k], (long long)triangles, covered, ref_covered, iou,
               (double)triangles / (double)(covered ? covered : 1));
        assert_true(triangles > 0);
        assert_true(covered > 0);
        if (heights_px[k] >= 30)
            assert_true(iou >= 0.9);
        /* about a vertex a pixel of surface (issue 30): at most 8 a covered pixel */
        assert_true((size_t)triangles <= 8 * covered);
        free(mask);
        free(ref_mask);
    }
    json_decref(report);
}

/* From a local archive directory the catalogue's panel shows the selected
 * model's thumbnail (meshbake's, docs/ARCHIVE.md "Thumbnails"): at 960x540
 * and scale 2 the picture fills x 672..936, y 96..294 (the list is 50
 * columns of 12 pixels from x 24, the panel 48 pixels further, 264 wide). */
/* The panel's picture at x 676..932, y 100..290 lit, nothing bright around it. */
static void assert_panel_picture(json_t *report)
{
    assert_true(json_is_true(json_object_get(report, "picture_shown")));
    json_t *m = json_array_get(json_object_get(report, "models"), 0);
    assert_true(json_is_true(json_object_get(m, "thumbnail")));
    uint32_t w, h;
    uint8_t *pixels = ms_test_png_read(json_string_value(json_object_get(report, "png")), &w, &h);
    assert_int_equal(w, 960);
    size_t lit = 0, outside = 0; /* the model's grey against the dark background */
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 640; x < w; ++x) {
            bool in_picture = x >= 676 && x < 932 && y >= 100 && y < 290;
            bool bright = pixels[3 * ((size_t)y * w + x)] > 90;
            lit += in_picture && bright;
            outside += !in_picture && bright && y >= 96 && y < 294;
        }
    assert_true(lit > 2000);
    assert_int_equal(outside, 0);
    free(pixels);
}

/* The states the scripted catalogue's panel went through ("panel"). */
static void assert_panel_states(json_t *report, const char *first, const char *second)
{
    json_t *panel = json_object_get(report, "panel");
    assert_int_equal(json_array_size(panel), second ? 2 : 1);
    assert_string_equal(json_string_value(json_array_get(panel, 0)), first);
    if (second)
        assert_string_equal(json_string_value(json_array_get(panel, 1)), second);
}

static void test_catalogue_panel_shows_the_thumbnail(void **state)
{
    fixture *f = *state;
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/panel.json", f->dir);
    snprintf(args, sizeof args, "%s --size 960x540 --screenshot-dir %s/panel --json", f->archives,
             f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *report = load_report(out);
    assert_panel_picture(report);
    assert_panel_states(report, "picture", NULL); /* read at once: one frame */
    assert_int_equal(json_integer_value(json_object_get(report, "frames")), 1);
    json_decref(report);
}

/* From a server the panel shows the same picture, fetched through the binary
 * door (GET_DOCUMENT THUMBNAIL and METADATA, for the selected model only) by
 * the catalogue's worker while frames are drawn: "loading" first. */
static void test_catalogue_panel_from_a_server(void **state)
{
    fixture *f = *state;
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/panel-server.json", f->dir);
    snprintf(args, sizeof args,
             "--server 127.0.0.1:%u --size 960x540 --screenshot-dir %s/panel-server --json",
             f->port, f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *report = load_report(out);
    assert_panel_picture(report);
    assert_panel_states(report, "loading", "picture");
    assert_true(json_integer_value(json_object_get(report, "frames")) >= 2);
    json_decref(report);
}

/* A server that lists its model and never answers its documents (a stalled
 * peer): the scripted catalogue screen draws on while the catalogue's worker
 * waits, the panel "loading" until the time-out (meshview's 5 s), then "no
 * picture"; no frame waits (the fetch on the drawing thread held the first
 * for the whole time-out). Two connections: the listing, the worker's. */
static void test_catalogue_draws_on_against_a_silent_server(void **state)
{
    fixture *f = *state;
    ms_test_quiet *quiet;
    uint16_t port;
    assert_int_equal(ms_test_quiet_start("quiet", false, &quiet, &port), 0);
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/quiet.json", f->dir);
    snprintf(args, sizeof args,
             "--server 127.0.0.1:%u --size 640x360 --screenshot-dir %s/quiet --json", port, f->dir);
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    clock_gettime(CLOCK_MONOTONIC, &t1);
    json_t *report = load_report(out);
    assert_panel_states(report, "loading", "no picture");
    assert_false(json_is_true(json_object_get(report, "picture_shown")));
    json_int_t frames = json_integer_value(json_object_get(report, "frames"));
    double slowest = json_real_value(json_object_get(report, "slowest_frame_ms"));
    double run_s = (double)(t1.tv_sec - t0.tv_sec) + (t1.tv_nsec - t0.tv_nsec) * 1e-9;
    print_message("silent server: %lld frames, the slowest %.1f ms, the run %.2f s\n",
                  (long long)frames, slowest, run_s);
    assert_true(frames >= 20);
    assert_true(slowest < 1000);
    assert_true(run_s >= 5.0 && run_s < 15.0);
    assert_int_equal(ms_test_quiet_connections(quiet), 2);
    json_decref(report);
    ms_test_quiet_stop(quiet);
}

static void test_catalogue_screen(void **state)
{
    fixture *f = *state;
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/catalogue.json", f->dir);
    snprintf(args, sizeof args, "--server 127.0.0.1:%u --size 320x200 --screenshot-dir %s/cat --json",
             f->port, f->dir);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *report = load_report(out);
    json_t *models = json_object_get(report, "models");
    assert_int_equal(json_array_size(models), 1);
    json_t *m = json_array_get(models, 0);
    assert_string_equal(json_string_value(json_object_get(m, "name")), MODEL);
    assert_true(json_integer_value(json_object_get(m, "triangles")) > 0);
    uint32_t w, h;
    uint8_t *pixels = ms_test_png_read(json_string_value(json_object_get(report, "png")), &w, &h);
    assert_int_equal(w, 320);
    assert_int_equal(h, 200);
    size_t bright = 0; /* text and the selection band */
    for (size_t i = 0; i < (size_t)w * h; ++i)
        bright += pixels[3 * i] > 100 || pixels[3 * i + 2] > 100;
    assert_true(bright > 200);
    free(pixels);
    json_decref(report);
}

static void test_help_and_usage_errors(void **state)
{
    fixture *f = *state;
    char out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/help.txt", f->dir);
    assert_int_equal(run_viewer(f, "--help", out, err_text, sizeof err_text), 0);
    char *help = read_text(out);
    assert_non_null(strstr(help, "usage: meshview"));
    assert_non_null(strstr(help, "wireframe"));
    assert_non_null(strstr(help, "fly mode"));
    free(help);
    static const char *const bad[] = {
        "--bogus",
        "",                                               /* neither server nor archive */
        "--server 127.0.0.1 --model demo",                /* no port */
        "--server 127.0.0.1:70000",
        "/tmp --server 127.0.0.1:7000",                   /* both */
        "/tmp --size 12x9000000",
        "/tmp --tolerance 0",
        "/tmp --shading shiny",
        "/tmp --upload-budget 12",
        "/tmp --model ../etc",
        "/tmp --path " PATH_FILE,                         /* a path needs a model */
        "/tmp --json",                                    /* JSON reports scripted runs */
        "/tmp /var",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        int status = run_viewer(f, bad[i], NULL, err_text, sizeof err_text);
        if (status != 2 || count_lines(err_text) != 1 || strncmp(err_text, "meshview: ", 10))
            fail_msg("'%s': status %d, stderr '%s'", bad[i], status, err_text);
    }
}

static void test_runtime_errors(void **state)
{
    fixture *f = *state;
    char args[2048], err_text[4096];
    /* No display, so no OpenGL 4.1 context. */
    snprintf(args, sizeof args, "%s --model " MODEL " --screenshot-dir %s/none", f->archives, f->dir);
    fixture no_display = *f;
    snprintf(no_display.bin, sizeof no_display.bin, "env DISPLAY=:1999 %.500s", f->bin);
    int status = run_viewer(&no_display, args, NULL, err_text, sizeof err_text);
    assert_int_equal(status, 1);
    assert_int_equal(count_lines(err_text), 1);
    assert_non_null(strstr(err_text, "OpenGL 4.1"));

    /* Unknown model, from the server and from the archive. */
    snprintf(args, sizeof args, "--server 127.0.0.1:%u --model nothere --screenshot-dir %s/x",
             f->port, f->dir);
    assert_int_equal(run_viewer(f, args, NULL, err_text, sizeof err_text), 1);
    assert_int_equal(count_lines(err_text), 1);
    assert_non_null(strstr(err_text, "does not exist"));
    snprintf(args, sizeof args, "%s --model nothere --screenshot-dir %s/x", f->archives, f->dir);
    assert_int_equal(run_viewer(f, args, NULL, err_text, sizeof err_text), 1);
    assert_non_null(strstr(err_text, "does not exist"));

    /* No server: the port of the fixture's server once it has stopped. */
    pid_t pid = f->server;
    f->server = 0;
    assert_int_equal(ms_test_stop(pid, SIGTERM, 10.0), 0);
    snprintf(args, sizeof args, "--server 127.0.0.1:%u --model " MODEL " --screenshot-dir %s/x",
             f->port, f->dir);
    assert_int_equal(run_viewer(f, args, NULL, err_text, sizeof err_text), 1);
    assert_int_equal(count_lines(err_text), 1);
    assert_non_null(strstr(err_text, "127.0.0.1"));
}

/* The server goes away while the viewer streams: the core gives up after its
 * reconnect time and the viewer ends with status 1 and one line. */
static void test_server_gone_mid_stream(void **state)
{
    fixture *f = *state;
    char serve[512], log[700], port_file[700];
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    snprintf(log, sizeof log, "%s/meshserve2.log", f->dir);
    snprintf(port_file, sizeof port_file, "%s/ports2", f->dir);
    char *argv[] = {serve, f->archives, "--bind", "127.0.0.1", "--port", "0", "--http-port", "0",
                    "--port-file", port_file, NULL};
    pid_t server = ms_test_spawn(argv, log);
    uint16_t port, http_port;
    assert_int_equal(ms_test_wait_ports(port_file, 15.0, &port, &http_port), 0);
    char err_file[700], args[1024];
    snprintf(err_file, sizeof err_file, "%s/gone.txt", f->dir);
    snprintf(args, sizeof args, "%s/gone-shots", f->dir);
    char addr[64];
    snprintf(addr, sizeof addr, "127.0.0.1:%u", port);
    /* Slow enough (20 kB/s) that the path is far from done after a second. */
    char *view_argv[] = {f->bin, "--server", addr, "--model", MODEL, "--path", PATH_FILE,
                         "--size", SIZE, "--bandwidth", "20000", "--screenshot-dir", args,
                         "--keyframe-timeout", "60", "--json", NULL};
    pid_t viewer = ms_test_spawn(view_argv, err_file);
    struct timespec second = {1, 0};
    nanosleep(&second, NULL);
    assert_int_equal(ms_test_stop(server, SIGKILL, 5.0), -1); /* killed */
    int status = ms_test_stop(viewer, 0, 40.0);                /* waits for its own exit */
    assert_int_equal(status, 1);
    char *text = read_text(err_file);
    assert_int_equal(count_lines(text), 1);
    assert_non_null(strstr(text, "meshview: "));
    free(text);
}

/* The interactive viewer (a visible window on the test display) on the
 * catalogue screen and on a model with the HUD: it draws until SIGTERM, then
 * ends with status 0 and prints nothing (no error, no leak report). */
static void test_interactive_until_terminated(void **state)
{
    fixture *f = *state;
    const char *modes[2] = {NULL, MODEL};
    for (int i = 0; i < 2; ++i) {
        char log[700];
        snprintf(log, sizeof log, "%s/interactive-%d.txt", f->dir, i);
        char *argv[] = {f->bin, f->archives, "--size", "320x200",
                        modes[i] ? "--model" : NULL, (char *)modes[i], NULL};
        pid_t viewer = ms_test_spawn(argv, log);
        struct timespec wait = {1, 500000000};
        nanosleep(&wait, NULL);
        assert_int_equal(ms_test_stop(viewer, SIGTERM, 20.0), 0);
        char *text = read_text(log);
        if (text[0])
            fail_msg("meshview printed: %.2000s", text);
        free(text);
    }
}

/* The interactive viewer on a model from meshserve lists the catalogue once
 * and opens the model from that list: three connections in all (the listing,
 * the core's, and the model's annotations document asked for once as the
 * model opens), not one more for the catalogue screen and one more to open
 * the model; at a distance each was a connection and a round trip more
 * before the first picture. It draws until its core asks for cells, and
 * ends cleanly on SIGTERM. */
static void test_interactive_from_a_server_lists_once(void **state)
{
    fixture *f = *state;
    char series[128], server[64], log[700];
    snprintf(series, sizeof series, "meshstream_model_requests_total{model=\"%s\"}", MODEL);
    snprintf(server, sizeof server, "127.0.0.1:%u", f->port);
    snprintf(log, sizeof log, "%s/interactive-server.txt", f->dir);
    uint64_t connections, requests = 0, n;
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_connections_total", &connections), 0);
    ms_test_metric(f->http_port, series, &requests); /* absent before any request */
    /* 640 x 360: the catalogue's panel fits in the frame drawn while the
     * model opens, which asks the server nothing */
    char *argv[] = {f->bin, "--server", server, "--model", MODEL, "--size", "640x360", NULL};
    pid_t viewer = ms_test_spawn(argv, log);
    bool asked = false, all = false;
    for (int i = 0; i < 400 && !(asked && all); ++i) { /* 40 s at most */
        asked = ms_test_metric(f->http_port, series, &n) == 0 && n > requests;
        /* the annotations come on the frame after the model opened */
        all = ms_test_metric(f->http_port, "meshstream_connections_total", &n) == 0 &&
              n - connections >= 3;
        struct timespec pause = {0, 100000000};
        if (!(asked && all))
            nanosleep(&pause, NULL);
    }
    assert_int_equal(ms_test_stop(viewer, SIGTERM, 20.0), 0);
    assert_true(asked);
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_connections_total", &n), 0);
    assert_int_equal(n - connections, 3);
    char *text = read_text(log);
    if (text[0])
        fail_msg("meshview printed: %.2000s", text);
    free(text);
}

/* The last keyframe's apo_bytes of a scripted run along the close-up path
 * (*total, when not NULL: the whole run's). */
static json_int_t run_apo_bytes_total(const fixture *f, const char *extra, const char *name, json_int_t *total)
{
    char args[2048], out[700], err_text[4096];
    snprintf(out, sizeof out, "%s/%s.json", f->dir, name);
    snprintf(args, sizeof args,
             "%s --model " MODEL " --path " PATH_FILE " --size " SIZE " %s --screenshot-dir %s/%s --json",
             f->archives, extra, f->dir, name);
    assert_int_equal(run_viewer(f, args, out, err_text, sizeof err_text), 0);
    json_t *report = load_report(out);
    json_t *keys = json_object_get(report, "keyframes");
    json_int_t bytes = json_integer_value(json_object_get(json_array_get(keys, json_array_size(keys) - 1),
                                                          "apo_bytes"));
    assert_int_equal(json_integer_value(json_object_get(report, "apo_bytes")) >= 0, 1);
    if (total)
        *total = json_integer_value(json_object_get(report, "apo_bytes"));
    json_decref(report);
    return bytes;
}

static json_int_t run_apo_bytes(const fixture *f, const char *extra, const char *name)
{
    return run_apo_bytes_total(f, extra, name, NULL);
}

/* APO where it pays (docs/ACCURACY.md, "Where APO pays"): at the default 1 px
 * the path's overview shows internal cells with chunks, yet meshview fetches
 * none of them (--apo-min-tolerance 2: at 1 px they add bytes and no
 * picture); allowed at any tolerance, it fetches them; at 2 px, the default's
 * threshold, it fetches them too. */
static void test_apo_only_where_geometry_is_coarse(void **state)
{
    fixture *f = *state;
    json_int_t fine, any, coarse;
    run_apo_bytes_total(f, "", "apo-default", &fine);
    run_apo_bytes_total(f, "--apo-min-tolerance 0", "apo-any", &any);
    run_apo_bytes_total(f, "--tolerance 2", "apo-coarse", &coarse);
    print_message("apo bytes along the path: 1 px %lld, 1 px at any tolerance %lld, 2 px %lld\n",
                  (long long)fine, (long long)any, (long long)coarse);
    assert_int_equal(fine, 0);
    assert_true(any > 0);
    assert_true(coarse > 0);
}

/* --shading geometry draws no APO normal, so it fetches no APO byte: at a
 * coarse tolerance, where the cut holds internal cells and APO shading fetches
 * their chunks, geometry shading fetches exactly 0 bytes of them. */
static void test_geometry_shading_fetches_no_apo(void **state)
{
    fixture *f = *state;
    json_int_t apo = run_apo_bytes(f, "--tolerance 12", "coarse-apo");
    json_int_t geometry = run_apo_bytes(f, "--tolerance 12 --shading geometry", "coarse-geometry");
    print_message("apo bytes at 12 px: APO shading %lld, geometry shading %lld\n", (long long)apo,
                  (long long)geometry);
    assert_true(apo > 0);
    assert_int_equal(geometry, 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_help_and_usage_errors),
        cmocka_unit_test(test_streaming_and_local_archive),
        cmocka_unit_test(test_geometry_shading_fetches_no_apo),
        cmocka_unit_test(test_apo_only_where_geometry_is_coarse),
        cmocka_unit_test(test_catalogue_screen),
        cmocka_unit_test(test_catalogue_panel_shows_the_thumbnail),
        cmocka_unit_test(test_catalogue_panel_from_a_server),
        cmocka_unit_test(test_catalogue_draws_on_against_a_silent_server),
        cmocka_unit_test(test_small_on_screen_never_vanishes),
        cmocka_unit_test(test_interactive_until_terminated),
        cmocka_unit_test(test_interactive_from_a_server_lists_once),
        cmocka_unit_test(test_server_gone_mid_stream),
        cmocka_unit_test(test_runtime_errors), /* stops the server: last */
    };
    return cmocka_run_group_tests_name("meshview", tests, group_setup, group_teardown);
}
