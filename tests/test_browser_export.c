/* The browser experience without meshserve (docs/BROWSER.md "Static
 * export"), and embedded in another site's page ("Embed"):
 *   - meshexport --web-dir writes the pages, the module and catalog.json
 *     beside three exported models (one with a public preview, one with
 *     colour: the trefoil fixture of tests/data), and a bad --web-dir is
 *     one line;
 *   - nginx (a plain static configuration: a root, mime.types, no rule)
 *     serves that tree; in headless Chromium the viewer page reaches view
 *     complete with meshrender's very cut for the camera, every request
 *     answered without an error; the catalogue lists the three models;
 *     the preview model completes at its public precision; the colour
 *     model draws in its colours, its streams read by byte range;
 *   - a page of another origin (served by that nginx) embeds meshserve's
 *     viewer with the one-line script (web/embed.js), hears its state by
 *     postMessage, and reads a cell range with the token across origins
 *     (meshserve cors_origins: a preflight, then Content-Range exposed).
 * The browser cases skip, saying why, only without chromium-headless-shell,
 * emscripten or nginx. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define TOKEN "export-test-token"
#define NGINX "/usr/sbin/nginx"
#define CLOSE_UP "0.3,0.2,1.6,0,0,0,0,1,0,40"

typedef struct fixture {
    char dir[512], archives[600], www[600];
    pid_t server, nginx;
    uint16_t port, http_port, nginx_port;
    char why_skip[256];
} fixture;

static int run_or_say(const char *command)
{
    char out[4096];
    int status = ms_test_run(command, out, sizeof out);
    if (status != 0)
        fprintf(stderr, "%s: exit %d: %s\n", command, status, out);
    return status;
}

/* A loopback port free a moment ago. */
static uint16_t free_port(void)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t length = sizeof a;
    uint16_t port = 0;
    if (fd >= 0 && bind(fd, (struct sockaddr *)&a, sizeof a) == 0 &&
        getsockname(fd, (struct sockaddr *)&a, &length) == 0)
        port = ntohs(a.sin_port);
    if (fd >= 0)
        close(fd);
    return port;
}

/* nginx serving f->www as files: the root, mime.types, an access log. */
static int start_nginx(fixture *f)
{
    char conf[700], text[8192], log[700];
    snprintf(text, sizeof text, "%s/nginx", f->dir);
    snprintf(log, sizeof log, "%s/nginx/logs", f->dir);
    if (mkdir(text, 0755) != 0 || mkdir(log, 0755) != 0)
        return -1;
    /* nginx's worker runs as another user when the test runs as root: it
     * must get through the test's folder (nothing there is secret) */
    if (chmod(f->dir, 0755) != 0)
        return -1;
    f->nginx_port = free_port();
    snprintf(text, sizeof text,
             "worker_processes 1;\nerror_log %s/nginx/logs/error.log warn;\n"
             "events { worker_connections 256; }\n"
             "http {\n  access_log %s/nginx/logs/access.log;\n"
             "  client_body_temp_path %s/nginx/body;\n  proxy_temp_path %s/nginx/proxy;\n"
             "  fastcgi_temp_path %s/nginx/fastcgi;\n  uwsgi_temp_path %s/nginx/uwsgi;\n"
             "  scgi_temp_path %s/nginx/scgi;\n  include /etc/nginx/mime.types;\n"
             "  default_type application/octet-stream;\n"
             "  server { listen 127.0.0.1:%u; root %s; }\n}\n",
             f->dir, f->dir, f->dir, f->dir, f->dir, f->dir, f->dir, f->nginx_port, f->www);
    snprintf(conf, sizeof conf, "%s/nginx/nginx.conf", f->dir);
    ms_test_write_file(conf, text, strlen(text));
    char prefix[700], globals[800];
    snprintf(prefix, sizeof prefix, "%s/nginx", f->dir);
    snprintf(globals, sizeof globals, "daemon off; pid %s/nginx/nginx.pid;", f->dir);
    snprintf(log, sizeof log, "%s/nginx/stderr.log", f->dir);
    char *argv[] = {NGINX, "-p", prefix, "-c", conf, "-g", globals, NULL};
    f->nginx = ms_test_spawn(argv, log);
    for (int i = 0; i < 100; ++i) {
        ms_test_http_response r;
        if (ms_test_http_get(f->nginx_port, "/catalog.json", NULL, &r) == 0) {
            ms_test_http_free(&r);
            return 0;
        }
        usleep(50000);
    }
    return -1;
}

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    *state = f; /* the teardown cleans up after a failed setup too */
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    snprintf(f->www, sizeof f->www, "%s/www", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    const char *web_dir = ms_test_browser_web_dir();
    char meshgen[600], meshbake[600], meshexport[600], trefoil[1024], command[16384];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    ms_test_bin_path(meshexport, sizeof meshexport, "meshexport");
    ms_test_model_path(trefoil, sizeof trefoil, "trefoil_color.ply.gz");
    /* one annotation on the demo model: the static viewer shows it (the
     * preview model has none: its page reads the empty set meshexport wrote) */
    char notes[700];
    snprintf(notes, sizeof notes, "%s/notes.json", f->dir);
    const char *note = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": "
                       "[{\"id\": \"top\", \"point\": [0, 0, 0.1], \"title\": \"Top\"}]}\n";
    ms_test_write_file(notes, note, strlen(note));
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 && "
             "%s %s/demo.ply -o %s --name preview --min-tris 1500 --no-apo --threads 2 "
             "--public-bits 9 && %s --annotations %s/notes.json -o %s --name demo && "
             "%s %s demo -o %s --web-dir %s && %s %s preview -o %s --web-dir %s && "
             "%s %s -o %s --name trefoil --min-tris 2000 --no-apo --threads 2 && "
             "%s %s trefoil -o %s --web-dir %s",
             meshgen, f->dir, meshbake, f->dir, f->archives, meshbake, f->dir, f->archives, meshbake,
             f->dir, f->archives, meshexport, f->archives, f->www, web_dir, meshexport, f->archives,
             f->www, web_dir, meshbake, trefoil, f->archives, meshexport, f->archives, f->www, web_dir);
    if (run_or_say(command) != 0)
        return -1;
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    if (!f->why_skip[0] && access(NGINX, X_OK) != 0)
        snprintf(f->why_skip, sizeof f->why_skip, "nginx is not installed");
    if (!f->why_skip[0] && start_nginx(f) != 0)
        return -1;
    /* meshserve for the embedding case: the nginx page's origin may read it */
    char config[700], settings[512], log[700], ports[700];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(settings, sizeof settings,
             "token = " TOKEN "\nweb_dir = %s\ncors_origins = http://127.0.0.1:%u\n",
             web_dir, f->nginx_port ? f->nginx_port : 1);
    ms_test_write_file(config, settings, strlen(settings));
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    const char *extra[] = {"--config", config, NULL};
    f->server = ms_test_meshserve_start(f->archives, extra, 0, ports, log, &f->port, &f->http_port);
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
    if (f->nginx > 0)
        ms_test_stop(f->nginx, SIGQUIT, 10.0);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Opens url in the browser: the driver's report. */
