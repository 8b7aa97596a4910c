/* The page's tools for looking closely against meshview's (docs/BROWSER.md,
 * "Light", "Sections", "Measuring", "Shareable views"), in headless Chromium
 * against a meshserve on loopback, meshview scripted under Xvfb on the same
 * archives, both at 320x240, tolerance 1 px:
 *   - view text both ways: meshview's text with a light and a plane opens in
 *     the page, which shows the very text back; then a Ctrl drag (the light
 *     turns by 180 degrees per canvas height) and Y (a plane across the view)
 *     in the page give a text meshview takes with --view and prints back to
 *     the byte, with the same light and planes in its report;
 *   - a section: the demo model cut by x = 0 (the half towards the eye away)
 *     in the page and in meshview from the same text: the section-coloured
 *     pixels (sRGB 214 64 48 within 3) and the silhouettes agree (IoU, the
 *     thresholds measured below), and the page's picture shows no surface
 *     where its picture of the same view without the plane shows background;
 *   - light: a subdivided unit cube's face seen head-on under directional
 *     lights at 0 and 60 degrees of azimuth and 45 of elevation: the centre's
 *     linear intensity is meshview's law, albedo (0.05 + 0.95 c^2) plus the
 *     highlight, c = L . N (Lambert's cosine under the self-shadowing factor),
 *     within 1.5/255 a channel in sRGB;
 *   - measuring: on the cube baked at 20 bits, T and a click add the surface
 *     point under the cursor; two rays along x onto its faces x = 0 and x = 1
 *     measure 1 within the reported precision, which is the grid step at the
 *     coarser point's bits (box side / 2^bits); once the view is complete
 *     the probe refines the cells under both points to the model's 20 bits,
 *     and the measure is 1 within 2^-20, in the unit the cube's sidecar
 *     metadata declares ("unit": "mm": the page's line ends "mm (20 bits,
 *     full)").
 *   - hostile view texts (a zero plane normal, four planes, a light out of
 *     range, a field out of order) end the page in state error with
 *     meshview's one line, nothing drawn, no console error.
 * Skips, saying why, without chromium-headless-shell or emscripten. */
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
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_camera.h"
#include "ms_test.h"
#include "ms_test_browser.h"
#include "ms_test_display.h"
#include "ms_test_net.h"
#include "ms_test_picture.h"

#define WIDTH 320
#define HEIGHT 240
#define GRID 8 /* the cube's faces: GRID x GRID squares */

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600];
    pid_t server;
    uint16_t port, http_port;
    char why_skip[256];
} fixture;

