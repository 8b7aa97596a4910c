/* Annotations in meshview (docs/VIEWER.md, "Annotations"; docs/ANNOTATIONS.md),
 * the built programs under Xvfb: a synthetic model of two boxes (the cube
 * [-1, 1]^3 and a small box in front of it, between it and the eye) is baked,
 * its annotations installed by `meshbake --annotations` beside the archive,
 * and meshview draws it scripted at 400x300 from the eye (0, -6, 0) looking
 * at the origin (z up, 40 degrees):
 *   - the marker of the annotation on the face the eye sees is drawn at the
 *     pixel the camera projects its point to (computed here), in the marker
 *     colour; the one on the cube's far face and the one behind the small box
 *     are hidden (no marker colour at their pixels), and the report says so;
 *   - --annotation ID selects one: its marker in the selected colour, the
 *     report's "selected";
 *   - --annotations FILE replaces the sidecar: a radius larger than the small
 *     box's distance from the point shows the marker behind it;
 *   - meshbake installs the file as the format writes it (read back equal),
 *     refuses a hostile file with one line, exit status 1; meshview refuses a
 *     hostile --annotations file (a stored view it cannot read) with one line,
 *     exit status 2;
 *   - both doors: meshserve serves the sidecar as the model's annotations
 *     document, by HTTP (GET /models/boxes/annotations) and by the binary
 *     door (GET_DOCUMENT, ms_client_fetch_document_at), both the file's bytes
 *     and read back the annotations given; a model without them: 404 and
 *     NO_DOCUMENT; meshview from the server shows the same markers, seen and
 *     hidden as from the archive; meshbake --remove removes the sidecar. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>
#include <jansson.h>

#include <signal.h>

#include "ms_annotations.h"
#include "ms_client.h"
#include "ms_proto.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define WIDTH 400
#define HEIGHT 300

static const uint8_t marker_rgb[3] = {51, 217, 255}, selected_rgb[3] = {255, 153, 38};

static const char annotations[] =
    "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": [\n"
    " {\"id\": \"front\", \"point\": [0.5, -1, 0.5], \"title\": \"Front face\",\n"
    "  \"text\": \"On the face the camera sees.\\nSecond line.\",\n"
    "  \"view\": \"mv1:t=0,0,0:d=6:o=0,0:f=40:u=z\"},\n"
    " {\"id\": \"back\", \"point\": [0, 1, 0], \"title\": \"Far face\"},\n"
    " {\"id\": \"shadowed\", \"point\": [-0.5, -1, -0.5], \"title\": \"Behind the small box\"}]}\n";

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600], cam[700], view_bin[600], bake_bin[600], file[700], sidecar[700];
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
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    char off[700], command[8192];
    snprintf(off, sizeof off, "%s/boxes.off", f->dir);
    if (ms_test_write_two_boxes(off) != 0)
        return -1;
    ms_test_bin_path(f->bake_bin, sizeof f->bake_bin, "meshbake");
    ms_test_bin_path(f->view_bin, sizeof f->view_bin, "meshview");
    snprintf(command, sizeof command, "%s %s -o %s --name boxes --no-thumbnail --json", f->bake_bin, off, f->archives);
    json_decref(ms_test_run_json(command, 0));
    snprintf(f->file, sizeof f->file, "%s/boxes.json", f->dir);
    snprintf(f->sidecar, sizeof f->sidecar, "%s/boxes.annotations.json", f->archives);
    ms_test_write_file(f->file, annotations, strlen(annotations));
    snprintf(f->cam, sizeof f->cam, "%s/boxes.cam", f->dir);
    FILE *out = fopen(f->cam, "w");
    if (!out)
        return -1;
    fprintf(out, "meshstream-camera-path 1\n0 0 -6 0 0 0 0 0 0 1 40\n");
    fclose(out);
    *state = f;
    return 0;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    if (!f)
        return 0;
    ms_test_display_stop(&f->display);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Where the camera of boxes.cam shows p (pixels, top-left origin): a pinhole
 * at (0, -6, 0) looking along +y, z up, 40 degrees vertically. */
static void project(const double p[3], double *x, double *y)
{
    double depth = p[1] + 6, t = tan(20.0 * M_PI / 180.0), aspect = (double)WIDTH / HEIGHT;
    *x = 0.5 * WIDTH * (1 + p[0] / (depth * t * aspect));
    *y = 0.5 * HEIGHT * (1 - p[2] / (depth * t));
}

