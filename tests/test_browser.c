/* The browser client (docs/BROWSER.md): meshserve --web-dir on loopback, the
 * pages of web/ with the WebAssembly module of `make wasm`
 * (build/wasm/site), run in headless Chromium on SwiftShader through
 * tests/browser-page (the DevTools protocol over a pipe):
 *   - the page routes: /, /view/NAME, /web/FILE with the right types, no
 *     file outside the page names, a clear 404 when no web_dir is set;
 *   - the viewer draws the demo model: view complete, the triangles of the
 *     cut, and its silhouette that of meshrender's picture of the same
 *     camera and tolerance (intersection over union >= 0.98); its first
 *     picture came from at most 32 kB of cells beside the index (the first
 *     look);
 *   - the catalogue page lists the models;
 *   - a model that does not exist: the page says so, in state 'error';
 *   - the page files deflated for a reader that accepts it, to the same bytes;
 *   - the page is cross-origin isolated (COOP and COEP) and decodes with
 *     the threaded module;
 *   - a camera that leaves before its cells came: its requests still
 *     waiting for an answer are cancelled (the page's counter), the server
 *     sees fewer than that camera needs, and the page completes at the
 *     next camera;
 *   - the server going away mid-stream (a relay with 150 ms each way, cut
 *     once the first cell is asked for): the page says it cannot reach the
 *     server or that it stopped answering (a request Chromium keeps waiting
 *     on is abandoned after 10 s without a byte), in state 'error', within
 *     20 s of the cut;
 *   - a preview model: without a token the page completes below full
 *     precision with no refused request; with the token (entered as the form
 *     keeps it, sent as Authorization) it reads more;
 *   - mouse and touch (orbit, pan, pinch) by the DevTools protocol's real
 *     input, from meshview's view text in the URL, the text shown back.
 * The cases that need the browser skip, saying why, only when
 * chromium-headless-shell or emscripten is not installed; with emscripten
 * installed a missing module fails (`make test` builds it). */
#include <math.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <zlib.h>
#include <jansson.h>

#include "ms_archive.h"
#include "ms_subtree.h"
#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_delay.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define TOKEN "browser-test-token"
#define PREVIEW_BITS 9
#define WIDTH 320
#define HEIGHT 240

typedef struct fixture {
    char dir[512], archives[600], log[600], port_file[600];
    pid_t server;
    uint16_t port, http_port;
    char why_skip[256]; /* set when the browser cases cannot run */
    size_t index_size;  /* the demo's index blob, bytes */
    size_t head_size;   /* its index head (header and root subtree), bytes */
} fixture;