/* The unit cube, each face a GRID x GRID grid of squares, wound outwards. */
static void write_cube(const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    int per = (GRID + 1) * (GRID + 1);
    fprintf(f, "ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
               "element face %d\nproperty list uchar int vertex_indices\nend_header\n",
            6 * per, 6 * 2 * GRID * GRID);
    for (int face = 0; face < 6; ++face) {
        int axis = face / 2, side = face % 2, u = (axis + 1) % 3, v = (axis + 2) % 3;
        for (int j = 0; j <= GRID; ++j)
            for (int i = 0; i <= GRID; ++i) {
                double p[3];
                p[axis] = side, p[u] = (double)i / GRID, p[v] = (double)j / GRID;
                fprintf(f, "%g %g %g\n", p[0], p[1], p[2]);
            }
    }
    for (int face = 0; face < 6; ++face) {
        int base = face * per, side = face % 2;
        for (int j = 0; j < GRID; ++j)
            for (int i = 0; i < GRID; ++i) {
                int a = base + j * (GRID + 1) + i, b = a + 1, c = a + GRID + 1, d = c + 1;
                /* u x v = +axis: counter-clockwise in (u, v) faces +axis */
                if (side)
                    fprintf(f, "3 %d %d %d\n3 %d %d %d\n", a, b, d, a, d, c);
                else
                    fprintf(f, "3 %d %d %d\n3 %d %d %d\n", a, d, b, a, c, d);
            }
    }
    fclose(f);
}

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
    char meshgen[600], meshbake[600], cube[700], command[8192], out[4096];
    ms_test_bin_path(meshgen, sizeof meshgen, "meshgen");
    ms_test_bin_path(meshbake, sizeof meshbake, "meshbake");
    snprintf(cube, sizeof cube, "%s/cube.ply", f->dir);
    write_cube(cube);
    char sidecar[700];
    snprintf(sidecar, sizeof sidecar, "%s/mm.json", f->dir);
    ms_test_write_file(sidecar, "{\"unit\": \"mm\"}", strlen("{\"unit\": \"mm\"}"));
    snprintf(command, sizeof command,
             "%s -o %s/demo.ply --triangles 20000 && "
             "%s %s/demo.ply -o %s --name demo --min-tris 1500 --no-apo --threads 2 && "
             "%s %s -o %s --name cube --bits 20 --no-apo --threads 2 --metadata %s",
             meshgen, f->dir, meshbake, f->dir, f->archives, meshbake, cube, f->archives, sidecar);
    if (ms_test_run(command, out, sizeof out) != 0) {
        fprintf(stderr, "%s: %s\n", command, out);
        return -1;
    }
    ms_test_browser_why_skip(f->why_skip, sizeof f->why_skip);
    f->server = ms_test_browser_serve(f->dir, f->archives, &f->port, &f->http_port);
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

/* The page of model at #view=TEXT (hud off), with the input steps (NULL:
 * none); its screenshot into shot. The driver's report, the page complete
 * and without a console error. */
static json_t *page(const fixture *f, const char *model, const char *view, const char *steps, const char *shot)
{
    char url[4096], arguments[2048], steps_file[700] = "";
    if (steps) {
        snprintf(steps_file, sizeof steps_file, "%s/steps.json", f->dir);
        ms_test_write_file(steps_file, steps, strlen(steps));
    }
    snprintf(url, sizeof url, "http://127.0.0.1:%u/view/%s#view=%s&tol=1&hud=0", f->http_port, model, view);
    snprintf(arguments, sizeof arguments, "--size %dx%d --out %s --timeout 120%s%s", WIDTH, HEIGHT, shot,
             steps ? " --input " : "", steps ? steps_file : "");
    json_t *report = ms_test_browser_run(url, arguments);
    if (strcmp(json_string_value(json_object_get(report, "state")), "complete") != 0)
        fail_msg("the page: %s (console: %s)", json_string_value(json_object_get(report, "message")),
                 json_string_value(json_array_get(json_object_get(report, "console"), 0)));
    json_t *console = json_object_get(report, "console");
    if (json_array_size(console))
        fail_msg("console: %s", json_string_value(json_array_get(console, 0)));
    return report;
}

/* meshview's scripted run of model at --view TEXT (its report; the picture's
 * path into png). */
static json_t *meshview(const fixture *f, const char *model, const char *view, const char *tag, char *png,
                        size_t size)
{
    char command[8192], bin[600];
    ms_test_bin_path(bin, sizeof bin, "meshview");
    snprintf(command, sizeof command,
             "%s %s --model %s --view '%s' --size %dx%d --shading geometry --tolerance 1 --frames 1 "
             "--screenshot-dir %s/%s --json",
             bin, f->archives, model, view, WIDTH, HEIGHT, f->dir, tag);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    if (png)
        snprintf(png, size, "%s", json_string_value(json_object_get(key, "png")));
    return report;
}

static double number(json_t *j) { return json_number_value(j); }

