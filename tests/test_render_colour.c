/* Per-vertex colour in the renderer (ms_render.h, "Vertex colours"; issue 34
 * item 3): two hand-made quads, each in a cell of its own, with four distinct
 * corner colours (0 and 255 among them), seen face-on so that a pixel is
 * 1/128 of the unit box. In ALBEDO shading every pixel inside a quad is the
 * barycentric interpolation of its triangle's corner colours, found here
 * independently, within one level, and the pixel nearest each corner is its
 * colour; with the wireframe overlay the pixels away from the edges are the
 * same. In LIT shading a quad of one colour is the colourless quad lit with
 * that colour (made linear) as the material's albedo, within one level: the
 * colour is the albedo, the normals only shade; the same on a baked demo model
 * shaded with its APO normals. Colours follow the cells' versions: a frame
 * whose run changed version with its colours uploads that cell only, at 20
 * bytes per vertex, and the picture shows the new colours beside the old; a
 * mesh losing its colours derives every cell and draws them grey at 16 bytes
 * per vertex; gaining them back derives every cell again. The coloured
 * trefoil of tests/data as one cell: the renderer's albedo picture against
 * the CPU reference renderer's (Embree, ms_study_render with albedo) from the
 * same camera, by the colour PSNR over the pixels both cover and over those
 * either covers: the comparison the colour scans get once the data path
 * carries colour. */
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

#include "ms_mesh_io.h"
#include "ms_render.h"
#include "ms_render_picture.h"
#include "ms_study_measure.h"
#include "ms_study_render.h"
#include "ms_test.h"
#include "ms_test_render.h"
#include "ms_viewer_readback.h"

#define WIDTH 128
#define HEIGHT 64
#define CELLS 9 /* the root and its eight children (n = 2) */

/* Quad q (0: cell 1, 1: cell 2) at z = 0.25, corners counter-clockwise seen
 * from +z, each 0.05 pixel outside the centre of its corner pixel (face_on):
 * columns 6 to 57 and 70 to 121, rows 6 to 57 (52 x 52 pixels each). */
#define PX(p) ((p) / 128.0)
static const double quad_x[2][2] = {{PX(6.45), PX(57.55)}, {PX(70.45), PX(121.55)}};
static const double quad_y[2] = {0.5 - PX(57.55), 0.5 - PX(6.45)};
static const uint8_t corner_colours[8][4] = {
    {255, 0, 0, 255}, {0, 255, 0, 255},   {0, 0, 255, 255},   {255, 255, 255, 255},
    {10, 20, 30, 255}, {200, 100, 50, 255}, {0, 128, 255, 255}, {77, 77, 77, 128},
};

typedef struct quads {
    double positions[8 * 3];
    uint32_t triangles[4 * 3];
    uint32_t triangle_cell[4];
    uint8_t colours[8 * 4];
    uint32_t run_cell[2], run_first[3];
    uint64_t run_version[2];
    ms_view_mesh mesh;
} quads;

static void quads_make(quads *q, bool runs)
{
    memset(q, 0, sizeof *q);
    for (int k = 0; k < 2; ++k) {
        for (int c = 0; c < 4; ++c) {
            double *p = &q->positions[3 * (4 * k + c)];
            p[0] = quad_x[k][c == 1 || c == 2];
            p[1] = quad_y[c >= 2];
            p[2] = 0.25;
        }
        const uint32_t base = 4u * (uint32_t)k, tri[6] = {0, 1, 2, 0, 2, 3};
        for (int i = 0; i < 6; ++i)
            q->triangles[6 * k + i] = base + tri[i];
        q->triangle_cell[2 * k] = q->triangle_cell[2 * k + 1] = 1u + (uint32_t)k;
    }
    memcpy(q->colours, corner_colours, sizeof q->colours);
    q->mesh.vertex_count = 8;
    q->mesh.triangle_count = 4;
    q->mesh.positions = q->positions;
    q->mesh.triangles = q->triangles;
    q->mesh.triangle_cell = q->triangle_cell;
    q->mesh.colours = q->colours;
    if (runs) {
        q->run_cell[0] = 1, q->run_cell[1] = 2;
        q->run_first[0] = 0, q->run_first[1] = 2, q->run_first[2] = 4;
        q->run_version[0] = 11, q->run_version[1] = 22;
        q->mesh.run_count = 2;
        q->mesh.run_cell = q->run_cell;
        q->mesh.run_first = q->run_first;
        q->mesh.run_version = q->run_version;
    }
}

