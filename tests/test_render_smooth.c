/* Smooth shading (ms_render.h, "Vertex normals"; docs/RENDERER.md): a
 * hand-made latitude-longitude sphere split into the eight cells of a two-level
 * model, drawn in NORMALS mode without APO. With smooth on, every covered pixel
 * off the silhouette shows the perspective-correct interpolation of the
 * area-weighted vertex normals of its triangle (found here independently, by
 * unprojecting the pixel and locating it on the mesh), close to the sphere's
 * radial normal, and neighbouring pixels of different cells never jump; with
 * smooth off every pixel shows exactly its triangle's flat normal, as before
 * vertex normals existed. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_render.h"
#include "ms_test.h"
#include "ms_test_render.h"
#include "ms_vec3.h"

#define SIZE 128
#define RINGS 24      /* latitude bands: 7.5 degrees each */
#define SEGMENTS 48   /* longitude steps: 7.5 degrees each */
#define RADIUS 0.35
#define CELLS 9       /* the root and its eight children (n = 2) */


static const double centre[3] = {0.5, 0.5, 0.5};

typedef struct sphere {
    double *positions;
    uint32_t *triangles, *triangle_cell;
    size_t vertex_count, triangle_count;
    double *vertex_normal; /* 3 per vertex: unit, area-weighted */
    double *face_normal;   /* 3 per triangle: unit */
} sphere;

static double angle_deg(const double a[3], const double b[3])
{
    double c = ms_vec3_dot(a, b) / sqrt(ms_vec3_dot(a, a) * ms_vec3_dot(b, b));
    return acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c)) * 180.0 / M_PI;
}

/* Poles on the x axis (on the silhouette seen from +z), rings in between,
 * triangles counter-clockwise seen from outside; each triangle drawn by the
 * child cell holding its centroid. */
static void sphere_build(sphere *s)
{
    s->vertex_count = 2 + (size_t)(RINGS - 1) * SEGMENTS;
    s->triangle_count = 2 * (size_t)SEGMENTS * (RINGS - 1);
    s->positions = malloc(3 * s->vertex_count * sizeof *s->positions);
    s->triangles = malloc(3 * s->triangle_count * sizeof *s->triangles);
    s->triangle_cell = malloc(s->triangle_count * sizeof *s->triangle_cell);
    s->vertex_normal = calloc(3 * s->vertex_count, sizeof *s->vertex_normal);
    s->face_normal = malloc(3 * s->triangle_count * sizeof *s->face_normal);
    assert_true(s->positions && s->triangles && s->triangle_cell && s->vertex_normal && s->face_normal);
    double *p = s->positions;
    p[0] = centre[0] + RADIUS, p[1] = centre[1], p[2] = centre[2];
    p[3] = centre[0] - RADIUS, p[4] = centre[1], p[5] = centre[2];
    for (int r = 1; r < RINGS; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            double theta = M_PI * r / RINGS, phi = 2.0 * M_PI * k / SEGMENTS;
            double *v = &p[3 * (2 + (size_t)(r - 1) * SEGMENTS + (size_t)k)];
            v[0] = centre[0] + RADIUS * cos(theta);
            v[1] = centre[1] + RADIUS * sin(theta) * cos(phi);
            v[2] = centre[2] + RADIUS * sin(theta) * sin(phi);
        }
#define RING_VERTEX(r, k) (2u + (uint32_t)((r) - 1) * SEGMENTS + (uint32_t)(((k) + SEGMENTS) % SEGMENTS))
    size_t t = 0;
    for (int k = 0; k < SEGMENTS; ++k) {
        uint32_t *tri = &s->triangles[3 * t++];
        tri[0] = 0, tri[1] = RING_VERTEX(1, k), tri[2] = RING_VERTEX(1, k + 1);
        tri = &s->triangles[3 * t++];
        tri[0] = 1, tri[1] = RING_VERTEX(RINGS - 1, k + 1), tri[2] = RING_VERTEX(RINGS - 1, k);
    }
    for (int r = 1; r < RINGS - 1; ++r)
        for (int k = 0; k < SEGMENTS; ++k) {
            uint32_t a = RING_VERTEX(r, k), b = RING_VERTEX(r, k + 1), c = RING_VERTEX(r + 1, k),
                     d = RING_VERTEX(r + 1, k + 1);
            uint32_t *tri = &s->triangles[3 * t++];
            tri[0] = a, tri[1] = c, tri[2] = d;
            tri = &s->triangles[3 * t++];
            tri[0] = a, tri[1] = d, tri[2] = b;
        }
#undef RING_VERTEX
    assert_int_equal(t, s->triangle_count);
    for (t = 0; t < s->triangle_count; ++t) {
        const uint32_t *tri = &s->triangles[3 * t];
        const double *a = &p[3 * (size_t)tri[0]], *b = &p[3 * (size_t)tri[1]], *c = &p[3 * (size_t)tri[2]];
        double u[3], v[3], n[3];
        for (int ax = 0; ax < 3; ++ax)
            u[ax] = b[ax] - a[ax], v[ax] = c[ax] - a[ax];
        ms_vec3_cross(u, v, n);
        for (int k = 0; k < 3; ++k)
            for (int ax = 0; ax < 3; ++ax)
                s->vertex_normal[3 * (size_t)tri[k] + (size_t)ax] += n[ax];
        ms_vec3_normalise(n);
        double out[3] = {a[0] - centre[0], a[1] - centre[1], a[2] - centre[2]};
        assert_true(ms_vec3_dot(n, out) > 0.0); /* wound outwards */
        memcpy(&s->face_normal[3 * t], n, sizeof n);
        uint32_t octant = 0;
        for (int ax = 0; ax < 3; ++ax)
            octant |= (uint32_t)((a[ax] + b[ax] + c[ax]) / 3.0 >= 0.5) << (2 - ax);
        s->triangle_cell[t] = 1 + octant;
    }
    for (size_t v = 0; v < s->vertex_count; ++v)
        ms_vec3_normalise(&s->vertex_normal[3 * v]);
}

