/* The page's shading modes against meshview's (docs/BROWSER.md, "Drawing"
 * and "APO"): the page draws with meshview's own shaders (client/view/
 * shaders, made GLSL ES 3.00 by web/es_shaders.py), cell by cell. The demo
 * model at two keyframes of scripts/paths/demo-closeup.cam, the page in
 * headless Chromium (#shading=, its #cam= moved keyframe by keyframe) and
 * meshview's scripted pictures of the same path, same size and tolerance,
 * both from one meshserve:
 *   - normals and cells (baked without APO): view complete in both with the
 *     same triangles, no console error, silhouette IoU >= 0.98, PSNR >= the
 *     bars below;
 *   - apo (baked with APO, a coarse tolerance): the same, with exactly
 *     meshview's APO bytes at each keyframe, and nearer meshview's picture
 *     than the page's geometry shading, which fetches no chunk;
 *   - a preview model without a token: every chunk drawn holds no level
 *     beyond the preview rule (ms_archive_preview_apo_levels) and the
 *     server refused nothing (its forbidden counter); with the token the
 *     root's chunk has the levels the preview withheld;
 *   - a shading the page does not know ends in state error with its line;
 *   - the site's shaders.js holds nothing GLSL ES 3.00 lacks, and
 *     web/es_shaders.py stops, naming the file, on a native text it does
 *     not expect.
 * Skips, saying why, without chromium-headless-shell or emscripten; needs
 * an X display for meshview (Xvfb, ms_test_display). */
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_archive.h"
#include "ms_preview.h"
#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define WIDTH 320
#define HEIGHT 240
#define KEYS 2

/* Keyframes 0 and 8 of scripts/paths/demo-closeup.cam: the whole sculpture
 * (few cells) and the carved relief (many). */
static const char *const KEYFRAMES[KEYS] = {
    "3.5 0.5 0.4 0.6 0 0.1 0 0 1 40",
    "0.95 0.1 0.2 0.6 0 0.1 0 0 1 30",
};

/* The PSNR bars (dB), measured (2026-12-06, docs/BROWSER.md "Drawing"):
 * the page against meshview, same mode, 49.46 and 63.36 (normals), 49.96 and
 * 52.84 (cells) at the two keyframes; a mode mistaken for another (the
 * page's lit, cells or APO picture against meshview's normals or cells)
 * 12.5 to 20.6. 40 dB passes the first with 9.5 dB to spare for SwiftShader
 * against llvmpipe (meshview also packs normals into 10 bits a component and
 * splits them at creases; the page keeps the decoder's float normals) and
 * refuses the second by 19 dB. */
#define NORMALS_PSNR_MIN 40.0
#define CELLS_PSNR_MIN 40.0
/* APO, at a coarse tolerance: measured 45.98 and 63.03 dB; the page's
 * geometry shading of the same cameras 43.57 and 53.34 against the same
 * pictures, so the test also requires the APO picture to be the nearer. */
#define APO_PSNR_MIN 35.0
/* APO is drawn where the cut shows cells with a chunk (internal cells: a
 * leaf renders the input itself): a coarse tolerance, in pixels (meshview's
 * --tolerance with APO: the geometry of the cells with a chunk; the others
 * refine to 1 px, as the page does). */
#define APO_TOLERANCE 8
#define TOKEN "modes-test-token"
/* The preview model's public bits: coarse enough that the rule withholds
 * levels of the root's chunk that the overview's footprint wants. */
