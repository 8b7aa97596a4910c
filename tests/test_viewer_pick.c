/* Picking a piece of a scene (ms_viewer_pick.h), pure:
 *   - on the shipped gallery's placements (scripts/scenes/gallery.json, each
 *     model given the same made-up bounds), the piece picked for world points:
 *     each piece's centre, the top and bottom of its bounds (boundaries), a
 *     point just inside and just outside the margin, and points of the room
 *     (the floor, a wall, a plinth's top beside its model, the air between
 *     two plinths), which pick nothing;
 *   - ties: a point in two pieces' bounds picks the nearer centre, the lower
 *     index on equal distances;
 *   - the sphere about a placed piece and the framing of it (orbit centre,
 *     distance) are the exact values;
 *   - cycling the selection wraps round both ways. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_scene.h"
#include "ms_viewer_pick.h"

#define GALLERY "scripts/scenes/gallery.json"

/* Made-up bounds of every gallery model, in its own units: 2 wide, 4 along
 * y, 1 along z (so a y-up model is 4 tall, a z-up one 1 tall). */
static const double model_lo[3] = {-1, -2, -0.5}, model_hi[3] = {1, 2, 0.5};

typedef struct gallery {
    ms_scene scene;
    ms_viewer_pick_box boxes[MS_SCENE_MAX_MODELS];
    size_t count;
} gallery;

static void load_gallery(gallery *g)
{
    ms_error err;
    if (ms_scene_load(GALLERY, &g->scene, &err) != MS_OK)
        fail_msg("%s", err.text);
    g->count = g->scene.model_count;
    assert_int_equal(g->count, 9);
    for (size_t i = 0; i < g->count; ++i) {
        ms_scene_model_transform(&g->scene.models[i], model_lo, model_hi, g->boxes[i].placement);
        memcpy(g->boxes[i].lo, model_lo, sizeof model_lo);
        memcpy(g->boxes[i].hi, model_hi, sizeof model_hi);
    }
}

static long pick(const gallery *g, double x, double y, double z)
{
    double p[3] = {x, y, z};
    return ms_viewer_pick_box_at(g->boxes, g->count, p, MS_VIEWER_PICK_MARGIN);
}

/* The model's height in its own units: its bounds along its up axis. */
static double own_height(const ms_scene_model *m)
{
    return model_hi[m->up_axis] - model_lo[m->up_axis];
}

static void test_gallery_pieces(void **state)
{
    (void)state;
    gallery g;
    load_gallery(&g);
    const double diagonal = sqrt(2.0 * 2.0 + 4.0 * 4.0 + 1.0 * 1.0);
    for (size_t i = 0; i < g.count; ++i) {
        const ms_scene_model *m = &g.scene.models[i];
        const double *at = m->position; /* the bottom centre of its bounds */
        double h = m->height, scale = m->height / own_height(m);
        /* the centre, the top and the bottom (on the plinth) of its bounds */
        assert_int_equal(pick(&g, at[0], at[1] + h / 2, at[2]), (long)i);
        assert_int_equal(pick(&g, at[0], at[1] + h, at[2]), (long)i);
        assert_int_equal(pick(&g, at[0], at[1], at[2]), (long)i);
        /* above the top: within the margin, then past it */
        double margin = MS_VIEWER_PICK_MARGIN * diagonal * scale;
        assert_int_equal(pick(&g, at[0], at[1] + h + 0.5 * margin, at[2]), (long)i);
        assert_int_equal(pick(&g, at[0], at[1] + h + 1.5 * margin, at[2]), -1);
        /* under its plinth's top, inside the plinth: the room */
        assert_int_equal(pick(&g, at[0], at[1] - 2 * margin, at[2]), -1);
        /* its sphere: the bounds' centre and half their diagonal, placed */
        double centre[3], radius;
        ms_scene_placed_sphere(g.boxes[i].placement, g.boxes[i].lo, g.boxes[i].hi, centre, &radius);
        assert_true(fabs(centre[0] - at[0]) < 1e-12 && fabs(centre[1] - (at[1] + h / 2)) < 1e-12 &&
                    fabs(centre[2] - at[2]) < 1e-12);
        assert_true(fabs(radius - 0.5 * diagonal * scale) < 1e-12);
    }
    /* the room: the floor's middle, a wall, a plinth's corner beside the
     * bunny, the air between the bunny's and the armadillo's plinths */
    assert_int_equal(pick(&g, 0, 0, 0), -1);
    assert_int_equal(pick(&g, 6, 2, 0), -1);
    assert_int_equal(pick(&g, -3.5 + 0.39, 1.0, 8 + 0.39), -1);
    assert_int_equal(pick(&g, -3.5, 1.2, 5.5), -1);
    ms_scene_free(&g.scene);
}

