/* meshview's parts that need no window: the bitmap font (every printable
 * character has its own non-empty glyph), the camera controller (orbit keeps
 * the distance, pan keeps the direction, re-centring looks at the point, the
 * camera it gives is valid), the HUD's lines (with the camera path's and a
 * selected piece's), the catalogue's row layout and
 * the nearest-rank quantile of the scripted report. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>
#include <GLFW/glfw3.h>

#include "ms_catalog.h"
#include "ms_test.h"

#include "ms_viewer_catalogue.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_font.h"
#include "ms_viewer_hud.h"
#include "ms_viewer_script.h"

/* |a - b| <= eps (cmocka's double comparison is not in every version). */
#define assert_near(a, b, eps) assert_true(fabs((double)(a) - (double)(b)) <= (eps))

static void test_font_glyphs_distinct(void **state)
{
    (void)state;
    for (int c = MS_FONT_FIRST; c <= MS_FONT_LAST; ++c) {
        unsigned set = 0;
        for (unsigned y = 0; y < MS_FONT_GLYPH_H; ++y)
            for (unsigned x = 0; x < MS_FONT_GLYPH_W; ++x)
                set += ms_font_pixel((char)c, x, y);
        if (c == ' ')
            assert_int_equal(set, 0);
        else if (set == 0)
            fail_msg("glyph '%c' is empty", c);
        for (int d = MS_FONT_FIRST; d < c; ++d)
            if (!memcmp(ms_font_glyph((char)c), ms_font_glyph((char)d), MS_FONT_GLYPH_H))
                fail_msg("glyphs '%c' and '%c' are the same", c, d);
    }
    /* Outside 32..126: the '?' glyph; outside the cell: unset. */
    assert_memory_equal(ms_font_glyph('\n'), ms_font_glyph('?'), MS_FONT_GLYPH_H);
    assert_false(ms_font_pixel('#', MS_FONT_GLYPH_W, 0));
    assert_false(ms_font_pixel('#', 0, MS_FONT_GLYPH_H));
    /* 'I' is a centred bar: its middle column set in rows 0..6. */
    for (unsigned y = 0; y < 7; ++y)
        assert_true(ms_font_pixel('I', 2, y));
}

static double dist3(const double a[3], const double b[3])
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                (a[2] - b[2]) * (a[2] - b[2]));
}

/* The home view frames the whole box: all eight corners project inside the
 * viewport, in front of the near plane, for a cube, a tall bust, a flat CAD-like
 * part and a long needle, every up axis and window shapes from portrait to
 * panoramic (the earlier 1.6 largest sides cropped a cube at 800x600). */
static void test_home_view_frames_the_box(void **state)
{
    (void)state;
    static const double sizes[][3] = {{1, 1, 1}, {1, 2, 1}, {4, 0.3, 2}, {10, 0.2, 0.2}};
    static const double aspects[] = {0.5, 1.0, 800.0 / 600.0, 16.0 / 9.0, 2.5};
    for (size_t s = 0; s < sizeof sizes / sizeof *sizes; ++s)
        for (int up = 0; up < 3; ++up)
            for (size_t a = 0; a < sizeof aspects / sizeof *aspects; ++a) {
                const double lo[3] = {-3, 7, 1};
                const double hi[3] = {lo[0] + sizes[s][0], lo[1] + sizes[s][1], lo[2] + sizes[s][2]};
                ms_viewer_controls c;
                ms_viewer_controls_init(&c, lo, hi, up, aspects[a]);
                ms_camera cam;
                ms_error err;
                double height = 600, width = height * aspects[a];
                assert_int_equal(ms_viewer_controls_camera(&c, width, height, &cam, &err), MS_OK);
                double t = tan(cam.fovy / 2), worst = 0;
                for (int corner = 0; corner < 8; ++corner) {
                    double p[3], x = 0, y = 0, z = 0;
                    for (int k = 0; k < 3; ++k) {
                        p[k] = ((corner >> k) & 1 ? hi[k] : lo[k]) - cam.position[k];
                        x += p[k] * cam.right[k], y += p[k] * cam.up[k], z += p[k] * cam.forward[k];
                    }
                    assert_true(z > cam.near_distance && z < cam.far_distance);
                    double ndc_x = fabs(x / (z * t * width / height)), ndc_y = fabs(y / (z * t));
                    worst = fmax(worst, fmax(ndc_x, ndc_y));
                }
                assert_true(worst <= 1.0);
                assert_true(worst > 0.3); /* framed, not a speck */
            }
}