#define PREVIEW_BITS 5

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600];
    pid_t server;
    uint16_t port, http_port;
    char why_skip[256];
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
    *state = f;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char meshgen[600], meshbake[600], command[8192], out[4096];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 && "
             "%s %s/demo.ply -o %s --name apo --min-tris 1500 --threads 2 && "
             "%s %s/demo.ply -o %s --name apopreview --min-tris 1500 --threads 2 --public-bits %d",
             meshgen, f->dir, meshbake, f->dir, f->archives, meshbake, f->dir, f->archives, meshbake, f->dir,
             f->archives, PREVIEW_BITS);
    if (ms_test_run(command, out, sizeof out) != 0) {
        fprintf(stderr, "%s: %s\n", command, out);
        return -1;
    }
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    char config[700], settings[700], ports[700], log[700];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(settings, sizeof settings, "token = " TOKEN "\nweb_dir = %s\n", ms_test_browser_web_dir());
    ms_test_write_file(config, settings, strlen(settings));
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    const char *extra[] = {"--config", config, NULL};
    f->server = ms_test_meshserve_start(f->archives, extra, 0, ports, log, &f->port, &f->http_port);
    return f->server ? 0 : -1;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    if (!f)
        return 0;
    if (f->server)
        ms_test_stop(f->server, SIGTERM, 10.0);
    ms_test_rmdir(f->dir);
    ms_test_display_stop(&f->display);
    free(f);
    return 0;
}

/* IoU of the silhouettes and PSNR (dB, all three channels) of two pictures
 * of WIDTH x HEIGHT. */
static void compare(const char *a_path, const char *b_path, double *iou, double *psnr)
{
    size_t covered, ref_covered;
    *iou = ms_test_silhouette_iou(a_path, b_path, WIDTH, HEIGHT, &covered, &ref_covered);
    *psnr = ms_test_png_psnr(a_path, b_path, WIDTH, HEIGHT);
}

/* One mode along the two keyframes: meshview's pictures and the page's. */
static json_t *mode_against_meshview(fixture *f, const char *model, const char *mode, int tolerance, double psnr_min)
{
    char path_file[700], text[1024], command[4096], meshview[600];
    size_t used = (size_t)snprintf(text, sizeof text, "meshstream-camera-path 1\n");
    for (int k = 0; k < KEYS; ++k)
        used += (size_t)snprintf(text + used, sizeof text - used, "%d %s\n", k, KEYFRAMES[k]);
    snprintf(path_file, sizeof path_file, "%s/closeup.cam", f->dir);
    ms_test_write_file(path_file, text, used);
    ms_test_bin_path(meshview, sizeof meshview, "meshview");
    snprintf(command, sizeof command,
             "%s --server 127.0.0.1:%u --model %s --path %s --size %dx%d --screenshot-dir %s/mv-%s "
             "--shading %s --tolerance %d --frames 1 --json",
             meshview, f->port, model, path_file, WIDTH, HEIGHT, f->dir, mode, mode, tolerance);
    json_t *mv = ms_test_run_json(command, 0);
    json_t *mv_keys = json_object_get(mv, "keyframes");
    assert_int_equal(json_array_size(mv_keys), KEYS);
    char first[256];
    snprintf(first, sizeof first, "%s", KEYFRAMES[0]);
    for (char *c = first; *c; ++c)
        *c = *c == ' ' ? ',' : *c;
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/%s#cam=%s&tol=%d&hud=0&shading=%s' --size %dx%d "
             "--out %s/page-%s.png --keyframes %s --timeout 120",
             f->http_port, model, first, tolerance, mode, WIDTH, HEIGHT, f->dir, mode, path_file);
    json_t *page = ms_test_run_json(command, 0);
    json_t *page_keys = json_object_get(page, "keyframes");
    assert_int_equal(json_array_size(page_keys), KEYS);
    assert_int_equal(json_array_size(json_object_get(page, "console")), 0);
    for (int k = 0; k < KEYS; ++k) {
        json_t *p = json_array_get(page_keys, (size_t)k), *m = json_array_get(mv_keys, (size_t)k);
        char shot[700], ref[700];
        snprintf(shot, sizeof shot, "%s/page-%s-%02d.png", f->dir, mode, k);
        snprintf(ref, sizeof ref, "%s/mv-%s/keyframe-%02d.png", f->dir, mode, k);
        double iou, psnr;
        compare(shot, ref, &iou, &psnr);
        json_t *timing = json_object_get(p, "timing");
        printf("%s %s, keyframe %d: page %s, %lld triangles in %lld cells, APO %lld bytes; meshview complete %s, "
               "%lld triangles, APO %lld bytes; IoU %.4f, PSNR %.2f dB\n",
               model, mode, k, json_string_value(json_object_get(p, "state")),
               (long long)json_integer_value(json_object_get(p, "triangles")),
               (long long)json_integer_value(json_object_get(p, "cells")),
               (long long)json_integer_value(json_object_get(timing, "apoBytes")),
               json_is_true(json_object_get(m, "complete")) ? "yes" : "no",
               (long long)json_integer_value(json_object_get(m, "triangles_drawn")),
               (long long)json_integer_value(json_object_get(m, "apo_bytes")), iou, psnr);
        assert_string_equal(json_string_value(json_object_get(p, "state")), "complete");
        assert_true(json_is_true(json_object_get(m, "complete")));
        assert_int_equal(json_integer_value(json_object_get(p, "triangles")),
                         json_integer_value(json_object_get(m, "triangles_drawn")));
        /* the chunks meshview fetched, byte for byte (both count from the start) */
        assert_int_equal(json_integer_value(json_object_get(timing, "apoBytes")),
                         json_integer_value(json_object_get(m, "apo_bytes")));
        assert_true(iou >= 0.98);
        assert_true(psnr >= psnr_min);
    }
    json_decref(mv);
    return page;
}