static void test_view_text_both_ways(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char text[] = "mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y:l=60,10:s=0,0,0,0,0,1";
    /* a Ctrl drag 24 px right, then Y */
    static const char steps[] =
        "[{\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mousePressed\", \"x\": 160, \"y\": 120, "
        "\"button\": \"left\", \"buttons\": 1, \"clickCount\": 1, \"modifiers\": 2}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseMoved\", \"x\": 184, \"y\": 120, "
        "\"button\": \"left\", \"buttons\": 1, \"modifiers\": 2}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseReleased\", \"x\": 184, \"y\": 120, "
        "\"button\": \"left\", \"buttons\": 0, \"clickCount\": 1, \"modifiers\": 2}},\n"
        " {\"method\": \"Input.dispatchKeyEvent\", \"params\": {\"type\": \"keyDown\", \"key\": \"y\", \"code\": "
        "\"KeyY\", \"windowsVirtualKeyCode\": 89, \"text\": \"y\"}},\n"
        " {\"settle\": true}]\n";
    char shot[700];
    snprintf(shot, sizeof shot, "%s/text.png", f->dir);
    json_t *report = page(f, "demo", text, steps, shot);
    json_t *first = json_object_get(report, "page");
    printf("page at meshview's text: %s\n", json_string_value(json_object_get(first, "view")));
    assert_string_equal(json_string_value(json_object_get(first, "view")), text);
    assert_true(number(json_object_get(json_object_get(first, "light"), "az")) == 60);
    json_t *step = json_object_get(json_array_get(json_object_get(report, "steps"), 0), "page");
    const char *moved = json_string_value(json_object_get(step, "view"));
    const char *hash = json_string_value(json_object_get(json_array_get(json_object_get(report, "steps"), 0), "hash"));
    printf("after a Ctrl drag of 24 px and Y: %s\nURL %s\n", moved, hash);
    assert_non_null(strstr(hash, "view=mv1:"));
    assert_null(strstr(hash, "cam="));
    /* 24 px of a 240 px canvas: 18 degrees of azimuth; a plane across x (the
     * axis nearest the view: y up, yaw 0.35 from +x) through the centre, the
     * eye's side (+x) cut away */
    static const char want[] = "mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y:l=78,10:s=0,0,0,0,0,1/0,0,0,1,0,0";
    assert_string_equal(moved, want);
    /* meshview takes both texts and prints them back to the byte */
    json_t *a = meshview(f, "demo", text, "mv-text", NULL, 0), *b = meshview(f, "demo", moved, "mv-moved", NULL, 0);
    assert_string_equal(json_string_value(json_object_get(a, "view")), text);
    assert_string_equal(json_string_value(json_object_get(b, "view")), moved);
    assert_true(number(json_object_get(json_object_get(b, "light"), "azimuth_deg")) == 78);
    assert_int_equal(json_array_size(json_object_get(b, "sections")), 2);
    json_decref(a);
    json_decref(b);
    json_decref(report);
}

static bool section_pixel(const uint8_t *p)
{
    static const int want[3] = {MS_SECTION_R, MS_SECTION_G, MS_SECTION_B};
    for (int k = 0; k < 3; ++k)
        if (abs((int)p[k] - want[k]) > 3)
            return false;
    return true;
}

static bool model_pixel(const uint8_t *rgb, size_t i)
{
    for (int c = 0; c < 3; ++c)
        if (abs((int)rgb[3 * i + c] - (int)rgb[c]) > 8)
            return true;
    return false;
}

