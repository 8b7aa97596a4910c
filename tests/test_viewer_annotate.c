/* meshview's annotations without a window (ms_viewer_annotate.h): a click
 * selects the nearest marker seen within reach (or none), the camera moves
 * to the selected annotation's stored view (part way after part of the time,
 * exactly there at the end, stopped by a drag), typing a new annotation,
 * deleting and saving it, and where they are loaded from. In process, no GL. */
#include <GLFW/glfw3.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"
#include "ms_viewer_annotate.h"

static const char file_text[] =
    "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": [\n"
    " {\"id\": \"a1\", \"point\": [1, 0, 0], \"title\": \"One\", \"view\": \"mv1:t=1,2,3:d=4:o=1,0.5:f=30:u=z:l=20,10\"},\n"
    " {\"id\": \"b\", \"point\": [0, 1, 0], \"title\": \"Two\"}]}\n";

static void setup(ms_viewer_annotate *a, ms_viewer_controls *c)
{
    ms_viewer_annotate_init(a, NULL, NULL);
    ms_error err;
    assert_int_equal(ms_annotations_parse(file_text, strlen(file_text), "t.json", &a->set, &err), MS_OK);
    a->marked = 2;
    a->pixel[0][0] = 100, a->pixel[0][1] = 50, a->seen[0] = true;
    a->pixel[1][0] = 104, a->pixel[1][1] = 50, a->seen[1] = true;
    double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    ms_viewer_controls_init(c, lo, hi, 2, 4.0 / 3.0);
}

static void click(ms_viewer_annotate *a, double x, double y)
{
    a->click_requested = true, a->click_x = x, a->click_y = y;
    ms_camera camera = {.width = 400, .height = 300};
    ms_viewer_annotate_frame(a, NULL, 1, &camera);
}

static void test_a_click_selects_and_the_camera_moves(void **state)
{
    (void)state;
    ms_viewer_annotate a;
    ms_viewer_controls c;
    ms_viewer_light light = {0};
    setup(&a, &c);
    click(&a, 101, 52); /* nearer the first */
    assert_int_equal(a.selected, 0);
    click(&a, 103.5, 45);
    assert_int_equal(a.selected, 1);
    click(&a, 100 + 2 * MS_VIEWER_ANNOTATE_MARKER_PX + 5, 50 + 2 * MS_VIEWER_ANNOTATE_MARKER_PX + 1); /* out of reach */
    assert_int_equal(a.selected, -1);
    a.seen[0] = false; /* a hidden marker is not clicked */
    click(&a, 100, 50);
    assert_int_equal(a.selected, 1);
    a.seen[0] = true;
    click(&a, 99, 50);
    assert_int_equal(a.selected, 0);
    /* the move: part way at half the time, there at the end, the light too */
    double from_target[3] = {c.target[0], c.target[1], c.target[2]};
    ms_viewer_annotate_animate(&a, &c, &light, 0.5 * MS_VIEWER_ANNOTATE_MOVE_S);
    assert_true(a.moving);
    for (int k = 0; k < 3; ++k) /* smoothstep(0.5) = 0.5 */
        assert_true(fabs(c.target[k] - (from_target[k] + 0.5 * ((double[]){1, 2, 3}[k] - from_target[k]))) < 1e-12);
    assert_false(light.directional);
    ms_viewer_annotate_animate(&a, &c, &light, 0.5 * MS_VIEWER_ANNOTATE_MOVE_S);
    assert_false(a.moving);
    assert_true(c.target[0] == 1 && c.target[1] == 2 && c.target[2] == 3);
    assert_true(c.distance == 4 && c.yaw == 1 && c.pitch == 0.5 && c.fovy_degrees == 30);
    assert_true(light.directional && light.azimuth_deg == 20 && light.elevation_deg == 10);
    /* without a view: the orbit centre goes to the point, the rest stays */
    ms_viewer_annotate_select(&a, 1);
    ms_viewer_annotate_animate(&a, &c, &light, 2 * MS_VIEWER_ANNOTATE_MOVE_S);
    assert_true(c.target[0] == 0 && c.target[1] == 1 && c.target[2] == 0);
    assert_true(c.distance == 4 && c.yaw == 1 && c.pitch == 0.5);
    /* a drag during the move stops it */
    ms_viewer_annotate_select(&a, 0);
    ms_viewer_annotate_animate(&a, &c, &light, 0.1);
    c.yaw += 0.25;
    ms_viewer_controls kept = c;
    ms_viewer_annotate_animate(&a, &c, &light, 0.1);
    assert_false(a.moving);
    assert_memory_equal(&c, &kept, sizeof c);
    ms_viewer_annotate_free(&a);
}

static void type(ms_viewer_annotate *a, const unsigned *cps, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        ms_viewer_annotate_char(a, cps[i]);
}

static void test_typing_deleting_saving(void **state)
{
    (void)state;
    ms_viewer_annotate a;
    ms_viewer_controls c;
    ms_viewer_light light = {0};
    setup(&a, &c);
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(a.save_path, sizeof a.save_path, "%s/saved.json", dir);
    /* Enter asks for a surface point (the next frame casts); the view is kept */
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_ENTER, 0, &c, &light, NULL));
    assert_true(a.add_requested);
    assert_int_equal(strncmp(a.add_view, "mv1:t=", 6), 0);
    a.add_requested = false;
    a.add_point[0] = 0.25, a.add_point[1] = -1, a.add_point[2] = 0.5;
    a.typing = MS_ANNOTATE_TYPING_TITLE;
    /* typed: a bidirectional override and a control character are left out */
    unsigned title[] = {'H', 'i', ' ', 0xE9, 0x202E, 0x7F, '<', 'b', '>'};
    type(&a, title, sizeof title / sizeof *title);
    assert_string_equal(a.title, "Hi \xc3\xa9<b>");
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_BACKSPACE, 0, &c, &light, NULL));
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_BACKSPACE, 0, &c, &light, NULL));
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_BACKSPACE, 0, &c, &light, NULL));
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_BACKSPACE, 0, &c, &light, NULL));
    assert_string_equal(a.title, "Hi ");
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_O, 0, &c, &light, NULL)); /* taken while typing */
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_ENTER, 0, &c, &light, NULL));
    assert_int_equal(a.typing, MS_ANNOTATE_TYPING_TEXT);
    unsigned text[] = {'o', 'k'};
    type(&a, text, 2);
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_ENTER, 0, &c, &light, NULL));
    assert_int_equal(a.typing, MS_ANNOTATE_NOT_TYPING);
    assert_int_equal(ms_annotations_count(a.set), 3);
    assert_int_equal(a.selected, 2);
    const ms_annotation *n = ms_annotations_get(a.set, 2);
    assert_string_equal(n->id, "a2"); /* a1 is taken */
    assert_string_equal(n->title, "Hi ");
    assert_string_equal(n->text, "ok");
    assert_string_equal(n->view, a.add_view);
    assert_true(n->point[0] == 0.25 && n->point[1] == -1 && n->point[2] == 0.5);
    /* saved, read back equal */
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_S, GLFW_MOD_CONTROL, &c, &light, NULL));
    ms_annotations *back;
    ms_error err;
    assert_int_equal(ms_viewer_annotate_read(a.save_path, &back, &err), MS_OK);
    assert_true(ms_annotations_equal(a.set, back));
    ms_annotations_free(back);
    /* Esc cancels typing; an empty title cancels too */
    a.typing = MS_ANNOTATE_TYPING_TITLE;
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_ESCAPE, 0, &c, &light, NULL));
    assert_int_equal(a.typing, MS_ANNOTATE_NOT_TYPING);
    a.typing = MS_ANNOTATE_TYPING_TITLE;
    a.title[0] = 0;
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_ENTER, 0, &c, &light, NULL));
    assert_int_equal(a.typing, MS_ANNOTATE_NOT_TYPING);
    assert_int_equal(ms_annotations_count(a.set), 3);
    /* Shift+Delete deletes the selected one; Delete alone is not taken */
    assert_false(ms_viewer_annotate_key(&a, GLFW_KEY_DELETE, 0, &c, &light, NULL));
    assert_true(ms_viewer_annotate_key(&a, GLFW_KEY_DELETE, GLFW_MOD_SHIFT, &c, &light, NULL));
    assert_int_equal(ms_annotations_count(a.set), 2);
    assert_int_equal(a.selected, -1);
    assert_null(ms_annotations_get(a.set, 2));
    ms_viewer_annotate_free(&a);
    ms_test_rmdir(dir);
}

