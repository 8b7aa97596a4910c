/* The Draco page (docs/BROWSER.md, "The Draco page"): /web/draco.html of
 * build/wasm/site downloads a model's whole Draco file from meshserve
 * (/models/NAME/draco) and decodes it with Draco's own WebAssembly decoder
 * (npm draco3d, which make wasm copies beside the pages), run in headless
 * Chromium on SwiftShader through tests/browser-page:
 *   - the demo model (20,172 triangles; its .drc from Debian's draco_encoder
 *     -qp 16 -cl 7, as the benchmarks write it) at two cameras: state
 *     'complete', exactly the Draco file's triangles (as draco_decoder reads
 *     them) and bytes, and the silhouette of meshrender's picture of the same
 *     camera (tolerance 1 px): IoU >= 0.98;
 *   - a model with no Draco file, a preview model without a token (the whole
 *     file needs full access) and a URL without a model: state 'error' with
 *     its one line; the preview with the token completes;
 *   - a site without Draco's decoder: state 'error' naming what is missing.
 * Skips, saying which, when chromium-headless-shell, Debian's draco tools,
 * emscripten (so no build/wasm/site) or npm draco3d (its decoder not in the
 * site: scripts/install-deps, then make wasm) is missing. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define TOKEN "draco-test-token"
#define WIDTH 320
#define HEIGHT 240

typedef struct fixture {
    char dir[512], archives[600];
    pid_t server;
    uint16_t port, http_port;
    long long drc_triangles, drc_bytes; /* the demo's Draco file, as draco_decoder reads it */
    char why_skip[256];
} fixture;

static int exists(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0;
}

static int run_or_say(const char *command, char *out, size_t size)
{
    int status = ms_test_run(command, out, size);
    if (status != 0)
        fprintf(stderr, "%s: exit %d: %s\n", command, status, out);
    return status;
}

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    *state = f;
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    if (!f->why_skip[0]) { /* and what the Draco page needs besides */
        if (!ms_test_have_program("draco_encoder") || !ms_test_have_program("draco_decoder"))
            snprintf(f->why_skip, sizeof f->why_skip,
                     "Debian's draco (draco_encoder, draco_decoder) is not installed (scripts/install-deps)");
        else if (!exists(MS_TEST_SITE "/draco.html"))
            snprintf(f->why_skip, sizeof f->why_skip,
                     "no " MS_TEST_SITE "/draco.html (emscripten missing? scripts/install-deps, then make wasm)");
        else if (!exists(MS_TEST_SITE "/draco_decoder_nodejs.js") || !exists(MS_TEST_SITE "/draco_decoder.wasm"))
            snprintf(f->why_skip, sizeof f->why_skip,
                     "npm draco3d's decoder is not in " MS_TEST_SITE " (scripts/install-deps, then make wasm)");
    }
    if (f->why_skip[0])
        return 0;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char meshgen[600], meshbake[600], command[16384], out[4096];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    /* demo and preview with their Draco files; nodraco without one */
    const char *d = f->dir, *a = f->archives;
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 >/dev/null && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 >/dev/null && "
             "%s %s/demo.ply -o %s --name preview --min-tris 1500 --no-apo --threads 2 "
             "--public-bits 9 >/dev/null && "
             "%s %s/demo.ply -o %s --name nodraco --min-tris 1500 --no-apo --threads 2 >/dev/null && "
             "draco_encoder -i %s/demo.ply -o %s/demo.drc -qp 16 -cl 7 >/dev/null && "
             "cp %s/demo.drc %s/preview.drc && "
             "draco_decoder -i %s/demo.drc -o %s/decoded.ply >/dev/null && "
             "head -c 1000 %s/decoded.ply | grep -a -m1 '^element face' | cut -d' ' -f3 && "
             "stat -c %%s %s/demo.drc",
             meshgen, d, meshbake, d, a, meshbake, d, a, meshbake, d, a, d, a, a, a, a, d, d, a);
    if (run_or_say(command, out, sizeof out) != 0 ||
        sscanf(out, "%lld %lld", &f->drc_triangles, &f->drc_bytes) != 2)
        return -1;
    printf("the demo's Draco file: %lld triangles, %lld bytes\n", f->drc_triangles, f->drc_bytes);
    char config[700], settings[256], log[700], ports[700];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    snprintf(settings, sizeof settings, "token = " TOKEN "\nweb_dir = " MS_TEST_SITE "\n");
    ms_test_write_file(config, settings, strlen(settings));
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
    if (f->dir[0])
        ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Opens path on the server at http_port in the browser: the driver's report. */
static json_t *open_page(uint16_t http_port, const char *path, const char *shot, const char *token)
{
    char command[4096];
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u%s' --size %dx%d --out %s --timeout 120%s%s",
             http_port, path, WIDTH, HEIGHT, shot, token ? " --token " : "", token ? token : "");
    json_t *report = ms_test_run_json(command, 0);
    printf("%s: %s, %s\n", path, json_string_value(json_object_get(report, "state")),
           json_string_value(json_object_get(report, "message")));
    return report;
}

static json_int_t page_int(json_t *report, const char *key)
{
    return json_integer_value(json_object_get(json_object_get(report, "page"), key));
}

static const char *report_state(json_t *report)
{
    return json_string_value(json_object_get(report, "state"));
}

/* The demo at the whole sculpture and a close-up: the Draco file's very
 * triangles and bytes, and meshrender's silhouette. The page draws the whole
 * mesh at Draco's 16 bits, meshrender the cut at 1 px: the outlines differ by
 * at most about a pixel here and there (measured IoU 0.998 and 0.999). */
