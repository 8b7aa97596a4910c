/* Hard cases through the whole chain (issue 18, item 6): a model offset by 10^7
 * with a 10^-3 extent, a flat model and a needle, each at p = 8 and p = 20:
 * written as a double-precision PLY, baked by meshbake (with its APO defaults),
 * decoded as a client decodes it (the archive's view, ms_view_decoder, selected
 * for a camera that sees the whole model with a tolerance that asks for full
 * precision, stitched) and measured:
 *   - every shown cell is at the archive's precision p;
 *   - per axis, every decoded vertex lies within half a grid step (box side /
 *     2^p) of an input vertex, plus the
 *     rounding of a double at the model's magnitude (at 10^7 a double's spacing,
 *     1.9e-9, is twice the p = 20 step of a 10^-3 model: the grid is finer than
 *     the numbers that hold it);
 *   - the symmetric Hausdorff distance between the decoded surface and the input
 *     is at most that per-axis bound times sqrt(3) (no triangle collapses on
 *     these models at either precision);
 *   - the image error of the decoded surface's render against the input's is
 *     reported and finite (normal angle, SSIM; PSNR finite or +inf).
 * Runs from the repository root (meshbake from the build's bin folder). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_study_cut.h"
#include "ms_study_measure.h"
#include "ms_study_render.h"
#include "ms_test.h"
#include "ms_view_decoder.h"

typedef struct model {
    const char *name;
    double *positions;
    uint32_t *triangles;
    size_t vertex_count, triangle_count;
    double eye[3], target[3], up[3];
} model;

static void model_alloc(model *m, size_t vertices, size_t triangles)
{
    m->positions = calloc(3 * vertices, sizeof *m->positions);
    m->triangles = calloc(3 * triangles, sizeof *m->triangles);
    assert_non_null(m->positions);
    assert_non_null(m->triangles);
    m->vertex_count = vertices;
    m->triangle_count = triangles;
}

static void model_free(model *m)
{
    free(m->positions);
    free(m->triangles);
}

/* A UV sphere of radius r about c: `rings` bands of `segments` quads, poles as fans. */
static void sphere(model *m, const double c[3], double r, uint32_t rings, uint32_t segments)
{
    model_alloc(m, 2 + (rings - 1) * segments, 2 * segments * (rings - 1));
    double *p = m->positions;
    p[0] = c[0], p[1] = c[1], p[2] = c[2] + r;
    p[3] = c[0], p[4] = c[1], p[5] = c[2] - r;
    for (uint32_t i = 1; i < rings; ++i)
        for (uint32_t j = 0; j < segments; ++j) {
            double th = M_PI * i / rings, ph = 2 * M_PI * j / segments;
            double *v = p + 3 * (2 + (i - 1) * segments + j);
            v[0] = c[0] + r * sin(th) * cos(ph);
            v[1] = c[1] + r * sin(th) * sin(ph);
            v[2] = c[2] + r * cos(th);
        }
    uint32_t *t = m->triangles;
    size_t n = 0;
#define RING(i, j) (2 + ((i) - 1) * segments + ((j) % segments))
    for (uint32_t j = 0; j < segments; ++j) {
        t[n++] = 0, t[n++] = RING(1, j), t[n++] = RING(1, j + 1);
        t[n++] = 1, t[n++] = RING(rings - 1, j + 1), t[n++] = RING(rings - 1, j);
    }
    for (uint32_t i = 1; i + 1 < rings; ++i)
        for (uint32_t j = 0; j < segments; ++j) {
            t[n++] = RING(i, j), t[n++] = RING(i + 1, j), t[n++] = RING(i + 1, j + 1);
            t[n++] = RING(i, j), t[n++] = RING(i + 1, j + 1), t[n++] = RING(i, j + 1);
        }
#undef RING
    m->triangle_count = n / 3;
}

