/* Looking closely in meshview, the parts that need no window
 * (docs/VIEWER.md, "Measuring", "Light", "Shareable views"):
 *   - measuring on synthetic models baked at 20 bits and streamed in process
 *     by the client core (local mode) until every cell is at 20 bits (the
 *     core's camera asks for more than the model has): a unit cube's edge
 *     (from face to face, rays along x) and a sphere's diameter (pole to pole,
 *     rays along z through the drawn poles) are within the reported precision
 *     of 1, and the precision
 *     is the grid step box_side / 2^20 exactly; a chain of three points sums
 *     its segments; a point picked on a coarse frame follows the surface when
 *     cast again on the fine one, its precision rising to the grid step at 20
 *     bits;
 *   - the ray cast on a hand-made frame: the nearest hit in front, the hit
 *     nearest an anchor along the whole line, a miss; the pixel ray through
 *     the framebuffer's centre is the view direction;
 *   - the light: --light's parsing, the eye direction for azimuth and
 *     elevation, the world direction from a camera, the raking presets' cycle
 *     and a drag's clamping;
 *   - the view text: printed and parsed back bit for bit (random states,
 *     with light and points), a canonical text printed back to itself, and
 *     hostile texts refused with one line each. */
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

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_client_core.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_progress.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_viewer_light.h"
#include "ms_section.h"
#include "ms_viewer_measure.h"
#include "ms_viewer_probe.h"
#include "ms_viewer_share.h"

#define WAIT_SECONDS 60.0

/* --- synthetic models ----------------------------------------------------- */

static void add_vertex(ms_mesh *m, double x, double y, double z)
{
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, m->vertex_count + 1, m->triangle_count, &err), MS_OK);
    double *p = &m->positions[3 * m->vertex_count++];
    p[0] = x, p[1] = y, p[2] = z;
}

static void add_triangle(ms_mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, m->vertex_count, m->triangle_count + 1, &err), MS_OK);
    uint32_t *t = &m->triangles[3 * m->triangle_count++];
    t[0] = a, t[1] = b, t[2] = c;
}