/* NORMALS: the smooth normal as a colour, (n + 1) / 2, unlit. */
static void test_normals_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    json_decref(mode_against_meshview(f, "demo", "normals", 1, NORMALS_PSNR_MIN));
}

/* CELLS: lit, each cell's albedo the tint of its number. */
static void test_cells_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    json_decref(mode_against_meshview(f, "demo", "cells", 1, CELLS_PSNR_MIN));
}

static uint64_t forbidden(const fixture *f)
{
    uint64_t n = 0;
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_forbidden_total{door=\"http\"}", &n), 0);
    return n;
}

/* The page's APO figure `key` at its last keyframe (window.meshstream.timing). */
static json_int_t page_timing(json_t *report, const char *key)
{
    json_t *keys = json_object_get(report, "keyframes"), *last = json_array_get(keys, json_array_size(keys) - 1);
    json_t *timing = json_object_get(last ? last : report, "timing");
    if (!timing)
        timing = json_object_get(json_object_get(report, "page"), "timing");
    return json_integer_value(json_object_get(timing, key));
}

/* APO (meshview's default --shading apo): the chunks fetched through the
 * side door and drawn from the 2D integer texture, against meshview's APO
 * pictures; APO bytes came. */
static void test_apo_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    json_t *page = mode_against_meshview(f, "apo", "apo", APO_TOLERANCE, APO_PSNR_MIN);
    printf("page: %lld APO requests, %lld APO bytes\n", (long long)page_timing(page, "apoRequests"),
           (long long)page_timing(page, "apoBytes"));
    assert_true(page_timing(page, "apoRequests") > 0);
    assert_true(page_timing(page, "apoBytes") > 0);
    /* its part of the worker (worker-apo.js) read once a camera wanted APO */
    json_t *keys = json_object_get(page, "keyframes");
    assert_true(json_is_true(json_object_get(
        json_object_get(json_array_get(keys, json_array_size(keys) - 1), "timing"), "apoLoaded")));
    /* the APO mode is what brings the page to meshview's APO picture: the
     * page's geometry shading of the same cameras (no chunk fetched, and so
     * every cell refined to the tolerance, not only those with a chunk) is
     * further from it */
    char first[256], command[4096];
    snprintf(first, sizeof first, "%s", KEYFRAMES[0]);
    for (char *c = first; *c; ++c)
        *c = *c == ' ' ? ',' : *c;
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/apo#cam=%s&tol=%d&hud=0&shading=geometry' "
             "--size %dx%d --out %s/page-geometry.png --keyframes %s/closeup.cam --timeout 120",
             f->http_port, first, APO_TOLERANCE, WIDTH, HEIGHT, f->dir, f->dir);
    json_t *plain = ms_test_run_json(command, 0);
    assert_int_equal(json_array_size(json_object_get(plain, "keyframes")), KEYS);
    for (int k = 0; k < KEYS; ++k) {
        char shot[700], apo_shot[700], ref[700];
        snprintf(shot, sizeof shot, "%s/page-geometry-%02d.png", f->dir, k);
        snprintf(apo_shot, sizeof apo_shot, "%s/page-apo-%02d.png", f->dir, k);
        snprintf(ref, sizeof ref, "%s/mv-apo/keyframe-%02d.png", f->dir, k);
        double iou, psnr_plain, psnr_apo;
        compare(shot, ref, &iou, &psnr_plain);
        compare(apo_shot, ref, &iou, &psnr_apo);
        json_t *timing = json_object_get(json_array_get(json_object_get(plain, "keyframes"), (size_t)k), "timing");
        printf("keyframe %d against meshview's APO picture: the page's APO %.2f dB, its geometry shading "
               "%.2f dB (%lld APO bytes)\n", k, psnr_apo, psnr_plain,
               (long long)json_integer_value(json_object_get(timing, "apoBytes")));
        assert_int_equal(json_integer_value(json_object_get(timing, "apoBytes")), 0); /* geometry: none fetched */
        assert_false(json_is_true(json_object_get(timing, "apoLoaded")));             /* nor its script */
        assert_true(psnr_apo > psnr_plain);
    }
    json_decref(plain);
    json_decref(page);
}