static void test_controls(void **state)
{
    (void)state;
    const double lo[3] = {10, -4, 2}, hi[3] = {12, -2.5, 4};
    ms_viewer_controls c;
    ms_viewer_controls_init(&c, lo, hi, 1, 1.0);
    assert_near(c.model_size, 2, 1e-12);
    assert_near(c.target[0], 11, 1e-12);
    assert_near(c.target[1], -3.25, 1e-12);
    assert_near(c.target[2], 3, 1e-12);
    double eye[3], forward[3];
    ms_viewer_controls_eye(&c, eye);
    assert_near(dist3(eye, c.target), c.distance, 1e-9);

    /* Orbit: target and distance stay, the eye moves. */
    double before[3];
    memcpy(before, eye, sizeof eye);
    ms_viewer_controls_rotate(&c, 120, -40, 600);
    ms_viewer_controls_eye(&c, eye);
    assert_near(dist3(eye, c.target), c.distance, 1e-9);
    assert_true(dist3(eye, before) > 0.1);
    assert_near(c.target[0], 11, 1e-12);

    /* Directions: orbiting, a drag to the right moves the eye to the screen's
     * left and a drag down lifts it; flying, the view turns right and down. */
    ms_camera cam0;
    ms_error err0;
    assert_int_equal(ms_viewer_controls_camera(&c, 800, 600, &cam0, &err0), MS_OK);
    ms_viewer_controls_eye(&c, before);
    ms_viewer_controls_rotate(&c, 10, 0, 600);
    ms_viewer_controls_eye(&c, eye);
    assert_true((eye[0] - before[0]) * cam0.right[0] + (eye[1] - before[1]) * cam0.right[1] +
                    (eye[2] - before[2]) * cam0.right[2] < 0);
    ms_viewer_controls_eye(&c, before);
    ms_viewer_controls_rotate(&c, 0, 10, 600);
    ms_viewer_controls_eye(&c, eye);
    assert_true(eye[1] > before[1]); /* y is up here */
    c.fly = true;
    assert_int_equal(ms_viewer_controls_camera(&c, 800, 600, &cam0, &err0), MS_OK);
    ms_viewer_controls_rotate(&c, 10, 10, 600);
    ms_viewer_controls_forward(&c, forward);
    assert_true(forward[0] * cam0.right[0] + forward[1] * cam0.right[1] +
                    forward[2] * cam0.right[2] > 0);
    assert_true(forward[1] < cam0.forward[1]);
    c.fly = false;

    /* Pan: eye and target move together; the direction stays. */
    double f0[3], f1[3], e0[3];
    ms_viewer_controls_forward(&c, f0);
    ms_viewer_controls_eye(&c, e0);
    ms_viewer_controls_pan(&c, 30, 10, 600);
    ms_viewer_controls_forward(&c, f1);
    assert_near(dist3(f0, f1), 0, 1e-12);
    ms_viewer_controls_eye(&c, eye);
    assert_true(dist3(eye, e0) > 0);

    /* Zoom in: closer. */
    double d0 = c.distance;
    ms_viewer_controls_zoom(&c, 2);
    assert_near(c.distance, d0 * 0.85 * 0.85, 1e-12);

    /* Re-centre: the eye stays and looks at the point. */
    ms_viewer_controls_eye(&c, e0);
    const double point[3] = {11.3, -3.2, 2.5};
    ms_viewer_controls_recentre(&c, point);
    ms_viewer_controls_eye(&c, eye);
    assert_near(dist3(eye, e0), 0, 1e-9);
    assert_near(dist3(c.target, point), 0, 1e-9);

    /* Fly: looking around keeps the eye; moving keeps the direction. */
    c.fly = true;
    ms_viewer_controls_rotate(&c, 50, 20, 600);
    ms_viewer_controls_eye(&c, eye);
    assert_near(dist3(eye, e0), 0, 1e-9);
    ms_viewer_controls_forward(&c, f0);
    ms_viewer_controls_fly(&c, 1, 0, 0, 1);
    ms_viewer_controls_forward(&c, f1);
    assert_near(dist3(f0, f1), 0, 1e-12);
    ms_viewer_controls_eye(&c, eye);
    double moved[3] = {eye[0] - e0[0], eye[1] - e0[1], eye[2] - e0[2]};
    double along = moved[0] * f0[0] + moved[1] * f0[1] + moved[2] * f0[2];
    assert_true(along > 0);
    assert_near(along, dist3(eye, e0), 1e-9);

    /* The camera: a valid ms_camera at the framebuffer size, looking along forward. */
    ms_camera cam;
    ms_error err;
    assert_int_equal(ms_viewer_controls_camera(&c, 1920, 1080, &cam, &err), MS_OK);
    assert_near(cam.width, 1920, 0);
    assert_near(cam.height, 1080, 0);
    ms_viewer_controls_forward(&c, forward);
    assert_near(dist3(cam.forward, forward), 0, 1e-9);
    assert_true(cam.near_distance > 0 && cam.far_distance > c.distance);
    assert_int_equal(ms_viewer_controls_camera(&c, 0, 1080, &cam, &err), MS_ERR_ARG);

    /* Pitch never reaches the pole. */
    ms_viewer_controls_reset(&c);
    c.fly = false;
    ms_viewer_controls_rotate(&c, 0, 100000, 600);
    assert_true(fabs(c.pitch) < M_PI / 2);
    assert_int_equal(ms_viewer_controls_camera(&c, 64, 64, &cam, &err), MS_OK);
}