static void model(ms_archive_header *h, ms_archive_cell cells[CELLS])
{
    ms_test_render_unit_header(2, CELLS, h);
    memset(cells, 0, CELLS * sizeof *cells);
    for (uint32_t i = 0; i < CELLS; ++i) {
        cells[i].parent = i ? 0 : MS_ARCHIVE_NONE;
        cells[i].first_child = i ? MS_ARCHIVE_NONE : 1;
        cells[i].level = i ? 1 : 0;
        if (i)
            for (int a = 0; a < 3; ++a)
                cells[i].position[a] = ((i - 1) >> a) & 1u;
    }
}

/* Looking down -z at the quads' plane from distance 1, x right and y up: pixel
 * (i, j) (top row first) sees x = (i + 1/2) / 128, y = 1/2 - (j + 1/2) / 128. */
static void face_on(ms_camera *camera)
{
    const double eye[3] = {0.5, 0.25, 1.25}, target[3] = {0.5, 0.25, 0.25}, up[3] = {0, 1, 0};
    double fovy = 2.0 * atan(0.25) * 180.0 / M_PI;
    assert_int_equal(ms_camera_look_at(eye, target, up, fovy, WIDTH, HEIGHT, 0.5, 2.0, camera, NULL), MS_OK);
}

static uint8_t *picture(const quads *q, const ms_render_options *o)
{
    ms_archive_header h;
    ms_archive_cell cells[CELLS];
    model(&h, cells);
    ms_camera camera;
    face_on(&camera);
    uint8_t *rgb;
    ms_error err;
    if (ms_render_picture(&h, cells, &q->mesh, NULL, 0, &camera, o, &rgb, &err) != MS_OK)
        fail_msg("%s", err.text);
    return rgb;
}

/* The quad under pixel (i, j) and its colour there by barycentric interpolation
 * of the corner colours (colours: 8 corners' r g b a), when the pixel centre
 * lies at least `margin` pixels inside it; -1 otherwise. */
static int expected(int i, int j, const uint8_t *colours, double margin, double rgb[3])
{
    double x = (i + 0.5) / 128.0, y = 0.5 - (j + 0.5) / 128.0, m = margin / 128.0;
    for (int k = 0; k < 2; ++k) {
        double x0 = quad_x[k][0], x1 = quad_x[k][1], y0 = quad_y[0], y1 = quad_y[1];
        if (x < x0 + m || x > x1 - m || y < y0 + m || y > y1 - m)
            continue;
        double s = (x - x0) / (x1 - x0), t = (y - y0) / (y1 - y0);
        /* corners 0 (0,0), 1 (1,0), 2 (1,1), 3 (0,1); diagonal 0-2 */
        double w[4] = {0, 0, 0, 0};
        if (s >= t)
            w[0] = 1 - s, w[1] = s - t, w[2] = t; /* triangle 0 1 2 */
        else
            w[0] = 1 - t, w[2] = s, w[3] = t - s; /* triangle 0 2 3 */
        for (int a = 0; a < 3; ++a) {
            rgb[a] = 0;
            for (int c = 0; c < 4; ++c)
                rgb[a] += w[c] * colours[4 * (4 * k + c) + a];
        }
        return k;
    }
    return -1;
}

static int worst_difference(const uint8_t *pixel, const double rgb[3])
{
    int worst = 0;
    for (int a = 0; a < 3; ++a) {
        int d = abs((int)pixel[a] - (int)lround(rgb[a]));
        worst = d > worst ? d : worst;
    }
    return worst;
}

