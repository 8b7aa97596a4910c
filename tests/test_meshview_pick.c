/* Picking on a drawn scene (ms_viewer_pick.h, ms_viewer_scene.h), in-process
 * under Xvfb: a room with two demo pieces is streamed from a local archive
 * and drawn into a 64x48 offscreen framebuffer (small: llvmpipe) until it
 * settles; the centre pixel's depth is read back and unprojected, and the
 * picked piece is the one the camera looks at, through the scene's placement
 * transforms; looking at the floor picks nothing (the room is not a piece).
 * The piece's figures (name, material, geometry, triangles, cells, bytes,
 * error) and framing it are checked on the open scene. The scene opens with
 * the index by subtree: each piece is placed (and picked) by the bounds its
 * core took from the root (ms_core_opening.content_lo / _hi), which stand it
 * on the floor at its declared height and leave the floor beside it to the
 * room. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_mesh_io.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_render.h"
#include "ms_viewer_pick.h"
#include "ms_viewer_readback.h"
#include "ms_viewer_scene.h"

#define WIDTH 64
#define HEIGHT 48
#define MAX_FRAMES 2000       /* bounds the wait for a settled view, in frames ... */
#define MAX_SECONDS 120.0     /* ... and in time (not a measurement) */

static const char scene_text[] =
    "{\"scene\": 1, \"name\": \"pick\",\n"
    " \"room\": {\"size\": [4, 3, 6]},\n"
    " \"models\": [\n"
    "  {\"model\": \"demo\", \"position\": [-0.8, 0, 0], \"height\": 1.0},\n"
    "  {\"model\": \"demo\", \"position\": [0.8, 0, 0], \"height\": 1.0, \"yaw\": 40,\n"
    "   \"material\": {\"type\": \"glossy\", \"specular\": 0.3, \"shininess\": 20}}]}\n";

typedef struct fixture {
    ms_test_gl gl;
    char dir[512], archives[600];
    ms_scene scene;
    ms_viewer_scene *vs;
    ms_archive_header headers[2]; /* the pieces' models' */
    ms_viewer_target target;
} fixture;

static fixture fx;

static void expect(ms_status st, const ms_error *err)
{
    if (st != MS_OK)
        fail_msg("%s", err->text);
}

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + ts.tv_nsec * 1e-9;
}

/* Steps and draws the scene for camera until it settles. */
static void draw_settled(const ms_camera *camera)
{
    ms_error err;
    ms_render_options ro;
    ms_render_options_default(&ro);
    double start = now_s();
    for (int frame = 0; frame < MAX_FRAMES && now_s() - start < MAX_SECONDS; ++frame) {
        ms_viewer_step step;
        expect(ms_viewer_scene_step(fx.vs, camera, 1u << 24, &step, &err), &err);
        ms_viewer_target_bind(&fx.target);
        ms_render_draw_stats drawn;
        expect(ms_viewer_scene_draw(fx.vs, camera, &ro, &drawn, &err), &err);
        if (step.settled)
            return;
        struct timespec pause = {0, 5000000};
        nanosleep(&pause, NULL);
    }
    fail_msg("the scene did not settle within %d frames or %.0f s", MAX_FRAMES, MAX_SECONDS);
}

/* A camera `back` metres in front of point (towards +z) and `above` it, looking at it. */
static void camera_at(const double point[3], double back, double above, ms_camera *camera)
{
    double eye[3] = {point[0], point[1] + above, point[2] + back}, up[3] = {0, 1, 0};
    ms_error err;
    expect(ms_camera_look_at(eye, point, up, 40, WIDTH, HEIGHT, 0.02, 20, camera, &err), &err);
}

/* The piece picked under the framebuffer's centre pixel; -1 for none, -2 when
 * nothing is drawn there. */
static long pick_centre(const ms_camera *camera)
{
    double world[3];
    if (!ms_viewer_pick_surface(camera, WIDTH / 2, HEIGHT / 2, world))
        return -2;
    return ms_viewer_pick_scene_piece(fx.vs, world);
}

static void test_centre_pixel_picks_the_piece_looked_at(void **state)
{
    (void)state;
    assert_int_equal(ms_viewer_scene_piece_count(fx.vs), 2);
    for (long k = 0; k < 2; ++k) {
        ms_viewer_pick_box box;
        assert_true(ms_viewer_pick_scene_box(fx.vs, k, &box));
        double centre[3], radius;
        ms_scene_placed_sphere(box.placement, box.lo, box.hi, centre, &radius);
        ms_camera camera;
        camera_at(centre, 2.5, 0.4, &camera);
        draw_settled(&camera);
        assert_int_equal(pick_centre(&camera), k);
        /* its figures, as the HUD shows them */
        ms_viewer_scene_piece piece;
        ms_viewer_scene_piece_info(fx.vs, (size_t)k, &piece);
        assert_string_equal(piece.model, "demo");
        assert_ptr_equal(piece.material, &fx.scene.models[k].material);
        assert_int_equal(piece.material->kind, k == 1 ? MS_MATERIAL_GLOSSY : MS_MATERIAL_DIFFUSE);
        assert_true(piece.impostor == 0.0f); /* impostors are not compiled in */
        assert_true(piece.triangles > 0 && piece.cells > 0 && piece.bytes > 0);
        assert_true(piece.achieved_error_px >= 0);
        /* framing it: the orbit centre at its bounds' centre */
        ms_viewer_controls c;
        double lo[3] = {-2, 0, -3}, hi[3] = {2, 3, 3};
        ms_viewer_controls_init(&c, lo, hi, 1, 1.0);
        assert_true(ms_viewer_pick_frame_piece(fx.vs, k, &c, (double)WIDTH / HEIGHT));
        assert_memory_equal(c.target, centre, sizeof centre);
        assert_true(c.distance > radius);
    }
    ms_viewer_controls c;
    double lo[3] = {-2, 0, -3}, hi[3] = {2, 3, 3};
    ms_viewer_controls_init(&c, lo, hi, 1, 1.0);
    ms_viewer_controls before = c;
    assert_false(ms_viewer_pick_frame_piece(fx.vs, 2, &c, 1));
    assert_false(ms_viewer_pick_frame_piece(fx.vs, -1, &c, 1));
    assert_memory_equal(&c, &before, sizeof c);
}