/* The levels of each chunk the page drew (window.meshstream.apo.levels, by
 * cell) within what the rule allows: the preview's
 * (ms_archive_preview_apo_levels at PREVIEW_BITS) or, with the token, the
 * chunk's own. Returns the cells; *beyond: those holding more levels than the
 * preview allows. */
static size_t check_levels(const fixture *f, json_t *report, bool preview, size_t *beyond)
{
    char path[700];
    snprintf(path, sizeof path, "%s/apopreview.msa", f->archives);
    ms_archive *archive;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &archive, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(archive);
    json_t *levels = json_object_get(json_object_get(json_object_get(report, "page"), "apo"), "levels");
    const char *key;
    json_t *value;
    size_t cells = 0;
    *beyond = 0;
    json_object_foreach(levels, key, value) {
        const ms_archive_cell *rec = ms_archive_get_cell(archive, (uint32_t)strtoul(key, NULL, 10));
        assert_non_null(rec);
        unsigned rule = ms_archive_preview_apo_levels(h, rec, PREVIEW_BITS + 1);
        json_int_t got = json_integer_value(value);
        assert_true(got >= 1 && got <= rec->apo_levels);
        if (preview)
            assert_true(got <= (json_int_t)rule);
        *beyond += got > (json_int_t)rule;
        printf("  cell %s (level %u): %lld of its %u levels, the preview's rule %u\n", key, (unsigned)rec->level,
               (long long)got, (unsigned)rec->apo_levels, rule);
        cells++;
    }
    ms_archive_close(archive);
    return cells;
}

/* A preview model without a token: the page asks for no APO level beyond
 * the preview (the server refuses any: its forbidden counter stays; every
 * chunk drawn within the rule), and with the token it takes the levels the
 * preview withheld. */