static int run_or_say(const char *command)
{
    char out[4096];
    int status = ms_test_run(command, out, sizeof out);
    if (status != 0)
        fprintf(stderr, "%s: exit %d: %s\n", command, status, out);
    return status;
}

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    snprintf(f->log, sizeof f->log, "%s/meshserve.log", f->dir);
    snprintf(f->port_file, sizeof f->port_file, "%s/ports", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char meshgen[600], meshbake[600], command[8192];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 && "
             "printf '{\"title\": \"Demo <script>window.pwned = 1</script>\", "
             "\"description\": \"<b>bold</b>\"}' > %s/demo.json && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 "
             "--metadata %s/demo.json && "
             "%s %s/demo.ply -o %s --name preview --min-tris 1500 --no-apo --threads 2 "
             "--public-bits %d",
             meshgen, f->dir, f->dir, meshbake, f->dir, f->archives, f->dir, meshbake, f->dir,
             f->archives, PREVIEW_BITS);
    if (run_or_say(command) != 0)
        return -1;
    char demo[700];
    snprintf(demo, sizeof demo, "%s/demo.msa", f->archives);
    ms_archive *archive;
    ms_error err;
    if (ms_archive_open(demo, &archive, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    (void)ms_archive_index_bytes(archive, &f->index_size);
    (void)ms_archive_index_head(archive, &f->head_size);
    ms_archive_close(archive);
    /* the built site; without it the page files of web/ still answer the
     * routes (the cases that need the module skip or fail below) */
    char config[700], settings[256];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(settings, sizeof settings, "token = " TOKEN "\nweb_dir = %s\n",
             ms_test_browser_web_dir());
    ms_test_write_file(config, settings, strlen(settings));
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    /* with emcc installed, a missing module fails the cases that need it */
    const char *extra[] = {"--config", config, NULL};
    f->server = ms_test_meshserve_start(f->archives, extra, 0, f->port_file, f->log, &f->port,
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
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Opens path (after http://127.0.0.1:PORT) in the browser; the driver's JSON
 * report, the screenshot written to shot. */
static json_t *open_page(const fixture *f, const char *path, const char *shot, const char *token)
{
    char url[1024], arguments[1024];
    snprintf(url, sizeof url, "http://127.0.0.1:%u%s", f->http_port, path);
    snprintf(arguments, sizeof arguments, "--size %dx%d --out %s --timeout 120%s%s", WIDTH, HEIGHT, shot,
             token ? " --token " : "", token ? token : "");
    return ms_test_browser_run(url, arguments);
}

static void test_page_routes(void **state)
{
    fixture *f = *state;
    static const struct {
        const char *path;
        int status;
        const char *type;
    } cases[] = {
        {"/", 200, "text/html; charset=utf-8"},
        {"/view/demo", 200, "text/html; charset=utf-8"},
        {"/view/no-such-model", 200, "text/html; charset=utf-8"}, /* the page says so */
        {"/web/view.js", 200, "text/javascript; charset=utf-8"},
        {"/web/meshstream.css", 200, "text/css; charset=utf-8"},
        {"/web/..%2Fmeshstream.conf", 404, NULL},
        {"/web/.hidden.js", 404, NULL},
        {"/web/notes.txt", 404, NULL},
        {"/web/missing.js", 404, NULL},
        {"/web/a/b.js", 404, NULL},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        ms_test_http_response r;
        assert_int_equal(ms_test_http_get(f->http_port, cases[i].path, NULL, &r), 0);
        if (r.status != cases[i].status)
            fail_msg("%s: %d, wanted %d", cases[i].path, r.status, cases[i].status);
        char type[128] = "";
        ms_test_http_header(&r, "Content-Type", type, sizeof type);
        if (cases[i].type)
            assert_string_equal(type, cases[i].type);
        ms_test_http_free(&r);
    }
    /* a reader that accepts deflate gets the page files deflated, to the
     * same bytes; one that does not, the file as it is */
    {
        ms_test_http_response plain, packed;
        char value[64] = "";
        assert_int_equal(ms_test_http_get(f->http_port, "/web/view.js", NULL, &plain), 0);
        assert_int_equal(plain.status, 200);
        assert_null(ms_test_http_header(&plain, "Content-Encoding", value, sizeof value));
        assert_string_equal(ms_test_http_header(&plain, "Vary", value, sizeof value), "Accept-Encoding");
        assert_int_equal(ms_test_http_get(f->http_port, "/web/view.js",
                                          "Accept-Encoding: gzip, deflate\r\n", &packed), 0);
        assert_int_equal(packed.status, 200);
        assert_string_equal(ms_test_http_header(&packed, "Content-Encoding", value, sizeof value),
                            "deflate");
        assert_true(packed.body_length < plain.body_length / 2);
        uLongf size = (uLongf)plain.body_length + 1;
        uint8_t *inflated = malloc(size);
        assert_non_null(inflated);
        assert_int_equal(uncompress(inflated, &size, packed.body, (uLong)packed.body_length), Z_OK);
        assert_int_equal(size, plain.body_length);
        assert_memory_equal(inflated, plain.body, size);
        free(inflated);
        /* again: the same bytes, from the door's cache (ms_page_cache.h) */
        ms_test_http_response again;
        assert_int_equal(ms_test_http_get(f->http_port, "/web/view.js",
                                          "Accept-Encoding: deflate\r\n", &again), 0);
        assert_int_equal(again.status, 200);
        assert_int_equal(again.body_length, packed.body_length);
        assert_memory_equal(again.body, packed.body, packed.body_length);
        ms_test_http_free(&again);
        ms_test_http_free(&plain);
        ms_test_http_free(&packed);
    }
    /* cross-origin isolation: the pages with the opener and embedder
     * policies, the scripts (the workers') with the embedder's, so that the
     * worker may take the threaded module */
    {
        static const struct {
            const char *path, *opener, *embedder;
        } isolated[] = {
            {"/view/demo", "same-origin", "require-corp"},
            {"/", "same-origin", "require-corp"},
            {"/web/worker.js", NULL, "require-corp"},
            {"/web/meshstream-mt-worker.js", NULL, "require-corp"},
            {"/web/meshstream.css", NULL, NULL},
        };
        for (size_t i = 0; i < sizeof isolated / sizeof *isolated; ++i) {
            ms_test_http_response r;
            char value[64];
            assert_int_equal(ms_test_http_get(f->http_port, isolated[i].path, NULL, &r), 0);
            assert_int_equal(r.status, 200);
            const char *opener = ms_test_http_header(&r, "Cross-Origin-Opener-Policy", value, sizeof value);
            if (isolated[i].opener)
                assert_string_equal(opener, isolated[i].opener);
            else
                assert_null(opener);
            const char *embedder = ms_test_http_header(&r, "Cross-Origin-Embedder-Policy", value, sizeof value);
            if (isolated[i].embedder)
                assert_string_equal(embedder, isolated[i].embedder);
            else
                assert_null(embedder);
            ms_test_http_free(&r);
        }
    }
    /* /view/NAME/: to /view/NAME, where the page's relative paths work */
    {
        ms_test_http_response moved;
        char location[64] = "";
        assert_int_equal(ms_test_http_get(f->http_port, "/view/demo/", NULL, &moved), 0);
        assert_int_equal(moved.status, 301);
        assert_string_equal(ms_test_http_header(&moved, "Location", location, sizeof location),
                            "/view/demo");
        ms_test_http_free(&moved);
    }
    /* the token is never taken from a URL, pages included */
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/view/demo?token=" TOKEN, NULL, &r), 0);
    assert_int_equal(r.status, 400);
    ms_test_http_free(&r);
    /* a server without web_dir says how to serve the pages */
    char log[700], ports[700];
    snprintf(log, sizeof log, "%s/bare.log", f->dir);
    snprintf(ports, sizeof ports, "%s/bare.ports", f->dir);
    uint16_t port, http_port;
    pid_t bare = ms_test_meshserve_start(f->archives, NULL, 0, ports, log, &port, &http_port);
    assert_true(bare > 0);
    assert_int_equal(ms_test_http_get(http_port, "/", NULL, &r), 0);
    assert_int_equal(r.status, 404);
    assert_non_null(strstr((const char *)r.body, "--web-dir"));
    ms_test_http_free(&r);
    assert_int_equal(ms_test_stop(bare, SIGTERM, 10.0), 0);
}

/* The viewer at two cameras of the demo model: the whole sculpture three
 * quarters on, and a close-up where the cut refines the cells in view (190
 * cells). Each: view complete, the very cut meshrender makes for the same
 * camera and tolerance (the same selection code: the same shown cells and
 * triangles), and the same silhouette (IoU >= 0.98). */
static void test_viewer_draws_the_model(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char *const cameras[] = {"0.9,0.6,3.2,0,0,0,0,1,0,40", "0.3,0.2,1.6,0,0,0,0,1,0,40"};
    enum { KEYS = sizeof cameras / sizeof *cameras };
    char ref_dir[700], archive[700];
    snprintf(archive, sizeof archive, "%s/demo.msa", f->archives);
    json_t *ref = ms_test_browser_reference(f->dir, archive, cameras, KEYS, WIDTH, HEIGHT, ref_dir, sizeof ref_dir);
    json_t *frames = json_object_get(ref, "frames");
    for (int k = 0; k < KEYS; ++k) {
        json_t *cut = json_object_get(json_array_get(frames, k), "cut");
        json_int_t ref_triangles = json_integer_value(json_object_get(cut, "triangles"));
        json_int_t ref_cells = json_integer_value(json_object_get(cut, "shown_cells"));
        char shot[700], page[256];
        snprintf(shot, sizeof shot, "%s/view_%d.png", f->dir, k);
        /* culled=2: meshrender's selection (the page's default is the client core's 6) */
        snprintf(page, sizeof page, "/view/demo#cam=%s&tol=1&culled=2&hud=0", cameras[k]);
        json_t *report = open_page(f, page, shot, NULL);
        assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
        assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
        printf("page: %lld triangles in %lld cells, %lld bytes, first pixels at %lld ms, "
               "complete at %lld ms; meshrender's cut: %lld triangles in %lld cells\n",
               (long long)ms_test_browser_page_int(report, "triangles"), (long long)ms_test_browser_page_int(report, "cells"),
               (long long)ms_test_browser_page_int(report, "bytes"), (long long)ms_test_browser_page_int(report, "firstPixelMs"),
               (long long)ms_test_browser_page_int(report, "completeMs"), (long long)ref_triangles,
               (long long)ref_cells);
        assert_int_equal(ms_test_browser_page_int(report, "triangles"), ref_triangles);
        assert_int_equal(ms_test_browser_page_int(report, "cells"), ref_cells);
        /* the page is cross-origin isolated: the worker decodes with the
         * threaded module, on as many threads as the cores allow (1 to 3) */
        json_t *timing = json_object_get(json_object_get(report, "page"), "timing");
        printf("threaded module: %s, %lld threads decoding\n",
               json_is_true(json_object_get(timing, "threaded")) ? "yes" : "no",
               (long long)json_integer_value(json_object_get(timing, "threads")));
        assert_true(json_is_true(json_object_get(timing, "threaded")));
        assert_true(json_integer_value(json_object_get(timing, "threads")) >= 1);
        assert_true(json_integer_value(json_object_get(timing, "threads")) <= 3);
        /* the WebGL context is made once the worker runs and holds the
         * module (creating it holds the page's thread, which the worker's
         * start waits for), or READY_WAIT_MS (400) after boot.js ran */
        const char *gl_after = json_string_value(json_object_get(timing, "glAfter"));
        json_int_t gl_ms = json_integer_value(json_object_get(timing, "glMs"));
        json_int_t alive_ms = json_integer_value(json_object_get(timing, "aliveMs"));
        json_int_t boot_ran = json_integer_value(json_object_get(json_object_get(timing, "boot"), "bootRan"));
        printf("WebGL context at %lld ms, after %s (worker alive at %lld ms, boot.js ran at %lld ms)\n",
               (long long)gl_ms, gl_after ? gl_after : "?", (long long)alive_ms, (long long)boot_ran);
        assert_non_null(gl_after);
        assert_true(gl_ms > 0);
        if (strcmp(gl_after, "worker") == 0) {
            assert_true(alive_ms > 0);
            assert_true(gl_ms >= alive_ms);
        } else {
            assert_string_equal(gl_after, "wait");
            assert_true(gl_ms >= boot_ran + 400);
        }
        /* the first look: the first picture came from at most 32 kB of cells
         * (docs/BROWSER.md), read beside the index, before the view's own;
         * the index by subtree: its head and the subtrees asked for by then,
         * less than the whole index */
        json_int_t first = json_integer_value(json_object_get(timing, "firstMeshBytes"));
        json_int_t first_index = json_integer_value(json_object_get(timing, "firstMeshIndexBytes"));
        printf("first picture after %lld bytes, %lld of them the index's (its head %zu, the whole "
               "index %zu); the index: %lld bytes in all, %lld subtrees\n", (long long)first,
               (long long)first_index, f->head_size, f->index_size,
               (long long)json_integer_value(json_object_get(timing, "indexWireBytes")),
               (long long)json_integer_value(json_object_get(timing, "subtrees")));
        assert_true(json_is_true(json_object_get(timing, "byHead")));
        /* the model's first three requests (catalogue entry, head, root
         * cell) sent by boot.js before the worker's script came: the
         * worker's own were answered by the browser's cache (docs/BROWSER.md,
         * "First pixels"); no APO at 1 px: the worker's APO part never read */
        assert_int_equal(json_integer_value(json_object_get(timing, "warmAnswers")), 3);
        /* the cells came several a request (the side door's cells route) */
        json_int_t cells = json_integer_value(json_object_get(timing, "requests")),
                   batches = json_integer_value(json_object_get(timing, "cellBatches"));
        printf("%lld cells in %lld requests of several\n", (long long)cells, (long long)batches);
        json_t *marks = json_object_get(timing, "marks");
        printf("%lld subtrees in %lld requests of several; early subtrees asked at %lld ms, first mesh at %lld ms\n",
               (long long)json_integer_value(json_object_get(timing, "subtrees")),
               (long long)json_integer_value(json_object_get(timing, "subtreeBatches")),
               (long long)json_integer_value(json_object_get(marks, "early subtrees")),
               (long long)json_integer_value(json_object_get(marks, "mesh")));
        /* the subtrees the camera's own plan wants were asked for before
         * the first look was drawn (docs/BROWSER.md, "First pixels"), and
         * several came in one request (the side door's subtrees route) */
        json_int_t subtrees = json_integer_value(json_object_get(timing, "subtrees"));
        json_t *early = json_object_get(marks, "early subtrees");
        assert_non_null(early);
        assert_true(json_integer_value(early) <= json_integer_value(json_object_get(marks, "mesh")));
        if (subtrees > 1) {
            assert_true(json_integer_value(json_object_get(timing, "subtreeBatches")) >= 1);
            assert_true(json_integer_value(json_object_get(timing, "subtreeBatches")) < subtrees);
        }
        assert_true(batches > 0);
        assert_true(cells > 2 * batches);
        assert_false(json_is_true(json_object_get(timing, "apoLoaded")));
        assert_true(first_index >= (json_int_t)f->head_size);
        assert_true(first_index < (json_int_t)f->index_size);
        assert_true(first > first_index);
        assert_true(first <= first_index + 32768);
        assert_true(first < ms_test_browser_page_int(report, "bytes"));

        char ref_png[800];
        snprintf(ref_png, sizeof ref_png, "%s/frame_%03d.png", ref_dir, k);
        size_t covered, ref_covered;
        double iou = ms_test_silhouette_iou(shot, ref_png, WIDTH, HEIGHT, &covered, &ref_covered);
        printf("silhouette: %zu px covered (meshrender %zu), IoU %.4f\n", covered, ref_covered, iou);
        assert_true(covered > (size_t)WIDTH * HEIGHT / 20);
        assert_true(iou >= 0.98);
        json_decref(report);
    }
    json_decref(ref);
}

static void test_catalogue_page(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char shot[700];
    snprintf(shot, sizeof shot, "%s/catalogue.png", f->dir);
    json_t *report = open_page(f, "/", shot, NULL);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_int_equal(ms_test_browser_page_int(report, "models"), 2);
    assert_string_equal(json_string_value(json_object_get(report, "message")), "2 models");
    /* both thumbnails shown; the sidecar's title is text, not markup: shown as
     * written, and no script element came of it */
    assert_int_equal(ms_test_browser_page_int(report, "thumbnails"), 2);
    json_t *titles = json_object_get(json_object_get(report, "page"), "titles");
    assert_int_equal(json_array_size(titles), 1);
    assert_string_equal(json_string_value(json_array_get(titles, 0)),
                        "Demo <script>window.pwned = 1</script>");
    assert_int_equal(ms_test_browser_page_int(report, "scripts"), 1);
    json_decref(report);
}

static void test_missing_model_says_so(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char shot[700];
    snprintf(shot, sizeof shot, "%s/missing.png", f->dir);
    json_t *report = open_page(f, "/view/no-such-model", shot, NULL);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "error");
    assert_string_equal(json_string_value(json_object_get(report, "message")),
                        "No model named \"no-such-model\" on this server");
    assert_int_equal(ms_test_browser_page_int(report, "triangles"), 0);
    json_decref(report);
}

static double seconds_now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

/* A server (or anything between) whose batch answers do not hold together:
 * the relay raises each answer's count by one, first the subtrees route's,
 * then the cells route's. The page ends in `error` with one line naming the
 * route, and nothing hangs (the close-up asks for several subtrees and
 * several cells at once). */
static void test_malformed_batches(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char *const magic[] = {"MSS1", "MSB1"};
    static const char *const expect[] = {"Subtrees: the server's answer is malformed",
                                         "Cells: the server's answer is malformed"};
    for (int k = 0; k < 2; ++k) {
        ms_test_delay *relay = NULL;
        uint16_t relay_port;
        assert_int_equal(ms_test_delay_start_mangling(f->http_port, 0.0, magic[k], &relay, &relay_port), 0);
        char url[256], arguments[800];
        snprintf(url, sizeof url, "http://127.0.0.1:%u/view/demo#cam=0.15,0.1,0.8,0,0,0,0,1,0,40&hud=0", relay_port);
        snprintf(arguments, sizeof arguments, "--size 320x240 --out %s/malformed-%d.png --timeout 60", f->dir, k);
        json_t *report = ms_test_browser_run(url, arguments);
        ms_test_delay_stop(relay);
        printf("%s answers bent: the page says %s, %s\n", magic[k],
               json_string_value(json_object_get(report, "state")),
               json_string_value(json_object_get(report, "message")));
        assert_string_equal(json_string_value(json_object_get(report, "state")), "error");
        assert_string_equal(json_string_value(json_object_get(report, "message")), expect[k]);
        json_decref(report);
    }
}

static void test_server_gone_mid_stream(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    ms_test_delay *relay = NULL;
    uint16_t relay_port;
    assert_int_equal(ms_test_delay_start(f->http_port, 0.15, &relay, &relay_port), 0);
    uint64_t before = 0;
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_model_requests_total{model=\"demo\"}", &before), 0);
    char url[256], shot[700], log[700];
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/demo#cam=0.3,0.2,1.6,0,0,0,0,1,0,40&hud=0",
             relay_port);
    snprintf(shot, sizeof shot, "%s/gone.png", f->dir);
    snprintf(log, sizeof log, "%s/gone.json", f->dir);
    char *argv[] = {"tests/browser-page", url, "--size", "320x240", "--out", shot, "--timeout", "60",
                    NULL};
    pid_t driver = ms_test_spawn(argv, log);
    assert_true(driver > 0);
    /* the index head and the root cell (asked for by the page's first
     * script, before its other scripts and the module have loaded) and one
     * more request of the model, from the started page: the server goes
     * away */
    double deadline = seconds_now() + 60;
    uint64_t requests = before;
    while (requests < before + 3 && seconds_now() < deadline) {
        usleep(5000);
        assert_int_equal(ms_test_metric(f->http_port, "meshstream_model_requests_total{model=\"demo\"}",
                                        &requests), 0);
    }
    ms_test_delay_stop(relay);
    double cut_at = seconds_now();
    assert_true(requests >= before + 3);
    int status = -1;
    while (seconds_now() < deadline) {
        pid_t done = waitpid(driver, &status, WNOHANG);
        if (done == driver)
            break;
        usleep(20000);
    }
    if (!WIFEXITED(status)) {
        kill(driver, SIGKILL);
        waitpid(driver, &status, 0);
        fail_msg("the browser's driver did not end within 60 s");
    }
    size_t length;
    unsigned char *text = ms_test_read_file(log, &length);
    json_error_t jerr;
    json_t *report = json_loadb((const char *)text, length, 0, &jerr);
    if (!report)
        fail_msg("%s: %.*s", log, (int)length, (const char *)text);
    printf("cut after %llu model requests; the page %.2f s later: %s, %s\n",
           (unsigned long long)(requests - before), seconds_now() - cut_at,
           json_string_value(json_object_get(report, "state")),
           json_string_value(json_object_get(report, "message")));
    assert_int_equal(WEXITSTATUS(status), 0);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "error");
    /* refused (a request after the cut) or silent (one the browser kept
     * waiting on: the worker abandons it after 10 s without a byte) */
    const char *message = json_string_value(json_object_get(report, "message"));
    assert_true(strstr(message, "The server cannot be reached (/models/demo/") == message ||
                strstr(message, "The server stopped answering (/models/demo/") == message);
    assert_true(seconds_now() - cut_at < 20.0);
    json_decref(report);
    free(text);
}