static void test_room_picks_nothing(void **state)
{
    (void)state;
    double floor_point[3] = {0, 0, 1.2}; /* in front of the pieces, between them */
    ms_camera camera;
    camera_at(floor_point, 1.2, 1.6, &camera); /* from inside the room, looking down */
    draw_settled(&camera);
    assert_int_equal(pick_centre(&camera), -1);
    /* outside the framebuffer: nothing */
    double world[3];
    assert_false(ms_viewer_pick_surface(&camera, WIDTH, 0, world));
    assert_false(ms_viewer_pick_surface(&camera, -1, 0, world));
}

/* The source's vertices through piece k's placement: their box in the scene
 * (*lo_out, *hi_out) and the placement's scale. */
static void placed_source_box(long k, double lo[3], double hi[3], double *scale)
{
    ms_viewer_pick_box box;
    assert_true(ms_viewer_pick_scene_box(fx.vs, k, &box));
    const double *t = box.placement;
    *scale = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    char source[700];
    snprintf(source, sizeof source, "%s/demo.ply", fx.dir);
    ms_mesh mesh = {0};
    ms_error err;
    expect(ms_mesh_load(source, &mesh, NULL, &err), &err);
    for (size_t v = 0; v < mesh.vertex_count; ++v) {
        const double *p = &mesh.positions[3 * v];
        for (int r = 0; r < 3; ++r) {
            double w = t[r] * p[0] + t[4 + r] * p[1] + t[8 + r] * p[2] + t[12 + r];
            lo[r] = v && lo[r] < w ? lo[r] : w;
            hi[r] = v && hi[r] > w ? hi[r] : w;
        }
    }
    ms_mesh_free(&mesh);
}

/* Opened by subtree, each piece is placed by the bounds its core took from
 * the root: the source's lowest point stands at the position's height and
 * its height is the declared one, within one root quantum (placed); by the
 * head's cell boxes the demo stood at half its height. */
static void test_pieces_stand_at_their_height(void **state)
{
    (void)state;
    for (long k = 0; k < 2; ++k) {
        const ms_archive_header *h = &fx.headers[k];
        double quantum = h->box_side / (double)(1u << h->root_bits);
        double lo[3], hi[3], scale;
        placed_source_box(k, lo, hi, &scale);
        const ms_scene_model *m = &fx.scene.models[k];
        assert_true(fabs(lo[1] - m->position[1]) <= quantum * scale);
        assert_true(fabs((hi[1] - lo[1]) - m->height) <= quantum * scale);
    }
}

/* The floor 5 cm to the right of the first piece's surface picks nothing
 * (the head's cell boxes reached 0.4 m past it). */
static void test_floor_beside_a_piece_picks_nothing(void **state)
{
    (void)state;
    double lo[3], hi[3], scale;
    placed_source_box(0, lo, hi, &scale);
    double beside[3] = {hi[0] + 0.05, 0, 0.5 * (lo[2] + hi[2])};
    ms_camera camera;
    camera_at(beside, 1.2, 1.6, &camera);
    draw_settled(&camera);
    double world[3];
    assert_true(ms_viewer_pick_surface(&camera, WIDTH / 2, HEIGHT / 2, world));
    assert_true(fabs(world[1]) < 0.01); /* the floor */
    assert_int_equal(ms_viewer_pick_scene_piece(fx.vs, world), -1);
}

static int setup(void **state)
{
    (void)state;
    ms_test_gl_start(&fx.gl);
    if (ms_nsp_test_demo_archive(fx.dir, sizeof fx.dir, fx.archives, sizeof fx.archives) != 0)
        return -1;
    ms_error err;
    if (ms_scene_parse(scene_text, strlen(scene_text), "pick.json", NULL, &fx.scene, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    ms_viewer_source source = {.archive_dir = fx.archives, .timeout_s = 10};
    ms_viewer_scene_settings settings = {.effects_off = MS_EFFECTS_ALL};
    settings.stream.apo_levels = 0; /* and the index by subtree (the default) */
    if (ms_viewer_scene_open(&source, &fx.scene, "pick.json", &settings, &fx.vs, &err) != MS_OK ||
        ms_viewer_target_init(&fx.target, WIDTH, HEIGHT, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    char path[700];
    snprintf(path, sizeof path, "%s/demo.msa", fx.archives);
    ms_archive *archive;
    if (ms_archive_open(path, &archive, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    fx.headers[0] = fx.headers[1] = *ms_archive_get_header(archive);
    ms_archive_close(archive);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    ms_viewer_scene_close(fx.vs);
    ms_viewer_target_free(&fx.target);
    ms_scene_free(&fx.scene);
    ms_test_gl_stop(&fx.gl);
    ms_test_rmdir(fx.dir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_centre_pixel_picks_the_piece_looked_at),
        cmocka_unit_test(test_room_picks_nothing),
        cmocka_unit_test(test_pieces_stand_at_their_height),
        cmocka_unit_test(test_floor_beside_a_piece_picks_nothing),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