static void sphere_free(sphere *s)
{
    free(s->positions);
    free(s->triangles);
    free(s->triangle_cell);
    free(s->vertex_normal);
    free(s->face_normal);
}

/* The triangles (at most 8) holding world point x: within 1e-5 of the plane and
 * barycentric coordinates all >= -0.02 (rasterisation and depth rounding put a
 * pixel next to an edge slightly outside its triangle: 0.02 is about a
 * twentieth of a pixel here); weights receive the coordinates. */
static int locate(const sphere *s, const double x[3], size_t found[8], double weights[8][3])
{
    int count = 0;
    for (size_t t = 0; t < s->triangle_count && count < 8; ++t) {
        const double *n = &s->face_normal[3 * t];
        const uint32_t *tri = &s->triangles[3 * t];
        const double *a = &s->positions[3 * (size_t)tri[0]], *b = &s->positions[3 * (size_t)tri[1]],
                     *c = &s->positions[3 * (size_t)tri[2]];
        double ax[3] = {x[0] - a[0], x[1] - a[1], x[2] - a[2]};
        if (fabs(ms_vec3_dot(ax, n)) > 1e-5)
            continue;
        double ab[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, ac[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double m[3], area2;
        ms_vec3_cross(ab, ac, m);
        area2 = ms_vec3_dot(m, n);
        double q[3];
        ms_vec3_cross(ab, ax, q);
        double wc = ms_vec3_dot(q, n) / area2;
        ms_vec3_cross(ax, ac, q);
        double wb = ms_vec3_dot(q, n) / area2, wa = 1.0 - wb - wc;
        if (wa < -2e-2 || wb < -2e-2 || wc < -2e-2)
            continue;
        found[count] = t;
        weights[count][0] = wa, weights[count][1] = wb, weights[count][2] = wc;
        count++;
    }
    return count;
}

typedef struct picture {
    float *rgba, *depth, *ids;
} picture;

static void draw(ms_render *r, const ms_camera *cam, bool smooth, picture *out)
{
    size_t np = (size_t)SIZE * SIZE;
    out->rgba = malloc(np * 4 * sizeof(float));
    out->ids = malloc(np * 4 * sizeof(float));
    out->depth = malloc(np * sizeof(float));
    assert_true(out->rgba && out->ids && out->depth);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, SIZE, SIZE);
    ms_render_options o;
    ms_render_options_default(&o);
    assert_true(o.smooth); /* the default */
    o.apo = false;
    o.smooth = smooth;
    o.shading = MS_SHADING_NORMALS;
    o.background[0] = o.background[1] = o.background[2] = 0.0f;
    ms_error err;
    if (ms_render_draw(r, cam, &o, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_test_fbo_read(&fbo, out->rgba, out->depth);
    o.shading = MS_SHADING_CELL_ID;
    if (ms_render_draw(r, cam, &o, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_test_fbo_read(&fbo, out->ids, NULL);
    ms_test_fbo_free(&fbo);
}

static void picture_free(picture *p)
{
    free(p->rgba);
    free(p->depth);
    free(p->ids);
}

static uint32_t pixel_cell(const picture *p, size_t at)
{
    uint32_t id = 0;
    for (int k = 0; k < 3; ++k)
        id |= (uint32_t)lroundf(p->ids[4 * at + (size_t)k] * 255.0f) << (8 * k);
    return id; /* cell + 1; 0 background */
}

static void pixel_normal(const picture *p, size_t at, double n[3])
{
    for (int k = 0; k < 3; ++k)
        n[k] = 2.0 * p->rgba[4 * at + (size_t)k] - 1.0;
}

/* Covered, and so are its eight neighbours (not on the silhouette). */
static bool inner(const picture *p, int x, int y)
{
    if (x < 1 || y < 1 || x >= SIZE - 1 || y >= SIZE - 1)
        return false;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
            if (p->depth[(size_t)(y + dy) * SIZE + (size_t)(x + dx)] >= 1.0f)
                return false;
    return true;
}

static void test_sphere(void **state)
{
    (void)state;
    sphere s;
    sphere_build(&s);
    ms_archive_header h;
    ms_test_render_unit_header(2, CELLS, &h);
    ms_archive_cell cells[CELLS];
    memset(cells, 0, sizeof cells);
    cells[0].parent = MS_ARCHIVE_NONE;
    cells[0].first_child = 1;
    for (uint32_t o = 0; o < 8; ++o) {
        ms_archive_cell *c = &cells[1 + o];
        c->parent = 0;
        c->first_child = MS_ARCHIVE_NONE;
        c->level = 1;
        c->position[0] = (o >> 2) & 1, c->position[1] = (o >> 1) & 1, c->position[2] = o & 1;
    }
    ms_render *r;
    ms_error err;
    if (ms_render_new(&h, cells, &r, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_view_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    mesh.vertex_count = s.vertex_count;
    mesh.triangle_count = s.triangle_count;
    mesh.positions = s.positions;
    mesh.triangles = s.triangles;
    mesh.triangle_cell = s.triangle_cell;
    ms_render_upload_stats up;
    ms_test_render_show(r, &mesh, NULL, 0, &up);
    assert_int_equal(up.cells_pending, 0);
    ms_camera cam;
    /* off-axis, so that the cell borders x = 0.5 and y = 0.5 cross the picture */
    const double eye[3] = {0.5 + 0.6, 0.5 + 0.7, 0.5 + 2.2}, upv[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(eye, centre, upv, 20.0, SIZE, SIZE, 1.0, 4.0, &cam, NULL), MS_OK);
    picture smooth, flat;
    draw(r, &cam, true, &smooth);
    draw(r, &cam, false, &flat);

    size_t covered = 0, located = 0, border_pairs = 0, differ = 0;
    double worst_interp = 0, worst_radial = 0, worst_flat = 0, worst_flat_radial = 0;
    double worst_border = 0, worst_flat_step = 0;
    for (int y = 0; y < SIZE; ++y)
        for (int x = 0; x < SIZE; ++x) {
            size_t at = (size_t)y * SIZE + (size_t)x;
            assert_true((smooth.depth[at] < 1.0f) == (pixel_cell(&smooth, at) != 0));
            assert_memory_equal(&smooth.depth[at], &flat.depth[at], sizeof(float));
            if (!inner(&smooth, x, y))
                continue;
            covered++;
            double world[3], radial[3], got[3], got_flat[3];
            assert_true(ms_render_unproject(&cam, x + 0.5, y + 0.5, smooth.depth[at], world));
            for (int a = 0; a < 3; ++a)
                radial[a] = world[a] - centre[a];
            pixel_normal(&smooth, at, got);
            pixel_normal(&flat, at, got_flat);
            double d_radial = angle_deg(got, radial), d_flat_radial = angle_deg(got_flat, radial);
            worst_radial = fmax(worst_radial, d_radial);
            worst_flat_radial = fmax(worst_flat_radial, d_flat_radial);
            differ += angle_deg(got, got_flat) > 1.0;
            size_t found[8];
            double w[8][3];
            int count = locate(&s, world, found, w);
            if (count > 0) {
                located++;
                /* the best of the candidate triangles (on an edge they agree) */
                double best_interp = 180, best_flat = 180;
                for (int i = 0; i < count; ++i) {
                    const uint32_t *tri = &s.triangles[3 * found[i]];
                    double want[3] = {0, 0, 0};
                    for (int k = 0; k < 3; ++k)
                        for (int a = 0; a < 3; ++a)
                            want[a] += w[i][k] * s.vertex_normal[3 * (size_t)tri[k] + (size_t)a];
                    best_interp = fmin(best_interp, angle_deg(got, want));
                    best_flat = fmin(best_flat, angle_deg(got_flat, &s.face_normal[3 * found[i]]));
                }
                worst_interp = fmax(worst_interp, best_interp);
                worst_flat = fmax(worst_flat, best_flat);
            }
            /* right and upper neighbours: the step between their normals beyond
             * the sphere's own turn between the two points (degrees per pixel
             * near the silhouette): none across a cell border when smooth; the
             * flat picture jumps at triangle edges */
            for (int k = 0; k < 2; ++k) {
                int nx = x + (k == 0), ny = y + (k == 1);
                if (!inner(&smooth, nx, ny))
                    continue;
                size_t nat = (size_t)ny * SIZE + (size_t)nx;
                double there[3], radial_there[3], other[3];
                assert_true(ms_render_unproject(&cam, nx + 0.5, ny + 0.5, smooth.depth[nat], there));
                for (int a = 0; a < 3; ++a)
                    radial_there[a] = there[a] - centre[a];
                double turn = angle_deg(radial, radial_there);
                pixel_normal(&flat, nat, other);
                worst_flat_step = fmax(worst_flat_step, angle_deg(got_flat, other) - turn);
                if (pixel_cell(&smooth, nat) == pixel_cell(&smooth, at))
                    continue;
                border_pairs++;
                pixel_normal(&smooth, nat, other);
                worst_border = fmax(worst_border, angle_deg(got, other) - turn);
            }
        }
    print_message("%zu inner pixels, %zu located on the mesh, %zu differ from flat by > 1 deg; smooth: worst %.3f deg "
                  "from the interpolated normal, %.3f from the radial one, %zu cell-border pairs, worst step beyond the sphere's turn %.3f deg; "
                  "flat: worst %.3f deg from the face normal, %.3f from the radial one, worst step %.3f deg\n",
                  covered, located, differ, worst_interp, worst_radial, border_pairs, worst_border, worst_flat,
                  worst_flat_radial, worst_flat_step);
    assert_true(covered > 5000);
    assert_true(located >= covered - covered / 100);
    assert_true(border_pairs > 100);
    /* smooth: the interpolated vertex normal, up to the 10-bit packing */
    assert_true(worst_interp < 0.5);
    assert_true(worst_radial < 2.0);
    assert_true(worst_border < 1.0);
    /* flat: the triangle's own normal, as before */
    assert_true(worst_flat < 0.1);
    assert_true(worst_flat_radial > 3.0);
    assert_true(worst_flat_step > 4.0);
    assert_true(differ > covered / 4);
    picture_free(&smooth);
    picture_free(&flat);
    ms_render_free(r);
    sphere_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_sphere),
    };
    return cmocka_run_group_tests(tests, ms_test_gl_group_setup, ms_test_gl_group_teardown);
}