/* The memory budget (#mem=MB): the page walked from the close-up to the
 * whole sculpture and to a close-up of its other side with a budget of 10
 * kB (each close-up's cut about 18 kB) forgets cells (timing.forgottenCells) and completes with the very cut
 * of the same walk without a budget (the same triangles and cells). */
static json_t *walk_page(const fixture *f, const char *mem, const char *name)
{
    static const char near[] = "0.15,0.1,0.8,0,0,0,0,1,0,40", far[] = "0.9,0.6,3.2,0,0,0,0,1,0,40",
                      back[] = "-0.15,0.1,-0.8,0,0,0,0,1,0,40";
    char steps[2048], steps_file[700], command[4096], shot[700];
    snprintf(steps, sizeof steps,
             "[{\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": \"location.hash = 'cam=%s&hud=0%s'\"}},\n"
             " {\"settle\": true},\n"
             " {\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": \"location.hash = 'cam=%s&hud=0%s'\"}},\n"
             " {\"settle\": true}]\n", far, mem, back, mem);
    snprintf(steps_file, sizeof steps_file, "%s/%s-steps.json", f->dir, name);
    ms_test_write_file(steps_file, steps, strlen(steps));
    snprintf(shot, sizeof shot, "%s/%s.png", f->dir, name);
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/demo#cam=%s&hud=0%s' --size %dx%d --out %s "
             "--input %s --timeout 120", f->http_port, near, mem, WIDTH, HEIGHT, shot, steps_file);
    json_t *report = ms_test_run_json(command, 0);
    json_t *seen = json_object_get(report, "steps");
    assert_int_equal(json_array_size(seen), 2);
    return report;
}