static void test_hud_lines(void **state)
{
    (void)state;
    ms_core_stats cs;
    memset(&cs, 0, sizeof cs);
    cs.model_open = true;
    cs.cells_shown = 12, cs.cells_loading = 3, cs.cells_cached = 40;
    cs.geometry_bytes_received = 2500000, cs.apo_bytes_received = 1250000;
    cs.achieved_error_px = 2.5, cs.tolerance_px = 1;
    cs.memory = 7300000;
    /* the GL storage beside the core's memory (issue 32 item 5) */
    ms_viewer_hud_info info = {.model = "dragon", .mode = "APO lit", .frame_ms = 16.7, .fps = 60,
                               .triangles_drawn = 123456, .cells_drawn = 9, .core = &cs,
                               .gl_bytes = 41950000};
    char lines[MS_HUD_MAX_LINES][MS_HUD_LINE_MAX];
    size_t n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 7);
    assert_string_equal(lines[0], "dragon  APO lit");
    assert_string_equal(lines[1], "frame 16.7 ms  60 fps");
    assert_string_equal(lines[2], "triangles 123456 in 9 cells");
    assert_string_equal(lines[3], "cells 12 shown  3 loading  40 cached");
    assert_string_equal(lines[4], "received 2.50 MB geometry  1.25 MB APO");
    assert_string_equal(lines[5], "error 2.50 px  tolerance 1.00 px");
    assert_string_equal(lines[6], "refining  core 7.3 MB + GL 42.0 MB");
    assert_near(ms_viewer_hud_progress(&info), 0.4, 1e-12);
    info.settled = true;
    n = ms_viewer_hud_lines(&info, lines);
    assert_string_equal(lines[6], "view complete  core 7.3 MB + GL 42.0 MB");
    assert_near(ms_viewer_hud_progress(&info), 1, 0);
    snprintf(cs.error, sizeof cs.error, "server gone");
    n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 8);
    assert_string_equal(lines[7], "server gone");
    /* a public preview without a token (issue 32): said under the state */
    cs.error[0] = '\0';
    cs.preview = true, cs.preview_bits = 12;
    n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 8);
    assert_string_equal(lines[6], "view complete  core 7.3 MB + GL 42.0 MB");
    assert_string_equal(lines[7], "preview: 12 bits, a token gives more");
}