/* A k x k grid of quads in z = 0 over [0, 1]^2, its inner vertices moved a
 * little in the plane (deterministically), so no two rows line up exactly. */
static void flat(model *m, uint32_t k)
{
    model_alloc(m, (size_t)(k + 1) * (k + 1), 2 * (size_t)k * k);
    uint64_t seed = 7;
    for (uint32_t i = 0; i <= k; ++i)
        for (uint32_t j = 0; j <= k; ++j) {
            double *v = m->positions + 3 * (i * (k + 1) + j);
            bool inner = i > 0 && i < k && j > 0 && j < k;
            v[0] = (j + (inner ? 0.3 * ((double)(ms_test_random(&seed) % 1000) / 1000 - 0.5) : 0)) / k;
            v[1] = (i + (inner ? 0.3 * ((double)(ms_test_random(&seed) % 1000) / 1000 - 0.5) : 0)) / k;
            v[2] = 0;
        }
    size_t n = 0;
    for (uint32_t i = 0; i < k; ++i)
        for (uint32_t j = 0; j < k; ++j) {
            uint32_t a = i * (k + 1) + j, b = a + 1, c = a + k + 1, d = c + 1;
            m->triangles[n++] = a, m->triangles[n++] = b, m->triangles[n++] = d;
            m->triangles[n++] = a, m->triangles[n++] = d, m->triangles[n++] = c;
        }
}

/* A closed square prism along x, length 1, width w, in `segments` sections. */
static void needle(model *m, double w, uint32_t segments)
{
    model_alloc(m, 4 * ((size_t)segments + 1), 8 * (size_t)segments + 4);
    static const double corner[4][2] = {{-1, -1}, {1, -1}, {1, 1}, {-1, 1}};
    for (uint32_t s = 0; s <= segments; ++s)
        for (int c = 0; c < 4; ++c) {
            double *v = m->positions + 3 * (4 * s + c);
            v[0] = (double)s / segments;
            v[1] = corner[c][0] * w / 2;
            v[2] = corner[c][1] * w / 2;
        }
    size_t n = 0;
    uint32_t *t = m->triangles;
    for (uint32_t s = 0; s < segments; ++s)
        for (uint32_t c = 0; c < 4; ++c) {
            uint32_t a = 4 * s + c, b = 4 * s + (c + 1) % 4, a2 = a + 4, b2 = b + 4;
            t[n++] = a, t[n++] = b, t[n++] = b2;
            t[n++] = a, t[n++] = b2, t[n++] = a2;
        }
    uint32_t e = 4 * segments;
    t[n++] = 0, t[n++] = 2, t[n++] = 1; /* the two end caps */
    t[n++] = 0, t[n++] = 3, t[n++] = 2;
    t[n++] = e, t[n++] = e + 1, t[n++] = e + 2;
    t[n++] = e, t[n++] = e + 2, t[n++] = e + 3;
    m->triangle_count = n / 3;
}

static void write_ply(const model *m, const char *path)
{
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fprintf(f, "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\nproperty double y\n"
               "property double z\nelement face %zu\nproperty list uchar int vertex_indices\nend_header\n",
            m->vertex_count, m->triangle_count);
    for (size_t v = 0; v < m->vertex_count; ++v)
        fprintf(f, "%.17g %.17g %.17g\n", m->positions[3 * v], m->positions[3 * v + 1], m->positions[3 * v + 2]);
    for (size_t t = 0; t < m->triangle_count; ++t)
        fprintf(f, "3 %u %u %u\n", m->triangles[3 * t], m->triangles[3 * t + 1], m->triangles[3 * t + 2]);
    assert_int_equal(fclose(f), 0);
}

/* The spacing of doubles at magnitude x (one ulp). */
static double ulp(double x)
{
    return nextafter(fabs(x), INFINITY) - fabs(x);
}

