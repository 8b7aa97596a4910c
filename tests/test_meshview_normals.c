/* Normals that respect the surface (docs/RENDERER.md, "Vertex normals"):
 * meshview, the built program, scripted under Xvfb at 160x120 without APO,
 * against meshrender's Embree picture of the same mesh from the same camera
 * path (PSNR over the RGB of every pixel):
 *   - a 12-triangle cube and an L-shaped bracket (20 triangles) against the
 *     flat render: at least 28 dB with the default crease angle (60 degrees);
 *     with --crease-angle 180 (every edge smooth: what meshview drew before
 *     creases) the cube falls far below; --flat restores it; a catalogue
 *     crease_angle of 180 does what the option does, and --crease-angle wins
 *     over the catalogue;
 *   - a sphere against the smooth render, and the same sphere with half of its
 *     triangles flipped at random: within 1 dB of each other (they draw the
 *     same normals up to the winding: the flipped picture equals the other
 *     but for a few pixels);
 *   - the dragon (res3) at 8 and 16 px, whose coarse levels' corners sit at
 *     kd-cell centres: the default crease angle draws it as well as 180
 *     (within 0.2 dB) and better than flat shading, against meshrender's
 *     smooth picture of the full mesh (the crease test's slack);
 *   - the dragon (res3) baked with APO, at 4 and 8 px: the normals picture
 *     with the filtered APO lookup (--apo-filter linear, the default) is no
 *     worse than the nearest leaf (--apo-filter none), and better than the
 *     same cut's own smooth normals, against Embree's normals of the full
 *     mesh over the pixels both cover;
 *   - the cube's albedo pictures, meshview --shading albedo against meshrender
 *     --albedo (no colours: the viewer's grey in both), by the colour PSNR
 *     over the pixels covered in either: every pixel covered in both is the
 *     grey exactly, and only the silhouette differs;
 *   - meshview's bad --crease-angle values are usage errors. */
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

#include "ms_catalog.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_study_measure.h"
#include "ms_test.h"
#include "ms_test_display.h"
#include "ms_test_picture.h"

#define WIDTH 160
#define HEIGHT 120

typedef struct fixture {
    ms_test_display display;
    char dir[512], archives[600];
} fixture;

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

/* A convex quad a b c d, counter-clockwise seen from outside. */
static void add_quad(ms_mesh *m, uint32_t a, uint32_t b, uint32_t c, uint32_t d)
{
    add_triangle(m, a, b, c);
    add_triangle(m, a, c, d);
}

/* A prism: the polygon of `count` corners (x, y) counter-clockwise, from z0 to
 * z1, its caps given as convex quads of corner numbers. */
static void add_prism(ms_mesh *m, const double (*corner)[2], uint32_t count, const uint32_t (*caps)[4],
                      uint32_t cap_count, double z0, double z1)
{
    uint32_t base = (uint32_t)m->vertex_count;
    for (uint32_t i = 0; i < count; ++i)
        add_vertex(m, corner[i][0], corner[i][1], z0);
    for (uint32_t i = 0; i < count; ++i)
        add_vertex(m, corner[i][0], corner[i][1], z1);
    for (uint32_t q = 0; q < cap_count; ++q) {
        const uint32_t *c = caps[q];
        add_quad(m, base + c[3], base + c[2], base + c[1], base + c[0]);                 /* bottom, facing -z */
        add_quad(m, base + count + c[0], base + count + c[1], base + count + c[2], base + count + c[3]); /* top */
    }
    for (uint32_t i = 0; i < count; ++i) {
        uint32_t j = (i + 1) % count;
        add_quad(m, base + i, base + j, base + count + j, base + count + i);
    }
}

