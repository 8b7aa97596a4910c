/* Camera, frustum culling, screen-space precision and hysteresis. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <math.h>
#include <string.h>
#include <cmocka.h>

#include "ms_camera.h"
#include "ms_viewer_controls.h"

static ms_camera standard_camera(void)
{
    /* At (0,0,10) looking at the origin, y up, 90 degrees, 1000x1000. */
    const double pos[3] = {0, 0, 10}, target[3] = {0, 0, 0}, up[3] = {0, 1, 0};
    ms_camera c;
    assert_int_equal(ms_camera_look_at(pos, target, up, 90.0, 1000, 1000, 0.01, 1000, &c, NULL),
                     MS_OK);
    return c;
}

static void test_look_at_basis_and_errors(void **state)
{
    (void)state;
    ms_camera c = standard_camera();
    assert_true(c.forward[2] == -1.0 && c.up[1] == 1.0 && c.right[0] == 1.0);
    assert_float_equal(ms_camera_pixels_per_unit(&c), 500.0, 1e-9);
    const double p[3] = {1, 2, 3}, up[3] = {0, 0, 1}, nan3[3] = {NAN, 0, 0};
    const double along[3] = {1, 2, 10};
    ms_camera out;
    ms_error err;
    assert_int_equal(ms_camera_look_at(p, p, up, 60, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "camera: position and target coincide");
    assert_int_equal(ms_camera_look_at(p, along, up, 60, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "camera: up is parallel to the view direction");
    const double target[3] = {0, 0, 0};
    assert_int_equal(ms_camera_look_at(p, target, up, 0, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_int_equal(ms_camera_look_at(p, target, up, 180, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_int_equal(ms_camera_look_at(p, target, up, NAN, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_int_equal(ms_camera_look_at(nan3, target, up, 60, 100, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_int_equal(ms_camera_look_at(p, target, up, 60, 0, 100, 0.1, 10, &out, &err), MS_ERR_ARG);
    assert_int_equal(ms_camera_look_at(p, target, up, 60, 100, 100, 1, 1, &out, &err), MS_ERR_ARG);
}

static void test_frustum_culling(void **state)
{
    (void)state;
    ms_camera c = standard_camera();
    ms_frustum fr;
    ms_camera_frustum(&c, &fr);
    const double centre_lo[3] = {-1, -1, -1}, centre_hi[3] = {1, 1, 1};
    assert_true(ms_frustum_keeps_box(&fr, centre_lo, centre_hi, 0));
    const double behind_lo[3] = {-1, -1, 11}, behind_hi[3] = {1, 1, 12};
    assert_false(ms_frustum_keeps_box(&fr, behind_lo, behind_hi, 0));
    const double far_lo[3] = {-1, -1, -2000}, far_hi[3] = {1, 1, -995};
    assert_false(ms_frustum_keeps_box(&fr, far_lo, far_hi, 0));
    /* 90 degrees: at depth 10 (z = 0) the frustum spans x in [-10, 10]. */
    const double left_lo[3] = {-12, -1, -0.5}, left_hi[3] = {-10.5, 1, 0};
    assert_false(ms_frustum_keeps_box(&fr, left_lo, left_hi, 0));
    assert_true(ms_frustum_keeps_box(&fr, left_lo, left_hi, 1.0)); /* margin keeps it */
    const double edge_lo[3] = {-12, -1, -0.5}, edge_hi[3] = {-9.5, 1, 0};
    assert_true(ms_frustum_keeps_box(&fr, edge_lo, edge_hi, 0));
    const double top_lo[3] = {-1, 10.5, -0.5}, top_hi[3] = {1, 11, 0};
    assert_false(ms_frustum_keeps_box(&fr, top_lo, top_hi, 0));
}

static void test_distance_and_precision(void **state)
{
    (void)state;
    ms_camera c = standard_camera();
    const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    assert_float_equal(ms_camera_box_distance(&c, lo, hi), 9.0, 1e-12);
    const double around_lo[3] = {-1, -1, 9}, around_hi[3] = {1, 1, 11};
    assert_true(ms_camera_box_distance(&c, around_lo, around_hi) == 0.0);
    const double corner_lo[3] = {3, 4, 10}, corner_hi[3] = {5, 5, 11};
    assert_float_equal(ms_camera_box_distance(&c, corner_lo, corner_hi), 5.0, 1e-12);
    /* Side 1 at distance 10 with 500 px per unit: the half-diagonal, sqrt(3)*25
     * px, at 0 bits; 43.3 px needs 6 bits for 1 px (0.68 px). */
    double need = ms_screen_bits_needed(&c, 1.0, 10.0, 1.0);
    assert_float_equal(need, log2(sqrt(3.0) * 25.0), 1e-12);
    assert_int_equal(ms_select_bits(need, 0, 0, 16, 0.5), 6);
    assert_float_equal(ms_screen_error_px(&c, 1.0, 0, 10.0), sqrt(3.0) * 25.0, 1e-12);
    assert_float_equal(ms_screen_error_px(&c, 1.0, 6, 10.0), sqrt(3.0) * 25.0 / 64.0, 1e-12);
    assert_float_equal(ms_screen_error_px(&c, 1.0, 0, 10.0), 1.0 * exp2(need), 1e-9);
    assert_true(isinf(ms_screen_error_px(&c, 1.0, 3, 0.0)));
    /* Coarser tolerance, fewer bits: 4 px is 2 bits less. */
    assert_float_equal(ms_screen_bits_needed(&c, 1.0, 10.0, 4.0), need - 2.0, 1e-12);
    /* Camera very near: everything; very far: nothing beyond the minimum. */
    assert_true(isinf(ms_screen_bits_needed(&c, 1.0, 0.0, 1.0)));
    assert_int_equal(ms_select_bits(ms_screen_bits_needed(&c, 1.0, 0.0, 1.0), 3, 0, 16, 0.5), 16);
    assert_int_equal(ms_select_bits(ms_screen_bits_needed(&c, 1.0, 1e12, 1.0), 9, 7, 16, 0.5), 7);
}

/* Clipping planes that frame a box from any eye: outside it, near is half the
 * way to its nearest point and far 1 % past its farthest corner; inside it,
 * near is far * 5e-5; a bad box gives the fixed fallback. */
static void test_depth_range_frames_the_box(void **state)
{
    (void)state;
    const double lo[3] = {-1, -1, -1}, hi[3] = {1, 1, 1};
    double near_d, far_d;
    for (double d = 3; d < 1e7; d *= 10) {
        const double eye[3] = {0, 0, d};
        ms_camera_depth_range(eye, lo, hi, &near_d, &far_d);
        assert_float_equal(near_d, 0.5 * (d - 1), 1e-9 * d);
        assert_float_equal(far_d, 1.01 * sqrt(2.0 + (d + 1) * (d + 1)), 1e-9 * d);
    }
    const double inside[3] = {0.5, 0, 0};
    ms_camera_depth_range(inside, lo, hi, &near_d, &far_d);
    assert_float_equal(far_d, 1.01 * sqrt(1.5 * 1.5 + 2.0), 1e-12);
    assert_float_equal(near_d, far_d * 5e-5, 1e-15);
    const double bad_lo[3] = {1, 0, NAN}, eye[3] = {0, 0, 5};
    ms_camera_depth_range(eye, bad_lo, hi, &near_d, &far_d);
    assert_true(near_d == 1e-4 && far_d == 1e4);
    const double point[3] = {0, 0, 0};
    ms_camera_depth_range(point, point, point, &near_d, &far_d);
    assert_true(near_d > 0 && far_d > near_d);
}

static void test_hysteresis(void **state)
{
    (void)state;
    /* Refines at once when the need exceeds the current precision. */
    assert_int_equal(ms_select_bits(8.01, 8, 0, 16, 0.5), 9);
    assert_int_equal(ms_select_bits(8.0, 8, 0, 16, 0.5), 8);
    /* Hovering just under a boundary does not coarsen... */
    assert_int_equal(ms_select_bits(7.9, 8, 0, 16, 0.5), 8);
    assert_int_equal(ms_select_bits(7.0, 8, 0, 16, 0.5), 8);
    /* ...only a clear margin does. */
    assert_int_equal(ms_select_bits(6.5, 8, 0, 16, 0.5), 7);
    assert_int_equal(ms_select_bits(2.2, 8, 0, 16, 0.5), 3);
    /* Oscillating need around 7.0 +- 0.2 settles, never flips back and forth. */
    unsigned bits = 8, changes = 0;
    for (int frame = 0; frame < 100; ++frame) {
        unsigned next = ms_select_bits(7.0 + ((frame & 1) ? 0.2 : -0.2), bits, 0, 16, 0.5);
        changes += next != bits;
        bits = next;
    }
    assert_int_equal(bits, 8);
    assert_int_equal(changes, 0);
    assert_int_equal(ms_select_bits(NAN, 4, 0, 16, 0.5), 16);
}

/* APO levels by footprint: exact levels for a camera whose pixels per unit
 * is 100 (height 200, fovy 90 degrees), a unit cube 4 units away: a texel at
 * depth d covers 25 / 2^d pixels. */
static void test_apo_footprint_levels(void **state)
{
    (void)state;
    ms_camera c;
    const double pos[3] = {0, 0, 0}, target[3] = {1, 0, 0}, up[3] = {0, 0, 1};
    assert_int_equal(ms_camera_look_at(pos, target, up, 90.0, 100, 200, 0.01, 100, &c, NULL),
                     MS_OK);
    assert_true(fabs(ms_camera_pixels_per_unit(&c) - 100.0) < 1e-9);
    const double cube[3] = {4, -0.5, -0.5};
    /* 25 / 2^d <= 1: d = 5 (0.78 px), six levels */
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 1.0, 11), 6);
    /* 25 / 2^d <= 3: d = 4 (1.56 px; d = 3 gives 3.1 px) */
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 3.0, 11), 5);
    /* exactly at the tolerance counts as within: 12.5 px at d = 1, 25 px at d = 0 */
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 12.5, 11), 2);
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 25.0, 11), 1);
    /* the root texel is always wanted, however small the cell looks */
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 50.0, 11), 1);
    /* twice as far, one level less; a cube twice as large, one level more */
    const double far_cube[3] = {8, -0.5, -0.5};
    assert_int_equal(ms_apo_footprint_levels(&c, far_cube, 1.0, 1.0, 11), 5);
    const double big_cube[3] = {4, -1, -1};
    assert_int_equal(ms_apo_footprint_levels(&c, big_cube, 2.0, 1.0, 11), 7);
    /* the cap: the caller's apo_levels, or the chunk's levels; 0 is off */
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 1.0, 4), 4);
    assert_int_equal(ms_apo_footprint_levels(&c, cube, 1.0, 1.0, 0), 0);
    /* inside the cube: measured from the near plane (0.01): 10,000 px at d = 0,
     * d = 14 (0.61 px), 15 levels, or the cap */
    const double around[3] = {-0.5, -0.5, -0.5};
    assert_int_equal(ms_apo_footprint_levels(&c, around, 1.0, 1.0, 32), 15);
    assert_int_equal(ms_apo_footprint_levels(&c, around, 1.0, 1.0, 11), 11);
    /* a cube off to the side is measured at its nearest point: (4, 3, 0) is 5 away:
     * 20 / 2^d <= 1 at d = 5 */
    const double side_cube[3] = {4, 3, -0.5};
    assert_int_equal(ms_apo_footprint_levels(&c, side_cube, 1.0, 1.0, 11), 6);
    assert_int_equal(ms_apo_footprint_levels(&c, side_cube, 1.0, 20.0 / 16.0, 11), 5);
}