/* The unit cube [0, 1]^3, 12 triangles wound outwards. */
static void cube(ms_mesh *m)
{
    for (int i = 0; i < 8; ++i)
        add_vertex(m, i & 1, (i >> 1) & 1, (i >> 2) & 1);
    static const uint32_t quads[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4},
                                         {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
    for (int q = 0; q < 6; ++q) {
        add_triangle(m, quads[q][0], quads[q][1], quads[q][2]);
        add_triangle(m, quads[q][0], quads[q][2], quads[q][3]);
    }
}

/* A latitude-longitude sphere of radius 0.5 about (0.5, 0.5, 0.5), 48 x 96,
 * its poles vertices at z = 1 and z = 0. */
static void sphere(ms_mesh *m)
{
    enum { RINGS = 48, SEGMENTS = 96 };
    add_vertex(m, 0.5, 0.5, 1.0);
    add_vertex(m, 0.5, 0.5, 0.0);
    for (int r = 1; r < RINGS; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            double theta = M_PI * r / RINGS, phi = 2.0 * M_PI * k / SEGMENTS;
            add_vertex(m, 0.5 + 0.5 * sin(theta) * cos(phi), 0.5 + 0.5 * sin(theta) * sin(phi),
                       0.5 + 0.5 * cos(theta));
        }
#define RING(r, k) (2u + (uint32_t)((r) - 1) * SEGMENTS + (uint32_t)(((k) + SEGMENTS) % SEGMENTS))
    for (int k = 0; k < SEGMENTS; ++k) {
        add_triangle(m, 0, RING(1, k), RING(1, k + 1));
        add_triangle(m, 1, RING(RINGS - 1, k + 1), RING(RINGS - 1, k));
    }
    for (int r = 1; r < RINGS - 1; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            add_triangle(m, RING(r, k), RING(r + 1, k), RING(r + 1, k + 1));
            add_triangle(m, RING(r, k), RING(r + 1, k + 1), RING(r, k + 1));
        }
#undef RING
}

typedef struct model {
    char dir[512], archives[600], file[4096];
    ms_archive_header header;
} model;

/* Bakes the mesh at 20 bits, no APO, cells of at most min_tris triangles. */
static void bake(model *md, const char *name, ms_mesh *mesh, uint32_t min_tris)
{
    ms_error err;
    char ply[700];
    ms_test_tmpdir(md->dir, sizeof md->dir);
    snprintf(md->archives, sizeof md->archives, "%s/archive", md->dir);
    assert_int_equal(mkdir(md->archives, 0755), 0);
    snprintf(ply, sizeof ply, "%s/%s.ply", md->dir, name);
    assert_int_equal(ms_ply_write(ply, mesh, true, true, &err), MS_OK);
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.apo.enabled = false;
    o.input = ply, o.archive_dir = md->archives, o.name = name;
    o.bits = 20;
    o.min_triangles = min_tris;
    o.threads = 2, o.mem_mb = 64;
    ms_bake_report report;
    if (ms_bake(&o, &report, &err) != MS_OK)
        fail_msg("bake: %s", err.text);
    snprintf(md->file, sizeof md->file, "%s", report.archive_path);
    ms_archive *archive;
    assert_int_equal(ms_archive_open(md->file, &archive, &err), MS_OK);
    md->header = *ms_archive_get_header(archive);
    ms_archive_close(archive);
    assert_int_equal(md->header.bits, 20);
}

/* The frame of a local core looking at the unit box's centre from eye on a
 * viewport of `pixels` square at a 0.05 px tolerance: complete, or the test
 * fails. */
static ms_core_frame *stream(const model *md, const double eye[3], double pixels)
{
    ms_core_options o = {0};
    o.archive_path = md->file;
    o.tolerance_px = 0.05; /* with a 1e6-pixel viewport: more than 20 bits wanted */
    o.hysteresis_bits = 0.0;
    o.export_frames = true;
    ms_core *core;
    ms_error err;
    if (ms_core_start(&o, &core, &err) != MS_OK)
        fail_msg("%s", err.text);
    double target[3] = {0.5, 0.5, 0.5}, up[3] = {0, 0, 1};
    if (fabs(eye[0] - 0.5) < 1e-9 && fabs(eye[1] - 0.5) < 1e-9)
        up[1] = 1, up[2] = 0;
    ms_camera cam;
    assert_int_equal(ms_camera_look_at(eye, target, up, 40, pixels, pixels, 1e-3, 1e3, &cam, &err), MS_OK);
    ms_core_set_camera(core, &cam);
    ms_core_stats stats;
    ms_core_frame *frame = NULL;
    bool complete = ms_test_core_wait_complete(core, WAIT_SECONDS, &stats, &frame);
    ms_core_stop(core);
    if (!complete || !frame)
        fail_msg("the view did not complete: %s", stats.error);
    return frame;
}

/* Every cell of the cut that draws is shown at `bits`. */
static void assert_cut_at(const ms_core_frame *frame, unsigned bits)
{
    for (size_t t = 0; t < frame->mesh.triangle_count; ++t)
        assert_int_equal(ms_core_frame_cell_bits(frame, frame->mesh.triangle_cell[t]), bits);
}

/* A two-point chain from the rays (o0, d0) and (o1, d1): its length is within
 * its precision of `expected`, the precision is the 20-bit grid step. */
static void assert_measures(const ms_core_frame *frame, const model *md, const double o0[3], const double d0[3],
                            const double o1[3], const double d1[3], double expected)
{
    ms_viewer_measure m = {0};
    assert_true(ms_viewer_measure_add(&m, frame, md->header.box_side, o0, d0));
    assert_true(ms_viewer_measure_add(&m, frame, md->header.box_side, o1, d1));
    ms_viewer_measure_result r;
    assert_true(ms_viewer_measure_result_of(&m, md->header.bits, &r));
    double step = md->header.box_side / 1048576.0;
    printf("measured %.9f (exact %.9f, off %.3g) +- %.3g, %u bits\n", r.length, expected, r.length - expected,
           r.precision, r.bits_min);
    assert_true(r.precision == step);
    assert_true(m.hit[0].step == step && m.hit[1].step == step);
    assert_int_equal(r.bits_min, 20);
    assert_true(r.full);
    assert_true(fabs(r.length - expected) <= r.precision);
}

static void test_cube_edge_at_20_bits(void **state)
{
    (void)state;
    model md;
    ms_mesh mesh = {0};
    cube(&mesh);
    bake(&md, "cube", &mesh, 0);
    ms_mesh_free(&mesh);
    double eye[3] = {2.2, -1.7, 1.9};
    ms_core_frame *frame = stream(&md, eye, 1e6);
    assert_cut_at(frame, 20);
    /* face x = 0 to face x = 1 along a line parallel to the edges along x */
    double a[3] = {-1, 0.3, 0.7}, plus[3] = {1, 0, 0}, b[3] = {2, 0.3, 0.7}, minus[3] = {-1, 0, 0};
    assert_measures(frame, &md, a, plus, b, minus, 1.0);
    /* a chain of three points on the top face */
    ms_viewer_measure m = {0};
    double down[3] = {0, 0, -1}, p0[3] = {0.1, 0.1, 3}, p1[3] = {0.9, 0.1, 3}, p2[3] = {0.9, 0.7, 3};
    assert_true(ms_viewer_measure_add(&m, frame, md.header.box_side, p0, down));
    assert_true(ms_viewer_measure_add(&m, frame, md.header.box_side, p1, down));
    assert_true(ms_viewer_measure_add(&m, frame, md.header.box_side, p2, down));
    ms_viewer_measure_result r;
    assert_true(ms_viewer_measure_result_of(&m, md.header.bits, &r));
    assert_int_equal(r.points, 3);
    assert_true(fabs(r.length - 1.4) < 1e-9);
    assert_true(fabs(r.last_length - 0.6) < 1e-9);
    assert_true(r.precision == 2 * md.header.box_side / 1048576.0);
    ms_viewer_measure_pop(&m);
    assert_true(ms_viewer_measure_result_of(&m, md.header.bits, &r));
    assert_true(fabs(r.length - 0.8) < 1e-9);
    /* a ray that misses adds nothing */
    double off[3] = {5, 5, 5};
    assert_false(ms_viewer_measure_add(&m, frame, md.header.box_side, off, down));
    assert_int_equal(m.count, 2);
    ms_core_frame_free(frame);
    ms_test_rmdir(md.dir);
}

static void test_sphere_diameter_at_20_bits(void **state)
{
    (void)state;
    model md;
    ms_mesh mesh = {0};
    sphere(&mesh);
    bake(&md, "sphere", &mesh, 600); /* a tree of cells */
    ms_mesh_free(&mesh);
    double far_eye[3] = {40, -30, 25}, eye[3] = {2.2, -1.7, 1.9};
    /* a coarse frame first: a point picked there, then the fine frame */
    ms_core_frame *coarse = stream(&md, far_eye, 64);
    ms_core_frame *frame = stream(&md, eye, 1e6);
    assert_cut_at(frame, 20);
    assert_true(coarse->cut_count < frame->cut_count);
    /* picked at the poles: the rays along z through the drawn poles (the
     * highest and the lowest vertex), as a click on each pole would be */
    const ms_view_mesh *cut = &frame->mesh;
    size_t hi = 0, lo = 0;
    for (size_t v = 1; v < cut->vertex_count; ++v) {
        hi = cut->positions[3 * v + 2] > cut->positions[3 * hi + 2] ? v : hi;
        lo = cut->positions[3 * v + 2] < cut->positions[3 * lo + 2] ? v : lo;
    }
    double top[3] = {cut->positions[3 * hi], cut->positions[3 * hi + 1], 3}, down[3] = {0, 0, -1};
    double bottom[3] = {cut->positions[3 * lo], cut->positions[3 * lo + 1], -2}, upward[3] = {0, 0, 1};
    assert_measures(frame, &md, top, down, bottom, upward, 1.0);

    ms_viewer_measure m = {0};
    double side[3] = {3, 0.5, 0.5}, west[3] = {-1, 0, 0};
    assert_true(ms_viewer_measure_add(&m, coarse, md.header.box_side, side, west));
    unsigned coarse_bits = m.hit[0].bits;
    assert_true(coarse_bits < 20);
    assert_true(m.hit[0].step == ldexp(md.header.box_side, -(int)coarse_bits));
    double coarse_x = m.hit[0].point[0];
    ms_viewer_measure_update(&m, frame, md.header.box_side);
    assert_true(m.found[0]);
    assert_int_equal(m.hit[0].bits, 20);
    /* on the fine surface: the sphere's point (1, 0.5, 0.5), to the 96-gon's sag */
    double sag = 0.5 * (1 - cos(M_PI / 96));
    printf("coarse %u bits: x %.9f; fine: x %.9f\n", coarse_bits, coarse_x, m.hit[0].point[0]);
    assert_true(fabs(m.hit[0].point[0] - 1.0) <= sag + m.hit[0].step);
    ms_core_frame_free(coarse);
    ms_core_frame_free(frame);
    ms_test_rmdir(md.dir);
}

/* The probe (ms_viewer_probe.h): points picked on a coarse frame of the
 * sphere (a tree of cells) are refined to 20 bits by a core of its own
 * fetching the cells under them, and the diameter between the poles is then
 * within the 20-bit step of 1; a point removed while its probe runs is not
 * written. */
static void test_probe_refines_to_full_precision(void **state)
{
    (void)state;
    model md;
    ms_mesh mesh = {0};
    sphere(&mesh);
    bake(&md, "sphere", &mesh, 600);
    ms_mesh_free(&mesh);
    double far_eye[3] = {40, -30, 25};
    ms_core_frame *coarse = stream(&md, far_eye, 64);
    ms_viewer_measure m = {0};
    double top[3] = {0.5, 0.5, 3}, down[3] = {0, 0, -1}, bottom[3] = {0.5, 0.5, -2}, upward[3] = {0, 0, 1};
    assert_true(ms_viewer_measure_add(&m, coarse, md.header.box_side, top, down));
    assert_true(ms_viewer_measure_add(&m, coarse, md.header.box_side, bottom, upward));
    ms_viewer_measure_result before, after;
    assert_true(ms_viewer_measure_result_of(&m, 20, &before));
    assert_true(before.bits_min < 20 && !before.refined);

    ms_viewer_source source = {.archive_dir = md.archives};
    ms_viewer_model vm = {.header = md.header};
    snprintf(vm.name, sizeof vm.name, "sphere");
    snprintf(vm.archive_path, sizeof vm.archive_path, "%s", md.file);
    ms_viewer_probe *probe;
    ms_error err;
    assert_int_equal(ms_viewer_probe_start(&source, &vm, &probe, &err), MS_OK);
    double until = ms_now_seconds() + WAIT_SECONDS;
    while (ms_viewer_probe_step(probe, &m) && ms_now_seconds() < until)
        ms_test_sleep_s(0.005);
    assert_true(m.refined[0] && m.refined[1]);
    assert_true(ms_viewer_measure_result_of(&m, 20, &after));
    printf("coarse %.9f +- %.3g (%u bits); probed %.9f +- %.3g (%u bits)\n", before.length, before.precision,
           before.bits_min, after.length, after.precision, after.bits_min);
    assert_true(after.refined && after.full);
    assert_int_equal(after.bits_min, 20);
    assert_true(after.precision == md.header.box_side / 1048576.0);
    /* the rays through (0.5, 0.5): near the poles, the fan's slope (a
     * 96-gon's first ring) adds at most 0.04 of a step a point */
    assert_true(fabs(after.length - 1.0) <= 1.1 * after.precision);
    /* a refined point stays when the view's coarse frame is cast again */
    ms_viewer_measure_update(&m, coarse, md.header.box_side);
    assert_int_equal(m.hit[0].bits, 20);
    /* a point popped while its probe runs: nothing written */
    double side[3] = {3, 0.5, 0.5}, west[3] = {-1, 0, 0};
    assert_true(ms_viewer_measure_add(&m, coarse, md.header.box_side, side, west));
    assert_true(ms_viewer_probe_step(probe, &m));
    ms_viewer_measure_pop(&m);
    assert_false(ms_viewer_probe_step(probe, &m));
    assert_int_equal(m.count, 2);
    ms_viewer_probe_stop(probe);
    ms_core_frame_free(coarse);
    ms_test_rmdir(md.dir);
}

/* --- the ray cast on a hand-made frame ------------------------------------ */

static void test_cast_on_a_hand_made_frame(void **state)
{
    (void)state;
    /* two parallel squares, z = 0 (cell 3) and z = 1 (cell 7), each two triangles */
    double positions[] = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0, 0, 0, 1, 1, 0, 1, 1, 1, 1, 0, 1, 1};
    uint32_t triangles[] = {0, 1, 2, 0, 2, 3, 4, 5, 6, 4, 6, 7}, cells[] = {3, 3, 7, 7};
    uint32_t cut_cells[] = {3, 7};
    uint8_t cut_bits[] = {12, 9};
    ms_core_frame frame = {.generation = 1, .cut_cells = cut_cells, .cut_bits = cut_bits, .cut_count = 2,
                           .cell_count = 8};
    frame.mesh.positions = positions, frame.mesh.vertex_count = 8;
    frame.mesh.triangles = triangles, frame.mesh.triangle_count = 4, frame.mesh.triangle_cell = cells;
    ms_viewer_measure_hit hit;
    double o[3] = {0.25, 0.5, 3}, d[3] = {0, 0, -2};
    assert_true(ms_viewer_measure_cast(&frame, 8.0, o, d, 0, 0, &hit));
    assert_int_equal(hit.cell, 7);
    assert_int_equal(hit.bits, 9);
    assert_true(hit.step == 8.0 / 512);
    assert_true(hit.point[2] == 1.0 && hit.t == 2.0);
    /* nearest to an anchor below both: the lower square, behind the origin too */
    double below[3] = {0.25, 0.5, 0.2};
    assert_true(ms_viewer_measure_cast(&frame, 8.0, below, d, -INFINITY, 0, &hit));
    assert_int_equal(hit.cell, 3);
    assert_true(hit.step == 8.0 / 4096 && hit.point[2] == 0.0);
    /* an edge shared by two triangles is hit; outside the squares nothing */
    double diagonal[3] = {0.5, 0.5, 3};
    assert_true(ms_viewer_measure_cast(&frame, 8.0, diagonal, d, 0, 0, &hit));
    double outside[3] = {1.5, 0.5, 3}, zero[3] = {0, 0, 0};
    assert_false(ms_viewer_measure_cast(&frame, 8.0, outside, d, 0, 0, &hit));
    assert_false(ms_viewer_measure_cast(&frame, 8.0, o, zero, 0, 0, &hit));
    assert_false(ms_viewer_measure_cast(NULL, 8.0, o, d, 0, 0, &hit));
    /* a section cutting away z > 0.5: the chain's ray passes through the upper
     * square (not drawn) to the lower one; without the plane, the upper again */
    ms_viewer_measure m;
    memset(&m, 0, sizeof m);
    double cut[1][4], cut_point[3] = {0, 0, 0.5}, cut_normal[3] = {0, 0, 1};
    ms_section_plane(cut_point, cut_normal, cut[0]);
    assert_true(ms_viewer_measure_set_planes(&m, (const double(*)[4])cut, 1));
    assert_false(ms_viewer_measure_set_planes(&m, (const double(*)[4])cut, 1)); /* unchanged */
    assert_true(ms_viewer_measure_add(&m, &frame, 8.0, o, d));
    assert_int_equal(m.hit[0].cell, 3);
    assert_true(m.hit[0].point[2] == 0.0);
    assert_true(ms_viewer_measure_set_planes(&m, NULL, 0));
    ms_viewer_measure_update(&m, &frame, 8.0); /* cast again from its anchor, both ways */
    assert_true(m.found[0] && m.hit[0].point[2] == 0.0); /* nearest the anchor: where it was */
    assert_true(ms_viewer_measure_add(&m, &frame, 8.0, o, d));
    assert_int_equal(m.hit[1].cell, 7);
    /* a plane cutting both squares away: nothing to measure */
    double all[1][4], all_point[3] = {0, 0, -1};
    ms_section_plane(all_point, cut_normal, all[0]);
    assert_true(ms_viewer_measure_set_planes(&m, (const double(*)[4])all, 1));
    assert_false(ms_viewer_measure_add(&m, &frame, 8.0, o, d));
    ms_viewer_measure_update(&m, &frame, 8.0);
    assert_false(m.found[0] || m.found[1]);
    /* the pixel ray through the framebuffer's centre is the view direction */
    ms_camera cam;
    ms_error err;
    double eye[3] = {0.5, -4, 0.5}, target[3] = {0.5, 0.5, 0.5}, up[3] = {0, 0, 1};
    assert_int_equal(ms_camera_look_at(eye, target, up, 40, 160, 120, 0.1, 100, &cam, &err), MS_OK);
    double ro[3], rd[3];
    ms_viewer_measure_pixel_ray(&cam, 80, 60, ro, rd);
    for (int a = 0; a < 3; ++a) {
        assert_true(ro[a] == eye[a]);
        assert_true(fabs(rd[a] - cam.forward[a]) < 1e-15);
    }
    /* the top edge's middle: 20 degrees up */
    ms_viewer_measure_pixel_ray(&cam, 80, 0, ro, rd);
    assert_true(fabs(rd[2] - sin(20 * M_PI / 180)) < 1e-12);
}