static json_t *open_url(const fixture *f, const char *url, const char *shot_name)
{
    char arguments[1024];
    snprintf(arguments, sizeof arguments, "--size 320x240 --out %s/%s --timeout 120", f->dir, shot_name);
    return ms_test_browser_run(url, arguments);
}

/* The nginx access log's answers with a status of 400 or more. */
static unsigned nginx_errors(const fixture *f)
{
    char command[800], out[64];
    snprintf(command, sizeof command,
             "awk '$9 >= 400' %s/nginx/logs/access.log | wc -l", f->dir);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    return (unsigned)atoi(out);
}

static void test_export_writes_the_site(void **state)
{
    fixture *f = *state;
    const char *files[] = {"index.html", "view/demo.html", "view/preview.html", "web/view.js",
                           "web/worker.js", "web/catalogue.js", "web/embed.js",
                           "web/meshstream.css", "models/demo.index", "models/preview.index"};
    char path[900];
    struct stat st;
    for (size_t i = 0; i < sizeof files / sizeof *files; ++i) {
        snprintf(path, sizeof path, "%s/%s", f->www, files[i]);
        if (stat(path, &st) != 0)
            fail_msg("meshexport --web-dir wrote no %s", files[i]);
    }
    /* the catalogue: the three exports, by name, each with its page; the
     * colour model's streams beside its geometry */
    snprintf(path, sizeof path, "%s/models/trefoil/cells/0/colour", f->www);
    if (stat(path, &st) != 0 || st.st_size == 0)
        fail_msg("meshexport wrote no colour stream for the trefoil's root");
    snprintf(path, sizeof path, "%s/catalog.json", f->www);
    json_error_t jerr;
    json_t *catalogue = json_load_file(path, 0, &jerr);
    assert_non_null(catalogue);
    assert_int_equal(json_integer_value(json_object_get(catalogue, "total")), 3);
    json_t *models = json_object_get(catalogue, "models");
    const char *names[] = {"demo", "preview"};
    const int public_bits[] = {16, 9};
    for (int i = 0; i < 2; ++i) {
        json_t *m = json_array_get(models, (size_t)i);
        char view[64];
        snprintf(view, sizeof view, "view/%s.html", names[i]);
        assert_string_equal(json_string_value(json_object_get(m, "name")), names[i]);
        assert_string_equal(json_string_value(json_object_get(m, "view")), view);
        assert_int_equal(json_integer_value(json_object_get(m, "public_max_bits")), public_bits[i]);
        assert_int_equal(json_integer_value(json_object_get(m, "triangles")), 20172);
    }
    json_decref(catalogue);
    /* a folder that holds no pages: one line */
    char bin[600], command[4096], out[1024];
    ms_test_bin_path(bin, sizeof bin, "meshexport");
    snprintf(command, sizeof command, "%s %s demo -o %s/other --web-dir %s 2>&1", bin, f->archives,
             f->dir, f->archives);
    assert_int_equal(ms_test_run(command, out, sizeof out), 1);
    char want[1024];
    snprintf(want, sizeof want,
             "meshexport: %s: no index.html: not a folder of the browser pages (make wasm "
             "builds them into build/wasm/site)\n", f->archives);
    assert_string_equal(out, want);
}