/* The thumbnails' home view is meshview's: the same camera, to the last
 * bit, as ms_viewer_controls_init + _camera, for boxes long along each axis,
 * each up axis, wide, tall and square viewports and an empty box. */
static void test_home_view_is_meshviews(void **state)
{
    (void)state;
    const double boxes[][6] = {{0, 0, 0, 1, 1, 1},       {-3, 2, 5, 7, 2.5, 6},
                               {1e6, 1e6, 0, 1e6 + 2, 1e6 + 9, 1}, {0, -4, 0, 1, 4, 0.5},
                               {2, 2, 2, 2, 2, 2}};
    const double sizes[][2] = {{160, 120}, {120, 160}, {64, 64}, {960, 540}};
    for (size_t b = 0; b < sizeof boxes / sizeof *boxes; ++b)
        for (int up = 0; up < 3; ++up)
            for (size_t s = 0; s < sizeof sizes / sizeof *sizes; ++s) {
                const double *lo = boxes[b], *hi = boxes[b] + 3;
                double w = sizes[s][0], h = sizes[s][1];
                ms_viewer_controls c;
                ms_viewer_controls_init(&c, lo, hi, up, w / h);
                ms_camera want, got;
                ms_error err;
                assert_int_equal(ms_viewer_controls_camera(&c, w, h, &want, &err), MS_OK);
                assert_int_equal(ms_camera_home(lo, hi, up, w, h, &got, &err), MS_OK);
                for (int k = 0; k < 3; ++k) {
                    assert_true(fabs(got.position[k] - want.position[k]) <=
                                1e-12 * (1 + fabs(want.position[k])));
                    assert_true(fabs(got.forward[k] - want.forward[k]) <= 1e-12);
                    assert_true(fabs(got.up[k] - want.up[k]) <= 1e-12);
                }
                assert_true(got.fovy == want.fovy);
                assert_true(fabs(got.near_distance - want.near_distance) <= 1e-9 * want.near_distance);
                assert_true(fabs(got.far_distance - want.far_distance) <= 1e-9 * want.far_distance);
            }
    /* z up is the default, as meshview's; a bad box or viewport is refused */
    const double lo[3] = {0, 0, 0}, hi[3] = {1, 2, 3}, bad[3] = {0, NAN, 0};
    ms_camera z, other;
    ms_error err;
    assert_int_equal(ms_camera_home(lo, hi, 2, 160, 120, &z, &err), MS_OK);
    assert_int_equal(ms_camera_home(lo, hi, 7, 160, 120, &other, &err), MS_OK);
    assert_memory_equal(&z, &other, sizeof z);
    assert_int_equal(ms_camera_home(bad, hi, 2, 160, 120, &other, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "home view: a non-finite box or an empty viewport");
    assert_int_equal(ms_camera_home(lo, hi, 2, 0, 120, &other, &err), MS_ERR_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_look_at_basis_and_errors),
        cmocka_unit_test(test_frustum_culling),
        cmocka_unit_test(test_distance_and_precision),
        cmocka_unit_test(test_depth_range_frames_the_box),
        cmocka_unit_test(test_hysteresis),
        cmocka_unit_test(test_apo_footprint_levels),
        cmocka_unit_test(test_home_view_is_meshviews),
    };
    return cmocka_run_group_tests_name("camera", tests, NULL, NULL);
}