/* --- the light ------------------------------------------------------------ */

static void test_light(void **state)
{
    (void)state;
    ms_viewer_light l = {0};
    assert_true(ms_viewer_light_parse("60,-12.5", &l));
    assert_true(l.directional && l.azimuth_deg == 60 && l.elevation_deg == -12.5);
    static const char *const bad[] = {"", "60", "60,", ",5", "181,0", "0,91", "a,b", "1,2,3", "nan,0", "1e999,0",
                                      "60 ,0"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        ms_viewer_light kept = l;
        assert_false(ms_viewer_light_parse(bad[i], &kept));
        assert_true(kept.azimuth_deg == 60);
    }
    /* eye directions: az 0 el 0 towards the viewer; az 90 from the right; el 90 from above */
    double e[3];
    ms_viewer_light_eye(&(ms_viewer_light){.directional = true, .azimuth_deg = 90}, e);
    assert_true(fabs(e[0] - 1) < 1e-15 && fabs(e[1]) < 1e-15 && fabs(e[2]) < 1e-15);
    ms_viewer_light_eye(&(ms_viewer_light){.directional = true, .elevation_deg = 90}, e);
    assert_true(fabs(e[1] - 1) < 1e-15);
    ms_viewer_light_eye(&(ms_viewer_light){0}, e);
    assert_true(e[0] == 0 && e[1] == 0 && e[2] == 1);
    /* in the world: a face seen head-on gets L.N = cos el cos az */
    ms_camera cam;
    ms_error err;
    double eye[3] = {0.5, -4, 0.5}, target[3] = {0.5, 0.5, 0.5}, up[3] = {0, 0, 1}, w[3];
    assert_int_equal(ms_camera_look_at(eye, target, up, 40, 160, 120, 0.1, 100, &cam, &err), MS_OK);
    ms_viewer_light_world(&(ms_viewer_light){.directional = true, .azimuth_deg = 60, .elevation_deg = 30}, &cam, w);
    double n[3] = {0, -1, 0};
    assert_true(fabs(w[0] * n[0] + w[1] * n[1] + w[2] * n[2] - cos(M_PI / 6) * cos(M_PI / 3)) < 1e-15);
    assert_true(w[0] > 0 && w[2] > 0); /* from the right (+x) and above (+z) */
    ms_render_options ro;
    ms_render_options_default(&ro);
    ms_viewer_light_apply(&l, &cam, &ro);
    assert_int_equal(ro.light_count, 1);
    assert_int_equal(ro.lights[0].kind, MS_RENDER_LIGHT_DIRECTIONAL);
    ms_viewer_light_apply(&(ms_viewer_light){0}, &cam, &ro);
    assert_int_equal(ro.lights[0].kind, MS_RENDER_LIGHT_HEAD);
    /* raking presets: left, top, right, bottom, head light, left again */
    ms_viewer_light p = {0};
    static const double presets[4][2] = {{-80, 0}, {0, 80}, {80, 0}, {0, -80}};
    for (int i = 0; i < 4; ++i) {
        ms_viewer_light_next_preset(&p);
        assert_true(p.directional && p.azimuth_deg == presets[i][0] && p.elevation_deg == presets[i][1]);
    }
    ms_viewer_light_next_preset(&p);
    assert_false(p.directional);
    p = l;
    ms_viewer_light_next_preset(&p); /* from a light of no preset: the head light */
    assert_false(p.directional);
    /* a drag: from the head light at 0, 0; half a turn across the height; clamped el, wrapped az */
    ms_viewer_light d = {0};
    ms_viewer_light_drag(&d, 50, -25, 100);
    assert_true(d.directional && d.azimuth_deg == 90 && d.elevation_deg == 45);
    ms_viewer_light_drag(&d, 100, -100, 100);
    assert_true(d.azimuth_deg == -90 && d.elevation_deg == 90);
    char text[64];
    ms_viewer_light_describe(&d, text, sizeof text);
    assert_string_equal(text, "light az -90.0 el 90.0 deg");
}

