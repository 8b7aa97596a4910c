/* Camera path playback in meshview's window (ms_viewer_playback.h), pure:
 *   - play starts where the camera is (the eye's nearest path time), the clock
 *     advances by the frames' seconds, pauses at the end, and plays again
 *     from the start;
 *   - pause holds the clock; steps go to the next / previous keyframe, the
 *     last / first at most, from the clock or, when off, from the eye;
 *   - the camera at a time is exactly ms_camera_path_sample's (near and far
 *     from the controls' depth range), and the controls are handed its view;
 *   - a drag, the wheel or a movement key (anything that moves the controls)
 *     stops playback at the next frame, and the controls' camera follows;
 *     toggling fly mode does not;
 *   - without a path every key does nothing; --path errors. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_viewer_playback.h"

/* Three keyframes: along x for 2 s, then up y for 3 s. */
static const char path_text[] = "meshstream-camera-path 1\n"
                                "0  0 0 10   0 0 0    0 1 0  60\n"
                                "2  10 0 10  10 0 0   0 1 0  40\n"
                                "5  10 5 10  10 0 0   0 1 0  40\n";

static void new_playback(ms_viewer_playback *p, ms_viewer_controls *c)
{
    ms_camera_path path;
    ms_error err;
    assert_int_equal(ms_camera_path_parse(path_text, strlen(path_text), "walk.cam", &path, &err), MS_OK);
    ms_viewer_playback_init(p, &path);
    assert_null(path.keys);
    double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    ms_viewer_controls_init(c, lo, hi, 1, 1.0);
}

/* Puts the controls' eye at eye, looking at target. */
static void stand(ms_viewer_controls *c, double x, double y, double z)
{
    double eye[3] = {x, y, z}, target[3] = {x, y, z - 10};
    ms_viewer_controls_look(c, eye, target, 50);
}

/* Playing from the path's first keyframe, exactly (standing at the path's
 * start puts the clock within rounding of 0; a step back makes it 0). */
static void play_from_start(ms_viewer_playback *p, ms_viewer_controls *c)
{
    stand(c, 0, 0, 10);
    ms_viewer_playback_step(p, -1, c);
    assert_true(p->time == 0.0);
    ms_viewer_playback_toggle(p, c);
    assert_int_equal(p->state, MS_PLAYBACK_PLAYING);
}

static void expect_same_camera(const ms_camera *a, const ms_camera *b)
{
    assert_memory_equal(a->position, b->position, sizeof a->position);
    assert_memory_equal(a->forward, b->forward, sizeof a->forward);
    assert_memory_equal(a->up, b->up, sizeof a->up);
    assert_memory_equal(a->right, b->right, sizeof a->right);
    assert_true(a->fovy == b->fovy && a->width == b->width && a->height == b->height);
    assert_true(a->near_distance == b->near_distance && a->far_distance == b->far_distance);
}

static void test_play_pause_and_the_end(void **state)
{
    (void)state;
    ms_viewer_playback p;
    ms_viewer_controls c;
    new_playback(&p, &c);
    assert_false(ms_viewer_playback_on(&p));
    /* the camera stands over the path's point at t = 1 (x = 5): play from there */
    stand(&c, 5, 3, 12);
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(p.state, MS_PLAYBACK_PLAYING);
    assert_true(ms_viewer_playback_on(&p));
    assert_true(fabs(p.time - 1.0) < 1e-9);
    ms_viewer_playback_advance(&p, 0.5);
    assert_true(fabs(p.time - 1.5) < 1e-9);
    /* pause: the clock holds */
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED);
    double held = p.time;
    ms_viewer_playback_advance(&p, 2);
    assert_true(p.time == held);
    /* on again, past the end: paused at the end */
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(p.state, MS_PLAYBACK_PLAYING);
    ms_viewer_playback_advance(&p, 100);
    assert_true(p.time == 5.0);
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED);
    /* playing from the end starts at the start */
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(p.state, MS_PLAYBACK_PLAYING);
    assert_true(p.time == 0.0);
    ms_viewer_playback_advance(&p, 0.25);
    assert_true(p.time == 0.25);
    /* a negative or NaN frame time moves nothing */
    ms_viewer_playback_advance(&p, -1);
    ms_viewer_playback_advance(&p, NAN);
    assert_true(p.time == 0.25);
    /* from off, standing at the path's end: from the start */
    ms_viewer_playback_stop(&p);
    stand(&c, 10, 5, 10);
    ms_viewer_playback_toggle(&p, &c);
    assert_true(p.time == 0.0);
    ms_viewer_playback_free(&p);
}

