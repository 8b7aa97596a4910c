/* APO as a correction (server/apo/ms_apo_correct.h, docs/APO.md "APO as a
 * correction"): the builder keeps a texel only where M's normal differs from
 * m's smooth normal by more than the tolerance. A fine sphere over a coarse
 * one whose smooth normals already give it holds no texel; a flat m under a
 * Gaussian bump keeps texels only where the bump's slope deviates, and the
 * lookup gives the smooth normal everywhere else; m's corner normals follow
 * the client's crease rule. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_apo_build.h"
#include "ms_apo_chunk.h"
#include "ms_apo_correct.h"
#include "ms_apo_filter.h"
#include "ms_apo_local_mesh.h"
#include "ms_apo_traverse.h"

/* A latitude-longitude sphere (centre c, radius r, `bands` bands of 2 bands
 * steps each), poles as fans. */
static void sphere(const double c[3], double r, uint32_t bands, ms_mesh *m)
{
    memset(m, 0, sizeof *m);
    uint32_t steps = 2 * bands, rings = bands - 1;
    size_t nv = 2 + (size_t)rings * steps, nt = 2 * (size_t)steps * (bands - 1);
    assert_int_equal(ms_mesh_reserve(m, nv, nt, NULL), MS_OK);
    double *p = m->positions;
    uint32_t *t = m->triangles;
    p[0] = c[0], p[1] = c[1], p[2] = c[2] + r;
    p[3] = c[0], p[4] = c[1], p[5] = c[2] - r;
    for (uint32_t i = 0; i < rings; ++i)
        for (uint32_t j = 0; j < steps; ++j) {
            double th = M_PI * (i + 1) / bands, ph = 2 * M_PI * j / steps;
            double *q = &p[3 * (2 + i * steps + j)];
            q[0] = c[0] + r * sin(th) * cos(ph), q[1] = c[1] + r * sin(th) * sin(ph), q[2] = c[2] + r * cos(th);
        }
    size_t k = 0;
#define V(i, j) (2u + (i) * steps + ((j) % steps))
    for (uint32_t j = 0; j < steps; ++j) {
        t[k++] = 0, t[k++] = V(0, j), t[k++] = V(0, j + 1);
        t[k++] = 1, t[k++] = V(rings - 1, j + 1), t[k++] = V(rings - 1, j);
    }
    for (uint32_t i = 0; i + 1 < rings; ++i)
        for (uint32_t j = 0; j < steps; ++j) {
            t[k++] = V(i, j), t[k++] = V(i + 1, j), t[k++] = V(i + 1, j + 1);
            t[k++] = V(i, j), t[k++] = V(i + 1, j + 1), t[k++] = V(i, j + 1);
        }
#undef V
    m->vertex_count = nv;
    m->triangle_count = k / 3;
}

static void build(const ms_mesh *m, const ms_mesh *M, bool correction, uint32_t init, uint32_t max,
                  ms_apo_tree *tree, ms_apo_build_stats *stats)
{
    ms_apo_builder *b;
    assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    o.init_depth = init;
    o.max_depth = max;
    o.tolerance = 0.2;
    o.correction = correction;
    o.correction_tolerance = 0.2;
    o.threads = 2;
    ms_error err;
    ms_error_clear(&err);
    ms_status st = ms_apo_builder_build_tree(b, m, M, &o, tree, stats, &err);
    if (st != MS_OK)
        fail_msg("%s", err.text);
    ms_apo_builder_destroy(b);
}

/* A sphere of 24 bands (7.5 degrees) over one of 12 (15 degrees): m's
 * interpolated vertex normals stay within a couple of degrees of the radial
 * normal, so not one texel is kept; without the correction every leaf is. */