static void test_memory_budget(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    json_t *tight = walk_page(f, "&mem=0.01", "budget"), *plain = walk_page(f, "", "no-budget");
    json_t *last = json_object_get(json_array_get(json_object_get(tight, "steps"), 1), "page");
    json_t *last_plain = json_object_get(json_array_get(json_object_get(plain, "steps"), 1), "page");
    json_t *timing = json_object_get(last, "timing");
    json_int_t budget = json_integer_value(json_object_get(timing, "memoryBudget"));
    json_int_t forgotten = json_integer_value(json_object_get(timing, "forgottenCells"));
    double forgotten_bytes = json_number_value(json_object_get(timing, "forgottenBytes"));
    printf("with #mem=0.01: budget %lld bytes, %lld cells and %.0f bytes forgotten; %lld triangles in %lld "
           "cells (without a budget: %lld in %lld)\n", (long long)budget, (long long)forgotten, forgotten_bytes,
           (long long)json_integer_value(json_object_get(last, "triangles")),
           (long long)json_integer_value(json_object_get(last, "cells")),
           (long long)json_integer_value(json_object_get(last_plain, "triangles")),
           (long long)json_integer_value(json_object_get(last_plain, "cells")));
    assert_string_equal(json_string_value(json_object_get(last, "state")), "complete");
    assert_string_equal(json_string_value(json_object_get(last_plain, "state")), "complete");
    assert_int_equal(budget, 10485); /* 0.01 MB */
    assert_true(forgotten > 0);
    assert_true(forgotten_bytes > 0);
    assert_int_equal(json_integer_value(json_object_get(json_object_get(last_plain, "timing"), "forgottenCells")), 0);
    assert_int_equal(json_integer_value(json_object_get(last, "triangles")),
                     json_integer_value(json_object_get(last_plain, "triangles")));
    assert_int_equal(json_integer_value(json_object_get(last, "cells")),
                     json_integer_value(json_object_get(last_plain, "cells")));
    json_decref(tight);
    json_decref(plain);
}