static void test_steps(void **state)
{
    (void)state;
    ms_viewer_playback p;
    ms_viewer_controls c;
    new_playback(&p, &c);
    stand(&c, 2, 0, 10); /* t = 0.4 */
    ms_viewer_playback_step(&p, 1, &c);
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED);
    assert_true(p.time == 2.0);
    ms_viewer_playback_step(&p, 1, &c);
    assert_true(p.time == 5.0);
    ms_viewer_playback_step(&p, 1, &c); /* the last at most */
    assert_true(p.time == 5.0);
    ms_viewer_playback_step(&p, -1, &c);
    assert_true(p.time == 2.0);
    ms_viewer_playback_step(&p, -1, &c);
    assert_true(p.time == 0.0);
    ms_viewer_playback_step(&p, -1, &c); /* the first at most */
    assert_true(p.time == 0.0);
    /* from a time between keyframes while playing */
    ms_viewer_playback_toggle(&p, &c);
    ms_viewer_playback_advance(&p, 3.5);
    assert_true(p.time == 3.5);
    ms_viewer_playback_step(&p, -1, &c);
    assert_true(p.time == 2.0);
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED);
    /* from off: from the eye (t = 3.8, on the rising segment) */
    ms_viewer_playback_stop(&p);
    stand(&c, 10, 3, 10);
    ms_viewer_playback_step(&p, 1, &c);
    assert_true(p.time == 5.0);
    ms_viewer_playback_stop(&p);
    ms_viewer_playback_step(&p, -1, &c);
    assert_true(p.time == 2.0);
    ms_viewer_playback_step(&p, 0, &c); /* no direction: nothing */
    assert_true(p.time == 2.0);
    ms_viewer_playback_free(&p);
}

static void test_camera_is_the_paths(void **state)
{
    (void)state;
    ms_viewer_playback p;
    ms_viewer_controls c;
    ms_error err;
    new_playback(&p, &c);
    play_from_start(&p, &c);
    const double at[] = {0.0, 0.75, 2.0, 3.25, 5.0};
    double previous = 0;
    for (size_t i = 0; i < sizeof at / sizeof *at; ++i) {
        ms_camera got, want;
        assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 640, 480, at[i] - previous, &got, &err), MS_OK);
        previous = at[i];
        assert_true(p.time == at[i]);
        double near_d, far_d;
        ms_viewer_controls_depth_range(&c, &near_d, &far_d);
        assert_int_equal(ms_camera_path_sample(&p.path, at[i], 640, 480, near_d, far_d, &want, &err), MS_OK);
        expect_same_camera(&got, &want);
        /* the controls hold the path's view: eye, target (the path's target
         * lies on the view, straight ahead) and field */
        ms_camera_key key;
        ms_camera_path_key_at(&p.path, at[i], &key);
        double eye[3];
        ms_viewer_controls_eye(&c, eye);
        for (int a = 0; a < 3; ++a) {
            assert_true(fabs(eye[a] - key.position[a]) < 1e-9);
            assert_true(fabs(c.target[a] - key.target[a]) < 1e-9);
        }
        assert_true(c.fovy_degrees == key.fovy_degrees);
    }
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED); /* reached the end */
    assert_true(ms_viewer_playback_on(&p));
    ms_viewer_playback_free(&p);
}