/* Bakes m at `bits`, decodes it at full precision for its camera, measures. */
static void through_the_chain(const model *m, unsigned bits, const char *dir)
{
    char ply[700], out[700], bin[512], cmd[2048], text[4096], archive_path[800];
    snprintf(ply, sizeof ply, "%s/%s.ply", dir, m->name);
    snprintf(out, sizeof out, "%s/%s-%u", dir, m->name, bits);
    write_ply(m, ply);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s %s -o %s --name %s --bits %u --threads 2", bin, ply, out, m->name, bits);
    if (ms_test_run(cmd, text, sizeof text) != 0)
        fail_msg("%s at p = %u: meshbake: %s", m->name, bits, text);
    snprintf(archive_path, sizeof archive_path, "%s/%s.msa", out, m->name);

    ms_error err;
    ms_archive *archive = NULL;
    ms_view *view = NULL;
    if (ms_archive_open(archive_path, &archive, &err) != MS_OK ||
        ms_view_create_from_archive(archive, &view, &err) != MS_OK)
        fail_msg("%s at p = %u: %s", m->name, bits, err.text);
    const ms_archive_header *h = ms_archive_get_header(archive);
    assert_int_equal(h->bits, bits);
    double extent = 0;
    for (int k = 0; k < 3; ++k) {
        double lo = INFINITY, hi = -INFINITY;
        for (size_t v = 0; v < m->vertex_count; ++v) {
            lo = fmin(lo, m->positions[3 * v + k]);
            hi = fmax(hi, m->positions[3 * v + k]);
        }
        extent = fmax(extent, hi - lo);
    }
    ms_camera camera;
    if (ms_camera_look_at(m->eye, m->target, m->up, 40, 96, 72, extent * 0.01, extent * 100, &camera, &err) != MS_OK)
        fail_msg("%s: camera: %s", m->name, err.text);
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = 1e-6; /* every cell in view at its finest precision */
    params.hysteresis = 0;
    params.culled_bits_less = 0;
    ms_view_mesh cut = {0};
    ms_study_cut_report report;
    if (ms_study_cut(archive, view, &camera, &params, NULL, &cut, &report, &err) != MS_OK)
        fail_msg("%s at p = %u: cut: %s", m->name, bits, err.text);
    assert_true(cut.triangle_count > 0);
    for (uint32_t c = 0; c < ms_view_cell_count(view); ++c)
        if (ms_view_state(view, c) == MS_VIEW_SHOWN && ms_view_cell(view, c)->triangle_count)
            assert_int_equal(ms_view_bits(view, c), ms_view_cell(view, c)->bits_max);

    /* per axis: each decoded vertex against the nearest input vertex (Chebyshev
     * distance, less a double's rounding at the input's magnitude) */
    double step = h->box_side / ldexp(1, (int)bits), worst = 0, bound = 0;
    for (size_t u = 0; u < cut.vertex_count; ++u) {
        const double *x = cut.positions + 3 * u;
        double best = INFINITY;
        for (size_t v = 0; v < m->vertex_count; ++v) {
            const double *y = m->positions + 3 * v;
            double d = 0;
            for (int k = 0; k < 3; ++k)
                d = fmax(d, fabs(x[k] - y[k]) - ulp(y[k]));
            best = fmin(best, d);
        }
        if (!(best <= step / 2))
            fail_msg("%s at p = %u: decoded vertex %zu (%.17g %.17g %.17g) is %g per axis from every input vertex, "
                     "more than half a step (%g)",
                     m->name, bits, u, x[0], x[1], x[2], best, step / 2);
        worst = fmax(worst, best);
    }
    for (size_t v = 0; v < m->vertex_count; ++v)
        for (int k = 0; k < 3; ++k)
            bound = fmax(bound, ulp(m->positions[3 * v + k]));
    bound = sqrt(3) * (step / 2 + bound);

    /* the surfaces, and their images */
    ms_study_scene *full = NULL, *decoded = NULL;
    if (ms_study_scene_new(m->positions, m->vertex_count, m->triangles, m->triangle_count, &full, &err) != MS_OK ||
        ms_study_scene_new(cut.positions, cut.vertex_count, cut.triangles, cut.triangle_count, &decoded, &err) !=
            MS_OK)
        fail_msg("%s: scene: %s", m->name, err.text);
    ms_study_distance_params dp = {.spacing = extent / 64, .threads = 2, .camera = &camera};
    ms_study_distance dist;
    if (ms_study_distance_measure(decoded, full, &dp, &dist, &err) != MS_OK)
        fail_msg("%s: distance: %s", m->name, err.text);
    print_message("%-7s p = %2u: %zu triangles, step %.3g, worst vertex %.3g (per axis, beyond rounding), "
                  "Hausdorff %.3g <= %.3g, %.3g px\n",
                  m->name, bits, cut.triangle_count, step, worst, dist.hausdorff, bound, dist.hausdorff_px);
    assert_true(dist.hausdorff <= bound * (1 + 1e-9));
    assert_true(isfinite(dist.hausdorff_px) && dist.samples_px > 0);

    ms_study_image reference = {0}, image = {0};
    ms_study_render_options ro = {.threads = 2};
    ms_study_image_error e;
    if (ms_study_render(full, &camera, &ro, &reference, &err) != MS_OK ||
        ms_study_render(decoded, &camera, &ro, &image, &err) != MS_OK ||
        ms_study_image_compare(&image, &reference, &e, &err) != MS_OK)
        fail_msg("%s: image: %s", m->name, err.text);
    print_message("        image: normal %.3g / %.3g deg, PSNR %.4g dB, SSIM %.4f, silhouette %llu of %llu px\n",
                  e.normal_mean_deg, e.normal_max_deg, e.psnr_db, e.ssim, (unsigned long long)e.silhouette_mismatch,
                  (unsigned long long)e.both_covered);
    assert_true(e.both_covered > 0); /* the model is in view */
    assert_true(isfinite(e.normal_mean_deg) && isfinite(e.normal_p95_deg) && isfinite(e.normal_max_deg));
    assert_true(isfinite(e.ssim) && e.ssim <= 1 && e.ssim > -1);
    assert_true(e.psnr_db > 0); /* finite, or +inf for identical images */
    ms_study_image_free(&reference);
    ms_study_image_free(&image);
    ms_study_scene_free(full);
    ms_study_scene_free(decoded);
    ms_view_mesh_free(&cut);
    ms_view_destroy(view);
    ms_archive_close(archive);
}