/* The gallery's placements turn the models (yaw) and stand z-up ones up:
 * points of a piece's own bounds, placed, pick it wherever they are. */
static void test_gallery_corners(void **state)
{
    (void)state;
    gallery g;
    load_gallery(&g);
    for (size_t i = 0; i < g.count; ++i)
        for (int k = 0; k < 8; ++k) {
            /* a corner of the bounds, pulled in by a thousandth towards the centre */
            double own[3], world[3];
            for (int a = 0; a < 3; ++a) {
                double corner = (k >> a) & 1 ? model_hi[a] : model_lo[a];
                own[a] = corner + 0.001 * (0.5 * (model_lo[a] + model_hi[a]) - corner);
            }
            const double *t = g.boxes[i].placement;
            for (int r = 0; r < 3; ++r)
                world[r] = t[r] * own[0] + t[4 + r] * own[1] + t[8 + r] * own[2] + t[12 + r];
            assert_int_equal(pick(&g, world[0], world[1], world[2]), (long)i);
        }
    ms_scene_free(&g.scene);
}

/* Two unplaced boxes (identity placements). */
static void two_boxes(ms_viewer_pick_box b[2], double a_hi_x, double b_lo_x, double b_hi_x)
{
    memset(b, 0, 2 * sizeof *b);
    for (int i = 0; i < 2; ++i)
        for (int d = 0; d < 4; ++d)
            b[i].placement[5 * d] = 1;
    double lo[2] = {0, b_lo_x}, hi[2] = {a_hi_x, b_hi_x};
    for (int i = 0; i < 2; ++i) {
        b[i].lo[0] = lo[i], b[i].hi[0] = hi[i];
        b[i].hi[1] = b[i].hi[2] = 1;
    }
}

static void test_ties(void **state)
{
    (void)state;
    ms_viewer_pick_box b[2];
    /* touching at x = 1, the first narrower: its centre is nearer */
    two_boxes(b, 1, 1, 3);
    double face[3] = {1, 0.5, 0.5};
    assert_int_equal(ms_viewer_pick_box_at(b, 2, face, 0), 0);
    /* the same widths: equal distances, the lower index */
    two_boxes(b, 1, 1, 2);
    assert_int_equal(ms_viewer_pick_box_at(b, 2, face, 0), 0);
    ms_viewer_pick_box swapped[2] = {b[1], b[0]};
    assert_int_equal(ms_viewer_pick_box_at(swapped, 2, face, 0), 0);
    /* overlapping: [0, 2] and [1, 3]; at x = 1.6 the second's centre (2) is
     * nearer than the first's (1) */
    two_boxes(b, 2, 1, 3);
    double inside[3] = {1.6, 0.5, 0.5};
    assert_int_equal(ms_viewer_pick_box_at(b, 2, inside, 0), 1);
    inside[0] = 1.4;
    assert_int_equal(ms_viewer_pick_box_at(b, 2, inside, 0), 0);
    /* outside both; no boxes; a degenerate placement is skipped */
    double away[3] = {5, 0.5, 0.5};
    assert_int_equal(ms_viewer_pick_box_at(b, 2, away, 0), -1);
    assert_int_equal(ms_viewer_pick_box_at(b, 0, inside, 0), -1);
    memset(b[0].placement, 0, sizeof b[0].placement);
    assert_int_equal(ms_viewer_pick_box_at(b, 2, inside, 0), 1);
}