/* A camera that leaves before its cells came: the page reached through a
 * relay with 150 ms each way, complete at the whole sculpture; then the
 * close-up (its plan asks for its cells at once, in requests of up to 16
 * cells, docs/BROWSER.md "The cells route"), and 0.15 s later (half the
 * relay's round trip: none of them answered yet) the whole
 * sculpture again. The close-up's requests still waiting for their answer
 * are cancelled (the page's counter: their cells), the server sees fewer
 * requests than the close-up has cells (as the close-up alone, cold, asks
 * for them: its own page's counter), and the page completes at the
 * sculpture. */
static void test_camera_change_cancels(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char far[] = "0.9,0.6,3.2,0,0,0,0,1,0,40", near[] = "0.3,0.2,1.6,0,0,0,0,1,0,40";
    char page[256], shot[700];
    /* what the close-up asks for, cold: its requests */
    snprintf(page, sizeof page, "/view/demo#cam=%s&hud=0", near);
    snprintf(shot, sizeof shot, "%s/near.png", f->dir);
    json_t *alone = open_page(f, page, shot, NULL);
    assert_string_equal(json_string_value(json_object_get(alone, "state")), "complete");
    json_int_t near_requests = json_integer_value(
        json_object_get(json_object_get(json_object_get(alone, "page"), "timing"), "requests"));
    json_decref(alone);

    ms_test_delay *relay = NULL;
    uint16_t relay_port;
    assert_int_equal(ms_test_delay_start(f->http_port, 0.15, &relay, &relay_port), 0);
    char steps[2048], steps_file[700], command[4096];
    snprintf(steps, sizeof steps,
             "[{\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": \"location.hash = 'cam=%s&hud=0'\"}},\n"
             " {\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": \"new Promise(r => setTimeout(r, 150))\", \"awaitPromise\": true}},\n"
             " {\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": \"location.hash = 'cam=%s&hud=0'\"}},\n"
             " {\"settle\": true}]\n", near, far);
    snprintf(steps_file, sizeof steps_file, "%s/cancel-steps.json", f->dir);
    ms_test_write_file(steps_file, steps, strlen(steps));
    uint64_t before = 0, after = 0;
    snprintf(shot, sizeof shot, "%s/cancel.png", f->dir);
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/demo#cam=%s&hud=0' --size %dx%d --out %s "
             "--input %s --timeout 120", relay_port, far, WIDTH, HEIGHT, shot, steps_file);
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_model_requests_total{model=\"demo\"}", &before), 0);
    json_t *report = ms_test_run_json(command, 0);
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_model_requests_total{model=\"demo\"}", &after), 0);
    ms_test_delay_stop(relay);
    json_t *steps_seen = json_object_get(report, "steps");
    assert_int_equal(json_array_size(steps_seen), 1);
    json_t *last = json_object_get(json_array_get(steps_seen, 0), "page");
    json_t *timing = json_object_get(last, "timing");
    json_int_t cancelled = json_integer_value(json_object_get(timing, "cancelled"));
    json_int_t answered = json_integer_value(json_object_get(timing, "requests"));
    printf("the close-up alone: %lld requests; with the camera gone after 0.15 s: %lld cancelled, %lld "
           "answered in all, the server saw %llu model requests (catalogue and index included)\n",
           (long long)near_requests, (long long)cancelled, (long long)answered,
           (unsigned long long)(after - before));
    assert_string_equal(json_string_value(json_object_get(last, "state")), "complete");
    assert_true(cancelled >= 10);
    assert_true(near_requests >= 20);
    /* the server saw the catalogue, the index, the sculpture's cells and
     * what of the close-up's had gone out: fewer than the close-up's alone
     * and the answered ones (the sculpture's among them) */
    assert_true(after - before < (uint64_t)(near_requests + answered));
    json_decref(report);
}