static void run_model(model *m)
{
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    through_the_chain(m, 8, dir);
    through_the_chain(m, 20, dir);
    ms_test_rmdir(dir);
    model_free(m);
}

static void test_offset_tiny(void **state)
{
    (void)state;
    model m = {.name = "offset", .up = {0, 0, 1}};
    const double c[3] = {1e7, -1e7, 1e7};
    sphere(&m, c, 5e-4, 12, 24);
    for (int k = 0; k < 3; ++k)
        m.target[k] = c[k];
    m.eye[0] = c[0] + 2e-3, m.eye[1] = c[1] + 2e-3, m.eye[2] = c[2] + 1e-3;
    run_model(&m);
}

static void test_flat(void **state)
{
    (void)state;
    model m = {.name = "flat", .eye = {0.5, -1.2, 1.5}, .target = {0.5, 0.5, 0}, .up = {0, 0, 1}};
    flat(&m, 24);
    run_model(&m);
}

static void test_needle(void **state)
{
    (void)state;
    model m = {.name = "needle", .eye = {0.5, 1.5, 0.4}, .target = {0.5, 0, 0}, .up = {0, 0, 1}};
    needle(&m, 0.02, 16);
    run_model(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_offset_tiny),
        cmocka_unit_test(test_flat),
        cmocka_unit_test(test_needle),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