/* The camera path's line while the path drives the camera, and a scene's
 * selected piece in three lines. */
static void test_hud_path_and_piece(void **state)
{
    (void)state;
    ms_core_stats cs;
    memset(&cs, 0, sizeof cs);
    cs.model_open = true;
    ms_viewer_playback pb;
    ms_viewer_playback_init(&pb, NULL);
    ms_camera_key keys[2] = {{.time = 0}, {.time = 26}};
    pb.path = (ms_camera_path){.keys = keys, .count = 2};
    ms_scene_material glossy = {.kind = MS_MATERIAL_GLOSSY, .albedo = {0.3f, 0.55f, 0.38f},
                                .specular = 0.35f, .shininess = 80};
    ms_viewer_scene_piece piece = {.model = "dragon", .material = &glossy, .triangles = 48210,
                                   .cells = 17, .bytes = 1234567, .achieved_error_px = 0.84};
    ms_viewer_hud_info info = {.model = "gallery", .mode = "APO lit", .core = &cs, .show_effects = true,
                               .effects_ran = 0, .playback = &pb, .piece = &piece, .piece_index = 1,
                               .piece_count = 9};
    char lines[MS_HUD_MAX_LINES][MS_HUD_LINE_MAX];
    /* off: no path line */
    size_t n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 8 + 3);
    assert_string_equal(lines[8], "piece 2 of 9: dragon  geometry");
    assert_string_equal(lines[9], "glossy  albedo 0.30 0.55 0.38  specular 0.35  shininess 80");
    assert_string_equal(lines[10], "48210 triangles in 17 cells  1.23 MB  error 0.84 px");
    pb.state = MS_PLAYBACK_PLAYING, pb.time = 12.34;
    n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 12);
    assert_string_equal(lines[8], "path 12.3 of 26.0 s  playing");
    pb.state = MS_PLAYBACK_PAUSED;
    piece.impostor = 1;
    ms_scene_material open = {.kind = MS_MATERIAL_DIFFUSE, .albedo = {0.7f, 0.6f, 0.48f}, .two_sided = true};
    piece.material = &open;
    snprintf(cs.error, sizeof cs.error, "dragon: server gone");
    cs.preview = true, cs.preview_bits = 0;
    const char extra[2][MS_HUD_LINE_MAX] = {"light az -80.0 el 0.0 deg",
                                            "measure 2 points: 1.06 +- 0.016 model units (6 bits)"};
    info.extra = extra, info.extra_count = 2; /* the light and a measurement (ms_viewer_inspect.h) */
    n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, MS_HUD_MAX_LINES); /* every line there can be */
    assert_string_equal(lines[14], extra[0]);
    assert_string_equal(lines[15], extra[1]);
    info.extra_count = 0;
    assert_string_equal(lines[8], "preview: 0 bits, a token gives more");
    assert_string_equal(lines[9], "dragon: server gone");
    assert_string_equal(lines[10], "path 12.3 of 26.0 s  paused");
    assert_string_equal(lines[11], "piece 2 of 9: dragon  impostor");
    assert_string_equal(lines[12], "diffuse  albedo 0.70 0.60 0.48  two-sided");
    cs.preview = false;
    piece.impostor = 0.5f;
    info.piece = NULL;
    n = ms_viewer_hud_lines(&info, lines);
    assert_int_equal(n, 10);
    info.piece = &piece;
    n = ms_viewer_hud_lines(&info, lines);
    assert_string_equal(lines[10], "piece 2 of 9: dragon  geometry to impostor");
}