static void test_smooth_sphere_holds_nothing(void **state)
{
    (void)state;
    const double c[3] = {0.5, 0.5, 0.5};
    ms_mesh m, M;
    sphere(c, 0.4, 12, &m);
    sphere(c, 0.4, 24, &M);
    ms_apo_tree full, corr;
    ms_apo_build_stats sf, sc;
    build(&m, &M, false, 5, 5, &full, &sf);
    build(&m, &M, true, 5, 5, &corr, &sc);
    print_message("full: %zu leaves, %zu internal; correction: %zu leaves (%zu dropped)\n", sf.leaves,
                  sf.internal_nodes, sc.leaves, sc.smooth_leaves);
    assert_true(sf.leaves > 1000);
    assert_int_equal(sc.leaves, 0);
    assert_int_equal(sc.smooth_leaves, sf.leaves);
    assert_int_equal(corr.node_count, 0);
    assert_int_equal(corr.level_count, 0);
    ms_apo_chunk chunk;
    assert_int_equal(ms_apo_chunk_encode(&corr, &chunk, NULL), MS_OK);
    assert_int_equal(chunk.level_count, 0); /* an empty chunk: the bake stores none */
    ms_apo_chunk_free(&chunk);
    ms_apo_tree_free(&full);
    ms_apo_tree_free(&corr);
    ms_mesh_free(&m);
    ms_mesh_free(&M);
}

/* The bump: z = 0.5 + A exp(-r^2 / (2 s^2)) around (0.3, 0.3), on a grid of
 * n x n squares over the unit square. Its slope angle atan(A x/s e^(-x^2/2)),
 * x = r / s, peaks at x = 1 (0.54 rad) and is below 0.1 rad beyond x = 2.6. */
#define BUMP_A 0.05
#define BUMP_S 0.05
#define BUMP_X 0.3
#define BUMP_Y 0.3

static void bump(uint32_t n, ms_mesh *M)
{
    memset(M, 0, sizeof *M);
    size_t nv = (size_t)(n + 1) * (n + 1);
    assert_int_equal(ms_mesh_reserve(M, nv, 2 * (size_t)n * n, NULL), MS_OK);
    for (uint32_t i = 0; i <= n; ++i)
        for (uint32_t j = 0; j <= n; ++j) {
            double x = (double)i / n, y = (double)j / n, r2 = (x - BUMP_X) * (x - BUMP_X) + (y - BUMP_Y) * (y - BUMP_Y);
            double *q = &M->positions[3 * ((size_t)i * (n + 1) + j)];
            q[0] = x, q[1] = y, q[2] = 0.5 + BUMP_A * exp(-r2 / (2 * BUMP_S * BUMP_S));
        }
    size_t k = 0;
    for (uint32_t i = 0; i < n; ++i)
        for (uint32_t j = 0; j < n; ++j) {
            uint32_t a = i * (n + 1) + j, b = a + n + 1;
            uint32_t *t = &M->triangles[3 * k];
            t[0] = a, t[1] = b, t[2] = b + 1, t[3] = a, t[4] = b + 1, t[5] = a + 1;
            k += 2;
        }
    M->vertex_count = nv;
    M->triangle_count = k;
}

static void flat(ms_mesh *m)
{
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_mesh_reserve(m, 4, 2, NULL), MS_OK);
    const double p[12] = {0, 0, 0.5, 1, 0, 0.5, 1, 1, 0.5, 0, 1, 0.5};
    const uint32_t t[6] = {0, 1, 2, 0, 2, 3};
    memcpy(m->positions, p, sizeof p);
    memcpy(m->triangles, t, sizeof t);
    m->vertex_count = 4;
    m->triangle_count = 2;
}

