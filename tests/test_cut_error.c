/* The error of a cut against the full model (docs/CLIENT.md, "The error of a
 * cut"): after the selection settles for a camera, every full-precision vertex
 * of a baked demo model has a point drawn for it in the stitched mesh, inside
 * the kd-cell of the shown cell holding it (within its diagonal, whole grid
 * cell included, foreign vertices snapped across cells too); no visible shown
 * cell's error (ms_view_cell_error_bound, the measured surface error of
 * docs/CODEC.md §4.3) projects above the tolerance; and that error is below
 * the half-diagonal in most cells (vertices slide along the surface, which
 * costs nothing on screen). */
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

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_nsp.h"
#include "ms_nsp_check.h"
#include "ms_quant.h"
#include "ms_test.h"
#include "ms_view_decoder.h"

typedef struct fixture {
    char dir[512];
    ms_bake_report bake;
    ms_qmesh q;
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    char ply[700];
    snprintf(ply, sizeof ply, "%s/demo.ply", f->dir);
    ms_nsp_test_demo_ply(ply, 60000);
    ms_nsp_test_bake(ply, f->dir, "demo", 16, 1500, &f->bake); /* geometry ahead: the default */
    ms_nsp_test_reference(ply, 16, &f->q);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_qmesh_free(&f->q);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

typedef struct keyed {
    uint64_t key;
    size_t vertex;
} keyed;

static int cmp_keyed(const void *a, const void *b)
{
    uint64_t x = ((const keyed *)a)->key, y = ((const keyed *)b)->key;
    return x < y ? -1 : x > y;
}

/* The shown cell whose cube holds grid point c (the shown cells tile the cube). */
static uint32_t shown_holding(const ms_view *v, const uint32_t c[3])
{
    const ms_archive_header *h = ms_view_header(v);
    ms_nsp_shape shape;
    ms_error err;
    assert_int_equal(ms_nsp_shape_init(&shape, h->bits, h->n, h->root_bits, &err), MS_OK);
    uint32_t id = 0;
    while (ms_view_state(v, id) == MS_VIEW_SPLIT) {
        const ms_archive_cell *r = ms_view_cell(v, id);
        id = r->first_child + ms_nsp_child_offset(&shape, r->level, c);
    }
    return id;
}

typedef struct outcome {
    size_t vertices, below_half, above_half;
    double worst_ratio; /* largest distance over its kd-cell diagonal */
    double worst_px;    /* largest visible bound on screen */
    size_t triangles;
} outcome;

/* Settles the selection for a camera at `distance` box sides from the centre
 * and checks every vertex of the model against its drawn point. */
static outcome check_camera(fixture *f, double distance, double tolerance)
{
    ms_error err;
    ms_archive *a;
    ms_view *v;
    assert_int_equal(ms_archive_open(f->bake.archive_path, &a, &err), MS_OK);
    assert_int_equal(ms_view_create_from_archive(a, &v, &err), MS_OK);
    const ms_archive_header *h = ms_view_header(v);
    double side = h->box_side, centre[3], eye[3], up[3] = {0, 0, 1};
    for (int k = 0; k < 3; ++k)
        centre[k] = h->box_origin[k] + 0.5 * side;
    eye[0] = centre[0] + 0.8 * distance * side;
    eye[1] = centre[1] + 0.5 * distance * side;
    eye[2] = centre[2] + 0.33 * distance * side;
    ms_camera cam;
    assert_int_equal(ms_camera_look_at(eye, centre, up, 40.0, 960, 540, 1e-3 * side, 100 * side,
                                       &cam, &err), MS_OK);
    ms_view_select_params sp;
    ms_view_select_params_default(&sp);
    sp.tolerance_px = tolerance;
    bool settled = false;
    for (int pass = 0; pass < 64 && !settled; ++pass) {
        ms_view_select(v, &cam, &sp, NULL);
        ms_view_apply_report r;
        assert_int_equal(ms_view_apply(v, &r, &err), MS_OK);
        settled = !r.splits && !r.merges && !r.refined && !r.coarsened;
    }
    assert_true(settled);
    ms_view_mesh m = {0};
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    outcome o = {0};
    o.triangles = m.triangle_count;
    assert_int_equal(m.unresolved, 0);
    /* the drawn vertices by key: each stands for the vertices in its kd-cell */
    keyed *order = malloc((m.vertex_count + 1) * sizeof *order);
    assert_non_null(order);
    for (size_t i = 0; i < m.vertex_count; ++i)
        order[i] = (keyed){m.keys[i], i};
    qsort(order, m.vertex_count, sizeof *order, cmp_keyed);
    double unit = side / (double)(1u << h->bits), ppu = ms_camera_pixels_per_unit(&cam);
    ms_frustum fr;
    ms_camera_frustum(&cam, &fr);
    for (uint32_t id = 0; id < ms_view_cell_count(v); ++id) {
        if (ms_view_state(v, id) != MS_VIEW_SHOWN || ms_view_cell(v, id)->geometry_length == 0)
            continue;
        const ms_archive_cell *r = ms_view_cell(v, id);
        double cs = side, lo[3], hi[3];
        for (unsigned l = 0; l < r->level; ++l)
            cs /= h->n;
        for (int k = 0; k < 3; ++k)
            lo[k] = h->box_origin[k] + cs * r->position[k], hi[k] = lo[k] + cs;
        double e = ms_view_cell_error_bound(v, id), half = 0.5 * sqrt(3.0) * ldexp(side, -(int)ms_view_bits(v, id));
        assert_true(e > 0 && e <= 2.0 * half * (1 + 1e-9));
        if (ms_frustum_keeps_box(&fr, lo, hi, 0.0)) {
            double px = e * ppu / ms_camera_box_distance(&cam, lo, hi);
            o.worst_px = fmax(o.worst_px, px);
        }
    }
    for (size_t i = 0; i < f->q.vertex_count; ++i) {
        const uint32_t *c = &f->q.coords[3 * i];
        uint64_t key = ms_quant_key(c[0], c[1], c[2], h->bits);
        /* the last drawn vertex whose key is not above it */
        size_t lo = 0, hi = m.vertex_count;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (order[mid].key <= key)
                lo = mid + 1;
            else
                hi = mid;
        }
        assert_true(lo > 0);
        size_t k = order[lo - 1].vertex;
        unsigned span = 3 * h->bits - m.levels[k];
        if (span < 64 && (key - m.keys[k]) >> span != 0)
            fail_msg("vertex %zu: no drawn vertex stands for it", i);
        uint32_t cell = shown_holding(v, c);
        double bound = ms_view_cell_error_bound(v, cell) / unit; /* grid units */
        double d2 = 0;
        for (int ax = 0; ax < 3; ++ax) {
            double p = (m.positions[3 * k + (size_t)ax] - h->box_origin[ax]) / unit;
            double e = fmax(fabs(p - c[ax]), fabs(p - (c[ax] + 1.0)));
            d2 += e * e;
        }
        double half = 0.5 * sqrt(3.0) * ldexp(1.0, (int)h->bits - (int)ms_view_bits(v, cell));
        o.worst_ratio = fmax(o.worst_ratio, sqrt(d2) / (2 * half)); /* inside its kd-cell */
        o.below_half += bound < half * (1 - 1e-9);
        o.above_half += bound > half * (1 + 1e-9);
        o.vertices++;
    }
    free(order);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    ms_archive_close(a);
    print_message("%.2f box sides, %.0f px: %zu triangles, worst distance / kd-cell diagonal %.4f, error "
                  "on screen %.3f px, vertices whose cell's error is below / above the "
                  "half-diagonal %zu / %zu of %zu\n", distance, tolerance, o.triangles,
                  o.worst_ratio, o.worst_px, o.below_half, o.above_half, o.vertices);
    return o;
}

static void test_every_vertex_within_its_bound(void **state)
{
    fixture *f = *state;
    static const double distances[] = {0.7, 1.5, 3.0, 8.0};
    static const double tolerances[] = {1.0, 4.0};
    size_t below = 0, above = 0;
    for (size_t t = 0; t < 2; ++t)
        for (size_t k = 0; k < 4; ++k) {
            outcome o = check_camera(f, distances[k], tolerances[t]);
            assert_int_equal(o.vertices, f->q.vertex_count);
            assert_true(o.worst_ratio <= 1.0);
            assert_true(o.worst_px <= tolerances[t] * (1 + 1e-9));
            below += o.below_half;
            above += o.above_half;
        }
    assert_true(below > 4 * above);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_vertex_within_its_bound),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
