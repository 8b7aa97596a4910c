/* The CPU reference renderer: a unit cube seen face-on covers exactly the
 * analytically expected pixels (all but those whose centre lies on the projected
 * border), at the expected depth and normal, shaded by the documented formula;
 * a sphere covers the disc its silhouette projects to; renders do not depend on
 * the thread count nor on a far-away origin; APO normals come from the drawing
 * cell's chunk at the hit's cell-local coordinate, the nearest leaf unfiltered
 * and the client's filter by default (8-cell interpolation, depth limited by
 * the pixel's footprint), and light with their own self-shadowing factor; a
 * smooth normal from a fold gives way to N_g; PNG output. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_apo_format.h"
#include "ms_study_measure.h"
#include "ms_study_render.h"
#include "ms_test.h"

/* The cube [c - 0.5, c + 0.5]^3, 12 triangles, outward. Front face (z = c + 0.5)
 * is triangles 0 and 1. */
static ms_study_scene *cube_scene(double c)
{
    double pos[24];
    for (int v = 0; v < 8; ++v) {
        pos[3 * v] = c + ((v & 1) ? 0.5 : -0.5);
        pos[3 * v + 1] = c + ((v & 2) ? 0.5 : -0.5);
        pos[3 * v + 2] = c + ((v & 4) ? 0.5 : -0.5);
    }
    static const uint32_t tri[36] = {
        4, 5, 7, 4, 7, 6, /* +z */
        0, 2, 3, 0, 3, 1, /* -z */
        1, 3, 7, 1, 7, 5, /* +x */
        0, 4, 6, 0, 6, 2, /* -x */
        2, 6, 7, 2, 7, 3, /* +y */
        0, 1, 5, 0, 5, 4, /* -y */
    };
    ms_study_scene *s;
    ms_error err;
    if (ms_study_scene_new(pos, 8, tri, 12, &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    return s;
}

static void look(const double pos[3], const double target[3], double w, double h, ms_camera *cam)
{
    const double up[3] = {0, 1, 0};
    ms_error err;
    if (ms_camera_look_at(pos, target, up, 40, w, h, 0.1, 100, cam, &err) != MS_OK)
        fail_msg("%s", err.text);
}

/* The pixel centre's slopes (x, y) as the renderer defines them. */
static void slopes(const ms_camera *cam, uint32_t i, uint32_t j, double *x, double *y)
{
    double ty = tan(cam->fovy / 2), tx = ty * cam->width / cam->height;
    *x = (2.0 * (i + 0.5) / cam->width - 1) * tx;
    *y = (1 - 2.0 * (j + 0.5) / cam->height) * ty;
}

static void render(const ms_study_scene *s, const ms_camera *cam, unsigned threads, ms_study_image *im)
{
    ms_study_render_options o = {.threads = threads};
    ms_error err;
    if (ms_study_render(s, cam, &o, im, &err) != MS_OK)
        fail_msg("%s", err.text);
}

static void test_cube_face_on(void **state)
{
    (void)state;
    ms_study_scene *s = cube_scene(0);
    ms_camera cam;
    const double eye[3] = {0, 0, 3}, target[3] = {0, 0, 0};
    look(eye, target, 63, 47, &cam);
    ms_study_image im = {0};
    render(s, &cam, 2, &im);
    assert_int_equal(im.width, 63);
    assert_int_equal(im.height, 47);
    /* The front face at eye depth 2.5 covers slopes |x|, |y| <= 0.5 / 2.5; the
     * sides hide behind it. */
    double ty = tan(cam.fovy / 2), pixel = 2 * ty / cam.height; /* slope per pixel */
    size_t covered = 0, border = 0;
    for (uint32_t j = 0; j < im.height; ++j)
        for (uint32_t i = 0; i < im.width; ++i) {
            size_t p = (size_t)j * im.width + i;
            double x, y;
            slopes(&cam, i, j, &x, &y);
            double margin = 0.2 - fmax(fabs(x), fabs(y)); /* > 0 inside */
            if (fabs(margin) < 0.01 * pixel) {
                border++;
                continue;
            }
            bool inside = margin > 0;
            if (inside != (bool)ms_study_image_covered(&im, p))
                fail_msg("pixel (%u, %u): covered %d, expected %d", i, j, ms_study_image_covered(&im, p), inside);
            if (!inside) {
                assert_true(isinf(im.depth[p]));
                assert_true(im.normal[3 * p] == 0 && im.normal[3 * p + 1] == 0 && im.normal[3 * p + 2] == 0);
                assert_int_equal(im.rgb[3 * p], ms_study_srgb8(MS_STUDY_BACKGROUND));
                continue;
            }
            covered++;
            assert_true(im.triangle[p] <= 1);
            assert_true(fabs(im.depth[p] - 2.5) < 1e-5);
            assert_true(im.normal[3 * p] == 0 && im.normal[3 * p + 1] == 0 && im.normal[3 * p + 2] == 1);
            /* N = Ng = +z, L = -dir / |dir| with dir = (x, y, -1): N.L = 1 / |dir| */
            double nl = 1 / sqrt(x * x + y * y + 1);
            double c = MS_STUDY_AMBIENT + nl * (MS_STUDY_DIFFUSE * nl + MS_STUDY_SPECULAR * pow(nl, MS_STUDY_SHININESS));
            int expect = ms_study_srgb8(c);
            assert_true(abs((int)im.rgb[3 * p] - expect) <= 1);
            assert_true(im.rgb[3 * p] == im.rgb[3 * p + 1] && im.rgb[3 * p] == im.rgb[3 * p + 2]);
        }
    /* the square is about 0.4 / pixel on a side; only its border may be unsure */
    double side = 0.4 / pixel;
    assert_true(covered >= (size_t)floor(side - 2) * (size_t)floor(side - 2));
    assert_true(covered <= (size_t)ceil(side + 2) * (size_t)ceil(side + 2));
    assert_true(border <= 4 * (size_t)ceil(side + 2));
    /* the centre pixel looks straight down the axis: full light, 255 */
    assert_int_equal(im.rgb[3 * (23 * 63 + 31)], 255);
    ms_study_image_free(&im);
    ms_study_scene_free(s);
}

/* A UV sphere of radius 1 with many segments, seen from distance D: a pixel is
 * covered when its ray passes within the inscribed polygon's radius of the
 * centre, and not when it misses the true sphere. */
static void test_sphere(void **state)
{
    (void)state;
    const unsigned rings = 64, segs = 128;
    size_t vc = (size_t)(rings + 1) * segs, tc = 2 * (size_t)rings * segs;
    double *pos = malloc(3 * vc * sizeof *pos);
    uint32_t *tri = malloc(3 * tc * sizeof *tri);
    assert_non_null(pos);
    assert_non_null(tri);
    for (unsigned r = 0; r <= rings; ++r)
        for (unsigned k = 0; k < segs; ++k) {
            double th = M_PI * r / rings, ph = 2 * M_PI * k / segs;
            double *p = &pos[3 * ((size_t)r * segs + k)];
            p[0] = sin(th) * cos(ph);
            p[1] = cos(th);
            p[2] = sin(th) * sin(ph);
        }
    size_t t = 0;
    for (unsigned r = 0; r < rings; ++r)
        for (unsigned k = 0; k < segs; ++k) {
            uint32_t a = r * segs + k, b = r * segs + (k + 1) % segs, c = a + segs, d = b + segs;
            uint32_t q[6] = {a, c, d, a, d, b};
            memcpy(&tri[3 * t], q, sizeof q);
            t += 2;
        }
    ms_study_scene *s;
    ms_error err;
    assert_int_equal(ms_study_scene_new(pos, vc, tri, tc, &s, &err), MS_OK);
    free(pos);
    free(tri);
    const double D = 4, eye[3] = {0, 0, D}, target[3] = {0, 0, 0};
    ms_camera cam;
    look(eye, target, 48, 40, &cam);
    ms_study_image im = {0};
    render(s, &cam, 0, &im);
    /* A ray at slope (x, y) passes the centre at distance D sin(a), tan a = |(x, y)|.
     * The tessellation's faces lie at least cos(pi / rings) (the coarser of the two
     * directions) from the centre. */
    double inner = cos(M_PI / rings), covered = 0;
    for (uint32_t j = 0; j < im.height; ++j)
        for (uint32_t i = 0; i < im.width; ++i) {
            double x, y;
            slopes(&cam, i, j, &x, &y);
            double dist = D * sin(atan(sqrt(x * x + y * y)));
            bool hit = ms_study_image_covered(&im, (size_t)j * im.width + i);
            if (dist < inner)
                assert_true(hit);
            if (dist > 1)
                assert_false(hit);
            covered += hit;
        }
    assert_true(covered > 100);
    /* Smooth shading: the interpolated vertex normals of a UV sphere are nearly
     * radial (exactly at the vertices); flat normals are off by up to half a
     * facet's angle. */
    ms_study_image smooth = {0};
    ms_study_render_options so = {.threads = 2, .smooth = true};
    assert_int_equal(ms_study_render(s, &cam, &so, &smooth, &err), MS_OK);
    double worst_flat = 0, worst_smooth = 0;
    for (uint32_t j = 0; j < im.height; ++j)
        for (uint32_t i = 0; i < im.width; ++i) {
            size_t p = (size_t)j * im.width + i;
            if (!ms_study_image_covered(&im, p))
                continue;
            assert_true(ms_study_image_covered(&smooth, p));
            assert_true(im.depth[p] == smooth.depth[p]);
            double x, y, hit[3], len = 0;
            slopes(&cam, i, j, &x, &y);
            const double dir[3] = {x, y, -1};
            for (int k = 0; k < 3; ++k) {
                hit[k] = eye[k] + im.depth[p] * dir[k];
                len += hit[k] * hit[k];
            }
            double flat_cos = 0, smooth_cos = 0;
            for (int k = 0; k < 3; ++k) {
                flat_cos += im.normal[3 * p + k] * hit[k] / sqrt(len);
                smooth_cos += smooth.normal[3 * p + k] * hit[k] / sqrt(len);
            }
            worst_flat = fmax(worst_flat, acos(fmin(1, flat_cos)));
            worst_smooth = fmax(worst_smooth, acos(fmin(1, smooth_cos)));
        }
    print_message("sphere: worst normal off the radius %.3f deg flat, %.3f deg smooth\n", worst_flat * 180 / M_PI,
                  worst_smooth * 180 / M_PI);
    assert_true(worst_flat > 0.5 * M_PI / 180);
    assert_true(worst_smooth < 0.1 * worst_flat);
    ms_study_image_free(&smooth);
    ms_study_image_free(&im);
    ms_study_scene_free(s);
}

static void test_deterministic_and_far_origin(void **state)
{
    (void)state;
    ms_study_scene *near_scene = cube_scene(0), *far_scene = cube_scene(1e7);
    ms_camera cam, far_cam;
    const double eye[3] = {1.7, 1.1, 2.3}, target[3] = {0.1, -0.05, 0};
    const double far_eye[3] = {1e7 + 1.7, 1e7 + 1.1, 1e7 + 2.3}, far_target[3] = {1e7 + 0.1, 1e7 - 0.05, 1e7};
    look(eye, target, 41, 37, &cam);
    look(far_eye, far_target, 41, 37, &far_cam);
    ms_study_image one = {0}, two = {0}, far_image = {0};
    render(near_scene, &cam, 1, &one);
    render(near_scene, &cam, 2, &two);
    render(far_scene, &far_cam, 2, &far_image);
    size_t n = (size_t)41 * 37;
    assert_memory_equal(one.triangle, two.triangle, n * sizeof *one.triangle);
    assert_memory_equal(one.depth, two.depth, n * sizeof *one.depth);
    assert_memory_equal(one.normal, two.normal, 3 * n * sizeof *one.normal);
    assert_memory_equal(one.rgb, two.rgb, 3 * n);
    /* the corner-on view sees three faces */
    bool seen[12] = {false};
    unsigned faces = 0;
    for (size_t p = 0; p < n; ++p)
        if (ms_study_image_covered(&one, p))
            seen[one.triangle[p]] = true;
    for (int f = 0; f < 6; ++f)
        faces += seen[2 * f] || seen[2 * f + 1];
    assert_int_equal(faces, 3);
    /* at 1e7 the scene is rendered in its own frame: no pixel moves */
    ms_study_image_error e;
    ms_error err;
    assert_int_equal(ms_study_image_compare(&far_image, &one, &e, &err), MS_OK);
    assert_int_equal(e.silhouette_mismatch, 0);
    assert_true(e.normal_max_deg < 1e-3);
    /* bad viewports */
    ms_camera bad = cam;
    bad.width = 10.5;
    assert_int_equal(ms_study_render(near_scene, &bad, NULL, &one, &err), MS_ERR_RANGE);
    bad.width = 70000;
    assert_int_equal(ms_study_render(near_scene, &bad, NULL, &one, &err), MS_ERR_RANGE);
    ms_study_apo *apo;
    assert_int_equal(ms_study_apo_new(1, 0, UINT32_MAX, MS_APO_MISSING_NEAREST, &apo, &err), MS_OK);
    ms_study_render_options o = {.apo = apo};
    assert_int_equal(ms_study_render(near_scene, &cam, &o, &one, &err), MS_ERR_ARG);
    ms_study_apo_free(apo);
    /* PNG */
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/cube.png", dir);
    assert_int_equal(ms_study_image_write_png(&two, path, &err), MS_OK);
    size_t size;
    unsigned char *png = ms_test_read_file(path, &size);
    assert_memory_equal(png, "\x89PNG", 4);
    free(png);
    ms_test_rmdir(dir);
    ms_study_image_free(&one);
    ms_study_image_free(&two);
    ms_study_image_free(&far_image);
    ms_study_scene_free(near_scene);
    ms_study_scene_free(far_scene);
}

static void unit(const float in[3], float out[3])
{
    double l = sqrt((double)in[0] * in[0] + (double)in[1] * in[1] + (double)in[2] * in[2]);
    for (int k = 0; k < 3; ++k)
        out[k] = (float)(in[k] / l);
}

/* The two-halves chunk: a root (mean +z) with 8 leaf children, the lower x half
 * (octants 0-3) normal A, the upper half B (decoded: a[], b[]). */
static const uint32_t TWO_HALVES_LEVELS[2] = {2, 8};
static uint32_t *two_halves_words(float a[3], float b[3])
{
    const float a_raw[3] = {-0.3f, 0.2f, 0.9f}, b_raw[3] = {0.5f, -0.1f, 0.8f};
    float a_in[3], b_in[3];
    unit(a_raw, a_in);
    unit(b_raw, b_in);
    uint32_t ca = ms_apo_normal_encode(a_in), cb = ms_apo_normal_encode(b_in);
    ms_apo_normal_decode(ca, a);
    ms_apo_normal_decode(cb, b);
    uint32_t *words = malloc(10 * sizeof *words);
    assert_non_null(words);
    words[0] = ms_apo_header_word(2, 0xFF);
    words[1] = ms_apo_mean_word(0, ms_apo_normal_encode((const float[3]){0, 0, 1}));
    for (int o = 0; o < 8; ++o)
        words[2 + o] = ms_apo_leaf_word(o < 4 ? ca : cb);
    return words;
}

/* The head light's shading of a pixel with normal n at slopes (x, y), the
 * self-shadowing factor taken from `shadow_from` (the documented formula). */
static int shaded(const float n[3], const double shadow_from[3], double x, double y)
{
    double len = sqrt(x * x + y * y + 1), l[3] = {-x / len, -y / len, 1 / len};
    double nl = fmax(0, n[0] * l[0] + n[1] * l[1] + n[2] * l[2]);
    double self = fmax(0, shadow_from[0] * l[0] + shadow_from[1] * l[1] + shadow_from[2] * l[2]);
    return ms_study_srgb8(MS_STUDY_AMBIENT +
                          self * (MS_STUDY_DIFFUSE * nl + MS_STUDY_SPECULAR * pow(nl, MS_STUDY_SHININESS)));
}

/* One cell holding the cube, its chunk the two halves. Read unfiltered (the
 * nearest leaf, meshview's --apo-filter none, the study's rule before the
 * client filtered), seen face-on, pixels left of the centre column get A, the
 * others B (a point on the mid-plane goes up; the centre column's hit points
 * sit on the plane to within Embree's rounding, which differs between its CPU
 * code paths, so either is accepted there), and each is lit with its APO
 * normal's own self-shadowing factor (the client's rule; the triangle's +z
 * factor gives other values). */
static void test_apo_normals(void **state)
{
    (void)state;
    ms_study_scene *s = cube_scene(0);
    float a[3], b[3];
    uint32_t *words = two_halves_words(a, b);
    const uint32_t *levels = TWO_HALVES_LEVELS;
    ms_apo_chunk chunk = {0};
    ms_apo_chunk_adopt(&chunk, words, 10, 2, levels);
    ms_study_apo *apo;
    ms_error err;
    assert_int_equal(ms_study_apo_new(1, 0, UINT32_MAX, MS_APO_MISSING_NEAREST, &apo, &err), MS_OK);
    ms_study_apo_set_filter(apo, MS_STUDY_APO_FILTER_NONE);
    const double origin[3] = {-0.5, -0.5, -0.5};
    assert_int_equal(ms_study_apo_put(apo, 0, origin, 1.0, &chunk, &err), MS_OK);
    assert_int_equal(ms_study_apo_chunk_count(apo), 1);
    ms_apo_chunk none = {0};
    assert_int_equal(ms_study_apo_put(apo, 1, origin, 1.0, &none, &err), MS_ERR_RANGE);
    uint32_t triangle_cell[12] = {0};
    ms_camera cam;
    const double eye[3] = {0, 0, 3}, target[3] = {0, 0, 0};
    look(eye, target, 31, 21, &cam);
    ms_study_render_options o = {.threads = 2, .apo = apo, .triangle_cell = triangle_cell};
    ms_study_image im = {0}, plain = {0};
    assert_int_equal(ms_study_render(s, &cam, &o, &im, &err), MS_OK);
    render(s, &cam, 2, &plain);
    size_t with_a = 0, with_b = 0, other_rule = 0;
    for (uint32_t j = 0; j < im.height; ++j)
        for (uint32_t i = 0; i < im.width; ++i) {
            size_t p = (size_t)j * im.width + i;
            assert_int_equal(ms_study_image_covered(&im, p), ms_study_image_covered(&plain, p));
            if (!ms_study_image_covered(&im, p))
                continue;
            const float *n = &im.normal[3 * p], *want = i < 15 ? a : b;
            if (i == 15 && fabs(n[0] - b[0]) > 1e-6)
                want = a;
            double l = sqrt((double)want[0] * want[0] + (double)want[1] * want[1] + (double)want[2] * want[2]);
            for (int k = 0; k < 3; ++k)
                assert_true(fabs(n[k] - want[k] / l) < 1e-6);
            with_a += i < 15;
            with_b += i >= 15;
            double x, y;
            slopes(&cam, i, j, &x, &y);
            const double own[3] = {n[0], n[1], n[2]}, ng[3] = {0, 0, 1};
            assert_true(abs((int)im.rgb[3 * p] - shaded(n, own, x, y)) <= 1);
            other_rule += abs((int)im.rgb[3 * p] - shaded(n, ng, x, y)) > 1;
        }
    assert_true(with_a > 0 && with_b > with_a);
    assert_true(other_rule > 0); /* the rule is seen: N_g's factor would shade otherwise */
    /* APO changes the shading and the normal error against the plain render is
     * the angle between +z and A or B */
    ms_study_image_error e;
    assert_int_equal(ms_study_image_compare(&im, &plain, &e, &err), MS_OK);
    double angle_a = acos(a[2]) * 180 / M_PI, angle_b = acos(b[2]) * 180 / M_PI;
    assert_true(fabs(e.normal_max_deg - fmax(angle_a, angle_b)) < 1e-3);
    assert_true(e.psnr_db < 60);
    /* the same chunk read with its first level only: the root's mean normal, +z */
    uint32_t *again = malloc(10 * sizeof *again);
    assert_non_null(again);
    memcpy(again, words, 10 * sizeof *words);
    ms_apo_chunk_adopt(&chunk, again, 10, 2, levels);
    ms_study_apo *first_level;
    assert_int_equal(ms_study_apo_new(1, 1, UINT32_MAX, MS_APO_MISSING_NEAREST, &first_level, &err), MS_OK);
    assert_int_equal(ms_study_apo_put(first_level, 0, origin, 1.0, &chunk, &err), MS_OK);
    o.apo = first_level;
    assert_int_equal(ms_study_render(s, &cam, &o, &im, &err), MS_OK);
    float up[3];
    ms_apo_normal_decode(ms_apo_normal_encode((const float[3]){0, 0, 1}), up);
    for (size_t p = 0; p < (size_t)im.width * im.height; ++p)
        if (ms_study_image_covered(&im, p))
            for (int k = 0; k < 3; ++k)
                assert_true(fabs(im.normal[3 * p + k] - up[k]) < 1e-6);
    ms_study_apo_free(first_level);
    /* the same through set_levels on the first set: one level, then whole again */
    o.apo = apo;
    assert_int_equal(ms_study_apo_set_levels(apo, 0, 1, &err), MS_OK);
    ms_study_image one_level = {0};
    assert_int_equal(ms_study_render(s, &cam, &o, &one_level, &err), MS_OK);
    assert_memory_equal(one_level.normal, im.normal, 3 * (size_t)im.width * im.height * sizeof *im.normal);
    assert_int_equal(ms_study_apo_set_levels(apo, 0, 0, &err), MS_OK);
    assert_int_equal(ms_study_render(s, &cam, &o, &one_level, &err), MS_OK);
    assert_true(ms_study_image_covered(&one_level, 10 * 31 + 12)); /* left of centre: A again, not +z */
    assert_true(one_level.normal[3 * (10 * 31 + 12)] != im.normal[3 * (10 * 31 + 12)]);
    assert_int_equal(ms_study_apo_set_levels(apo, 1, 0, &err), MS_ERR_RANGE);
    ms_study_image_free(&one_level);
    ms_study_image_free(&im);
    ms_study_image_free(&plain);
    ms_study_apo_free(apo);
    ms_study_scene_free(s);
}

/* The angle between two unit vectors, radians. */
static double angle(const double u[3], const float v[3])
{
    double c = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
    return acos(fmin(1, fmax(-1, c)));
}

/* The two-halves chunk read as the client reads it by default (filtered: the
 * footprint depth, then 8-cell interpolation; docs/APO.md "Filtering"), the cube
 * seen face-on at 31 x 21 (a pixel is 0.087 of the cube at the front face: the
 * footprint depth 4 leaves the depth-1 leaves whole). Along x the centre leaf's
 * nearer face decides: in the outer quarters it is the cube's face (no
 * neighbour there), so the normal is exactly A (left) or B (right); in the
 * inner quarters it is the mid-plane, and the normal is A and B blended with
 * the neighbour's weight t = (distance from the leaf's centre) / (leaf width),
 * normalised; across y and z the neighbours are of the same half. NEAREST (the
 * footprint depth only) is the unfiltered picture here. Seen from 60 units at
 * 3 x 3 pixels a pixel is 8.7 cubes wide: the footprint depth is 0 and the
 * centre pixel shows the root's mean (+z), where the unfiltered lookup gives
 * a leaf (its hit is on the mid-plane to Embree's rounding: A or B). */
static void test_apo_filtered(void **state)
{
    (void)state;
    ms_study_scene *s = cube_scene(0);
    float a[3], b[3];
    uint32_t *words = two_halves_words(a, b);
    ms_apo_chunk chunk = {0};
    ms_apo_chunk_adopt(&chunk, words, 10, 2, TWO_HALVES_LEVELS);
    ms_study_apo *apo;
    ms_error err;
    assert_int_equal(ms_study_apo_new(1, 0, UINT32_MAX, MS_APO_MISSING_NEAREST, &apo, &err), MS_OK);
    const double origin[3] = {-0.5, -0.5, -0.5};
    assert_int_equal(ms_study_apo_put(apo, 0, origin, 1.0, &chunk, &err), MS_OK);
    uint32_t triangle_cell[12] = {0};
    ms_camera cam;
    const double eye[3] = {0, 0, 3}, target[3] = {0, 0, 0};
    look(eye, target, 31, 21, &cam);
    ms_study_render_options o = {.threads = 2, .apo = apo, .triangle_cell = triangle_cell};
    ms_study_image im = {0}, nearest = {0}, none = {0};
    assert_int_equal(ms_study_render(s, &cam, &o, &im, &err), MS_OK);
    ms_study_apo_set_filter(apo, MS_STUDY_APO_FILTER_NEAREST);
    assert_int_equal(ms_study_render(s, &cam, &o, &nearest, &err), MS_OK);
    ms_study_apo_set_filter(apo, MS_STUDY_APO_FILTER_NONE);
    assert_int_equal(ms_study_render(s, &cam, &o, &none, &err), MS_OK);
    size_t n_pixels = (size_t)im.width * im.height;
    assert_memory_equal(nearest.normal, none.normal, 3 * n_pixels * sizeof *im.normal);
    double ad[3] = {a[0], a[1], a[2]}, bd[3] = {b[0], b[1], b[2]};
    double la = sqrt(ad[0] * ad[0] + ad[1] * ad[1] + ad[2] * ad[2]), lb = sqrt(bd[0] * bd[0] + bd[1] * bd[1] + bd[2] * bd[2]);
    for (int k = 0; k < 3; ++k) {
        ad[k] /= la;
        bd[k] /= lb;
    }
    size_t outer = 0, blended = 0;
    for (uint32_t j = 0; j < im.height; ++j)
        for (uint32_t i = 0; i < im.width; ++i) {
            size_t p = (size_t)j * im.width + i;
            if (!ms_study_image_covered(&im, p))
                continue;
            double x, y;
            slopes(&cam, i, j, &x, &y);
            double u = 0.5 + 2.5 * x; /* the hit's cell-local x on the front face */
            if (fabs(u - 0.25) < 1e-4 || fabs(u - 0.5) < 1e-4 || fabs(u - 0.75) < 1e-4)
                continue; /* on a leaf's centre or face: either side */
            const float *n = &im.normal[3 * p];
            double want[3];
            if (u < 0.25 || u > 0.75) {
                memcpy(want, u < 0.25 ? ad : bd, sizeof want);
                outer++;
            } else {
                double t = u < 0.5 ? (u - 0.25) / 0.5 : (0.75 - u) / 0.5, len = 0;
                const double *own = u < 0.5 ? ad : bd, *other = u < 0.5 ? bd : ad;
                for (int k = 0; k < 3; ++k) {
                    want[k] = (1 - t) * own[k] + t * other[k];
                    len += want[k] * want[k];
                }
                for (int k = 0; k < 3; ++k)
                    want[k] /= sqrt(len);
                /* strictly between A and B, on the arc joining them */
                assert_true(angle(ad, n) > 1e-3 && angle(bd, n) > 1e-3);
                assert_true(fabs(angle(ad, n) + angle(bd, n) - acos(ad[0] * bd[0] + ad[1] * bd[1] + ad[2] * bd[2])) <
                            1e-4);
                blended++;
            }
            for (int k = 0; k < 3; ++k)
                if (fabs(n[k] - want[k]) > 1e-4)
                    fail_msg("pixel (%u, %u), u = %.4f: normal[%d] %.6f, expected %.6f", i, j, u, k, n[k], want[k]);
        }
    assert_true(outer > 0 && blended > 0);
    /* far away: the footprint depth is 0, the root's mean (+z) */
    const double far_eye[3] = {0, 0, 60};
    look(far_eye, target, 3, 3, &cam);
    float up[3];
    ms_apo_normal_decode(ms_apo_normal_encode((const float[3]){0, 0, 1}), up);
    for (int f = 0; f < 3; ++f) {
        ms_study_apo_set_filter(apo, (ms_study_apo_filter)f);
        assert_int_equal(ms_study_render(s, &cam, &o, &im, &err), MS_OK);
        assert_true(ms_study_image_covered(&im, 4));
        const float *want = f == MS_STUDY_APO_FILTER_NONE ? b : up;
        if (f == MS_STUDY_APO_FILTER_NONE && fabs(im.normal[12] - b[0]) > 1e-6)
            want = a; /* the hit is on the mid-plane to Embree's rounding: either leaf */
        for (int k = 0; k < 3; ++k)
            if (fabs(im.normal[3 * 4 + k] - want[k]) > 1e-6)
                fail_msg("filter %d: normal (%.6f, %.6f, %.6f), expected (%.6f, %.6f, %.6f)", f, im.normal[12],
                         im.normal[13], im.normal[14], want[0], want[1], want[2]);
    }
    ms_study_apo_filter parsed;
    assert_true(ms_study_apo_filter_parse("linear", &parsed) && parsed == MS_STUDY_APO_FILTER_LINEAR);
    assert_true(ms_study_apo_filter_parse("nearest", &parsed) && parsed == MS_STUDY_APO_FILTER_NEAREST);
    assert_true(ms_study_apo_filter_parse("none", &parsed) && parsed == MS_STUDY_APO_FILTER_NONE);
    assert_false(ms_study_apo_filter_parse("Linear", &parsed));
    ms_study_image_free(&im);
    ms_study_image_free(&nearest);
    ms_study_image_free(&none);
    ms_study_apo_free(apo);
    ms_study_scene_free(s);
}

/* A fold: triangle 0 in z = 0 facing +z, triangle 1 on its hypotenuse folded
 * back over it (its third corner at (0.3, 0.3, 0.1), wound to face about -z).
 * The shared corners' area-weighted normals lean to +z, so near the shared
 * edge triangle 1's interpolated normal lies against its own stored normal:
 * there, as in the client's shader, its facing N_g stands in exactly; where it
 * does not (near its own corner) the normal is the interpolated one turned over
 * with the face, on N_g's side. Seen from above, both kinds of pixel occur. */
static void test_smooth_fold(void **state)
{
    (void)state;
    const double pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.3, 0.3, 0.1};
    const uint32_t tri[6] = {0, 1, 2, 2, 1, 3};
    ms_study_scene *s;
    ms_error err;
    assert_int_equal(ms_study_scene_new(pos, 4, tri, 2, &s, &err), MS_OK);
    ms_camera cam;
    const double eye[3] = {0.35, 0.35, 3}, target[3] = {0.35, 0.35, 0};
    look(eye, target, 61, 61, &cam);
    ms_study_render_options o = {.threads = 2, .smooth = true};
    ms_study_image im = {0};
    assert_int_equal(ms_study_render(s, &cam, &o, &im, &err), MS_OK);
    /* triangle 1's stored normal is -(0.1, 0.1, 0.4) normalised; facing the camera, +(0.1, 0.1, 0.4) */
    double len = sqrt(0.18), ng[3] = {0.1 / len, 0.1 / len, 0.4 / len};
    size_t as_ng = 0, interpolated = 0;
    for (size_t p = 0; p < (size_t)im.width * im.height; ++p) {
        if (!ms_study_image_covered(&im, p) || im.triangle[p] != 1)
            continue;
        const float *n = &im.normal[3 * p];
        if (fabs(n[0] - ng[0]) < 1e-6 && fabs(n[1] - ng[1]) < 1e-6 && fabs(n[2] - ng[2]) < 1e-6) {
            as_ng++;
            continue;
        }
        assert_true(n[0] * ng[0] + n[1] * ng[1] + n[2] * ng[2] > 0);
        interpolated++;
    }
    print_message("fold: %zu pixels of triangle 1 with N_g, %zu with the interpolated normal\n", as_ng,
                  interpolated);
    assert_true(as_ng > 10 && interpolated > 10);
    ms_study_image_free(&im);
    ms_study_scene_free(s);
}

/* The cube of an archive cell. */
static void test_cell_cube(void **state)
{
    (void)state;
    /* the cube of an archive cell: level 2 of a box of side 8 with n = 4 */
    ms_archive_header h = {.box_origin = {1, 2, 3}, .box_side = 8, .n = 4};
    ms_archive_cell c = {.level = 2, .position = {3, 0, 15}};
    double origin[3], side;
    ms_study_cell_cube(&h, &c, origin, &side);
    assert_true(side == 0.5);
    assert_true(origin[0] == 2.5 && origin[1] == 2 && origin[2] == 10.5);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_face_on),
        cmocka_unit_test(test_sphere),
        cmocka_unit_test(test_deterministic_and_far_origin),
        cmocka_unit_test(test_apo_normals),
        cmocka_unit_test(test_apo_filtered),
        cmocka_unit_test(test_smooth_fold),
        cmocka_unit_test(test_cell_cube),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