static void test_section_against_meshview(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const char text[] = "mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y:s=0,0,0,1,0,0";
    static const char whole[] = "mv1:t=0,0,0:d=3.4:o=0.35,-0.2:f=40:u=y";
    char shot[700], uncut[700], ref[800];
    snprintf(shot, sizeof shot, "%s/section.png", f->dir);
    snprintf(uncut, sizeof uncut, "%s/uncut.png", f->dir);
    json_decref(page(f, "demo", text, NULL, shot));
    json_decref(page(f, "demo", whole, NULL, uncut));
    json_decref(meshview(f, "demo", text, "mv-section", ref, sizeof ref));
    uint32_t w, h, w2, h2, w3, h3;
    uint8_t *a = ms_test_png_read(shot, &w, &h), *b = ms_test_png_read(ref, &w2, &h2),
            *u = ms_test_png_read(uncut, &w3, &h3);
    assert_true(w == WIDTH && h == HEIGHT && w2 == WIDTH && h2 == HEIGHT && w3 == WIDTH && h3 == HEIGHT);
    size_t s_and = 0, s_or = 0, m_and = 0, m_or = 0, sa = 0, cut = 0, stray = 0;
    for (size_t i = 0; i < (size_t)WIDTH * HEIGHT; ++i) {
        bool xs = section_pixel(a + 3 * i), ys = section_pixel(b + 3 * i);
        bool xm = model_pixel(a, i), ym = model_pixel(b, i), um = model_pixel(u, i);
        s_and += xs && ys, s_or += xs || ys, sa += xs;
        m_and += xm && ym, m_or += xm || ym;
        cut += um && !xm;   /* surface cut away: background now */
        stray += xm && !um; /* surface where the whole model shows none */
    }
    double s_iou = s_or ? (double)s_and / (double)s_or : 0, m_iou = m_or ? (double)m_and / (double)m_or : 0;
    printf("section pixels: page %zu, IoU with meshview's %.4f; silhouette IoU %.4f; %zu pixels cut away to the "
           "background, %zu outside the whole model's\n",
           sa, s_iou, m_iou, cut, stray);
    assert_true(sa > 1000);
    assert_true(cut > 1000);
    assert_int_equal(stray, 0);
    assert_true(s_iou >= 0.95);
    assert_true(m_iou >= 0.98);
    free(a), free(b), free(u);
}