static void cube(ms_mesh *m)
{
    static const double square[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    static const uint32_t caps[1][4] = {{0, 1, 2, 3}};
    add_prism(m, square, 4, caps, 1, 0, 1);
    assert_int_equal(m->triangle_count, 12);
}

/* An L-shaped bracket: two arms 1 long and 0.3 thick, 0.6 deep. */
static void bracket(ms_mesh *m)
{
    static const double l[6][2] = {{0, 0}, {1, 0}, {1, 0.3}, {0.3, 0.3}, {0.3, 1}, {0, 1}};
    static const uint32_t caps[2][4] = {{0, 1, 2, 3}, {0, 3, 4, 5}};
    add_prism(m, l, 6, caps, 2, 0, 0.6);
    assert_int_equal(m->triangle_count, 20);
}

/* A latitude-longitude sphere (radius 0.5, centre 0.5, 24 x 48), wound outwards. */
static void sphere(ms_mesh *m)
{
    enum { RINGS = 24, SEGMENTS = 48 };
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

/* Flips half of the triangles, chosen at random (a fixed seed). */
static size_t flip_half(ms_mesh *m)
{
    uint64_t state = 0x2545F4914F6CDD1Dull;
    size_t flipped = 0;
    for (size_t t = 0; t < m->triangle_count; ++t) {
        state ^= state << 13, state ^= state >> 7, state ^= state << 17;
        if (state & 1) {
            uint32_t *tri = &m->triangles[3 * t];
            uint32_t swap = tri[1];
            tri[1] = tri[2], tri[2] = swap;
            flipped++;
        }
    }
    return flipped;
}

/* Writes DIR/NAME.ply and bakes it (no APO: the vertex normals are what is
 * tested) into the archive directory; the camera path DIR/NAME.cam looks at
 * the unit box's centre from eye_offset. */
static void make_model(const fixture *f, const char *name, ms_mesh *m, const double eye_offset[3])
{
    char ply[700], command[4096], bin[600], cam[700];
    ms_error err;
    snprintf(ply, sizeof ply, "%s/%s.ply", f->dir, name);
    assert_int_equal(ms_ply_write(ply, m, true, true, &err), MS_OK);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name %s --no-apo --min-tris 400 --json", bin, ply,
             f->archives, name);
    json_decref(ms_test_run_json(command, 0));
    snprintf(cam, sizeof cam, "%s/%s.cam", f->dir, name);
    FILE *out = fopen(cam, "w");
    assert_non_null(out);
    fprintf(out, "meshstream-camera-path 1\n0 %.9g %.9g %.9g 0.5 0.5 0.5 0 1 0 40\n", 0.5 + eye_offset[0],
            0.5 + eye_offset[1], 0.5 + eye_offset[2]);
    fclose(out);
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
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
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

/* meshview on model NAME along DIR/NAME.cam with extra options; the keyframe's
 * PNG into png (a path), the report returned. */
static json_t *view(const fixture *f, const char *name, const char *tag, const char *extra, char *png, size_t size)
{
    char bin[600], command[4096];
    ms_test_bin_path(bin, sizeof bin, "meshview");
    snprintf(command, sizeof command,
             "%s %s --model %s --path %s/%s.cam --size %dx%d --no-apo --frames 1 --screenshot-dir %s/%s-%s "
             "--json %s",
             bin, f->archives, name, f->dir, name, WIDTH, HEIGHT, f->dir, name, tag, extra);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    snprintf(png, size, "%s", json_string_value(json_object_get(key, "png")));
    return report;
}

/* meshrender's picture of DIR/PLY.ply along DIR/NAME.cam into png (and its
 * normals picture, rgb = (N + 1) / 2, N turned to the camera). */
static void reference(const fixture *f, const char *ply, const char *name, bool smooth, char *png, size_t size)
{
    char bin[600], command[4096];
    ms_test_bin_path(bin, sizeof bin, "meshrender");
    snprintf(command, sizeof command,
             "%s %s/%s.ply -p %s/%s.cam -o %s/%s-ref%s --width %d --height %d%s --normals --json", bin, f->dir, ply,
             f->dir, name, f->dir, ply, smooth ? "-smooth" : "", WIDTH, HEIGHT, smooth ? " --smooth" : "");
    json_decref(ms_test_run_json(command, 0));
    snprintf(png, size, "%s/%s-ref%s/frame_000.png", f->dir, ply, smooth ? "-smooth" : "");
}

/* Of the pixels both normals pictures cover (meshview's background is 0.02
 * linear: 5; meshrender's 0), the share whose normal colours agree within 2
 * in every channel (the 10-bit packing), and how many there are. */
static double normals_agree(const char *view_png, const char *ref_png, size_t *both)
{
    uint32_t wa, ha, wb, hb;
    uint8_t *a = ms_test_png_read(view_png, &wa, &ha), *b = ms_test_png_read(ref_png, &wb, &hb);
    assert_int_equal(wa, wb);
    assert_int_equal(ha, hb);
    size_t agree = 0;
    *both = 0;
    for (size_t i = 0; i < (size_t)wa * ha; ++i) {
        const uint8_t *x = &a[3 * i], *y = &b[3 * i];
        if ((x[0] == 5 && x[1] == 5 && x[2] == 5) || (y[0] == 0 && y[1] == 0 && y[2] == 0))
            continue;
        (*both)++;
        agree += abs(x[0] - y[0]) <= 2 && abs(x[1] - y[1]) <= 2 && abs(x[2] - y[2]) <= 2;
    }
    free(a);
    free(b);
    return *both ? (double)agree / (double)*both : 0.0;
}

/* PSNR of two PNGs of the same size over every RGB value, dB. */
static double psnr(const char *a, const char *b)
{
    uint32_t wa, ha, wb, hb;
    uint8_t *pa = ms_test_png_read(a, &wa, &ha), *pb = ms_test_png_read(b, &wb, &hb);
    assert_int_equal(wa, wb);
    assert_int_equal(ha, hb);
    double sum = 0;
    size_t n = 3 * (size_t)wa * ha;
    for (size_t i = 0; i < n; ++i) {
        double d = (double)pa[i] - (double)pb[i];
        sum += d * d;
    }
    free(pa);
    free(pb);
    return sum > 0 ? 10.0 * log10(255.0 * 255.0 / (sum / (double)n)) : INFINITY;
}

/* The cube's albedo pictures: meshview's and meshrender's (the comparison the
 * colour scans get once archives carry colour). */
static void cube_albedo(const fixture *f)
{
    char albedo[800], bin[600], command[4096], ref[800];
    json_t *report = view(f, "cube", "albedo", "--shading albedo", albedo, sizeof albedo);
    assert_string_equal(json_string_value(json_object_get(report, "shading")), "albedo");
    json_decref(report);
    ms_test_bin_path(bin, sizeof bin, "meshrender");
    snprintf(command, sizeof command,
             "%s %s/cube.ply -p %s/cube.cam -o %s/cube-ref-albedo --width %d --height %d --albedo --json", bin, f->dir,
             f->dir, f->dir, WIDTH, HEIGHT);
    json_decref(ms_test_run_json(command, 0));
    snprintf(ref, sizeof ref, "%s/cube-ref-albedo/frame_000.png", f->dir);
    uint32_t wa, ha, wb, hb;
    uint8_t *a = ms_test_png_read(albedo, &wa, &ha), *b = ms_test_png_read(ref, &wb, &hb);
    assert_true(wa == wb && ha == hb);
    size_t n = (size_t)wa * ha, both = 0;
    uint8_t *mask = malloc(n);
    assert_non_null(mask);
    static const uint8_t bg[3] = {39, 39, 39}, grey[3] = {221, 216, 209};
    size_t covered = ms_study_colour_mask(a, b, n, bg, false, mask);
    for (size_t p = 0; p < n; ++p)
        if (memcmp(&a[3 * p], bg, 3) != 0 && memcmp(&b[3 * p], bg, 3) != 0) {
            assert_memory_equal(&a[3 * p], grey, 3);
            assert_memory_equal(&b[3 * p], grey, 3);
            both++;
        }
    ms_study_colour_error e;
    ms_error err;
    assert_int_equal(ms_study_colour_psnr(a, b, n, mask, &e, &err), MS_OK);
    print_message("cube albedo: %zu pixels covered in either, %zu in both, colour PSNR %.2f dB\n", covered, both,
                  e.psnr_db);
    /* the silhouette differs where the cut's corners sit within its 1 px
     * tolerance (the archive's error table: a corner's whole distance) */
    assert_true(both > covered * 95 / 100);
    assert_true(e.psnr_db > 17.0);
    free(mask);
    free(a);
    free(b);
}

static void test_cube_and_bracket_keep_their_edges(void **state)
{
    fixture *f = *state;
    const double cube_eye[3] = {1.9, 1.4, 2.6}, bracket_eye[3] = {-1.2, 1.7, 2.7};
    ms_mesh m = {0};
    cube(&m);
    make_model(f, "cube", &m, cube_eye);
    ms_mesh_free(&m);
    bracket(&m);
    make_model(f, "bracket", &m, bracket_eye);
    ms_mesh_free(&m);

    char ref[800], png[800], pillow[800], flat[800], normals[800], ref_normals[800];
    reference(f, "cube", "cube", false, ref, sizeof ref);
    json_decref(view(f, "cube", "default", "", png, sizeof png));
    double cube_db = psnr(png, ref);
    cube_albedo(f);
    /* the normals themselves: every face pixel shows its face's normal */
    snprintf(ref_normals, sizeof ref_normals, "%s/cube-ref/normals_000.png", f->dir);
    size_t both, both_before;
    json_decref(view(f, "cube", "normals", "--shading normals", normals, sizeof normals));
    double cube_agree = normals_agree(normals, ref_normals, &both);
    json_decref(view(f, "cube", "normals-smooth", "--shading normals --crease-angle 180", normals, sizeof normals));
    double cube_agree_before = normals_agree(normals, ref_normals, &both_before);
    json_t *report = view(f, "cube", "smooth", "--crease-angle 180", pillow, sizeof pillow);
    assert_true(json_real_value(json_object_get(report, "crease_angle_deg")) == 180.0);
    json_decref(report);
    double pillow_db = psnr(pillow, ref);
    report = view(f, "cube", "flat", "--crease-angle 180 --flat", flat, sizeof flat);
    assert_true(json_is_true(json_object_get(report, "flat")));
    json_decref(report);
    double flat_db = psnr(flat, ref);

    reference(f, "bracket", "bracket", false, ref, sizeof ref);
    json_decref(view(f, "bracket", "default", "", png, sizeof png));
    double bracket_db = psnr(png, ref);
    json_decref(view(f, "bracket", "smooth", "--crease-angle 180", pillow, sizeof pillow));
    double bracket_pillow_db = psnr(pillow, ref);
    snprintf(ref_normals, sizeof ref_normals, "%s/bracket-ref/normals_000.png", f->dir);
    size_t bracket_both, bracket_both_before;
    json_decref(view(f, "bracket", "normals", "--shading normals", normals, sizeof normals));
    double bracket_agree = normals_agree(normals, ref_normals, &bracket_both);
    json_decref(
        view(f, "bracket", "normals-smooth", "--shading normals --crease-angle 180", normals, sizeof normals));
    double bracket_agree_before = normals_agree(normals, ref_normals, &bracket_both_before);
    printf("against Embree flat: cube %.2f dB (every edge smooth %.2f, --flat %.2f), bracket %.2f dB "
           "(every edge smooth %.2f); normals equal to Embree's: cube %.1f %% of %zu px (every edge smooth "
           "%.1f %%), bracket %.1f %% of %zu px (every edge smooth %.1f %%)\n",
           cube_db, pillow_db, flat_db, bracket_db, bracket_pillow_db, 100 * cube_agree, both,
           100 * cube_agree_before, 100 * bracket_agree, bracket_both, 100 * bracket_agree_before);
    /* Both renderers light alike (Lambert and highlight times the
     * self-shadowing factor max(0, L.Ng)); what differs is meshview's plaster
     * albedo against meshrender's grey, and the highlight's weights. */
    assert_true(bracket_db >= 28.0);
    assert_true(cube_db >= 28.0);
    assert_true(flat_db >= cube_db - 0.5);
    assert_true(pillow_db < cube_db - 4.0);
    assert_true(bracket_pillow_db < bracket_db - 3.0);
    assert_true(cube_agree >= 0.97);
    assert_true(bracket_agree >= 0.95);
    assert_true(cube_agree_before < 0.5);
    assert_true(bracket_agree_before < 0.5);
}

/* The catalogue's crease_angle is the model's default; --crease-angle wins. */
static void test_catalogue_crease_angle(void **state)
{
    fixture *f = *state;
    const double cube_eye[3] = {1.9, 1.4, 2.6};
    ms_mesh m = {0};
    cube(&m);
    make_model(f, "cube2", &m, cube_eye);
    ms_mesh_free(&m);
    ms_catalog catalog;
    ms_error err;
    assert_int_equal(ms_catalog_load(f->archives, &catalog, &err), MS_OK);
    ms_catalog_entry entry = *ms_catalog_find(&catalog, "cube2");
    assert_false(entry.has_crease_angle); /* meshbake sets none */
    entry.has_crease_angle = true;
    entry.crease_angle_deg = 180;
    assert_int_equal(ms_catalog_update(f->archives, &entry, &err), MS_OK);
    ms_catalog_free(&catalog);

    char png[800], smooth[800], ours[800];
    json_t *report = view(f, "cube2", "catalogue", "", png, sizeof png);
    assert_true(json_real_value(json_object_get(report, "crease_angle_deg")) == 180.0);
    json_decref(report);
    json_decref(view(f, "cube2", "smooth", "--crease-angle 180", smooth, sizeof smooth));
    assert_int_equal(ms_test_png_differing(png, smooth, 0), 0);
    report = view(f, "cube2", "option", "--crease-angle 60", ours, sizeof ours);
    assert_true(json_real_value(json_object_get(report, "crease_angle_deg")) == 60.0);
    json_decref(report);
    assert_true(ms_test_png_differing(ours, smooth, 8) > 1000);

    /* baking the model again keeps the catalogue's crease angle */
    cube(&m);
    make_model(f, "cube2", &m, cube_eye);
    ms_mesh_free(&m);
    assert_int_equal(ms_catalog_load(f->archives, &catalog, &err), MS_OK);
    const ms_catalog_entry *kept = ms_catalog_find(&catalog, "cube2");
    assert_true(kept->has_crease_angle);
    assert_true(kept->crease_angle_deg == 180.0);
    ms_catalog_free(&catalog);
}

static void test_flipped_faces_shade_as_consistent_ones(void **state)
{
    fixture *f = *state;
    const double eye[3] = {1.1, 1.6, 2.6};
    ms_mesh m = {0};
    sphere(&m);
    make_model(f, "sphere", &m, eye);
    size_t flipped = flip_half(&m);
    assert_true(flipped > m.triangle_count / 3 && flipped < 2 * m.triangle_count / 3);
    make_model(f, "flipped", &m, eye);
    ms_mesh_free(&m);
    /* the flipped mesh's camera path is the sphere's */
    char ref[800], png[800], flipped_png[800];
    reference(f, "sphere", "sphere", true, ref, sizeof ref);
    json_decref(view(f, "sphere", "default", "", png, sizeof png));
    json_decref(view(f, "flipped", "default", "", flipped_png, sizeof flipped_png));
    double consistent_db = psnr(png, ref), flipped_db = psnr(flipped_png, ref);
    size_t differing = ms_test_png_differing(png, flipped_png, 2);
    printf("against Embree smooth: sphere %.2f dB, half its faces flipped %.2f dB (%zu of %zu triangles; "
           "%zu pixels differ by more than 2)\n",
           consistent_db, flipped_db, flipped, (size_t)(2 * 48 * 23), differing);
    assert_true(consistent_db >= 28.0);
    assert_true(fabs(consistent_db - flipped_db) <= 1.0);
}

/* A scan's coarse levels without geometry ahead or smoothing (meshbake --ahead 0
 * --smooth 0; with ahead, a window's last level still): their corners sit at
 * kd-cell centres, so their
 * triangles' normals are rough and many edges look sharper than the crease
 * angle; the crease test widens the angle by each triangle's slack, so the
 * default draws the dragon at 8 and 16 px as every edge smooth does (without
 * the slack: 3.6 dB lower on the full dragon, voxel steps) and far above
 * flat shading, against meshrender's smooth picture of the full mesh. Then the
 * default bake (geometry ahead: corners at their descendants' barycentres,
 * smoothed below the precision where half the vertices are alone) draws the
 * same cuts better still. */
static void test_coarse_scan_levels_stay_smooth(void **state)
{
    fixture *f = *state;
    char model[4096], bin[600], command[8192], cam[700], ref[800];
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name scan --no-apo --min-tris 1500 --ahead 0 --smooth 0 --json",
             bin,
             model, f->archives);
    json_decref(ms_test_run_json(command, 0));
    snprintf(command, sizeof command, "%s %s -o %s --name ahead --no-apo --min-tris 1500 --json", bin, model,
             f->archives);
    json_decref(ms_test_run_json(command, 0));
    static const char *const cams[] = {"ahead", "scan"}; /* the last one for meshrender */
    for (size_t c = 0; c < 2; ++c) {
        snprintf(cam, sizeof cam, "%s/%s.cam", f->dir, cams[c]);
        FILE *out = fopen(cam, "w");
        assert_non_null(out);
        fprintf(out, "meshstream-camera-path 1\n0 0.10 0.20 0.28 -0.006 0.125 -0.005 0 1 0 40\n");
        fclose(out);
    }
    ms_test_bin_path(bin, sizeof bin, "meshrender");
    snprintf(command, sizeof command, "%s %s -p %s -o %s/scan-ref --width %d --height %d --smooth --json", bin,
             model, cam, f->dir, WIDTH, HEIGHT);
    json_decref(ms_test_run_json(command, 0));
    snprintf(ref, sizeof ref, "%s/scan-ref/frame_000.png", f->dir);
    static const char *tolerances[] = {"8", "16"};
    for (size_t i = 0; i < 2; ++i) {
        char extra[128], tag[64], png[800], smooth[800], flat[800];
        snprintf(extra, sizeof extra, "--tolerance %s", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s", tolerances[i]);
        json_t *report = view(f, "scan", tag, extra, png, sizeof png);
        assert_true(json_real_value(json_object_get(report, "crease_angle_deg")) == 60.0);
        json_decref(report);
        snprintf(extra, sizeof extra, "--tolerance %s --crease-angle 180", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-smooth", tolerances[i]);
        json_decref(view(f, "scan", tag, extra, smooth, sizeof smooth));
        snprintf(extra, sizeof extra, "--tolerance %s --flat", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-flat", tolerances[i]);
        json_decref(view(f, "scan", tag, extra, flat, sizeof flat));
        char ahead_png[800];
        snprintf(extra, sizeof extra, "--tolerance %s", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-ahead", tolerances[i]);
        json_decref(view(f, "ahead", tag, extra, ahead_png, sizeof ahead_png));
        double ours = psnr(png, ref), every_edge = psnr(smooth, ref), faceted = psnr(flat, ref);
        double ahead = psnr(ahead_png, ref);
        printf("dragon res3 at %s px against Embree smooth of the full mesh: cell centres: crease 60 %.2f dB, "
               "180 %.2f dB, flat %.2f dB; geometry ahead: %.2f dB\n",
               tolerances[i], ours, every_edge, faceted, ahead);
        assert_true(ours >= every_edge - 0.2);
        assert_true(ours >= faceted + 1.0);
        assert_true(ahead >= ours + 1.0);
    }
}

/* PSNR of two normals pictures over the pixels both cover (meshview's
 * background 5, meshrender's 0, as normals_agree). */
static double normals_psnr(const char *view_png, const char *ref_png)
{
    uint32_t wa, ha, wb, hb;
    uint8_t *a = ms_test_png_read(view_png, &wa, &ha), *b = ms_test_png_read(ref_png, &wb, &hb);
    assert_int_equal(wa, wb);
    assert_int_equal(ha, hb);
    double sum = 0;
    size_t n = 0;
    for (size_t i = 0; i < (size_t)wa * ha; ++i) {
        const uint8_t *x = &a[3 * i], *y = &b[3 * i];
        if ((x[0] == 5 && x[1] == 5 && x[2] == 5) || (y[0] == 0 && y[1] == 0 && y[2] == 0))
            continue;
        for (int k = 0; k < 3; ++k)
            sum += ((double)x[k] - y[k]) * ((double)x[k] - y[k]);
        n += 3;
    }
    free(a);
    free(b);
    assert_true(n > 3000);
    return sum > 0 ? 10.0 * log10(255.0 * 255.0 / (sum / (double)n)) : INFINITY;
}

/* meshview's normals picture of NAME with APO (the archive's chunks) and the
 * extra options; the keyframe's PNG into png. */
static void view_apo_normals(const fixture *f, const char *name, const char *tag, const char *extra, char *png,
                             size_t size)
{
    char bin[600], command[4096];
    ms_test_bin_path(bin, sizeof bin, "meshview");
    snprintf(command, sizeof command,
             "%s %s --model %s --path %s/%s.cam --size %dx%d --shading normals --frames 1 --screenshot-dir "
             "%s/%s-%s --json %s",
             bin, f->archives, name, f->dir, name, WIDTH, HEIGHT, f->dir, name, tag, extra);
    json_t *report = ms_test_run_json(command, 0);
    json_t *key = json_array_get(json_object_get(report, "keyframes"), 0);
    assert_true(json_is_true(json_object_get(key, "complete")));
    snprintf(png, size, "%s", json_string_value(json_object_get(key, "png")));
    json_decref(report);
}

/* APO at a coarse cut (issue 31): the nearest-leaf lookup shows the octree's
 * cells as blocks; the filtered lookup (8-cell interpolation, footprint depth)
 * is no worse against Embree's normals of the full mesh, and both beat the
 * cut's own smooth normals. The chunks are corrections of those smooth normals
 * (docs/APO.md): texels only where they differ by more than 0.2 rad, so the
 * gain over geometry is smaller than with every texel (before: 4 px linear
 * 27.2, geometry 23.1 dB; 8 px 21.9, 18.4 dB; at 2.0 to 2.5 times the APO
 * bytes). Measured (160 x 120): 4 px linear 24.8, none 24.6, geometry 23.1 dB;
 * 8 px linear 19.4, geometry 18.4 dB. */
static void test_filtered_apo_no_worse(void **state)
{
    fixture *f = *state;
    char model[4096], bin[600], command[8192], cam[700], ref[800];
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name scanapo --min-tris 1500 --json", bin, model,
             f->archives);
    json_decref(ms_test_run_json(command, 0));
    snprintf(cam, sizeof cam, "%s/scanapo.cam", f->dir);
    FILE *out = fopen(cam, "w");
    assert_non_null(out);
    fprintf(out, "meshstream-camera-path 1\n0 0.10 0.20 0.28 -0.006 0.125 -0.005 0 1 0 40\n");
    fclose(out);
    ms_test_bin_path(bin, sizeof bin, "meshrender");
    snprintf(command, sizeof command, "%s %s -p %s -o %s/scanapo-ref --width %d --height %d --smooth --normals --json",
             bin, model, cam, f->dir, WIDTH, HEIGHT);
    json_decref(ms_test_run_json(command, 0));
    snprintf(ref, sizeof ref, "%s/scanapo-ref/normals_000.png", f->dir);
    static const char *tolerances[] = {"4", "8"};
    for (size_t i = 0; i < 2; ++i) {
        char extra[128], tag[64], linear[800], none[800], geometry[800];
        snprintf(extra, sizeof extra, "--tolerance %s", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-linear", tolerances[i]);
        view_apo_normals(f, "scanapo", tag, extra, linear, sizeof linear);
        snprintf(extra, sizeof extra, "--tolerance %s --apo-filter none", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-none", tolerances[i]);
        view_apo_normals(f, "scanapo", tag, extra, none, sizeof none);
        snprintf(extra, sizeof extra, "--tolerance %s --no-apo", tolerances[i]);
        snprintf(tag, sizeof tag, "t%s-geometry", tolerances[i]);
        view_apo_normals(f, "scanapo", tag, extra, geometry, sizeof geometry);
        double l = normals_psnr(linear, ref), n = normals_psnr(none, ref), g = normals_psnr(geometry, ref);
        printf("dragon res3 with APO at %s px, normals against Embree of the full mesh: filtered %.2f dB, "
               "nearest leaf %.2f dB, the cut's smooth normals %.2f dB\n",
               tolerances[i], l, n, g);
        assert_true(l >= n);
        assert_true(l >= g + 0.5);
    }
}

/* A colour model streamed from its archive (issue 34): meshview's albedo
 * picture of the trefoil fixture (per-vertex colour, 8 bits a channel) against
 * meshrender's albedo picture of the whole coloured mesh, from a camera that
 * frames it: at least 30 dB over the pixels both cover, and the silhouettes
 * agree (the cut at 1 px is not the full mesh at its edge). */
static void test_colour_model_albedo_matches_embree(void **state)
{
    fixture *f = *state;
    char ply[700], command[4096], bin[600], cam[700];
    ms_test_model_path(ply, sizeof ply, "trefoil_color.ply.gz");
    ms_mesh mesh;
    ms_error err;
    assert_int_equal(ms_mesh_load(ply, &mesh, NULL, &err), MS_OK);
    assert_non_null(mesh.colours);
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < mesh.vertex_count; ++v)
        for (int k = 0; k < 3; ++k) {
            lo[k] = fmin(lo[k], mesh.positions[3 * v + k]);
            hi[k] = fmax(hi[k], mesh.positions[3 * v + k]);
        }
    ms_mesh_free(&mesh);
    double c[3] = {(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2};
    double size = fmax(hi[0] - lo[0], fmax(hi[1] - lo[1], hi[2] - lo[2]));
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s %s -o %s --name trefoil --no-apo --json", bin, ply, f->archives);
    json_t *baked = ms_test_run_json(command, 0);
    assert_true(json_integer_value(json_object_get(json_object_get(baked, "colour"), "bytes")) > 0);
    json_decref(baked);
    snprintf(cam, sizeof cam, "%s/trefoil.cam", f->dir);
    FILE *out = fopen(cam, "w");
    assert_non_null(out);
    fprintf(out, "meshstream-camera-path 1\n0 %.9g %.9g %.9g %.9g %.9g %.9g 0 1 0 40\n", c[0] + 0.4 * size,
            c[1] + 0.5 * size, c[2] + 1.6 * size, c[0], c[1], c[2]);
    fclose(out);
    char albedo[800], ref[800];
    json_decref(view(f, "trefoil", "albedo", "--shading albedo", albedo, sizeof albedo));
    ms_test_bin_path(bin, sizeof bin, "meshrender");
    snprintf(command, sizeof command, "%s %s -p %s -o %s/trefoil-ref --width %d --height %d --albedo --json", bin,
             ply, cam, f->dir, WIDTH, HEIGHT);
    json_decref(ms_test_run_json(command, 0));
    snprintf(ref, sizeof ref, "%s/trefoil-ref/frame_000.png", f->dir);
    uint32_t wa, ha, wb, hb;
    uint8_t *a = ms_test_png_read(albedo, &wa, &ha), *b = ms_test_png_read(ref, &wb, &hb);
    assert_true(wa == wb && ha == hb);
    size_t n = (size_t)wa * ha;
    uint8_t *mask = malloc(n);
    assert_non_null(mask);
    static const uint8_t bg[3] = {39, 39, 39};
    size_t either = ms_study_colour_mask(a, b, n, bg, false, mask);
    size_t both = ms_study_colour_mask(a, b, n, bg, true, mask);
    ms_study_colour_error e;
    assert_int_equal(ms_study_colour_psnr(a, b, n, mask, &e, &err), MS_OK);
    print_message("trefoil albedo: %zu pixels covered in either, %zu in both (IoU %.4f), colour PSNR %.2f dB "
                  "over both, largest difference %u\n",
                  either, both, (double)both / (double)either, e.psnr_db, e.max_difference);
    assert_true(both > 2000);
    assert_true((double)both / (double)either >= 0.97);
    assert_true(e.psnr_db >= 30.0);
    free(mask);
    free(a);
    free(b);
}

static void test_bad_crease_angles(void **state)
{
    fixture *f = *state;
    static const char *bad[] = {"-1", "181", "nan", "abc", ""};
    char bin[600], command[4096], out[4096];
    ms_test_bin_path(bin, sizeof bin, "meshview");
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        snprintf(command, sizeof command, "%s %s --model cube --crease-angle '%s' 2>&1", bin, f->archives, bad[i]);
        assert_int_equal(ms_test_run(command, out, sizeof out), 2);
        assert_non_null(strstr(out, "--crease-angle"));
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_and_bracket_keep_their_edges),
        cmocka_unit_test(test_catalogue_crease_angle),
        cmocka_unit_test(test_flipped_faces_shade_as_consistent_ones),
        cmocka_unit_test(test_coarse_scan_levels_stay_smooth),
        cmocka_unit_test(test_filtered_apo_no_worse),
        cmocka_unit_test(test_colour_model_albedo_matches_embree),
        cmocka_unit_test(test_bad_crease_angles),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