static void test_user_takes_the_camera_back(void **state)
{
    (void)state;
    ms_viewer_playback p;
    ms_viewer_controls c;
    ms_camera cam, want;
    ms_error err;
    new_playback(&p, &c);
    play_from_start(&p, &c);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.5, &cam, &err), MS_OK);
    /* fly mode on moves nothing: still playing */
    c.fly = true;
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.5, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_PLAYING);
    assert_true(p.time == 1.0);
    c.fly = false;
    /* a drag: stopped at the next frame, the clock kept, the controls' camera */
    ms_viewer_controls_rotate(&c, 12, -5, 200);
    ms_viewer_controls c_after = c;
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.5, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_OFF);
    assert_true(p.time == 1.0);
    assert_memory_equal(&c, &c_after, sizeof c);
    assert_int_equal(ms_viewer_controls_camera(&c, 320, 200, &want, &err), MS_OK);
    expect_same_camera(&cam, &want);
    /* the wheel while paused */
    ms_viewer_playback_step(&p, 1, &c);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_PAUSED);
    ms_viewer_controls_zoom(&c, 1);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_OFF);
    /* a movement key (fly) while playing */
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    ms_viewer_controls_fly(&c, 1, 0, 0, 0.1);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_OFF);
    /* a reset (R) */
    ms_viewer_playback_toggle(&p, &c);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    ms_viewer_controls_reset(&c);
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 320, 200, 0.1, &cam, &err), MS_OK);
    assert_int_equal(p.state, MS_PLAYBACK_OFF);
    ms_viewer_playback_free(&p);
}

static void test_without_a_path(void **state)
{
    (void)state;
    ms_viewer_playback p;
    ms_viewer_controls c;
    ms_camera cam, want;
    ms_error err;
    double lo[3] = {0, 0, 0}, hi[3] = {1, 2, 3};
    ms_viewer_controls_init(&c, lo, hi, 2, 1.0);
    ms_viewer_playback_init(&p, NULL);
    assert_int_equal(ms_viewer_playback_load(&p, NULL, &err), MS_OK);
    ms_viewer_playback_toggle(&p, &c);
    ms_viewer_playback_step(&p, 1, &c);
    assert_false(ms_viewer_playback_on(&p));
    assert_int_equal(ms_viewer_playback_frame_camera(&p, &c, 100, 100, 1, &cam, &err), MS_OK);
    assert_int_equal(ms_viewer_controls_camera(&c, 100, 100, &want, &err), MS_OK);
    expect_same_camera(&cam, &want);
    assert_int_equal(ms_viewer_playback_camera(&p, &c, 100, 100, &cam, &err), MS_ERR_EMPTY);
    assert_string_equal(err.text, "no camera path to play");
    /* a file that is not there: its one line, still no path */
    assert_int_equal(ms_viewer_playback_load(&p, "/nonexistent/walk.cam", &err), MS_ERR_IO);
    assert_non_null(strstr(err.text, "/nonexistent/walk.cam: cannot open"));
    assert_int_equal(p.path.count, 0);
    /* the first path given wins: a second load keeps it */
    ms_camera_path path;
    assert_int_equal(ms_camera_path_parse(path_text, strlen(path_text), "walk.cam", &path, &err), MS_OK);
    ms_viewer_playback_init(&p, &path);
    assert_int_equal(ms_viewer_playback_load(&p, "/nonexistent/other.cam", &err), MS_OK);
    assert_int_equal(p.path.count, 3);
    ms_viewer_playback_free(&p);
    assert_null(p.path.keys);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_play_pause_and_the_end),
        cmocka_unit_test(test_steps),
        cmocka_unit_test(test_camera_is_the_paths),
        cmocka_unit_test(test_user_takes_the_camera_back),
        cmocka_unit_test(test_without_a_path),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
