/* The built-in demo model: exact counts, a closed consistently oriented manifold,
 * outward orientation, bounded relief, determinism. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_demo_model.h"

static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Every directed edge must appear exactly once and its reverse exactly once: that
 * is a closed, consistently oriented 2-manifold (edge-wise). */
static void check_closed_oriented(const ms_mesh *m)
{
    size_t ne = 3 * m->triangle_count;
    uint64_t *directed = malloc(ne * sizeof *directed);
    assert_non_null(directed);
    for (size_t t = 0; t < m->triangle_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = m->triangles[3 * t + k], b = m->triangles[3 * t + (k + 1) % 3];
            assert_true(a != b);
            directed[3 * t + k] = (a << 32) | b;
        }
    qsort(directed, ne, sizeof *directed, compare_u64);
    for (size_t i = 0; i < ne; ++i) {
        if (i > 0)
            assert_true(directed[i] != directed[i - 1]);
        uint64_t rev = (directed[i] << 32) | (directed[i] >> 32);
        assert_non_null(bsearch(&rev, directed, ne, sizeof *directed, compare_u64));
    }
    /* Euler characteristic of a sphere: V - E + F = 2, with E = 3F/2. */
    assert_int_equal((int64_t)m->vertex_count - (int64_t)(ne / 2) + (int64_t)m->triangle_count, 2);
    free(directed);
}

static void test_counts_and_grid_choice(void **state)
{
    (void)state;
    assert_int_equal(ms_demo_grid_for_triangles(0), MS_DEMO_MIN_GRID);
    assert_int_equal(ms_demo_grid_for_triangles(12 * 100 * 100), 100);
    assert_int_equal(ms_demo_grid_for_triangles(10000000), 913);
    assert_int_equal(ms_demo_grid_for_triangles(UINT64_MAX), MS_DEMO_MAX_GRID);
    ms_demo_model model = {.grid = 30, .seed = 0};
    assert_int_equal(ms_demo_vertex_count(&model), 6 * 900 + 2);
    assert_int_equal(ms_demo_triangle_count(&model), 12 * 900);
}

static void test_closed_manifold_outward_bounded(void **state)
{
    (void)state;
    const uint32_t grids[] = {2, 3, 29, 64};
    for (size_t g = 0; g < sizeof grids / sizeof *grids; ++g) {
        ms_demo_model model = {.grid = grids[g], .seed = 7};
        ms_mesh m = {0};
        ms_error err;
        assert_int_equal(ms_demo_build(&model, &m, &err), MS_OK);
        assert_int_equal(m.vertex_count, ms_demo_vertex_count(&model));
        assert_int_equal(m.triangle_count, ms_demo_triangle_count(&model));
        check_closed_oriented(&m);
        /* Outward: the signed volume is positive. Bounded relief: radii stay in a
         * band that keeps the surface star-shaped and sculpture-sized. */
        double volume = 0.0;
        for (size_t t = 0; t < m.triangle_count; ++t) {
            const double *a = m.positions + 3 * m.triangles[3 * t];
            const double *b = m.positions + 3 * m.triangles[3 * t + 1];
            const double *c = m.positions + 3 * m.triangles[3 * t + 2];
            volume += (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) +
                       a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
        }
        assert_true(volume > 0.5);
        for (size_t v = 0; v < m.vertex_count; ++v) {
            const double *p = m.positions + 3 * v;
            double r = sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
            assert_true(r > 0.3 && r < 1.6);
        }
        ms_mesh_free(&m);
    }
}

static void test_deterministic_and_seed_dependent(void **state)
{
    (void)state;
    ms_demo_model a = {.grid = 16, .seed = 0}, b = {.grid = 16, .seed = 1};
    ms_mesh m1 = {0}, m2 = {0}, m3 = {0};
    assert_int_equal(ms_demo_build(&a, &m1, NULL), MS_OK);
    assert_int_equal(ms_demo_build(&a, &m2, NULL), MS_OK);
    assert_int_equal(ms_demo_build(&b, &m3, NULL), MS_OK);
    assert_memory_equal(m1.positions, m2.positions, 3 * m1.vertex_count * sizeof(double));
    assert_memory_equal(m1.triangles, m3.triangles, 3 * m1.triangle_count * sizeof(uint32_t));
    assert_true(memcmp(m1.positions, m3.positions, 3 * m1.vertex_count * sizeof(double)) != 0);
    ms_mesh_free(&m1);
    ms_mesh_free(&m2);
    ms_mesh_free(&m3);
}

static void test_bad_grid_rejected(void **state)
{
    (void)state;
    ms_demo_model model = {.grid = 1, .seed = 0};
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_demo_build(&model, &m, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "grid 1"));
    model.grid = MS_DEMO_MAX_GRID + 1;
    assert_int_equal(ms_demo_build(&model, &m, &err), MS_ERR_ARG);
    assert_null(m.positions);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_counts_and_grid_choice),
        cmocka_unit_test(test_closed_manifold_outward_bounded),
        cmocka_unit_test(test_deterministic_and_seed_dependent),
        cmocka_unit_test(test_bad_grid_rejected),
    };
    return cmocka_run_group_tests_name("demo_model", tests, NULL, NULL);
}