static double srgb_decode(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

static void test_lambert_on_a_face(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    /* the face x = 1 head-on (y up, yaw 0: the eye on +x), filling the middle */
    static const struct {
        const char *light;
        double cos_ln, cos_nh;
    } cases[] = {
        {":l=0,0", 1.0, 1.0},
        {":l=60,0", 0.5, 0.86602540378443865}, /* the half vector at 30 degrees */
        {":l=0,45", 0.70710678118654752, 0.92387953251128674},
    };
    static const double albedo[3] = {0.72, 0.69, 0.64};
    double diffuse[3];
    for (int k = 0; k < 3; ++k) {
        char text[256], shot[700];
        snprintf(text, sizeof text, "mv1:t=0.5,0.5,0.5:d=3:o=0,0:f=30:u=y%s", cases[k].light);
        snprintf(shot, sizeof shot, "%s/lambert-%d.png", f->dir, k);
        json_decref(page(f, "cube", text, NULL, shot));
        uint32_t w, h;
        uint8_t *rgb = ms_test_png_read(shot, &w, &h);
        double c = cases[k].cos_ln, highlight = 0.18 * c * pow(cases[k].cos_nh, 40);
        double worst = 0, mean_d = 0;
        for (int ch = 0; ch < 3; ++ch) {
            double sum = 0;
            for (int y = HEIGHT / 2 - 2; y < HEIGHT / 2 + 2; ++y)
                for (int x = WIDTH / 2 - 2; x < WIDTH / 2 + 2; ++x)
                    sum += rgb[3 * ((size_t)y * WIDTH + (size_t)x) + (size_t)ch];
            double got = sum / 16 / 255, lin = albedo[ch] * (0.05 + 0.95 * c * c) + highlight;
            double want = lin <= 0.0031308 ? 12.92 * lin : 1.055 * pow(lin, 1 / 2.4) - 0.055;
            worst = fmax(worst, fabs(got - want) * 255);
            mean_d += ((srgb_decode(got) - highlight) / albedo[ch] - 0.05) / 0.95 / 3;
        }
        diffuse[k] = mean_d;
        printf("light %s: L.N %.4f, centre within %.2f/255 of meshview's law; diffuse factor %.4f (c^2 %.4f)\n",
               cases[k].light + 3, c, worst, mean_d, c * c);
        assert_true(worst <= 1.5);
        free(rgb);
    }
    printf("Lambert ratios: %.4f (want 0.25), %.4f (want 0.5)\n", diffuse[1] / diffuse[0], diffuse[2] / diffuse[0]);
    assert_true(fabs(diffuse[1] / diffuse[0] - 0.25) < 0.01);
    assert_true(fabs(diffuse[2] / diffuse[0] - 0.5) < 0.01);
}

static void check_edge(json_t *m);

static void test_measure_cube_edge(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    /* T, a click at the centre (one point), Delete; then two rays along x
     * onto the faces x = 0 and x = 1 through the cube's middle */
    static const char steps[] =
        "[{\"method\": \"Input.dispatchKeyEvent\", \"params\": {\"type\": \"keyDown\", \"key\": \"t\", \"code\": "
        "\"KeyT\", \"windowsVirtualKeyCode\": 84, \"text\": \"t\"}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mousePressed\", \"x\": 160, \"y\": 120, "
        "\"button\": \"left\", \"buttons\": 1, \"clickCount\": 1}},\n"
        " {\"method\": \"Input.dispatchMouseEvent\", \"params\": {\"type\": \"mouseReleased\", \"x\": 160, \"y\": 120, "
        "\"button\": \"left\", \"buttons\": 0, \"clickCount\": 1}},\n"
        " {\"settle\": true},\n"
        " {\"method\": \"Input.dispatchKeyEvent\", \"params\": {\"type\": \"keyDown\", \"key\": \"Delete\", \"code\": "
        "\"Delete\", \"windowsVirtualKeyCode\": 46}},\n"
        " {\"method\": \"Runtime.evaluate\", \"params\": {\"expression\": "
        "\"MsTools.measureRay([-1, 0.5, 0.5], [1, 0, 0]); MsTools.measureRay([2, 0.5, 0.5], [-1, 0, 0])\"}},\n"
        " {\"settle\": true},\n"
        /* the probe: wait until both points are refined */
        " {\"method\": \"Runtime.evaluate\", \"params\": {\"awaitPromise\": true, \"expression\": "
        "\"new Promise(r => { const t = setInterval(() => { const m = window.meshstream.measure; "
        "if (m.refined && !m.refining) { clearInterval(t); r(); } }, 50); })\"}},\n"
        " {\"settle\": true}]\n";
    char shot[700];
    snprintf(shot, sizeof shot, "%s/measure.png", f->dir);
    json_t *report = page(f, "cube", "mv1:t=0.5,0.5,0.5:d=3:o=0.6,0.4:f=40:u=y", steps, shot);
    json_t *steps_done = json_object_get(report, "steps");
    assert_int_equal(json_array_size(steps_done), 3);
    json_t *clicked = json_object_get(json_object_get(json_array_get(steps_done, 0), "page"), "measure");
    printf("a click: %s\n", json_string_value(json_object_get(clicked, "text")));
    assert_int_equal(json_array_size(json_object_get(clicked, "points")), 1);
    json_t *hit = json_array_get(json_object_get(clicked, "points"), 0);
    assert_true(json_is_object(hit));
    json_t *m = json_object_get(json_object_get(json_array_get(steps_done, 2), "page"), "measure");
    check_edge(m);
    /* as the view held them, before the probe: coarser, and as exact */
    json_t *held = json_object_get(m, "view");
    double length = number(json_object_get(held, "length")), precision = number(json_object_get(held, "precision"));
    int bits = (int)number(json_object_get(held, "bitsMin"));
    printf("as the view held them: %.9f +- %.9f (%d bits)\n", length, precision, bits);
    assert_true(bits >= 1 && bits < 20);
    assert_true(precision == ldexp(1.0, -bits) * ldexp(number(json_object_get(json_array_get(json_object_get(m, "points"), 0), "step")), 20));
    assert_true(fabs(length - 1.0) <= precision);
    json_decref(report);
}

/* The measure of the two rays onto x = 0 and x = 1, refined: 1 within its
 * precision, the grid step at the points' bits, 20. */
static void check_edge(json_t *m)
{
    json_t *points = json_object_get(m, "points");
    assert_int_equal(json_array_size(points), 2);
    double length = number(json_object_get(m, "length")), precision = number(json_object_get(m, "precision"));
    double step[2], bits[2], box[2];
    for (int i = 0; i < 2; ++i) {
        json_t *p = json_array_get(points, (size_t)i);
        step[i] = number(json_object_get(p, "step"));
        bits[i] = number(json_object_get(p, "bits"));
        box[i] = ldexp(step[i], (int)bits[i]);
        assert_true(number(json_object_get(p, "modelBits")) == 20);
    }
    printf("%s: length %.9f, precision %.9f (bits %g and %g; box side %.9f)\n",
           json_string_value(json_object_get(m, "text")), length, precision, bits[0], bits[1], box[0]);
    assert_true(box[0] == box[1]);
    assert_true(precision == fmax(step[0], step[1]));
    assert_true(precision == ldexp(box[0], -(int)fmin(bits[0], bits[1])));
    assert_true(fabs(length - 1.0) <= precision);
    assert_true(json_is_true(json_object_get(m, "refined")));
    assert_true(json_is_true(json_object_get(m, "full")));
    assert_true(bits[0] == 20 && bits[1] == 20);
    /* in the unit the cube's metadata declares */
    assert_string_equal(json_string_value(json_object_get(m, "unit")), "mm");
    const char *text = json_string_value(json_object_get(m, "text"));
    const char *tail = strstr(text, " mm (20 bits, full)");
    assert_non_null(tail);
    assert_string_equal(tail, " mm (20 bits, full)");
}

static void test_bad_view_text(void **state)
{
    fixture *f = *state;
    MS_TEST_NEED_BROWSER(f->why_skip);
    static const struct {
        const char *text, *line;
    } cases[] = {
        {"mv1:t=0,0,0:d=3:o=0,0:f=40:u=y:s=0,0,0,0,0,0",
         "a section plane wants six numbers PX,PY,PZ,NX,NY,NZ, the normal not zero, at most 3 planes"},
        {"mv1:t=0,0,0:d=3:o=0,0:f=40:u=y:s=0,0,0,1,0,0/0,0,0,1,0,0/0,0,0,1,0,0/0,0,0,1,0,0",
         "a section plane wants six numbers PX,PY,PZ,NX,NY,NZ, the normal not zero, at most 3 planes"},
        {"mv1:t=0,0,0:d=3:o=0,0:f=40:u=y:l=0,91", "l= wants AZ,EL in degrees, AZ in [-180, 180], EL in [-90, 90]"},
        {"mv1:t=0,0,0:d=3:o=0,0:f=40:u=y:s=0,0,0,1,0,0:l=0,0",
         "unknown or misplaced field after u= (l=, s=, then m=, may follow)"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        char command[4096], shot[700], want[512];
        snprintf(shot, sizeof shot, "%s/bad.png", f->dir);
        snprintf(command, sizeof command,
                 "tests/browser-page 'http://127.0.0.1:%u/view/demo#view=%s' --size %dx%d --out %s --timeout 60",
                 f->http_port, cases[i].text, WIDTH, HEIGHT, shot);
        json_t *report = ms_test_run_json(command, 0);
        const char *message = json_string_value(json_object_get(report, "message"));
        printf("%s: %s\n", cases[i].text, message);
        assert_string_equal(json_string_value(json_object_get(report, "state")), "error");
        snprintf(want, sizeof want, "The view in the URL is not meshview's text: %s (docs/VIEWER.md, \"Shareable "
                 "views\").", cases[i].line);
        assert_string_equal(message, want);
        assert_int_equal(json_array_size(json_object_get(report, "console")), 0);
        json_decref(report);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_view_text_both_ways),
        cmocka_unit_test(test_section_against_meshview),
        cmocka_unit_test(test_lambert_on_a_face),
        cmocka_unit_test(test_measure_cube_edge),
        cmocka_unit_test(test_bad_view_text),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