static void test_framing(void **state)
{
    (void)state;
    gallery g;
    load_gallery(&g);
    ms_viewer_controls c;
    double lo[3] = {-2, 0, -2}, hi[3] = {2, 4, 2};
    ms_viewer_controls_init(&c, lo, hi, 1, 1.0);
    double yaw = c.yaw, pitch = c.pitch;
    /* the gargoyle, z-up: 0.35 m tall on its plinth at (2.5, 1.2, -11) */
    assert_string_equal(g.scene.models[8].model, "gargoyle");
    double centre[3], radius;
    ms_scene_placed_sphere(g.boxes[8].placement, g.boxes[8].lo, g.boxes[8].hi, centre, &radius);
    ms_viewer_controls_frame(&c, centre, radius, 16.0 / 9.0);
    const double expect_radius = 0.5 * sqrt(21.0) * 0.35; /* half the diagonal times 0.35 / 1 */
    assert_true(fabs(radius - expect_radius) < 1e-12);
    assert_true(fabs(c.target[0] - 2.5) < 1e-12 && fabs(c.target[1] - (1.2 + 0.175)) < 1e-12 &&
                fabs(c.target[2] + 11) < 1e-12);
    assert_true(c.distance == radius / sin(40 * M_PI / 360)); /* half of the 40 degree field */
    assert_true(c.yaw == yaw && c.pitch == pitch);             /* the view keeps its direction */
    /* narrower than tall: the horizontal field holds it */
    ms_viewer_controls_frame(&c, centre, radius, 0.5);
    assert_true(c.distance == radius / sin(atan(tan(40 * M_PI / 360) * 0.5)));
    /* the sphere then just fits: its tangent from the eye is the half field */
    double eye[3], d2 = 0;
    ms_viewer_controls_eye(&c, eye);
    for (int a = 0; a < 3; ++a)
        d2 += (eye[a] - centre[a]) * (eye[a] - centre[a]);
    assert_true(fabs(asin(radius / sqrt(d2)) - atan(tan(40 * M_PI / 360) * 0.5)) < 1e-9);
    /* nothing to frame: unchanged */
    ms_viewer_controls before = c;
    ms_viewer_controls_frame(&c, centre, 0, 1);
    ms_viewer_controls_frame(&c, centre, NAN, 1);
    ms_viewer_controls_frame(&c, centre, 1, 0);
    assert_memory_equal(&c, &before, sizeof c);
    ms_scene_free(&g.scene);
}

static void test_cycle(void **state)
{
    (void)state;
    assert_int_equal(ms_viewer_pick_cycle(-1, 9, 1), 0);
    assert_int_equal(ms_viewer_pick_cycle(-1, 9, -1), 8);
    assert_int_equal(ms_viewer_pick_cycle(0, 9, 1), 1);
    assert_int_equal(ms_viewer_pick_cycle(8, 9, 1), 0);
    assert_int_equal(ms_viewer_pick_cycle(0, 9, -1), 8);
    assert_int_equal(ms_viewer_pick_cycle(4, 9, -1), 3);
    assert_int_equal(ms_viewer_pick_cycle(12, 9, -1), 8); /* out of range: as none */
    assert_int_equal(ms_viewer_pick_cycle(3, 0, 1), -1);
    assert_int_equal(ms_viewer_pick_cycle(0, 1, 1), 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_gallery_pieces), cmocka_unit_test(test_gallery_corners),
        cmocka_unit_test(test_ties),           cmocka_unit_test(test_framing),
        cmocka_unit_test(test_cycle),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