static uint64_t forbidden(const fixture *f)
{
    uint64_t n = 0;
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_forbidden_total{door=\"http\"}", &n), 0);
    return n;
}

static void test_preview_and_token(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    /* close to the surface: a camera that wants more than the preview */
    static const char page[] = "/view/preview#cam=0.15,0.1,0.8,0,0,0,0,1,0,40&tol=1&hud=0";
    char shot[700];
    snprintf(shot, sizeof shot, "%s/preview.png", f->dir);
    uint64_t refused = forbidden(f);
    json_t *anonymous = open_page(f, page, shot, NULL);
    assert_string_equal(json_string_value(json_object_get(anonymous, "state")), "complete");
    assert_int_equal(forbidden(f), refused); /* it asked for nothing past the preview */
    snprintf(shot, sizeof shot, "%s/full.png", f->dir);
    json_t *full = open_page(f, page, shot, TOKEN);
    assert_string_equal(json_string_value(json_object_get(full, "state")), "complete");
    assert_int_equal(forbidden(f), refused);
    json_int_t a = ms_test_browser_page_int(anonymous, "bits"), b = ms_test_browser_page_int(full, "bits");
    printf("preview: cells up to %lld bits, %lld triangles, %lld bytes; with the token: %lld "
           "bits, %lld triangles, %lld bytes\n",
           (long long)a, (long long)ms_test_browser_page_int(anonymous, "triangles"),
           (long long)ms_test_browser_page_int(anonymous, "bytes"), (long long)b,
           (long long)ms_test_browser_page_int(full, "triangles"), (long long)ms_test_browser_page_int(full, "bytes"));
    assert_true(ms_test_browser_page_int(anonymous, "triangles") > 0);
    assert_int_equal(a, PREVIEW_BITS);
    assert_true(b > PREVIEW_BITS);
    assert_non_null(strstr(json_string_value(json_object_get(anonymous, "message")),
                           "a token gives more"));
    assert_null(strstr(json_string_value(json_object_get(full, "message")), "a token gives more"));
    json_decref(anonymous);
    json_decref(full);
}

