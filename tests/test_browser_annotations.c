/* Annotations in the browser page (docs/BROWSER.md, "Annotations";
 * web/annotations.js) and through the side door: meshserve --web-dir serves
 * a baked two-box model (ms_test_write_two_boxes) whose sidecar, installed by
 * `meshbake --annotations`, holds a title with a <script> element and a text
 * with an <img onerror>; headless Chromium (tests/browser-page) opens
 * /view/boxes from the eye (0, -6, 0):
 *   - the door: GET /models/boxes/annotations answers the sidecar's bytes;
 *     a model without annotations, and no model, answer 404;
 *   - the markers sit at the CSS pixels the camera projects their points to
 *     (computed here); the one on the far face and the one behind the small
 *     box are hidden by the page's ray test;
 *   - a real click on the front marker shows its title and text as written
 *     (no element made of them: as many script elements as before, nothing ran),
 *     puts #annotation=front in the URL and moves the camera to the stored
 *     view (eye (0, 6, 0)), from where the far face's marker is the one seen.
 * The door cases skip, saying so, while meshserve does not serve the
 * annotations document; the browser cases also skip when
 * chromium-headless-shell or emscripten is not installed. */
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
#include <cmocka.h>
#include <jansson.h>

#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_net.h"

#define WIDTH 320
#define HEIGHT 240

static const char title[] = "Front <script>window.pwned = 1</script>";
static const char text[] = "<img src=x onerror=\"window.pwned = 2\">\nline two";

typedef struct fixture {
    char dir[512], archives[600], log[600], port_file[600], sidecar[700];
    pid_t server;
    uint16_t port, http_port;
    char why_skip[256];     /* the browser cases cannot run */
} fixture;

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
    char off[700], file[700], bake[600], command[8192], out[4096];
    snprintf(off, sizeof off, "%s/boxes.off", f->dir);
    if (ms_test_write_two_boxes(off) != 0)
        return -1;
    json_t *notes = json_pack(
        "{s:s, s:i, s:[{s:s, s:[f, f, f], s:s, s:s, s:s}, {s:s, s:[f, f, f], s:s}, {s:s, s:[f, f, f], s:s}]}",
        "format", "meshstream-annotations", "version", 1, "annotations", "id", "front", "point", 0.5, -1.0, 0.5,
        "title", title, "text", text, "view", "mv1:t=0,0,0:d=6:o=0,0:f=40:u=z:l=30,10", "id", "back", "point", 0.0, 1.0,
        0.0, "title", "Far face", "id", "shadowed", "point", -0.5, -1.0, -0.5, "title", "Behind the small box");
    snprintf(file, sizeof file, "%s/notes.json", f->dir);
    if (!notes || json_dump_file(notes, file, 0) != 0)
        return -1;
    json_decref(notes);
    ms_test_bin_path(bake, sizeof bake, "meshbake");
    snprintf(command, sizeof command,
             "%s %s -o %s --name boxes --no-thumbnail && %s %s -o %s --name plain --no-thumbnail && "
             "%s --annotations %s -o %s --name boxes",
             bake, off, f->archives, bake, off, f->archives, bake, file, f->archives);
    if (ms_test_run(command, out, sizeof out) != 0) {
        fprintf(stderr, "%s: %s\n", command, out);
        return -1;
    }
    snprintf(f->sidecar, sizeof f->sidecar, "%s/boxes.annotations.json", f->archives);
    char config[700], settings[256];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(settings, sizeof settings, "web_dir = %s\n", ms_test_browser_web_dir());
    ms_test_write_file(config, settings, strlen(settings));
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    const char *extra[] = {"--config", config, NULL};
    f->server = ms_test_meshserve_start(f->archives, extra, 0, f->port_file, f->log, &f->port, &f->http_port);
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

static void test_the_door_serves_the_sidecar(void **state)
{
    fixture *f = *state;
    size_t size;
    unsigned char *want = ms_test_read_file(f->sidecar, &size);
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/models/boxes/annotations", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, size);
    assert_memory_equal(r.body, want, size);
    ms_test_http_free(&r);
    free(want);
    const char *none[] = {"/models/plain/annotations", "/models/nope/annotations"};
    for (size_t i = 0; i < 2; ++i) {
        assert_int_equal(ms_test_http_get(f->http_port, none[i], NULL, &r), 0);
        if (r.status != 404)
            fail_msg("%s: %d, wanted 404", none[i], r.status);
        ms_test_http_free(&r);
    }
}

/* The CSS pixel of p seen from the eye (0, -6, 0) looking at the origin, z
 * up, 40 degrees (the device scale is 1: CSS pixels are the canvas's). */
static void project(const double p[3], double *x, double *y)
{
    double depth = p[1] + 6, t = tan(20.0 * M_PI / 180.0), aspect = (double)WIDTH / HEIGHT;
    *x = 0.5 * WIDTH * (1 + p[0] / (depth * t * aspect));
    *y = 0.5 * HEIGHT * (1 - p[2] / (depth * t));
}