/* meshview on the archive, or with source "--server HOST:PORT" from a server. */
static json_t *view_from(const fixture *f, const char *source, const char *tag, const char *extra, uint8_t **rgb)
{
    char command[8192];
    snprintf(command, sizeof command,
             "%s %s --model boxes --path %s --size %dx%d --frames 1 --hud --screenshot-dir %s/%s --json %s",
             f->view_bin, source ? source : f->archives, f->cam, WIDTH, HEIGHT, f->dir, tag, extra);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    uint32_t w, h;
    *rgb = ms_test_png_read(json_string_value(json_object_get(key, "png")), &w, &h);
    assert_int_equal(w, WIDTH);
    assert_int_equal(h, HEIGHT);
    return report;
}

static json_t *view(const fixture *f, const char *tag, const char *extra, uint8_t **rgb)
{
    return view_from(f, NULL, tag, extra, rgb);
}

/* The report's marker for id: seen, and its pixel equal to the projection. */
static bool marker_seen(json_t *report, const char *id, const double point[3])
{
    json_t *markers = json_object_get(json_object_get(report, "annotations"), "markers"), *m;
    size_t i;
    json_array_foreach(markers, i, m) {
        if (strcmp(json_string_value(json_object_get(m, "id")), id) != 0)
            continue;
        double x, y;
        project(point, &x, &y);
        json_t *pixel = json_object_get(m, "pixel");
        assert_true(fabs(json_real_value(json_array_get(pixel, 0)) - x) < 1e-6);
        assert_true(fabs(json_real_value(json_array_get(pixel, 1)) - y) < 1e-6);
        return json_is_true(json_object_get(m, "seen"));
    }
    fail_msg("no marker %s", id);
    return false;
}

/* The picture's colour at the pixel p projects to. */
static const uint8_t *at(const uint8_t *rgb, const double p[3])
{
    double x, y;
    project(p, &x, &y);
    return rgb + 3 * ((size_t)y * WIDTH + (size_t)x);
}

static const double front[3] = {0.5, -1, 0.5}, back[3] = {0, 1, 0}, shadowed[3] = {-0.5, -1, -0.5};

static void test_markers_are_drawn_where_seen(void **state)
{
    fixture *f = *state;
    char command[8192], out[4096];
    snprintf(command, sizeof command, "%s --annotations %s -o %s --name boxes --json", f->bake_bin, f->file,
             f->archives);
    json_t *installed = ms_test_run_json(command, 0);
    assert_int_equal(json_integer_value(json_object_get(installed, "count")), 3);
    /* installed as the format writes it: read back, the same annotations */
    ms_annotations *given, *sidecar;
    ms_error err;
    assert_int_equal(ms_annotations_load(f->file, &given, &err), MS_OK);
    assert_int_equal(ms_annotations_load(json_string_value(json_object_get(installed, "annotations")), &sidecar,
                                         &err),
                     MS_OK);
    assert_true(ms_annotations_equal(given, sidecar));
    ms_annotations_free(given);
    ms_annotations_free(sidecar);
    json_decref(installed);

    uint8_t *rgb;
    json_t *report = view(f, "plain", "", &rgb);
    json_t *notes = json_object_get(report, "annotations");
    assert_string_equal(json_string_value(json_object_get(notes, "from")), "archive");
    assert_int_equal(json_integer_value(json_object_get(notes, "count")), 3);
    assert_true(json_is_null(json_object_get(notes, "selected")));
    assert_true(marker_seen(report, "front", front));
    assert_false(marker_seen(report, "back", back));         /* the cube's own front face hides it */
    assert_false(marker_seen(report, "shadowed", shadowed)); /* the small box hides it */
    assert_memory_equal(at(rgb, front), marker_rgb, 3);
    assert_memory_not_equal(at(rgb, back), marker_rgb, 3);
    assert_memory_not_equal(at(rgb, shadowed), marker_rgb, 3);
    free(rgb);
    json_decref(report);

    /* selected: the selected colour */
    report = view(f, "selected", "--annotation front", &rgb);
    assert_string_equal(json_string_value(json_object_get(json_object_get(report, "annotations"), "selected")),
                        "front");
    assert_memory_equal(at(rgb, front), selected_rgb, 3);
    free(rgb);
    json_decref(report);

    /* --annotations FILE: a radius of 2 reaches past the small box */
    char file[800];
    snprintf(file, sizeof file, "%s/radius.json", f->dir);
    const char *wide = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": [\n"
                       " {\"id\": \"wide\", \"point\": [-0.5, -1, -0.5], \"radius\": 2, \"title\": \"Wide\"}]}\n";
    ms_test_write_file(file, wide, strlen(wide));
    char extra[900];
    snprintf(extra, sizeof extra, "--annotations %s", file);
    report = view(f, "radius", extra, &rgb);
    assert_string_equal(json_string_value(json_object_get(json_object_get(report, "annotations"), "from")), "file");
    assert_true(marker_seen(report, "wide", shadowed));
    assert_memory_equal(at(rgb, shadowed), marker_rgb, 3);
    free(rgb);
    json_decref(report);

    /* hostile files: one line each */
    const char *duplicate = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": ["
                            "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\"}, "
                            "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\"}]}";
    ms_test_write_file(file, duplicate, strlen(duplicate));
    snprintf(command, sizeof command, "%s --annotations %s -o %s --name boxes", f->bake_bin, file, f->archives);
    assert_int_equal(ms_test_run(command, out, sizeof out), 1);
    char want[2000];
    snprintf(want, sizeof want, "meshbake: %s: annotation 2 (a): id 'a' is used twice\n", file);
    assert_string_equal(out, want);
    const char *bad_view = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": ["
                           "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", "
                           "\"view\": \"mv1:t=0,0,0:d=-1:o=0,0:f=40:u=z\"}]}";
    ms_test_write_file(file, bad_view, strlen(bad_view));
    snprintf(command, sizeof command, "%s %s --model boxes --annotations %s", f->view_bin, f->archives, file);
    assert_int_equal(ms_test_run(command, out, sizeof out), 2);
    snprintf(want, sizeof want,
             "meshview: --annotations: %s: annotation 1 (a): view: d= wants a distance > 0 (docs/VIEWER.md, "
             "\"Shareable views\")\n",
             file);
    assert_string_equal(out, want);
}