/* Where they come from: the archive's sidecar (none without one, a refused
 * one's line), --annotations FILE first; where Ctrl+S saves; --annotation ID. */
static void test_loading(void **state)
{
    (void)state;
    char dir[512], path[700], file[700];
    ms_test_tmpdir(dir, sizeof dir);
    ms_viewer_source local = {.archive_dir = dir};
    ms_viewer_annotate a;
    ms_viewer_annotate_init(&a, NULL, "b");
    ms_viewer_annotate_load(&a, &local, "m", NULL); /* no sidecar: none, an empty set to add to */
    assert_string_equal(a.from, "none");
    assert_non_null(a.set);
    assert_int_equal(ms_annotations_count(a.set), 0);
    snprintf(path, sizeof path, "%s/m.annotations.json", dir);
    assert_string_equal(a.save_path, path);
    assert_string_equal(a.message, "--annotation: no annotation 'b' among 0");
    ms_test_write_file(path, file_text, strlen(file_text));
    ms_viewer_annotate_load(&a, &local, "m", NULL); /* the same model: kept as it is */
    assert_int_equal(ms_annotations_count(a.set), 0);
    ms_viewer_annotate_free(&a);
    ms_viewer_annotate_init(&a, NULL, "b");
    ms_viewer_annotate_load(&a, &local, "m", NULL);
    assert_string_equal(a.from, "archive");
    assert_int_equal(ms_annotations_count(a.set), 2);
    assert_int_equal(a.selected, 1);
    assert_true(a.go);
    assert_string_equal(a.message, "");
    ms_viewer_annotate_free(&a);
    /* a refused sidecar: none, its line */
    const char *bad = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": ["
                      "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"view\": \"mv1:nope\"}]}";
    ms_test_write_file(path, bad, strlen(bad));
    ms_viewer_annotate_init(&a, NULL, NULL);
    ms_viewer_annotate_load(&a, &local, "m", NULL);
    assert_null(a.set);
    assert_string_equal(a.from, "none");
    assert_non_null(strstr(a.message, "m.annotations.json: annotation 1 (a): view: "));
    ms_viewer_annotate_free(&a);
    /* --annotations FILE wins over the sidecar, and is where Ctrl+S saves */
    snprintf(file, sizeof file, "%s/mine.json", dir);
    ms_test_write_file(file, file_text, strlen(file_text));
    ms_viewer_annotate_init(&a, file, NULL);
    ms_viewer_annotate_load(&a, &local, "m", NULL);
    assert_string_equal(a.from, "file");
    assert_string_equal(a.save_path, file);
    assert_int_equal(ms_annotations_count(a.set), 2);
    ms_viewer_annotate_free(&a);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_click_selects_and_the_camera_moves),
        cmocka_unit_test(test_typing_deleting_saving),
        cmocka_unit_test(test_loading),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