static void test_catalogue_rows(void **state)
{
    (void)state;
    ms_viewer_model_entry entries[30];
    memset(entries, 0, sizeof entries);
    for (int i = 0; i < 30; ++i)
        snprintf(entries[i].name, sizeof entries[i].name, "model%02d", i);
    ms_viewer_model_list list = {.entries = entries, .count = 30};
    ms_viewer_catalogue cat = {.list = &list};
    char row[160];
    entries[0].triangles = 1234567, entries[0].bytes = 2500000, entries[0].apo = true;
    ms_viewer_catalogue_row_text(&entries[0], row, sizeof row);
    assert_non_null(strstr(row, "1,234,567"));
    assert_non_null(strstr(row, "2.5 MB"));
    assert_non_null(strstr(row, "APO"));
    /* Rows under the cursor: the first row, not the title; scrolling follows
     * the selection. */
    long first = -1;
    for (double y = 0; y < 200 && first < 0; y += 1)
        first = ms_viewer_catalogue_row_at(&cat, 100, y, 640, 200, 1);
    assert_int_equal(first, 0);
    assert_int_equal(ms_viewer_catalogue_row_at(&cat, 100, 1, 640, 200, 1), -1);
    ms_viewer_catalogue_move(&cat, 29, 200, 1);
    assert_int_equal(cat.selected, 29);
    assert_true(cat.first > 0);
    ms_viewer_catalogue_move(&cat, -100, 200, 1);
    assert_int_equal(cat.selected, 0);
    assert_int_equal(cat.first, 0);
    /* the panel's metadata lines: words wrapped, cut with "...", one '?' a
     * non-ASCII character, line feeds kept */
    char out[256];
    assert_int_equal(ms_viewer_catalogue_wrap("Demo <script>alert(1)</script> sculpture", 22, 2,
                                              out, sizeof out), 2);
    assert_string_equal(out, "Demo\n<script>alert(1)</s...");
    assert_int_equal(ms_viewer_catalogue_wrap("by M\xc3\xbcller & S\xc3\xb8n \xf0\x9f\x97\xbf", 30, 1,
                                              out, sizeof out), 1);
    assert_string_equal(out, "by M?ller & S?n ?");
    assert_int_equal(ms_viewer_catalogue_wrap("one\ntwo words here", 9, 3, out, sizeof out), 3);
    assert_string_equal(out, "one\ntwo words\nhere");
    assert_int_equal(ms_viewer_catalogue_wrap("one\ntwo words here", 9, 2, out, sizeof out), 2);
    assert_string_equal(out, "one\ntwo wo...");
    assert_int_equal(ms_viewer_catalogue_wrap("", 9, 2, out, sizeof out), 0);
    assert_string_equal(out, "");
}

static void test_quantile(void **state)
{
    (void)state;
    double v[] = {5, 1, 4, 2, 3, 10, 9, 8, 7, 6};
    assert_near(ms_viewer_quantile(v, 10, 0.5), 5, 0);
    assert_near(ms_viewer_quantile(v, 10, 0.95), 10, 0);
    assert_near(ms_viewer_quantile(v, 10, 0), 1, 0);
    assert_near(ms_viewer_quantile(v, 0, 0.5), 0, 0);
}

/* K's cycle of crease angles. */
static void test_crease_angle_cycle(void **state)
{
    (void)state;
    assert_true(ms_viewer_next_crease_angle(60) == 90);
    assert_true(ms_viewer_next_crease_angle(90) == 180);
    assert_true(ms_viewer_next_crease_angle(180) == 30);
    assert_true(ms_viewer_next_crease_angle(30) == 45);
    assert_true(ms_viewer_next_crease_angle(0) == 30);
    assert_true(ms_viewer_next_crease_angle(50) == 60); /* a catalogue's angle between two steps */
    assert_true(ms_viewer_next_crease_angle(120) == 180);
}

/* N, C and B: a shading mode, the same key again lit, another key that mode. */
static void test_shading_keys(void **state)
{
    (void)state;
    assert_int_equal(ms_viewer_toggle_shading(MS_SHADING_LIT, MS_SHADING_ALBEDO), MS_SHADING_ALBEDO);
    assert_int_equal(ms_viewer_toggle_shading(MS_SHADING_ALBEDO, MS_SHADING_ALBEDO), MS_SHADING_LIT);
    assert_int_equal(ms_viewer_toggle_shading(MS_SHADING_NORMALS, MS_SHADING_ALBEDO), MS_SHADING_ALBEDO);
    assert_int_equal(ms_viewer_toggle_shading(MS_SHADING_ALBEDO, MS_SHADING_CELLS), MS_SHADING_CELLS);
    assert_int_equal(ms_viewer_toggle_shading(MS_SHADING_NORMALS, MS_SHADING_NORMALS), MS_SHADING_LIT);
}