/* --- the view text -------------------------------------------------------- */

static double random_double(uint64_t *s, double lo, double hi)
{
    return lo + (hi - lo) * (double)(ms_test_random(s) >> 11) / 9007199254740992.0;
}

static void assert_same_state(const ms_viewer_share *a, const ms_viewer_share *b)
{
    assert_memory_equal(a->target, b->target, sizeof a->target);
    assert_memory_equal(&a->distance, &b->distance, sizeof a->distance);
    assert_memory_equal(&a->yaw, &b->yaw, sizeof a->yaw);
    assert_memory_equal(&a->pitch, &b->pitch, sizeof a->pitch);
    assert_memory_equal(&a->fovy_degrees, &b->fovy_degrees, sizeof a->fovy_degrees);
    assert_int_equal(a->up_axis, b->up_axis);
    assert_int_equal(a->light.directional, b->light.directional);
    if (a->light.directional) {
        assert_memory_equal(&a->light.azimuth_deg, &b->light.azimuth_deg, sizeof(double));
        assert_memory_equal(&a->light.elevation_deg, &b->light.elevation_deg, sizeof(double));
    }
    assert_int_equal(a->sections.count, b->sections.count);
    assert_memory_equal(a->sections.point, b->sections.point, a->sections.count * sizeof a->sections.point[0]);
    assert_memory_equal(a->sections.normal, b->sections.normal, a->sections.count * sizeof a->sections.normal[0]);
    assert_int_equal(a->points, b->points);
    assert_memory_equal(a->anchor, b->anchor, a->points * sizeof a->anchor[0]);
    assert_memory_equal(a->direction, b->direction, a->points * sizeof a->direction[0]);
}