/* The marker of id in a step's page: its seen flag (its pixel checked when want is given). */
static bool seen(json_t *annotations, const char *id, const double *want)
{
    json_t *m;
    size_t i;
    json_array_foreach(json_object_get(annotations, "markers"), i, m) {
        if (strcmp(json_string_value(json_object_get(m, "id")), id) != 0)
            continue;
        if (want) {
            double x, y;
            project(want, &x, &y);
            if (fabs(json_number_value(json_object_get(m, "x")) - x) > 1e-3 ||
                fabs(json_number_value(json_object_get(m, "y")) - y) > 1e-3)
                fail_msg("%s at %g, %g, wanted %g, %g", id, json_number_value(json_object_get(m, "x")),
                         json_number_value(json_object_get(m, "y")), x, y);
        }
        return json_is_true(json_object_get(m, "seen"));
    }
    fail_msg("no marker %s", id);
    return false;
}

static void test_the_page_shows_them(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const double front[3] = {0.5, -1, 0.5}, back[3] = {0, 1, 0}, shadowed[3] = {-0.5, -1, -0.5};
    double x, y;
    project(front, &x, &y);
    char steps[1024], steps_path[700], shot[700], command[4096];
    snprintf(steps, sizeof steps,
             "[{\"settle\": true},\n"
             " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mousePressed\", \"x\": %.0f, "
             "\"y\": %.0f, \"button\": \"left\", \"clickCount\": 1}},\n"
             " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseReleased\", \"x\": %.0f, "
             "\"y\": %.0f, \"button\": \"left\", \"clickCount\": 1}},\n"
             " {\"settle\": true}, {\"settle\": true}, {\"settle\": true}, {\"settle\": true}]\n",
             x, y, x, y);
    snprintf(steps_path, sizeof steps_path, "%s/steps.json", f->dir);
    ms_test_write_file(steps_path, steps, strlen(steps));
    snprintf(shot, sizeof shot, "%s/page.png", f->dir);
    snprintf(command, sizeof command,
             "tests/browser-page 'http://127.0.0.1:%u/view/boxes#cam=0,-6,0,0,0,0,0,0,1,40&hud=0' --size %dx%d "
             "--out %s --timeout 120 --input %s",
             f->http_port, WIDTH, HEIGHT, shot, steps_path);
    json_t *report = ms_test_run_json(command, 0);
    assert_string_equal(json_string_value(json_object_get(report, "state")), "complete");
    json_t *list = json_object_get(report, "steps");
    assert_int_equal(json_array_size(list), 5);
    /* before the click: where the markers are, which are seen */
    json_t *before = json_object_get(json_object_get(json_array_get(list, 0), "page"), "annotations");
    assert_string_equal(json_string_value(json_object_get(before, "state")), "loaded");
    assert_int_equal(json_integer_value(json_object_get(before, "count")), 3);
    assert_string_equal(json_string_value(json_object_get(before, "occlusion")), "tested");
    assert_true(seen(before, "front", front));
    assert_false(seen(before, "back", back));
    assert_false(seen(before, "shadowed", shadowed));
    assert_true(json_is_null(json_object_get(before, "selected")));
    /* after it: the text as text, the URL, the camera and light of the stored view */
    json_t *last = json_array_get(list, 4), *after = json_object_get(json_object_get(last, "page"), "annotations");
    assert_string_equal(json_string_value(json_object_get(after, "selected")), "front");
    assert_string_equal(json_string_value(json_object_get(after, "title")), title);
    assert_string_equal(json_string_value(json_object_get(after, "text")), text);
    assert_int_equal(json_integer_value(json_object_get(after, "scripts")),
                     json_integer_value(json_object_get(before, "scripts")));
    assert_true(json_is_null(json_object_get(after, "pwned")));
    const char *hash = json_string_value(json_object_get(last, "hash"));
    assert_non_null(strstr(hash, "annotation=front"));
    /* the page's view text of that camera and the view's light, taken on
     * arrival as meshview takes it (its yaw may print as -0) */
    const char *view = json_string_value(json_object_get(json_object_get(last, "page"), "view"));
    assert_true(!strcmp(view, "mv1:t=0,0,0:d=6:o=0,0:f=40:u=z:l=30,10") ||
                !strcmp(view, "mv1:t=0,0,0:d=6:o=-0,0:f=40:u=z:l=30,10"));
    /* the URL holds it (a raking light is not a #cam=: the view text says it) */
    char wanted[256];
    snprintf(wanted, sizeof wanted, "view=%s", view);
    assert_non_null(strstr(hash, wanted));
    json_t *light = json_object_get(json_object_get(last, "page"), "light");
    assert_true(json_real_value(json_object_get(light, "az")) == 30.0 ||
                json_integer_value(json_object_get(light, "az")) == 30);
    assert_true(json_real_value(json_object_get(light, "el")) == 10.0 ||
                json_integer_value(json_object_get(light, "el")) == 10);
    assert_false(seen(after, "front", NULL));
    assert_true(seen(after, "back", NULL));
    assert_false(seen(after, "shadowed", NULL));
    assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
    json_decref(report);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_the_door_serves_the_sidecar),
        cmocka_unit_test(test_the_page_shows_them),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