static void test_apo_preview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char url[512], arguments[900];
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/apopreview#cam=%s&tol=%d&hud=0", f->http_port,
             "3.5,0.5,0.4,0.6,0,0.1,0,0,1,40", APO_TOLERANCE);
    uint64_t refused = forbidden(f);
    snprintf(arguments, sizeof arguments, "--size %dx%d --out %s/preview.png --timeout 120", WIDTH, HEIGHT, f->dir);
    json_t *anonymous = ms_test_browser_run(url, arguments);
    assert_string_equal(json_string_value(json_object_get(anonymous, "state")), "complete");
    assert_int_equal(forbidden(f), refused);
    snprintf(arguments, sizeof arguments, "--size %dx%d --out %s/preview-token.png --timeout 120 --token " TOKEN,
             WIDTH, HEIGHT, f->dir);
    json_t *full = ms_test_browser_run(url, arguments);
    assert_string_equal(json_string_value(json_object_get(full, "state")), "complete");
    assert_int_equal(forbidden(f), refused);
    size_t beyond_a, beyond_b;
    size_t a = check_levels(f, anonymous, true, &beyond_a), b = check_levels(f, full, false, &beyond_b);
    printf("preview: %zu chunks, %lld APO bytes in %lld requests; with the token %zu chunks (%zu beyond the "
           "preview's levels), %lld bytes in %lld\n", a, (long long)page_timing(anonymous, "apoBytes"),
           (long long)page_timing(anonymous, "apoRequests"), b, beyond_b, (long long)page_timing(full, "apoBytes"),
           (long long)page_timing(full, "apoRequests"));
    assert_true(a > 0);
    assert_int_equal(beyond_a, 0);
    assert_true(beyond_b > 0);
    json_decref(anonymous);
    json_decref(full);
}

/* The ES variant is made from meshview's shader files (web/es_shaders.py):
 * the site's shaders.js holds none of what GLSL ES 3.00 lacks, and a native
 * text the port does not expect stops the build with one line naming it. */
static void test_es_shaders(void **state)
{
    fixture *f = *state;
    size_t size;
    unsigned char *bytes = ms_test_read_file(MS_TEST_SITE "/shaders.js", &size);
    if (!bytes) {
        MS_TEST_NEED_BROWSER(f->why_skip); /* no site: skipped or failed there */
        fail_msg("no " MS_TEST_SITE "/shaders.js");
    }
    char *js = malloc(size + 1);
    assert_non_null(js);
    memcpy(js, bytes, size);
    js[size] = '\0';
    free(bytes);
    assert_non_null(strstr(js, "#version 300 es"));
    assert_null(strstr(js, "#version 410"));
    assert_null(strstr(js, "usamplerBuffer"));
    assert_null(strstr(js, "texelFetch(apo_words, word"));
    assert_null(strstr(js, "bitCount("));
    /* sections by discard in the fragment stage (the vertex stage's clip
     * distances stay in its MS_SECTIONS block, which the page never defines) */
    assert_non_null(strstr(js, "if (k < section_count && dot(section_plane[k].xyz, FRAG_CELL) + "
                               "section_plane[k].w < 0.0)"));
    assert_non_null(strstr(js, "apo_word(internal ? word + 1 : word)"));
    free(js);
    char command[4096], out[4096];
    snprintf(command, sizeof command,
             "mkdir -p %s/glsl && cp client/view/shaders/cell.vert.glsl client/view/shaders/apo.glsl %s/glsl/ && "
             "sed 's/#version 410 core/#version 450 core/' client/view/shaders/cell.frag.glsl > %s/glsl/cell.frag.glsl && "
             "python3 web/es_shaders.py %s/glsl/out.js %s/glsl 2>&1",
             f->dir, f->dir, f->dir, f->dir, f->dir);
    assert_int_not_equal(ms_test_run(command, out, sizeof out), 0);
    printf("%s", out);
    assert_non_null(strstr(out, "es_shaders.py: cell.frag.glsl: '#version 410 core\\n' found 0 times, expected 1 "
                                "(has the native shader changed?)"));
}

static void test_unknown_shading(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char url[256], arguments[900];
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/demo#shading=apo-ish", f->http_port);
    snprintf(arguments, sizeof arguments, "--size %dx%d --out %s/bad.png --timeout 60", WIDTH, HEIGHT, f->dir);
    json_t *report = ms_test_browser_run(url, arguments);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "error");
    assert_string_equal(json_string_value(json_object_get(report, "message")),
                        "The shading in the URL is not one of apo, geometry, normals, cells (#shading=MODE).");
    json_decref(report);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_normals_against_meshview),
        cmocka_unit_test(test_cells_against_meshview),
        cmocka_unit_test(test_apo_against_meshview),
        cmocka_unit_test(test_apo_preview),
        cmocka_unit_test(test_unknown_shading),
        cmocka_unit_test(test_es_shaders),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