static void test_static_viewer(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    /* the module with its type, as a plain nginx sends it */
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->nginx_port, "/web/meshstream.wasm", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    char type[64] = "";
    assert_string_equal(ms_test_http_header(&r, "Content-Type", type, sizeof type), "application/wasm");
    ms_test_http_free(&r);
    /* meshrender's cut for the camera */
    char cameras[700], text[256], command[4096], meshrender[600];
    snprintf(cameras, sizeof cameras, "%s/closeup.cam", f->dir);
    snprintf(text, sizeof text, "meshstream-camera-path 1\n0 0.3 0.2 1.6 0 0 0 0 1 0 40\n");
    ms_test_write_file(cameras, text, strlen(text));
    ms_test_bin_path(meshrender, sizeof meshrender, "meshrender");
    snprintf(command, sizeof command,
             "%s %s/demo.msa -p %s -o %s/ref --width 320 --height 240 --tolerance 1 --threads 2 --json",
             meshrender, f->archives, cameras, f->dir);
    json_t *ref = ms_test_run_json(command, 0);
    json_t *cut = json_object_get(json_array_get(json_object_get(ref, "frames"), 0), "cut");
    char url[512];
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/demo.html#cam=" CLOSE_UP "&tol=1&culled=2&hud=0",
             f->nginx_port);
    unsigned errors = nginx_errors(f);
    json_t *report = open_url(f, url, "static.png");
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
    assert_int_equal(ms_test_browser_page_int(report, "triangles"), json_integer_value(json_object_get(cut, "triangles")));
    assert_int_equal(ms_test_browser_page_int(report, "cells"), json_integer_value(json_object_get(cut, "shown_cells")));
    /* the annotation, from the file meshexport wrote beside the tree */
    json_t *notes = json_object_get(json_object_get(report, "page"), "annotations");
    assert_string_equal(json_string_value(json_object_get(notes, "state")), "loaded");
    assert_int_equal(json_integer_value(json_object_get(notes, "count")), 1);
    assert_int_equal(nginx_errors(f), errors); /* every byte range within its file, no 404 */
    /* the index by subtree, from the files meshexport wrote */
    json_t *timing = json_object_get(json_object_get(report, "page"), "timing");
    assert_true(json_is_true(json_object_get(timing, "byHead")));
    printf("static viewer: the index by subtree, %lld subtrees, %lld bytes\n",
           (long long)json_integer_value(json_object_get(timing, "subtrees")),
           (long long)json_integer_value(json_object_get(timing, "indexWireBytes")));
    assert_true(json_integer_value(json_object_get(timing, "subtrees")) > 0);
    /* a file server has no cells route: each cell its own byte range */
    assert_int_equal(json_integer_value(json_object_get(timing, "cellBatches")), 0);
    json_decref(report);
    /* a site exported before heads were: the whole index, the same cut, the
     * head's 404 */
    char head[900], away[900];
    snprintf(head, sizeof head, "%s/models/demo.head", f->www);
    snprintf(away, sizeof away, "%s/models/demo.head.away", f->www);
    assert_int_equal(rename(head, away), 0);
    report = open_url(f, url, "static-whole.png");
    assert_int_equal(rename(away, head), 0);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_int_equal(ms_test_browser_page_int(report, "triangles"), json_integer_value(json_object_get(cut, "triangles")));
    assert_int_equal(ms_test_browser_page_int(report, "cells"), json_integer_value(json_object_get(cut, "shown_cells")));
    timing = json_object_get(json_object_get(report, "page"), "timing");
    assert_false(json_is_true(json_object_get(timing, "byHead")));
    assert_int_equal(json_integer_value(json_object_get(timing, "subtrees")), 0);
    /* boot.js's request and the worker's: a 404 is no answer the browser keeps */
    assert_int_equal(nginx_errors(f), errors + 2);
    json_decref(report);
    json_decref(ref);
}