static void test_albedo_interpolates_the_corner_colours(void **state)
{
    (void)state;
    quads q;
    quads_make(&q, false);
    ms_render_options o;
    ms_render_options_default(&o);
    o.shading = MS_SHADING_ALBEDO;
    uint8_t *rgb = picture(&q, &o);
    /* every pixel a pixel inside a quad: the interpolation, within one level */
    int checked = 0, worst = 0;
    for (int j = 0; j < HEIGHT; ++j)
        for (int i = 0; i < WIDTH; ++i) {
            double want[3];
            if (expected(i, j, q.colours, 0.0, want) < 0)
                continue;
            int d = worst_difference(&rgb[3 * ((size_t)j * WIDTH + (size_t)i)], want);
            if (d > 1)
                fail_msg("pixel (%d, %d): %u %u %u, expected %.2f %.2f %.2f", i, j, rgb[3 * (j * WIDTH + i)],
                         rgb[3 * (j * WIDTH + i) + 1], rgb[3 * (j * WIDTH + i) + 2], want[0], want[1], want[2]);
            worst = d > worst ? d : worst;
            checked++;
        }
    assert_int_equal(checked, 2 * 52 * 52);
    /* the corner pixels (their centres 0.05 pixel inside each corner) are the
     * corners' colours within one level: 0 and 255 included */
    for (int k = 0; k < 2; ++k)
        for (int c = 0; c < 4; ++c) {
            double x = quad_x[k][c == 1 || c == 2], y = quad_y[c >= 2];
            int i = (int)lround(x * 128.0 + (c == 1 || c == 2 ? -0.05 : 0.05) - 0.5);
            int j = (int)lround((0.5 - y) * 128.0 + (c >= 2 ? 0.05 : -0.05) - 0.5);
            const uint8_t *pixel = &rgb[3 * ((size_t)j * WIDTH + (size_t)i)];
            for (int a = 0; a < 3; ++a)
                if (abs((int)pixel[a] - (int)q.colours[4 * (4 * k + c) + a]) > 1)
                    fail_msg("corner %d of quad %d at pixel (%d, %d): channel %d is %u, not %u", c, k, i, j, a,
                             pixel[a], q.colours[4 * (4 * k + c) + a]);
        }
    /* bad arguments: one line, nothing drawn */
    ms_error err;
    uint8_t *none = (uint8_t *)&err;
    ms_camera camera;
    face_on(&camera);
    assert_int_equal(ms_render_picture(NULL, NULL, &q.mesh, NULL, 0, &camera, &o, &none, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render picture: no model header and index");
    assert_null(none);
    /* the background is the lit picture's: options.background sRGB-encoded */
    assert_int_equal(rgb[0], 39);
    /* the wireframe overlay: the same pixels away from the edges */
    o.wireframe = true;
    uint8_t *wire = picture(&q, &o);
    int same = 0, darker = 0;
    for (int j = 0; j < HEIGHT; ++j)
        for (int i = 0; i < WIDTH; ++i) {
            double want[3], x = (i + 0.5) / 128.0, y = 0.5 - (j + 0.5) / 128.0;
            int k = expected(i, j, q.colours, 3.0, want);
            if (k < 0)
                continue;
            /* 3 pixels from the diagonal too */
            double side = quad_y[1] - quad_y[0], s = (x - quad_x[k][0]) / side, t = (y - quad_y[0]) / side;
            if (fabs(s - t) * side * 128.0 / sqrt(2.0) < 3.0)
                continue;
            const uint8_t *a = &rgb[3 * ((size_t)j * WIDTH + (size_t)i)], *b = &wire[3 * ((size_t)j * WIDTH + (size_t)i)];
            assert_true(abs(a[0] - b[0]) <= 1 && abs(a[1] - b[1]) <= 1 && abs(a[2] - b[2]) <= 1);
            same++;
        }
    for (size_t p = 0; p < (size_t)WIDTH * HEIGHT; ++p)
        darker += wire[3 * p] + wire[3 * p + 1] + wire[3 * p + 2] < rgb[3 * p] + rgb[3 * p + 1] + rgb[3 * p + 2] - 30;
    assert_true(same > 2 * 40 * 40);
    assert_true(darker > 200); /* the wires are drawn */
    free(wire);
    free(rgb);
}

static float linear(uint8_t v)
{
    double c = v / 255.0;
    return (float)(c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4));
}

/* The pixels of quad k (a pixel inside) of two pictures differ by at most one level. */
static void same_quad(const uint8_t *a, const uint8_t *b, int k)
{
    int checked = 0;
    for (int j = 0; j < HEIGHT; ++j)
        for (int i = 0; i < WIDTH; ++i) {
            double want[3];
            if (expected(i, j, corner_colours[0], 1.0, want) != k)
                continue;
            for (int c = 0; c < 3; ++c) {
                size_t at = 3 * ((size_t)j * WIDTH + (size_t)i) + (size_t)c;
                if (abs((int)a[at] - (int)b[at]) > 1)
                    fail_msg("quad %d pixel (%d, %d) channel %d: %u against %u", k, i, j, c, a[at], b[at]);
            }
            checked++;
        }
    assert_int_equal(checked, 50 * 50);
}

static void test_lit_colour_is_the_albedo(void **state)
{
    (void)state;
    static const uint8_t colour[2][3] = {{200, 150, 100}, {30, 60, 90}};
    quads q;
    quads_make(&q, false);
    for (int v = 0; v < 8; ++v)
        memcpy(&q.colours[4 * v], colour[v / 4], 3);
    ms_render_options o;
    ms_render_options_default(&o);
    uint8_t *coloured = picture(&q, &o);
    q.mesh.colours = NULL;
    uint8_t *grey = picture(&q, &o);
    /* the colourless quads: the material's albedo, not the quads' colour */
    assert_true(memcmp(coloured, grey, 3 * (size_t)WIDTH * HEIGHT) != 0);
    for (int k = 0; k < 2; ++k) {
        for (int a = 0; a < 3; ++a)
            o.albedo[a] = linear(colour[k][a]);
        uint8_t *want = picture(&q, &o);
        same_quad(coloured, want, k);
        free(want);
    }
    free(grey);
    free(coloured);
}

/* The demo model shaded with its APO normals: in one colour, the colourless
 * model with that colour as its albedo. */
static void test_apo_shades_the_colour(void **state)
{
    (void)state;
    char dir[256];
    ms_test_tmpdir(dir, sizeof dir);
    ms_archive *archive = ms_test_render_bake_demo(16, dir, 12, 2000, 0);
    ms_render *unused;
    ms_view *view;
    ms_test_render_open(archive, &unused, &view);
    ms_render_free(unused);
    const double look[3] = {1.0, 0.5, 0.7};
    ms_camera camera;
    ms_view_mesh mesh = {0};
    ms_test_render_look(archive, view, look, 96, 96, 1.0, &camera, &mesh);
    ms_core_apo_chunk *apo;
    size_t apo_count;
    ms_test_render_apo(archive, &mesh, 0, false, &apo, &apo_count);
    assert_true(apo_count > 0);
    static const uint8_t colour[3] = {180, 90, 40};
    uint8_t *colours = malloc(4 * mesh.vertex_count);
    assert_non_null(colours);
    for (size_t v = 0; v < mesh.vertex_count; ++v)
        memcpy(&colours[4 * v], colour, 3), colours[4 * v + 3] = 255;
    const ms_archive_header *h = ms_archive_get_header(archive);
    const ms_archive_cell *cells = ms_archive_get_cell(archive, 0);
    ms_render_options o;
    ms_render_options_default(&o);
    uint8_t *flat_apo, *with_colour, *with_albedo;
    ms_error err;
    mesh.colours = colours;
    assert_int_equal(ms_render_picture(h, cells, &mesh, apo, apo_count, &camera, &o, &with_colour, &err), MS_OK);
    o.apo = false;
    assert_int_equal(ms_render_picture(h, cells, &mesh, apo, apo_count, &camera, &o, &flat_apo, &err), MS_OK);
    o.apo = true;
    mesh.colours = NULL;
    for (int a = 0; a < 3; ++a)
        o.albedo[a] = linear(colour[a]);
    assert_int_equal(ms_render_picture(h, cells, &mesh, apo, apo_count, &camera, &o, &with_albedo, &err), MS_OK);
    size_t n = 3 * 96 * 96, differ = 0, covered = 0;
    for (size_t p = 0; p < n; ++p) {
        assert_true(abs((int)with_colour[p] - (int)with_albedo[p]) <= 1);
        differ += with_colour[p] != flat_apo[p];
        covered += with_colour[p] != 39;
    }
    assert_true(covered > n / 10);
    assert_true(differ > covered / 10); /* the APO normals shade: not the picture without them */
    free(flat_apo);
    free(with_colour);
    free(with_albedo);
    free(colours);
    free(apo);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
    ms_archive_close(archive);
    ms_test_rmdir(dir);
}

/* ---- colours follow the cells' versions ------------------------------------ */

static void show(ms_render *r, const ms_view_mesh *mesh, ms_render_frame_stats *fs, ms_render_upload_stats *up)
{
    ms_error err;
    if (ms_render_set_frame(r, mesh, NULL, 0, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_render_frame_stats_get(r, fs);
    if (ms_render_upload(r, 1u << 30, up, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(up->cells_pending, 0);
}

/* The albedo picture of what r draws now, and the colour at the centre of
 * quad k's triangle 0 1 2 (s = 2/3, t = 1/3). */
static void centre_colour(ms_render *r, int k, uint8_t out[3])
{
    ms_camera camera;
    face_on(&camera);
    ms_render_options o;
    ms_render_options_default(&o);
    o.shading = MS_SHADING_ALBEDO;
    ms_viewer_target target;
    ms_error err;
    assert_int_equal(ms_viewer_target_init(&target, WIDTH, HEIGHT, &err), MS_OK);
    ms_viewer_target_bind(&target);
    assert_int_equal(ms_render_draw(r, &camera, &o, NULL, &err), MS_OK);
    uint8_t *rgb;
    assert_int_equal(ms_viewer_read_rgb(WIDTH, HEIGHT, &rgb, &err), MS_OK);
    double side = quad_y[1] - quad_y[0], x = quad_x[k][0] + side * 2.0 / 3.0, y = quad_y[0] + side / 3.0;
    int i = (int)floor(x * 128.0), j = (int)floor((0.5 - y) * 128.0);
    memcpy(out, &rgb[3 * ((size_t)j * WIDTH + (size_t)i)], 3);
    free(rgb);
    glBindFramebuffer(GL_FRAMEBUFFER, 0);
    ms_viewer_target_free(&target);
}

static void assert_near(const uint8_t got[3], int r, int g, int b)
{
    if (abs(got[0] - r) > 2 || abs(got[1] - g) > 2 || abs(got[2] - b) > 2)
        fail_msg("%u %u %u, expected %d %d %d", got[0], got[1], got[2], r, g, b);
}

static void test_colours_follow_the_versions(void **state)
{
    (void)state;
    ms_archive_header h;
    ms_archive_cell cells[CELLS];
    model(&h, cells);
    ms_render *r;
    ms_error err;
    assert_int_equal(ms_render_new(&h, cells, &r, &err), MS_OK);
    quads q;
    quads_make(&q, true);
    /* each quad one colour: its centre shows it exactly */
    for (int v = 0; v < 8; ++v)
        memcpy(&q.colours[4 * v], v < 4 ? (const uint8_t[3]){250, 0, 5} : (const uint8_t[3]){1, 128, 254}, 3);
    ms_render_frame_stats fs;
    ms_render_upload_stats up;
    ms_render_memory_stats m;
    const uint64_t coloured_cell = 4 * 20 + 2 * 12, grey_cell = 4 * 16 + 2 * 12;
    show(r, &q.mesh, &fs, &up);
    assert_int_equal(fs.cells_changed, 2);
    assert_int_equal(up.bytes, 2 * coloured_cell);
    ms_render_memory(r, &m);
    assert_int_equal(m.mesh_bytes, 2 * coloured_cell);
    uint8_t c[3];
    centre_colour(r, 0, c);
    assert_near(c, 250, 0, 5);
    centre_colour(r, 1, c);
    assert_near(c, 1, 128, 254);

    /* cell 1's colours change with its version: cell 1 alone goes up again */
    for (int v = 0; v < 4; ++v)
        memcpy(&q.colours[4 * v], (const uint8_t[3]){0, 255, 0}, 3);
    q.run_version[0] = 12;
    show(r, &q.mesh, &fs, &up);
    assert_int_equal(fs.cells_changed, 1);
    assert_int_equal(fs.cells_derived, 1);
    assert_int_equal(up.bytes, coloured_cell);
    ms_render_memory(r, &m);
    assert_int_equal(m.mesh_bytes, 2 * coloured_cell);
    centre_colour(r, 0, c);
    assert_near(c, 0, 255, 0);
    centre_colour(r, 1, c);
    assert_near(c, 1, 128, 254);

    /* the same frame again: nothing derived, nothing sent */
    show(r, &q.mesh, &fs, &up);
    assert_int_equal(fs.cells_changed, 0);
    assert_int_equal(up.bytes, 0);

    /* the colours gone, the versions the same: every cell again, grey */
    q.mesh.colours = NULL;
    show(r, &q.mesh, &fs, &up);
    assert_int_equal(fs.cells_changed, 2);
    assert_int_equal(up.bytes, 2 * grey_cell);
    ms_render_memory(r, &m);
    assert_int_equal(m.mesh_bytes, 2 * grey_cell);
    centre_colour(r, 1, c);
    assert_near(c, 221, 216, 209); /* the default albedo 0.72 0.69 0.64, sRGB-encoded */

    /* and back: every cell again, in colour */
    q.mesh.colours = q.colours;
    show(r, &q.mesh, &fs, &up);
    assert_int_equal(fs.cells_changed, 2);
    assert_int_equal(up.bytes, 2 * coloured_cell);
    centre_colour(r, 0, c);
    assert_near(c, 0, 255, 0);
    ms_render_free(r);
}

/* The trefoil as a one-cell model in the box [-0.25, 0.25]^3. */
static void test_trefoil_against_embree(void **state)
{
    (void)state;
    char path[600];
    ms_test_model_path(path, sizeof path, "trefoil_color.ply.gz");
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_load(path, &m, NULL, &err), MS_OK);
    uint32_t *root = calloc(m.triangle_count, sizeof *root);
    assert_non_null(root);
    ms_view_mesh mesh = {.vertex_count = m.vertex_count,
                         .triangle_count = m.triangle_count,
                         .positions = m.positions,
                         .triangles = m.triangles,
                         .triangle_cell = root,
                         .colours = m.colours};
    ms_archive_header h;
    ms_test_render_unit_header(2, 1, &h);
    h.box_side = 0.5;
    h.box_origin[0] = h.box_origin[1] = h.box_origin[2] = -0.25;
    ms_archive_cell cell;
    memset(&cell, 0, sizeof cell);
    cell.parent = cell.first_child = MS_ARCHIVE_NONE;
    const double eye[3] = {0.5, 0.2, 0.8}, target[3] = {0, -0.028, 0}, up[3] = {0, 1, 0};
    enum { W = 240, H = 180 };
    ms_camera camera;
    assert_int_equal(ms_camera_look_at(eye, target, up, 35, W, H, 0.1, 10, &camera, NULL), MS_OK);
    ms_render_options o;
    ms_render_options_default(&o);
    o.shading = MS_SHADING_ALBEDO;
    uint8_t *gl;
    assert_int_equal(ms_render_picture(&h, &cell, &mesh, NULL, 0, &camera, &o, &gl, &err), MS_OK);
    ms_study_scene *scene;
    assert_int_equal(ms_study_scene_new(m.positions, m.vertex_count, m.triangles, m.triangle_count, &scene, &err),
                     MS_OK);
    ms_study_image im = {0};
    ms_study_render_options so = {.threads = 2, .colours = m.colours, .albedo = true};
    assert_int_equal(ms_study_render(scene, &camera, &so, &im, &err), MS_OK);
    size_t n = (size_t)W * H;
    uint8_t *mask = malloc(n);
    assert_non_null(mask);
    static const uint8_t bg[3] = {39, 39, 39};
    ms_study_colour_error both, either;
    size_t in_both = ms_study_colour_mask(gl, im.rgb, n, bg, true, mask);
    assert_int_equal(ms_study_colour_psnr(gl, im.rgb, n, mask, &both, &err), MS_OK);
    size_t in_either = ms_study_colour_mask(gl, im.rgb, n, bg, false, mask);
    assert_int_equal(ms_study_colour_psnr(gl, im.rgb, n, mask, &either, &err), MS_OK);
    print_message("trefoil albedo, renderer against Embree: %zu pixels in both (%.2f dB, largest difference %u), "
                  "%zu in either (%.2f dB)\n",
                  in_both, both.psnr_db, both.max_difference, in_either, either.psnr_db);
    /* 6697 pixels in both, 88 dB, at most one level apart; one pixel of the
     * silhouette differs (44 dB over either) */
    assert_true(in_both > n / 8);
    assert_true(in_either - in_both <= 5);
    assert_true(both.psnr_db > 60.0 && both.max_difference <= 1);
    assert_true(either.psnr_db > 35.0);
    free(mask);
    free(gl);
    ms_study_image_free(&im);
    ms_study_scene_free(scene);
    free(root);
    ms_mesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_albedo_interpolates_the_corner_colours),
        cmocka_unit_test(test_lit_colour_is_the_albedo),
        cmocka_unit_test(test_apo_shades_the_colour),
        cmocka_unit_test(test_colours_follow_the_versions),
        cmocka_unit_test(test_trefoil_against_embree),
    };
    return cmocka_run_group_tests_name("render_colour", tests, ms_test_gl_group_setup, ms_test_gl_group_teardown);
}