static void test_bump_keeps_texels_where_it_deviates(void **state)
{
    (void)state;
    ms_mesh m, M;
    flat(&m);
    bump(160, &M);
    ms_apo_tree tree;
    ms_apo_build_stats st;
    build(&m, &M, true, 4, 6, &tree, &st);
    print_message("bump: %zu leaves kept, %zu dropped, %zu internal\n", st.leaves, st.smooth_leaves,
                  st.internal_nodes);
    assert_true(st.leaves >= 16);
    assert_true(st.smooth_leaves > 10 * st.leaves);
    const float up[3] = {0, 0, 1};
    size_t leaves = 0;
    for (size_t i = 0; i < tree.node_count; ++i) {
        const ms_apo_node *n = &tree.nodes[i];
        double w = ldexp(1.0, -(int)n->depth);
        double cx = (n->cell[0] + 0.5) * w - BUMP_X, cy = (n->cell[1] + 0.5) * w - BUMP_Y;
        /* every node lies over the bump: within 2.6 s plus its half-diagonal */
        assert_true(sqrt(cx * cx + cy * cy) <= 2.6 * BUMP_S + w * M_SQRT1_2);
        if (n->child_mask)
            continue;
        ++leaves;
        /* a kept leaf's normal is off +z (m's smooth normal) by more than 0.2 rad */
        assert_true(ms_apo_unsigned_angle(n->normal, up) > 0.2);
    }
    assert_int_equal(leaves, st.leaves);
    /* The lookup: the smooth normal away from the bump, exactly; a texel on
     * its steepest ring. */
    ms_apo_chunk chunk;
    ms_apo_view view;
    assert_int_equal(ms_apo_chunk_encode(&tree, &chunk, NULL), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&view, &chunk, NULL), MS_OK);
    const float far_away[3] = {0.8f, 0.7f, 0.5f}, steep[3] = {(float)(BUMP_X + BUMP_S), (float)BUMP_Y, 0.5f};
    const float smooth[3] = {0.0f, 0.0f, 1.0f};
    ms_apo_lookup_result r;
    ms_apo_lookup(&view, far_away, 30, MS_APO_MISSING_STOP, &r);
    assert_true(r.smooth);
    ms_apo_filter_result f;
    ms_apo_lookup_filtered_smooth(&view, far_away, 30, MS_APO_MISSING_STOP, smooth, &f);
    assert_int_equal(f.texels, 0);
    assert_true(f.normal[0] == 0.0f && f.normal[1] == 0.0f && f.normal[2] == 1.0f);
    ms_apo_lookup(&view, steep, 30, MS_APO_MISSING_STOP, &r);
    assert_false(r.smooth);
    assert_true(r.normal[0] > 0.2f); /* leaning away from the bump's top, along +x */
    ms_apo_chunk_free(&chunk);
    ms_apo_tree_free(&tree);
    ms_mesh_free(&m);
    ms_mesh_free(&M);
}

/* m's corner normals: a cube's 90 degree edges stay hard (each corner its own
 * face's normal), a shallow fold (10 degrees) is joined; with a vertex error the
 * slack joins a fold that the crease alone would keep. */
static void test_corner_normals_follow_the_crease(void **state)
{
    (void)state;
    /* two triangles sharing the edge (0,0,0)-(0,1,0), folded by `angle` */
    const double angles[3] = {M_PI / 2, 10 * M_PI / 180, 80 * M_PI / 180};
    const double errors[3] = {0.0, 0.0, 0.5};
    const bool joined[3] = {false, true, true};
    for (int k = 0; k < 3; ++k) {
        ms_mesh mesh;
        memset(&mesh, 0, sizeof mesh);
        assert_int_equal(ms_mesh_reserve(&mesh, 4, 2, NULL), MS_OK);
        double a = angles[k];
        const double p[12] = {0, 0, 0, 0, 1, 0, -0.5, 0.5, 0, 0.5 * cos(a), 0.5, 0.5 * sin(a)};
        const uint32_t t[6] = {0, 1, 2, 1, 0, 3};
        memcpy(mesh.positions, p, sizeof p);
        memcpy(mesh.triangles, t, sizeof t);
        mesh.vertex_count = 4, mesh.triangle_count = 2;
        ms_apo_local_mesh lm;
        const double origin[3] = {0, 0, 0};
        assert_int_equal(ms_apo_local_mesh_make(&mesh, origin, 1.0, "m", &lm, NULL), MS_OK);
        assert_int_equal(ms_apo_local_mesh_corner_normals(&lm, M_PI / 3, errors[k], NULL), MS_OK);
        /* corner 0 of triangle 0 and corner 1 of triangle 1: both vertex 0 */
        const float *c0 = &lm.cnormal[0], *c1 = &lm.cnormal[9 + 3];
        double dot = (double)c0[0] * c1[0] + (double)c0[1] * c1[1] + (double)c0[2] * c1[2];
        if (joined[k]) {
            assert_true(dot > 0.999999);
        } else {
            assert_true(ms_apo_unsigned_angle(c0, &lm.fnormal[0]) < 1e-6);
            assert_true(ms_apo_unsigned_angle(c1, &lm.fnormal[3]) < 1e-6);
        }
        ms_apo_local_mesh_free(&lm);
        ms_mesh_free(&mesh);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_smooth_sphere_holds_nothing),
        cmocka_unit_test(test_bump_keeps_texels_where_it_deviates),
        cmocka_unit_test(test_corner_normals_follow_the_crease),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
