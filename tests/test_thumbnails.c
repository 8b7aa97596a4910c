/* Thumbnails and sidecar metadata end to end: meshbake renders
 * DIR/NAME.thumb.png (160x120, at the preview's precision for a preview
 * model) and keeps the sidecar in the catalogue; --thumbnail, --set-public-bits
 * and --remove keep the picture in step; hostile sidecars get one line;
 * meshserve serves the picture (GET /models/NAME/thumbnail, cacheable, only
 * within the public preview, no archive opened) and the metadata (/catalog,
 * searchable with q=). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_catalog.h"
#include "ms_png.h"
#include "ms_test.h"
#include "ms_test_net.h"

typedef struct fixture {
    char dir[512], archives[600], ply[600], bake[4096];
} fixture;

static void write_text(const char *path, const char *text)
{
    ms_test_write_file(path, text, strlen(text));
}

static json_t *bake(const fixture *f, const char *args)
{
    char cmd[16384];
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --threads 2 --json %s", f->bake, f->ply,
             f->archives, args);
    return ms_test_run_json(cmd, 0);
}

/* A picture's pixels (160x120 RGB asserted). */
static uint8_t *picture(const fixture *f, const char *name)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.thumb.png", f->archives, name);
    uint8_t *rgb;
    uint32_t w, h;
    ms_error err;
    assert_int_equal(ms_png_read_rgb(path, 1024, 1024, &rgb, &w, &h, &err), MS_OK);
    assert_int_equal(w, 160);
    assert_int_equal(h, 120);
    return rgb;
}