static void test_view_text_round_trip(void **state)
{
    (void)state;
    uint64_t seed = 0x9E3779B97F4A7C15ull;
    char text[MS_VIEWER_SHARE_MAX], again[MS_VIEWER_SHARE_MAX];
    size_t longest = 0;
    for (int i = 0; i < 2000; ++i) {
        ms_viewer_share v = {0}, back;
        for (int a = 0; a < 3; ++a)
            v.target[a] = random_double(&seed, -1e6, 1e6) * (i % 3 ? 1 : 1e-9);
        v.distance = random_double(&seed, 1e-6, 1e4);
        v.yaw = random_double(&seed, -10, 10);
        v.pitch = random_double(&seed, -1.5533, 1.5533);
        v.fovy_degrees = i % 5 ? random_double(&seed, 1, 179) : 40;
        v.up_axis = i % 3;
        if (i % 2)
            v.light = (ms_viewer_light){true, random_double(&seed, -180, 180), random_double(&seed, -90, 90)};
        v.sections.count = (size_t)(i % 4);
        for (size_t k = 0; k < v.sections.count; ++k)
            for (int a = 0; a < 3; ++a) {
                v.sections.point[k][a] = random_double(&seed, -1e3, 1e3);
                v.sections.normal[k][a] = random_double(&seed, -1, 1) + (a == 1 ? 3 : 0);
            }
        v.points = (size_t)(i % 17);
        for (size_t p = 0; p < v.points; ++p)
            for (int a = 0; a < 3; ++a) {
                v.anchor[p][a] = random_double(&seed, -1e3, 1e3);
                v.direction[p][a] = random_double(&seed, -1, 1) + (a == 0 ? 3 : 0);
            }
        if (i == 7)
            v.target[0] = -0.0, v.target[1] = 5e-324, v.target[2] = 1.7976931348623157e308;
        ms_viewer_share_print(&v, text, sizeof text);
        if (strlen(text) > longest)
            longest = strlen(text);
        ms_error err;
        if (ms_viewer_share_parse(text, &back, &err) != MS_OK)
            fail_msg("'%s': %s", text, err.text);
        assert_same_state(&v, &back);
        ms_viewer_share_print(&back, again, sizeof again);
        assert_string_equal(text, again);
    }
    printf("longest view text: %zu bytes (16 points, 3 sections)\n", longest);
    assert_true(longest < MS_VIEWER_SHARE_MAX);

    /* a canonical text prints back to itself; through the controls too */
    const char *canonical = "mv1:t=0.5,0.25,-3:d=2.5:o=0.7853981633974483,-0.1:f=40:u=z:l=-80,0"
                            ":m=0.1,0.2,0.3,0,0,-1/0.9,0.2,0.3,0,0,-1";
    ms_viewer_share v, w;
    ms_error err;
    assert_int_equal(ms_viewer_share_parse(canonical, &v, &err), MS_OK);
    ms_viewer_share_print(&v, text, sizeof text);
    assert_string_equal(text, canonical);
    ms_viewer_controls c;
    double lo[3] = {0, 0, 0}, hi[3] = {1, 1, 1};
    ms_viewer_controls_init(&c, lo, hi, 1, 1.5);
    ms_viewer_light light = {0};
    ms_viewer_measure m = {0};
    ms_viewer_share_give(&v, &c, &light, &m);
    assert_int_equal(c.up_axis, 2);
    assert_int_equal(m.count, 2);
    assert_false(m.found[0]);
    ms_viewer_share_take(&c, &light, &m, &w);
    ms_viewer_share_print(&w, text, sizeof text);
    assert_string_equal(text, canonical);
    /* and without light and points */
    assert_int_equal(ms_viewer_share_parse("mv1:t=0,0,0:d=1:o=0,0:f=40:u=y", &v, &err), MS_OK);
    assert_false(v.light.directional);
    assert_int_equal(v.points, 0);
    assert_int_equal(v.sections.count, 0);
    /* sections: between the light and the points, exact both ways */
    const char *sectioned = "mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:l=10,20:s=0,0,-0.005,0,0,1/0.25,0,0,-1,0,0:m=0,0,0,0,0,1";
    assert_int_equal(ms_viewer_share_parse(sectioned, &v, &err), MS_OK);
    assert_int_equal(v.sections.count, 2);
    assert_true(v.sections.point[0][2] == -0.005 && v.sections.normal[0][2] == 1);
    assert_true(v.sections.point[1][0] == 0.25 && v.sections.normal[1][0] == -1);
    ms_viewer_share_print(&v, text, sizeof text);
    assert_string_equal(text, sectioned);
    assert_int_equal(ms_viewer_share_parse("mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:s=1,2,3,0.5,0.5,0", &v, &err), MS_OK);
    ms_viewer_share_print(&v, text, sizeof text);
    assert_string_equal(text, "mv1:t=0,0,0:d=1:o=0,0:f=40:u=y:s=1,2,3,0.5,0.5,0");
}