/* Mouse and touch through the DevTools protocol's real input: a drag orbits
 * (meshview's pi per canvas height), a right drag pans (a pixel a pixel at
 * the target's depth), a two-finger spread zooms; the page starts at
 * meshview's view text (#view=mv1:...), shows the text of its camera (the
 * same text back), and rewrites its URL's #cam= as the camera moves. */
static void test_controls_and_view_text(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char steps[] =
        "[{\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mousePressed\", \"x\": 160, \"y\": 120, \"button\": \"left\", \"buttons\": 1, \"clickCount\": 1}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseMoved\", \"x\": 200, \"y\": 120, \"button\": \"left\", \"buttons\": 1}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseReleased\", \"x\": 200, \"y\": 120, \"button\": \"left\", \"buttons\": 0, \"clickCount\": 1}},\n"
        " {\"settle\": true},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mousePressed\", \"x\": 160, \"y\": 120, \"button\": \"right\", \"buttons\": 2, \"clickCount\": 1}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseMoved\", \"x\": 160, \"y\": 144, \"button\": \"right\", \"buttons\": 2}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseReleased\", \"x\": 160, \"y\": 144, \"button\": \"right\", \"buttons\": 0, \"clickCount\": 1}},\n"
        " {\"settle\": true},\n"
        " {\"method\": \"Input.dispatchTouchEvent\", \"params\": {\"type\": \"touchStart\", \"touchPoints\": [{\"x\": 140, \"y\": 120, \"id\": 1}, {\"x\": 180, \"y\": 120, \"id\": 2}]}},\n"
        " {\"method\": \"Input.dispatchTouchEvent\", \"params\": {\"type\": \"touchMove\", \"touchPoints\": [{\"x\": 120, \"y\": 120, \"id\": 1}, {\"x\": 200, \"y\": 120, \"id\": 2}]}},\n"
        " {\"method\": \"Input.dispatchTouchEvent\", \"params\": {\"type\": \"touchEnd\", \"touchPoints\": []}},\n"
        " {\"settle\": true}]\n";
    char steps_file[700], shot[700], command[4096];
    snprintf(steps_file, sizeof steps_file, "%s/steps.json", f->dir);
    ms_test_write_file(steps_file, steps, strlen(steps));
    snprintf(shot, sizeof shot, "%s/controls.png", f->dir);
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/demo#view=mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y&hud=0' "
             "--size %dx%d --out %s --input %s --timeout 120",
             f->http_port, WIDTH, HEIGHT, shot, steps_file);
    json_t *report = ms_test_run_json(command, 0);
    json_t *page = json_object_get(report, "page");
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_string_equal(json_string_value(json_object_get(page, "view")),
                        "mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y");
    assert_true(json_real_value(json_object_get(page, "progress")) == 1.0 ||
                json_integer_value(json_object_get(page, "progress")) == 1);
    json_t *after = json_object_get(report, "steps");
    assert_int_equal(json_array_size(after), 3);
    double t[3][3], d[3], yaw[3], pitch[3];
    for (int k = 0; k < 3; ++k) {
        json_t *step = json_array_get(after, (size_t)k);
        const char *view = json_string_value(json_object_get(json_object_get(step, "page"), "view"));
        const char *hash = json_string_value(json_object_get(step, "hash"));
        printf("after step %d: %s, URL #%s\n", k, view, hash + 1);
        assert_string_equal(json_string_value(json_object_get(json_object_get(step, "page"), "state")),
                            "complete");
        assert_int_equal(sscanf(view, "mv1:t=%lf,%lf,%lf:d=%lf:o=%lf,%lf:f=40:u=y", &t[k][0], &t[k][1],
                                &t[k][2], &d[k], &yaw[k], &pitch[k]), 6);
        assert_non_null(strstr(hash, "cam="));
        assert_null(strstr(hash, "view="));
    }
    const double pi = 3.14159265358979323846;
    /* 40 px right: the yaw turns by 40 pi / 240; nothing else moves */
    assert_true(fabs(yaw[0] - (0.35 + 40 * pi / 240)) < 1e-9);
    assert_true(fabs(pitch[0] + 0.2) < 1e-9 && fabs(d[0] - 3.4) < 1e-9);
    assert_true(fabs(t[0][0]) < 1e-12 && fabs(t[0][1]) < 1e-12 && fabs(t[0][2]) < 1e-12);
    /* 24 px down with the right button: the target rises along the camera's
     * up by 24 pixels at its depth (2 d tan(20 deg) / 240 a pixel) */
    double rise = 24 * 2 * 3.4 * tan(20 * pi / 180) / 240;
    assert_true(fabs(t[1][1] - rise * cos(0.2)) < 1e-9);
    assert_true(fabs(d[1] - 3.4) < 1e-9 && fabs(yaw[1] - yaw[0]) < 1e-12);
    /* two fingers from 40 px apart to 80: half the distance */
    assert_true(fabs(d[2] - 1.7) < 1e-9 && fabs(yaw[2] - yaw[0]) < 1e-12);
    json_decref(report);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_page_routes),
        cmocka_unit_test(test_viewer_draws_the_model),
        cmocka_unit_test(test_catalogue_page),
        cmocka_unit_test(test_missing_model_says_so),
        cmocka_unit_test(test_malformed_batches),
        cmocka_unit_test(test_server_gone_mid_stream),
        cmocka_unit_test(test_camera_change_cancels),
        cmocka_unit_test(test_memory_budget),
        cmocka_unit_test(test_preview_and_token),
        cmocka_unit_test(test_controls_and_view_text),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