static void test_static_catalogue_and_preview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char url[512];
    unsigned errors = nginx_errors(f);
    snprintf(url, sizeof url, "http://127.0.0.1:%u/", f->nginx_port);
    json_t *report = open_url(f, url, "catalogue.png");
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_string_equal(json_string_value(json_object_get(report, "message")), "3 models");
    /* the three pictures, drawn within each model's public preview, from
     * the paths the site's catalogue names */
    assert_int_equal(ms_test_browser_page_int(report, "thumbnails"), 3);
    assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
    json_decref(report);
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/preview.html#cam=" CLOSE_UP "&tol=1&hud=0",
             f->nginx_port);
    report = open_url(f, url, "preview.png");
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_int_equal(ms_test_browser_page_int(report, "bits"), 9);
    assert_true(ms_test_browser_page_int(report, "triangles") > 0);
    assert_non_null(strstr(json_string_value(json_object_get(report, "message")), "(the public preview)"));
    assert_int_equal(nginx_errors(f), errors); /* nothing asked past the exported preview */
    json_decref(report);
}

static void test_static_colour(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    char url[512], shot[700];
    unsigned errors = nginx_errors(f);
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/trefoil.html#cam=0.6,0.5,3.4,0,0,0,0,1,0,40&tol=1&hud=0",
             f->nginx_port);
    json_t *report = open_url(f, url, "trefoil.png");
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
    json_t *timing = json_object_get(json_object_get(report, "page"), "timing");
    snprintf(shot, sizeof shot, "%s/trefoil.png", f->dir);
    double chroma = ms_test_png_mean_chroma(shot);
    printf("static colour: %lld colour bytes, mean chroma %.1f\n",
           (long long)json_integer_value(json_object_get(timing, "colourBytes")), chroma);
    assert_true(json_integer_value(json_object_get(timing, "colourBytes")) > 0);
    assert_true(chroma > 40.0); /* its colours, not the grey material (about 10) */
    assert_int_equal(nginx_errors(f), errors); /* every colour range within its file */
    json_decref(report);
}

static void test_embedded_in_another_site(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    /* the museum's page: at nginx's origin, the viewer and the side door at
     * meshserve's (localhost: another origin than 127.0.0.1) */
    char page[4096], path[700], url[256];
    snprintf(page, sizeof page,
             "<!DOCTYPE html><html><body>\n"
             "<script src=\"http://localhost:%u/web/embed.js\" data-model=\"demo\" "
             "data-view=\"cam=" CLOSE_UP "&amp;hud=0\" async></script>\n"
             "<script>\n"
             "let frame = null, cors = null;\n"
             "function update() {\n"
             "  if (frame && frame.state !== 'loading' && cors !== null)\n"
             "    window.meshstream = Object.assign({}, frame, { cors });\n"
             "}\n"
             "addEventListener('message', e => {\n"
             "  if (e.origin === 'http://localhost:%u' && e.data.meshstream) { frame = e.data.meshstream; update(); }\n"
             "});\n"
             "fetch('http://localhost:%u/models/preview/cells/0/geometry?bits=12',\n"
             "      { headers: { Authorization: 'Bearer " TOKEN "', Range: 'bytes=0-3' } })\n"
             "  .then(a => a.arrayBuffer().then(b => { cors = a.status + ' ' + b.byteLength + ' ' +\n"
             "        a.headers.get('Content-Range'); update(); }))\n"
             "  .catch(e => { cors = 'failed: ' + e.message; update(); });\n"
             "</script></body></html>\n",
             f->http_port, f->http_port, f->http_port);
    snprintf(path, sizeof path, "%s/museum.html", f->www);
    ms_test_write_file(path, page, strlen(page));
    snprintf(url, sizeof url, "http://127.0.0.1:%u/museum.html", f->nginx_port);
    json_t *report = open_url(f, url, "museum.png");
    json_t *p = json_object_get(report, "page");
    printf("cross-origin read: %s\n", json_string_value(json_object_get(p, "cors")));
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    assert_true(ms_test_browser_page_int(report, "triangles") > 0);
    const char *cors = json_string_value(json_object_get(p, "cors"));
    assert_non_null(cors);
    assert_int_equal(strncmp(cors, "206 4 bytes 0-3/", 16), 0);
    json_decref(report);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_export_writes_the_site),
        cmocka_unit_test(test_static_viewer),
        cmocka_unit_test(test_static_catalogue_and_preview),
        cmocka_unit_test(test_static_colour),
        cmocka_unit_test(test_embedded_in_another_site),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