static const ms_catalog_entry *entry(ms_catalog *c, const fixture *f, const char *name)
{
    ms_error err;
    assert_int_equal(ms_catalog_load(f->archives, c, &err), MS_OK);
    const ms_catalog_entry *e = ms_catalog_find(c, name);
    assert_non_null(e);
    return e;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    assert_int_equal(mkdir(f->archives, 0755), 0);
    snprintf(f->ply, sizeof f->ply, "%s/demo.ply", f->dir);
    char gen[4096], cmd[9000], out[4096];
    ms_test_bin_path(gen, sizeof gen, "meshgen");
    ms_test_bin_path(f->bake, sizeof f->bake, "meshbake");
    snprintf(cmd, sizeof cmd, "%s -o '%s' --triangles 20000", gen, f->ply);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static void test_bake_renders_and_keeps(void **state)
{
    fixture *f = *state;
    char path[700], cmd[16384], out[8192], want[2048];
    snprintf(path, sizeof path, "%s/meta.json", f->dir);
    write_text(path, "{\"title\": \"Demo <script>alert(1)</script>\", \"creator\": \"M\\u00fcller\", "
                     "\"description\": \"The demo sculpture,\\nin marble.\"}");
    char args[800];
    snprintf(args, sizeof args, "--name full --up y --metadata '%s'", path);
    json_t *full = bake(f, args);
    json_t *thumb = json_object_get(full, "thumbnail");
    assert_int_equal(json_integer_value(json_object_get(thumb, "width")), 160);
    assert_int_equal(json_integer_value(json_object_get(thumb, "height")), 120);
    json_int_t full_bytes = json_integer_value(json_object_get(thumb, "bytes"));
    assert_true(full_bytes > 500 && full_bytes < 32768);
    json_decref(full);
    /* a preview one bit coarser than the full model's picture (6 bits: the
     * 160x120 home view of the demo at a pixel's tolerance) */
    json_t *preview = bake(f, "--name preview --public-bits 5");
    json_int_t preview_bits =
        json_integer_value(json_object_get(json_object_get(preview, "thumbnail"), "bits"));
    assert_true(preview_bits >= 1 && preview_bits <= 5);
    json_decref(preview);
    /* the preview's picture is not the full model's */
    uint8_t *a = picture(f, "full"), *b = picture(f, "preview");
    assert_true(memcmp(a, b, 3 * 160 * 120) != 0);
    free(b);
    ms_catalog c;
    const ms_catalog_entry *e = entry(&c, f, "full");
    assert_string_equal(e->metadata->title, "Demo <script>alert(1)</script>");
    assert_string_equal(e->metadata->creator, "M\xc3\xbcller");
    assert_null(e->metadata->licence);
    assert_true(e->has_thumbnail);
    assert_true(e->thumbnail_bits > 5);
    assert_int_equal(e->thumbnail_up, 1);
    e = ms_catalog_find(&c, "preview");
    assert_null(e->metadata);
    assert_int_equal(e->thumbnail_bits, preview_bits);
    ms_catalog_free(&c);
    /* --thumbnail renders the same picture again (y up, as it was) */
    snprintf(cmd, sizeof cmd, "%s --thumbnail full -o '%s' --json", f->bake, f->archives);
    json_decref(ms_test_run_json(cmd, 0));
    uint8_t *again = picture(f, "full");
    assert_memory_equal(a, again, 3 * 160 * 120);
    free(again);
    free(a);
    /* hostile sidecars: one line, nothing baked */
    const struct {
        const char *text, *error;
    } hostile[] = {
        {"{\"title\": \"abc\\u202edcba\"}",
         "metadata title holds a bidirectional override or isolate character"},
        {"{\"title\": [\"x\"]}", "metadata title is not a string"},
        {"{\"rights\": \"all\"}",
         "unknown metadata field 'rights' (title, creator, date, licence, description, unit)"},
    };
    for (size_t i = 0; i < sizeof hostile / sizeof *hostile; ++i) {
        write_text(path, hostile[i].text);
        snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name bad --metadata '%s'", f->bake, f->ply,
                 f->archives, path);
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
        snprintf(want, sizeof want, "meshbake: %s: %s\n", path, hostile[i].error);
        assert_string_equal(out, want);
    }
    snprintf(path, sizeof path, "%s/bad.msa", f->archives);
    assert_int_not_equal(access(path, F_OK), 0);
    snprintf(cmd, sizeof cmd, "%s --list '%s' --metadata x.json", f->bake, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s --thumbnail nope -o '%s'", f->bake, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(want, sizeof want, "meshbake: no model 'nope' in %s/catalog.json\n", f->archives);
    assert_string_equal(out, want);
    /* a coarser preview than the picture: a new picture; the metadata stays */
    snprintf(cmd, sizeof cmd, "%s --set-public-bits 4 -o '%s' --name full", f->bake, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    e = entry(&c, f, "full");
    assert_int_equal(e->public_max_bits, 4);
    assert_true(e->has_thumbnail && e->thumbnail_bits <= 4);
    assert_int_equal(e->thumbnail_up, 1); /* the picture's up kept */
    assert_string_equal(e->metadata->title, "Demo <script>alert(1)</script>");
    ms_catalog_free(&c);
    /* --remove takes the picture too */
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name gone --no-thumbnail", f->bake, f->ply,
             f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(path, sizeof path, "%s/gone.thumb.png", f->archives);
    assert_int_not_equal(access(path, F_OK), 0);
    snprintf(cmd, sizeof cmd, "%s --thumbnail gone -o '%s'", f->bake, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_int_equal(access(path, F_OK), 0);
    snprintf(cmd, sizeof cmd, "%s --remove gone -o '%s'", f->bake, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_int_not_equal(access(path, F_OK), 0);
}

static void get(uint16_t port, const char *path, const char *headers, int status,
                ms_test_http_response *r)
{
    assert_int_equal(ms_test_http_get(port, path, headers, r), 0);
    if (r->status != status)
        fail_msg("GET %s: status %d, expected %d: %s", path, r->status, status, (char *)r->body);
}

static void test_meshserve_serves_them(void **state)
{
    fixture *f = *state;
    json_decref(bake(f, "--name full"));
    json_decref(bake(f, "--name shown --public-bits 7"));
    char path[700];
    snprintf(path, sizeof path, "%s/meta.json", f->dir);
    write_text(path, "{\"title\": \"<img src=x onerror=alert(1)>\", \"description\": \"Carrara "
                     "marble, \\u00e9t\\u00e9 1998\", \"unit\": \"cm\"}");
    char args[800];
    snprintf(args, sizeof args, "--name withheld --public-bits 6 --metadata '%s'", path);
    json_decref(bake(f, args));
    /* the catalogue says a preview coarser than the picture (a hand edit):
     * the picture is not served */
    ms_catalog c;
    ms_catalog_entry e = *entry(&c, f, "withheld");
    assert_true(e.thumbnail_bits >= 2);
    e.public_max_bits = (uint8_t)(e.thumbnail_bits - 1);
    ms_error err;
    assert_int_equal(ms_catalog_update(f->archives, &e, &err), MS_OK);
    ms_catalog_free(&c);

    char bin[512], port_file[700], log[700];
    snprintf(port_file, sizeof port_file, "%s/ports", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    char *argv[] = {bin, f->archives, "--port", "0", "--http-port", "0", "--port-file",
                    port_file, NULL};
    pid_t pid = ms_test_spawn(argv, log);
    uint16_t port, http;
    if (ms_test_wait_ports(port_file, 10.0, &port, &http) != 0)
        fail_msg("meshserve did not start (see %s)", log);

    ms_test_http_response r;
    char value[256], etag[256], conditional[400];
    get(http, "/models/full/thumbnail", NULL, 200, &r);
    size_t size;
    snprintf(path, sizeof path, "%s/full.thumb.png", f->archives);
    unsigned char *file = ms_test_read_file(path, &size);
    assert_int_equal(r.body_length, size);
    assert_memory_equal(r.body, file, size);
    free(file);
    assert_string_equal(ms_test_http_header(&r, "Content-Type", value, sizeof value), "image/png");
    assert_string_equal(ms_test_http_header(&r, "Cache-Control", value, sizeof value),
                        "public, max-age=3600");
    assert_non_null(ms_test_http_header(&r, "ETag", etag, sizeof etag));
    ms_test_http_free(&r);
    snprintf(conditional, sizeof conditional, "If-None-Match: %s\r\n", etag);
    get(http, "/models/full/thumbnail", conditional, 304, &r);
    assert_int_equal(r.body_length, 0);
    ms_test_http_free(&r);
    get(http, "/models/shown/thumbnail", NULL, 200, &r);
    ms_test_http_free(&r);
    get(http, "/models/withheld/thumbnail", NULL, 404, &r);
    assert_string_equal((char *)r.body, "error: no thumbnail for this model\n");
    ms_test_http_free(&r);
    get(http, "/models/nope/thumbnail", NULL, 404, &r);
    assert_string_equal((char *)r.body, "error: no such model\n");
    ms_test_http_free(&r);
    get(http, "/models/..%2Ffull/thumbnail", NULL, 404, &r);
    ms_test_http_free(&r);
    uint64_t open_models = 99;
    assert_int_equal(ms_test_metric(http, "meshstream_open_models", &open_models), 0);
    assert_int_equal(open_models, 0); /* pictures open no archive */

    /* /catalog: metadata as JSON strings, "thumbnail", q= over title and description */
    get(http, "/catalog?q=MARBLE", NULL, 200, &r);
    json_error_t jerr;
    json_t *page = json_loads((char *)r.body, 0, &jerr);
    ms_test_http_free(&r);
    assert_non_null(page);
    assert_int_equal(json_integer_value(json_object_get(page, "total")), 1);
    json_t *m = json_array_get(json_object_get(page, "models"), 0);
    assert_string_equal(json_string_value(json_object_get(m, "name")), "withheld");
    assert_string_equal(json_string_value(json_object_get(m, "title")),
                        "<img src=x onerror=alert(1)>");
    assert_string_equal(json_string_value(json_object_get(m, "description")),
                        "Carrara marble, \xc3\xa9t\xc3\xa9 1998");
    assert_true(json_is_false(json_object_get(m, "thumbnail")));
    assert_null(json_object_get(m, "creator"));
    assert_string_equal(json_string_value(json_object_get(m, "unit")), "cm");
    json_decref(page);
    get(http, "/catalog?q=onerror", NULL, 200, &r);
    if (!strstr((char *)r.body, "\"total\": 1"))
        fail_msg("q=onerror: %s", (char *)r.body);
    ms_test_http_free(&r);
    get(http, "/catalog?q=%C3%A9t%C3%A9", NULL, 200, &r); /* UTF-8 matches as it is */
    assert_non_null(strstr((char *)r.body, "\"total\": 1"));
    ms_test_http_free(&r);
    get(http, "/catalog?q=granite", NULL, 200, &r);
    assert_non_null(strstr((char *)r.body, "\"total\": 0"));
    ms_test_http_free(&r);
    get(http, "/catalog", NULL, 200, &r);
    page = json_loads((char *)r.body, 0, &jerr);
    ms_test_http_free(&r);
    json_t *models = json_object_get(page, "models");
    assert_int_equal(json_array_size(models), 3);
    assert_true(json_is_true(json_object_get(json_array_get(models, 0), "thumbnail"))); /* full */
    assert_true(json_is_true(json_object_get(json_array_get(models, 1), "thumbnail"))); /* shown */
    assert_null(json_object_get(json_array_get(models, 0), "title"));
    assert_null(json_object_get(json_array_get(models, 0), "unit"));
    json_decref(page);
    ms_test_stop(pid, SIGTERM, 10.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_bake_renders_and_keeps, setup, teardown),
        cmocka_unit_test_setup_teardown(test_meshserve_serves_them, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