/* The catalogue's search on a local directory: typed keys filter the names,
 * titles and descriptions (ASCII case-insensitively), Backspace widens
 * again; the list is whole (total = count: no pages to fetch). */
static void test_catalogue_search_local(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    static const char *const names[] = {"alpha", "beta_bust", "gamma", "delta"};
    static const char *const titles[] = {NULL, NULL, "Bust of Igea", NULL};
    static const char *const descriptions[] = {NULL, NULL, NULL, "A marble BUST, 1998"};
    ms_error err;
    for (int i = 0; i < 4; ++i) {
        ms_catalog_entry e;
        memset(&e, 0, sizeof e);
        snprintf(e.name, sizeof e.name, "%s", names[i]);
        e.source = (char *)"scan.ply";
        snprintf(e.baked_at, sizeof e.baked_at, "2026-12-06T00:00:00Z");
        e.triangles = 100, e.vertices = 52, e.cells = 1, e.bits = 12, e.n = 2;
        e.public_max_bits = 12;
        ms_metadata m = {.title = (char *)titles[i], .description = (char *)descriptions[i]};
        e.metadata = titles[i] || descriptions[i] ? &m : NULL;
        if (ms_catalog_update(dir, &e, &err) != MS_OK)
            fail_msg("%s", err.text);
    }
    ms_viewer_source source = {.archive_dir = dir};
    ms_viewer_model_list list;
    assert_int_equal(ms_viewer_list_page(&source, NULL, &list, &err), MS_OK);
    assert_int_equal(list.count, 4);
    ms_viewer_catalogue cat = {.list = &list, .archive_dir = dir, .source = &source};
    static const int keys[] = {GLFW_KEY_B, GLFW_KEY_U, GLFW_KEY_S, GLFW_KEY_T};
    for (size_t i = 0; i < 4; ++i)
        assert_int_equal(ms_viewer_catalogue_key(&cat, keys[i], 200, 1), MS_CATALOGUE_STAY);
    assert_string_equal(cat.search, "bust");
    assert_int_equal(list.count, 3); /* the name, the title, the description */
    assert_int_equal(list.total, 3);
    assert_string_equal(list.entries[0].name, "beta_bust");
    assert_string_equal(list.entries[1].name, "delta");
    assert_string_equal(list.entries[2].name, "gamma");
    assert_string_equal(ms_metadata_field(list.entries[2].metadata, 0), "Bust of Igea");
    ms_viewer_catalogue_key(&cat, GLFW_KEY_MINUS, 200, 1);
    assert_int_equal(list.count, 0);
    ms_viewer_catalogue_move(&cat, 3, 200, 1); /* nothing to choose: no harm */
    assert_int_equal(cat.selected, 0);
    for (int i = 0; i < 5; ++i)
        ms_viewer_catalogue_key(&cat, GLFW_KEY_BACKSPACE, 200, 1);
    assert_string_equal(cat.search, "");
    assert_int_equal(list.count, 4);
    ms_viewer_catalogue_free(&cat);
    ms_viewer_model_list_free(&list);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_font_glyphs_distinct), cmocka_unit_test(test_controls),
        cmocka_unit_test(test_hud_lines),            cmocka_unit_test(test_hud_path_and_piece),
        cmocka_unit_test(test_catalogue_rows),       cmocka_unit_test(test_home_view_frames_the_box),
        cmocka_unit_test(test_quantile),             cmocka_unit_test(test_crease_angle_cycle),
        cmocka_unit_test(test_shading_keys),         cmocka_unit_test(test_catalogue_search_local),
    };
    return cmocka_run_group_tests_name("viewer_parts", tests, NULL, NULL);
}