static void test_draco_page_draws_the_model(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char *const cameras[] = {"0.9,0.6,3.2,0,0,0,0,1,0,40", "0.3,0.2,1.6,0,0,0,0,1,0,40"};
    enum { KEYS = sizeof cameras / sizeof *cameras };
    char ref_dir[700], archive[700];
    snprintf(archive, sizeof archive, "%s/demo.msa", f->archives);
    json_decref(ms_test_browser_reference(f->dir, archive, cameras, KEYS, WIDTH, HEIGHT, ref_dir, sizeof ref_dir));
    for (int k = 0; k < KEYS; ++k) {
        char shot[700], page[256], ref_png[800];
        snprintf(shot, sizeof shot, "%s/draco_%d.png", f->dir, k);
        snprintf(page, sizeof page, "/web/draco.html#model=demo&cam=%s&hud=0", cameras[k]);
        json_t *report = open_page(f->http_port, page, shot, NULL);
        assert_string_equal(report_state(report), "complete");
        assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
        printf("Draco page: %lld triangles, %lld bytes, first pixels at %lld ms, complete at %lld ms\n",
               (long long)page_int(report, "triangles"), (long long)page_int(report, "bytes"),
               (long long)page_int(report, "firstPixelMs"), (long long)page_int(report, "completeMs"));
        assert_int_equal(page_int(report, "triangles"), f->drc_triangles);
        assert_int_equal(page_int(report, "bytes"), f->drc_bytes);
        assert_true(page_int(report, "firstPixelMs") > 0);
        assert_int_equal(page_int(report, "completeMs"), page_int(report, "firstPixelMs"));

        snprintf(ref_png, sizeof ref_png, "%s/frame_%03d.png", ref_dir, k);
        size_t covered, ref_covered;
        double iou = ms_test_silhouette_iou(shot, ref_png, WIDTH, HEIGHT, &covered, &ref_covered);
        printf("silhouette: %zu px covered (meshrender %zu), IoU %.4f\n", covered, ref_covered, iou);
        assert_true(covered > (size_t)WIDTH * HEIGHT / 20);
        assert_true(iou >= 0.98);
        json_decref(report);
    }
}

/* Each refusal ends in state 'error' with its one line and nothing drawn. */
static void test_draco_page_errors(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const struct {
        const char *path, *token, *message;
    } cases[] = {
        {"/web/draco.html#model=nodraco&hud=0", NULL,
         "No Draco file for this model (/models/nodraco/draco)"},
        {"/web/draco.html#model=preview&hud=0", NULL,
         "The whole model needs a token (/models/preview/draco)"},
        {"/web/draco.html#model=no-such-model&hud=0", NULL,
         "No such model (/models/no-such-model/draco)"},
        {"/web/draco.html#hud=0", NULL, "No model in the URL (#model=NAME)."},
        {"/web/draco.html#model=demo&cam=1,2,3", NULL,
         "The camera in the URL is not ten numbers (#cam=PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY)."},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        char shot[700];
        snprintf(shot, sizeof shot, "%s/error_%zu.png", f->dir, i);
        json_t *report = open_page(f->http_port, cases[i].path, shot, cases[i].token);
        assert_string_equal(report_state(report), "error");
        assert_string_equal(json_string_value(json_object_get(report, "message")), cases[i].message);
        assert_int_equal(page_int(report, "triangles"), 0);
        json_decref(report);
    }
    /* the preview with the token: the whole file, as the demo's */
    char shot[700];
    snprintf(shot, sizeof shot, "%s/preview_token.png", f->dir);
    json_t *report = open_page(f->http_port, "/web/draco.html#model=preview&hud=0", shot, TOKEN);
    assert_string_equal(report_state(report), "complete");
    assert_int_equal(page_int(report, "triangles"), f->drc_triangles);
    json_decref(report);
}

/* A site without Draco's decoder (make wasm without npm draco3d): the page
 * says what is missing. */
static void test_draco_page_without_decoder(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char site[700], command[4096], out[1024], config[700], settings[800], log[700], ports[700];
    snprintf(site, sizeof site, "%s/bare-site", f->dir);
    snprintf(command, sizeof command,
             "mkdir -p %s && cp " MS_TEST_SITE "/draco.html " MS_TEST_SITE "/draco.js " MS_TEST_SITE "/camera.js " MS_TEST_SITE "/draco-worker.js "
             MS_TEST_SITE "/meshstream.css %s/",
             site, site);
    assert_int_equal(run_or_say(command, out, sizeof out), 0);
    snprintf(config, sizeof config, "%s/bare.conf", f->dir);
    snprintf(log, sizeof log, "%s/bare.log", f->dir);
    snprintf(ports, sizeof ports, "%s/bare.ports", f->dir);
    snprintf(settings, sizeof settings, "web_dir = %s\n", site);
    ms_test_write_file(config, settings, strlen(settings));
    const char *extra[] = {"--config", config, NULL};
    uint16_t port, http_port;
    pid_t bare = ms_test_meshserve_start(f->archives, extra, 0, ports, log, &port, &http_port);
    assert_true(bare > 0);
    char shot[700];
    snprintf(shot, sizeof shot, "%s/no_decoder.png", f->dir);
    json_t *report = open_page(http_port, "/web/draco.html#model=demo&hud=0", shot, NULL);
    assert_string_equal(report_state(report), "error");
    assert_string_equal(json_string_value(json_object_get(report, "message")),
                        "Draco's decoder is not on this server (draco_decoder_nodejs.js of npm "
                        "draco3d: scripts/install-deps, then make wasm)");
    json_decref(report);
    assert_int_equal(ms_test_stop(bare, SIGTERM, 10.0), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_draco_page_draws_the_model),
        cmocka_unit_test(test_draco_page_errors),
        cmocka_unit_test(test_draco_page_without_decoder),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