static void test_hostile_view_texts(void **state)
{
    (void)state;
    static const char *const bad[] = {
        "",
        "mv1",
        "mv2:t=0,0,0:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,0:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,0,0,0:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,0,nan:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,0,1e400:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,0,0:d=0:o=0,0:f=40:u=z",
        "mv1:t=0,0,0:d=-1:o=0,0:f=40:u=z",
        "mv1:t=0,0,0:d=1:o=0,1.6:f=40:u=z",
        "mv1:t=0,0,0:d=1:o=0,0:f=180:u=z",
        "mv1:t=0,0,0:d=1:o=0,0:f=0:u=z",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=w",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=zz",
        "mv1:t=0,0,0:d=1:o=0,0:f=40",
        "mv1:d=1:t=0,0,0:o=0,0:f=40:u=z",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:l=200,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:l=0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0,1/",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0,1:l=0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:x=1",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=1,2,3,0,0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=1,2,3,0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=1,2,3,0,0,1/",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=x=1",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=1,2,3,0,0,1/1,2,3,0,0,1/1,2,3,0,0,1/1,2,3,0,0,1",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=1e300,0,0,1e300,0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=1,2,3,0,0,1:s=0,0,0,0,0,1",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=0,0,0,0,0,1:l=0,0",
        "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:s=0,0,nan,0,0,1",
        "mv1:t= 0,0,0:d=1:o=0,0:f=40:u=z",
        "mv1:t=0,,0:d=1:o=0,0:f=40:u=z",
        "mv1:t=0x1p3,0,0:d=1:o=0,0:f=40:u=z:q",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        ms_viewer_share v;
        ms_error err = {0};
        if (ms_viewer_share_parse(bad[i], &v, &err) == MS_OK)
            fail_msg("'%s' accepted", bad[i]);
        assert_non_null(err.text[0] ? err.text : NULL);
        assert_null(strchr(err.text, '\n'));
    }
    /* 17 points, and a text of 4096 bytes */
    char text[8192] = "mv1:t=0,0,0:d=1:o=0,0:f=40:u=z:m=";
    for (int i = 0; i < 17; ++i)
        strcat(text, i ? "/1,2,3,0,0,1" : "1,2,3,0,0,1");
    ms_viewer_share v;
    ms_error err;
    assert_int_not_equal(ms_viewer_share_parse(text, &v, &err), MS_OK);
    assert_non_null(strstr(err.text, "16"));
    memset(text, '1', sizeof text - 1);
    text[sizeof text - 1] = 0;
    memcpy(text, "mv1:t=", 6);
    assert_int_not_equal(ms_viewer_share_parse(text, &v, &err), MS_OK);
    assert_int_not_equal(ms_viewer_share_parse(NULL, &v, &err), MS_OK);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cast_on_a_hand_made_frame),
        cmocka_unit_test(test_light),
        cmocka_unit_test(test_view_text_round_trip),
        cmocka_unit_test(test_hostile_view_texts),
        cmocka_unit_test(test_cube_edge_at_20_bits),
        cmocka_unit_test(test_sphere_diameter_at_20_bits),
        cmocka_unit_test(test_probe_refines_to_full_precision),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