/* Parses a document's bytes and compares them with the file's, and the set with the given file's. */
static void same_as_given(const fixture *f, const uint8_t *bytes, size_t length)
{
    size_t size;
    unsigned char *file = ms_test_read_file(f->sidecar, &size);
    assert_int_equal(length, size);
    assert_memory_equal(bytes, file, size);
    free(file);
    ms_annotations *given, *served;
    ms_error err;
    assert_int_equal(ms_annotations_load(f->file, &given, &err), MS_OK);
    assert_int_equal(ms_annotations_parse((const char *)bytes, length, "served", &served, &err), MS_OK);
    assert_true(ms_annotations_equal(given, served));
    ms_annotations_free(given);
    ms_annotations_free(served);
}

static void test_both_doors_and_meshview_from_a_server(void **state)
{
    fixture *f = *state;
    char log[700], ports[700], off[700], command[8192], out[4096];
    snprintf(off, sizeof off, "%s/boxes.off", f->dir);
    snprintf(command, sizeof command, "%s %s -o %s --name plain --no-thumbnail && %s --annotations %s -o %s --name boxes",
             f->bake_bin, off, f->archives, f->bake_bin, f->file, f->archives);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    uint16_t port, http_port;
    pid_t server = ms_test_meshserve_start(f->archives, NULL, 0, ports, log, &port, &http_port);
    assert_true(server > 0);
    /* the side door */
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(http_port, "/models/boxes/annotations", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    same_as_given(f, r.body, r.body_length);
    ms_test_http_free(&r);
    assert_int_equal(ms_test_http_get(http_port, "/models/plain/annotations", NULL, &r), 0);
    assert_int_equal(r.status, 404);
    ms_test_http_free(&r);
    /* the binary door */
    ms_client_options o = {.host = "127.0.0.1", .port = port, .agent = "test"};
    uint8_t *bytes;
    size_t length;
    ms_error err;
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "boxes", MS_DOCUMENT_ANNOTATIONS, &bytes, &length, &err),
                     MS_OK);
    same_as_given(f, bytes, length);
    free(bytes);
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "plain", MS_DOCUMENT_ANNOTATIONS, &bytes, &length, &err),
                     MS_ERR_IO);
    assert_non_null(strstr(err.text, ": NO_DOCUMENT "));
    /* meshview from the server: the same markers */
    char source[64];
    snprintf(source, sizeof source, "--server 127.0.0.1:%u", port);
    uint8_t *rgb;
    json_t *report = view_from(f, source, "server", "", &rgb);
    json_t *notes = json_object_get(report, "annotations");
    assert_string_equal(json_string_value(json_object_get(notes, "from")), "server");
    assert_int_equal(json_integer_value(json_object_get(notes, "count")), 3);
    assert_true(marker_seen(report, "front", front));
    assert_false(marker_seen(report, "back", back));
    assert_false(marker_seen(report, "shadowed", shadowed));
    assert_memory_equal(at(rgb, front), marker_rgb, 3);
    free(rgb);
    json_decref(report);
    ms_test_stop(server, SIGTERM, 10.0);
    /* meshbake --remove takes the sidecar away with the model */
    snprintf(command, sizeof command, "%s --remove boxes -o %s", f->bake_bin, f->archives);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    struct stat st;
    assert_int_not_equal(stat(f->sidecar, &st), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_markers_are_drawn_where_seen),
        cmocka_unit_test(test_both_doors_and_meshview_from_a_server),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
