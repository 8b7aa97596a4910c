/* The APO builder: structure and sampling on the demo sculpture, determinism
 * across thread counts, the variation measures (density), the sampling
 * fallbacks with exact outcomes, empty and bad input; the triangle/cube test and
 * the quadric simplifier. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_apo_build.h"
#include "ms_apo_chunk.h"
#include "ms_apo_testtree.h"
#include "ms_apo_render.h"
#include "ms_apo_sample.h"
#include "ms_demo_model.h"
#include "ms_simplify.h"
#include "ms_tri_box.h"

static void build(const ms_mesh *m, const ms_mesh *big, const ms_apo_build_options *o, ms_apo_tree *tree,
                  ms_apo_build_stats *stats)
{
    ms_apo_builder *b;
    ms_error err;
    ms_error_clear(&err);
    assert_int_equal(ms_apo_builder_create(&b, &err), MS_OK);
    ms_status st = ms_apo_builder_build_tree(b, m, big, o, tree, stats, &err);
    if (st != MS_OK)
        fail_msg("build failed: %s", err.text);
    ms_apo_builder_destroy(b);
}

static void test_demo_structure_and_normals(void **state)
{
    (void)state;
    ms_mesh big, m;
    ms_test_demo_mesh(40, &big);
    ms_test_demo_mesh(10, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&big, &o);
    o.init_depth = 2;
    o.max_depth = 7;
    o.tolerance = 0.1;
    ms_apo_tree tree;
    ms_apo_build_stats st;
    build(&m, &big, &o, &tree, &st);
    assert_int_equal(ms_apo_tree_check(&tree, NULL), MS_OK);
    size_t in, leaves;
    ms_apo_tree_counts(&tree, &in, &leaves);
    assert_int_equal(in, st.internal_nodes);
    assert_int_equal(leaves, st.leaves);
    assert_true(leaves > 500);
    assert_int_equal(st.levels, 8);
    assert_int_equal(st.samples, st.ray_hits + st.closest_points + st.unsampled);
    assert_int_equal(st.unsampled, 0);
    assert_true(st.ray_hits > 0.95 * st.samples);
    assert_true(st.m_to_M_distance > 0.0 && st.m_to_M_distance < 0.05);
    /* Unit normals everywhere; leaf normals point away from the sculpture's
     * centre (it is a displaced sphere) nearly everywhere. */
    size_t outward = 0;
    double centre = 0.5 * (1.0 / 1.02) + (1.0 - 1.0 / 1.02) / 2.0; /* cube-local model centre, ~0.5 */
    (void)centre;
    for (size_t i = 0; i < tree.node_count; ++i) {
        const ms_apo_node *n = &tree.nodes[i];
        double len = sqrt((double)n->normal[0] * n->normal[0] + (double)n->normal[1] * n->normal[1] +
                          (double)n->normal[2] * n->normal[2]);
        assert_true(fabs(len - 1.0) < 1e-5);
        if (n->child_mask)
            continue;
        double w = ldexp(1.0, -(int)n->depth), dot = 0;
        for (int a = 0; a < 3; ++a)
            dot += ((n->cell[a] + 0.5) * w - 0.5) * n->normal[a];
        outward += dot > 0;
    }
    assert_true(outward > 0.95 * leaves);
    /* It encodes, loads and decodes. */
    ms_apo_chunk chunk;
    ms_apo_view view;
    assert_int_equal(ms_apo_chunk_encode(&tree, &chunk, NULL), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&view, &chunk, NULL), MS_OK);
    assert_int_equal(chunk.texel_count, leaves + 2 * in);
    ms_apo_chunk_free(&chunk);
    ms_apo_tree_free(&tree);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

static void test_same_output_whatever_the_threads(void **state)
{
    (void)state;
    ms_mesh big, m;
    ms_test_demo_mesh(30, &big);
    ms_test_demo_mesh(8, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&big, &o);
    o.max_depth = 7;
    o.tolerance = 0.05;
    ms_apo_chunk ref;
    memset(&ref, 0, sizeof ref);
    const unsigned threads[] = {1, 2, 3, 5};
    for (size_t k = 0; k < 4; ++k) {
        o.threads = threads[k];
        ms_apo_builder *b;
        ms_apo_chunk c;
        assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
        assert_int_equal(ms_apo_builder_build_chunk(b, &m, &big, &o, &c, NULL, NULL), MS_OK);
        ms_apo_builder_destroy(b);
        if (k == 0) {
            ref = c;
            assert_true(ref.texel_count > 1000);
            continue;
        }
        assert_int_equal(c.texel_count, ref.texel_count);
        assert_memory_equal(c.texels, ref.texels, 4 * c.texel_count);
        ms_apo_chunk_free(&c);
    }
    ms_apo_chunk_free(&ref);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

/* Every triangle cut into 4 at its edge midpoints: the same surface, 4x denser. */
static void subdivide(const ms_mesh *in, ms_mesh *out)
{
    memset(out, 0, sizeof *out);
    assert_int_equal(ms_mesh_reserve(out, 6 * in->triangle_count, 4 * in->triangle_count, NULL), MS_OK);
    for (size_t t = 0; t < in->triangle_count; ++t) {
        double p[6][3];
        for (int k = 0; k < 3; ++k)
            memcpy(p[k], &in->positions[3 * in->triangles[3 * t + k]], sizeof p[k]);
        for (int k = 0; k < 3; ++k)
            for (int a = 0; a < 3; ++a)
                p[3 + k][a] = 0.5 * (p[k][a] + p[(k + 1) % 3][a]);
        memcpy(&out->positions[18 * t], p, sizeof p);
        const int pieces[4][3] = {{0, 3, 5}, {3, 1, 4}, {5, 4, 2}, {3, 4, 5}};
        for (int q = 0; q < 4; ++q)
            for (int k = 0; k < 3; ++k)
                out->triangles[12 * t + 3 * q + k] = (uint32_t)(6 * t + pieces[q][k]);
    }
    out->vertex_count = 6 * in->triangle_count;
    out->triangle_count = 4 * in->triangle_count;
}

static void transform(ms_mesh *mesh, double scale, const double offset[3])
{
    for (size_t i = 0; i < mesh->vertex_count; ++i)
        for (int a = 0; a < 3; ++a)
            mesh->positions[3 * i + a] = mesh->positions[3 * i + a] * scale + offset[a];
}

static void build_words(const ms_mesh *m, const ms_mesh *big, const ms_apo_build_options *o, ms_apo_chunk *c)
{
    ms_apo_builder *b;
    assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
    assert_int_equal(ms_apo_builder_build_chunk(b, m, big, o, c, NULL, NULL), MS_OK);
    ms_apo_builder_destroy(b);
}

/* Tiny extents and huge offsets: a power-of-two scale changes nothing at all
 * (every step is exact); an offset of ten million units changes almost nothing
 * (the cube frame is computed in double precision before going to float). */
static void test_tiny_extent_and_huge_offset(void **state)
{
    (void)state;
    ms_mesh big, m;
    ms_test_demo_mesh(20, &big);
    ms_test_demo_mesh(6, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&big, &o);
    o.max_depth = 7;
    o.tolerance = 0.1;
    ms_apo_chunk ref, tiny, far;
    build_words(&m, &big, &o, &ref);
    const double zero[3] = {0, 0, 0}, shift[3] = {1e7, -3e6, 5e5};
    double scale = ldexp(1.0, -20);
    transform(&big, scale, zero);
    transform(&m, scale, zero);
    ms_apo_build_options ot = o;
    ot.cube_size *= scale;
    for (int a = 0; a < 3; ++a)
        ot.cube_origin[a] *= scale;
    build_words(&m, &big, &ot, &tiny);
    assert_int_equal(tiny.texel_count, ref.texel_count);
    assert_memory_equal(tiny.texels, ref.texels, 4 * ref.texel_count);
    transform(&big, 1.0 / scale, shift);
    transform(&m, 1.0 / scale, shift);
    ms_apo_build_options of = o;
    for (int a = 0; a < 3; ++a)
        of.cube_origin[a] += shift[a];
    build_words(&m, &big, &of, &far);
    double ratio = (double)far.texel_count / (double)ref.texel_count;
    print_message("offset 1e7: %zu words against %zu\n", far.texel_count, ref.texel_count);
    assert_true(ratio > 0.995 && ratio < 1.005);
    ms_apo_chunk_free(&ref);
    ms_apo_chunk_free(&tiny);
    ms_apo_chunk_free(&far);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

/* A chunk for one cell (the upper octant of the model's cube), as meshbake will
 * build them: m and M are the whole meshes, only the part in the cube is kept,
 * and rays near the cube's faces still find M outside it. */
static void test_cell_chunk(void **state)
{
    (void)state;
    ms_mesh big, m;
    ms_test_demo_mesh(30, &big);
    ms_test_demo_mesh(10, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&big, &o);
    o.cube_size *= 0.5;
    for (int a = 0; a < 3; ++a)
        o.cube_origin[a] += o.cube_size;
    o.max_depth = 6;
    o.tolerance = 0.05;
    ms_apo_builder *b;
    ms_apo_chunk c;
    ms_apo_build_stats st;
    assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
    assert_int_equal(ms_apo_builder_build_chunk(b, &m, &big, &o, &c, &st, NULL), MS_OK);
    ms_apo_builder_destroy(b);
    assert_true(c.level_count == 7 && c.texel_count > 1000);
    assert_int_equal(st.unsampled, 0);
    assert_true(st.ray_hits > 0.95 * st.samples);
    ms_apo_view v;
    ms_apo_tree t;
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, NULL), MS_OK);
    assert_int_equal(ms_apo_view_decode(&v, &t, NULL), MS_OK);
    assert_int_equal(t.node_count, st.internal_nodes + st.leaves);
    ms_apo_tree_free(&t);
    ms_apo_chunk_free(&c);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

/* The same surface at two densities (4x the triangles): the spread measure gives
 * nearly the same octree, the published measure a much larger one. */
static void test_measure_density(void **state)
{
    (void)state;
    ms_mesh sparse, dense, m;
    ms_test_demo_mesh(24, &sparse);
    subdivide(&sparse, &dense);
    ms_test_demo_mesh(8, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&dense, &o);
    o.max_depth = 8;
    size_t counts[2][2];
    for (int measure = 0; measure < 2; ++measure) {
        o.measure = measure ? MS_APO_MEASURE_CLASSIC : MS_APO_MEASURE_SPREAD;
        o.tolerance = measure ? 0.5 : 0.12;
        for (int k = 0; k < 2; ++k) {
            ms_apo_tree t;
            ms_apo_build_stats st;
            build(&m, k ? &dense : &sparse, &o, &t, &st);
            counts[measure][k] = t.node_count;
            ms_apo_tree_free(&t);
        }
    }
    double spread_ratio = (double)counts[0][1] / (double)counts[0][0];
    double classic_ratio = (double)counts[1][1] / (double)counts[1][0];
    print_message("nodes sparse/dense: spread %zu/%zu (x%.2f), classic %zu/%zu (x%.2f)\n", counts[0][0],
                  counts[0][1], spread_ratio, counts[1][0], counts[1][1], classic_ratio);
    assert_true(spread_ratio > 0.75 && spread_ratio < 1.35);
    assert_true(classic_ratio > 1.5);
    ms_mesh_free(&sparse);
    ms_mesh_free(&dense);
    ms_mesh_free(&m);
}

/* A mesh from a list of triangles given by their corners. */
static void triangles(ms_mesh *mesh, const double (*corners)[3][3], size_t count)
{
    memset(mesh, 0, sizeof *mesh);
    assert_int_equal(ms_mesh_reserve(mesh, 3 * count, count, NULL), MS_OK);
    for (size_t t = 0; t < count; ++t)
        for (int k = 0; k < 3; ++k) {
            memcpy(&mesh->positions[9 * t + 3 * k], corners[t][k], 3 * sizeof(double));
            mesh->triangles[3 * t + k] = (uint32_t)(3 * t + k);
        }
    mesh->vertex_count = 3 * count;
    mesh->triangle_count = count;
}

static const double m_triangle[1][3][3] = {{{0.2, 0.2, 0.5}, {0.8, 0.2, 0.5}, {0.5, 0.8, 0.5}}};

static void check_leaf_codes(const ms_apo_tree *t, const float want[3])
{
    uint32_t code = ms_apo_normal_encode(want);
    size_t leaves = 0;
    for (size_t i = 0; i < t->node_count; ++i) {
        assert_int_equal(ms_apo_normal_encode(t->nodes[i].normal), code);
        leaves += !t->nodes[i].child_mask;
    }
    assert_true(leaves >= 8);
}

static void fallback_options(ms_apo_build_options *o, double search)
{
    ms_apo_build_options_default(o);
    o->init_depth = 3;
    o->max_depth = 3;
    o->search_distance = search;
}

/* No hit and no triangle of M within the search distance: m's own normal, and
 * every sample counted as unsampled. */
static void test_leaf_without_hit_or_nearby_triangle(void **state)
{
    (void)state;
    const double far_away[1][3][3] = {{{0.0, 0.0, 0.05}, {1.0, 0.0, 0.05}, {0.0, 1.0, 0.05}}};
    ms_mesh m, big;
    triangles(&m, m_triangle, 1);
    triangles(&big, far_away, 1);
    ms_apo_build_options o;
    fallback_options(&o, 0.01);
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&m, &big, &o, &t, &st);
    assert_true(st.samples > 0);
    assert_int_equal(st.unsampled, st.samples);
    assert_int_equal(st.ray_hits, 0);
    assert_int_equal(st.closest_points, 0);
    const float up[3] = {0, 0, 1};
    check_leaf_codes(&t, up);
    ms_apo_tree_free(&t);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

/* A degenerate m (a triangle collapsed to a point) has no direction: no ray,
 * no nearby M, so the documented +z. */
static void test_degenerate_m_triangle(void **state)
{
    (void)state;
    const double point[1][3][3] = {{{0.3, 0.6, 0.2}, {0.3, 0.6, 0.2}, {0.3, 0.6, 0.2}}};
    const double far_away[1][3][3] = {{{0.9, 0.9, 0.9}, {1.0, 0.9, 0.9}, {0.9, 1.0, 0.9}}};
    ms_mesh m, big;
    triangles(&m, point, 1);
    triangles(&big, far_away, 1);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    o.init_depth = 4;
    o.max_depth = 4;
    o.search_distance = 0.05;
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&m, &big, &o, &t, &st);
    assert_int_equal(t.level_count, 5); /* a single chain of cells down to the point */
    assert_int_equal(t.node_count, 5);
    assert_int_equal(st.unsampled, 1);
    const float up[3] = {0, 0, 1};
    for (size_t i = 0; i < t.node_count; ++i)
        assert_int_equal(ms_apo_normal_encode(t.nodes[i].normal), ms_apo_normal_encode(up));
    ms_apo_tree_free(&t);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

/* Rays parallel to M (a wall at x = 0.95) never hit; the closest point of the
 * wall is within the search distance: every sample takes the wall's normal. */
static void test_closest_point_fallback(void **state)
{
    (void)state;
    const double wall[2][3][3] = {{{0.95, 0.0, 0.0}, {0.95, 1.0, 0.0}, {0.95, 0.0, 1.0}},
                                  {{0.95, 1.0, 0.0}, {0.95, 1.0, 1.0}, {0.95, 0.0, 1.0}}};
    ms_mesh m, big;
    triangles(&m, m_triangle, 1);
    triangles(&big, wall, 2);
    ms_apo_build_options o;
    fallback_options(&o, 0.9);
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&m, &big, &o, &t, &st);
    assert_int_equal(st.closest_points, st.samples);
    const float plus_x[3] = {1, 0, 0};
    check_leaf_codes(&t, plus_x);
    ms_apo_tree_free(&t);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

/* A plane of M just below m: every ray hits it, both directions are tried. */
static void test_rays_hit_both_ways(void **state)
{
    (void)state;
    const double below[2][3][3] = {{{0.0, 0.0, 0.48}, {1.0, 0.0, 0.48}, {0.0, 1.0, 0.48}},
                                   {{1.0, 0.0, 0.48}, {1.0, 1.0, 0.48}, {0.0, 1.0, 0.48}}};
    ms_mesh m, big;
    triangles(&m, m_triangle, 1);
    triangles(&big, below, 2);
    ms_apo_build_options o;
    fallback_options(&o, 0.0); /* automatic: h = 0.02 */
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&m, &big, &o, &t, &st);
    assert_true(fabs(st.m_to_M_distance - 0.02) < 1e-6);
    assert_int_equal(st.ray_hits, st.samples);
    const float up[3] = {0, 0, 1};
    check_leaf_codes(&t, up);
    ms_apo_tree_free(&t);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

/* The debug picture of a plane: every pixel meets it, all with the same normal,
 * so the same Lambert value; a small disc of m shows only where it is. */
static void test_render_top_view(void **state)
{
    (void)state;
    const double plane[2][3][3] = {{{0.0, 0.0, 0.5}, {1.0, 0.0, 0.5}, {0.0, 1.0, 0.5}},
                                   {{1.0, 0.0, 0.5}, {1.0, 1.0, 0.5}, {0.0, 1.0, 0.5}}};
    ms_mesh m, big;
    triangles(&m, plane, 2);
    triangles(&big, plane, 2);
    ms_apo_build_options o;
    fallback_options(&o, 0.0);
    ms_apo_builder *b;
    ms_apo_chunk c;
    assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
    assert_int_equal(ms_apo_builder_build_chunk(b, &m, &big, &o, &c, NULL, NULL), MS_OK);
    ms_apo_view v;
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, NULL), MS_OK);
    uint8_t grey[64 * 48];
    assert_int_equal(ms_apo_render_top_view(&v, 30, 64, 48, grey), 64 * 48);
    for (size_t i = 0; i < sizeof grey; ++i)
        assert_int_equal(grey[i], 231); /* 30.5 + 225 / |(0.3, 0.4, 1)| */
    ms_apo_chunk_free(&c);
    /* m a single small triangle in the middle: only its cells show. */
    ms_mesh_free(&m);
    triangles(&m, m_triangle, 1);
    assert_int_equal(ms_apo_builder_build_chunk(b, &m, &big, &o, &c, NULL, NULL), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, NULL), MS_OK);
    uint64_t hits = ms_apo_render_top_view(&v, 30, 64, 48, grey);
    assert_true(hits > 0 && hits < 64 * 48 / 2);
    assert_int_equal(grey[0], 0);
    assert_int_equal(grey[24 * 64 + 32], 231);
    ms_apo_chunk_free(&c);
    ms_apo_builder_destroy(b);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

static void test_empty_and_bad_input(void **state)
{
    (void)state;
    const double outside[1][3][3] = {{{2.0, 2.0, 2.0}, {3.0, 2.0, 2.0}, {2.0, 3.0, 2.0}}};
    ms_mesh m, big;
    triangles(&m, outside, 1);
    triangles(&big, m_triangle, 1);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_apo_builder *b;
    assert_int_equal(ms_apo_builder_create(&b, NULL), MS_OK);
    ms_apo_chunk c;
    ms_apo_build_stats st;
    assert_int_equal(ms_apo_builder_build_chunk(b, &m, &big, &o, &c, &st, NULL), MS_OK);
    assert_int_equal(c.level_count, 0);
    assert_int_equal(c.texel_count, 0);
    assert_int_equal(st.leaves, 0);
    ms_apo_chunk_free(&c);
    ms_apo_tree t;
    ms_error err;
    /* Bad options. */
    o.max_depth = MS_APO_MAX_DEPTH + 1;
    assert_int_equal(ms_apo_builder_build_tree(b, &big, &big, &o, &t, NULL, &err), MS_ERR_ARG);
    ms_apo_build_options_default(&o);
    o.cube_size = 0.0;
    assert_int_equal(ms_apo_builder_build_tree(b, &big, &big, &o, &t, NULL, &err), MS_ERR_ARG);
    o.cube_size = NAN;
    assert_int_equal(ms_apo_builder_build_tree(b, &big, &big, &o, &t, NULL, &err), MS_ERR_ARG);
    ms_apo_build_options_default(&o);
    o.tolerance = NAN;
    assert_int_equal(ms_apo_builder_build_tree(b, &big, &big, &o, &t, NULL, &err), MS_ERR_ARG);
    /* Bad meshes. */
    ms_apo_build_options_default(&o);
    big.positions[4] = NAN;
    assert_int_equal(ms_apo_builder_build_tree(b, &m, &big, &o, &t, NULL, &err), MS_ERR_RANGE);
    big.positions[4] = 0.2;
    big.triangles[2] = 7;
    assert_int_equal(ms_apo_builder_build_tree(b, &big, &m, &o, &t, NULL, &err), MS_ERR_ARG);
    assert_null(t.nodes);
    ms_apo_builder_destroy(b);
    ms_mesh_free(&m);
    ms_mesh_free(&big);
}

static void test_triangle_cube_overlap(void **state)
{
    (void)state;
    const float c[3] = {0.5f, 0.5f, 0.5f};
    /* Inside, crossing, touching a face, touching an edge only, just outside. */
    float a[3] = {0.4f, 0.4f, 0.5f}, b[3] = {0.6f, 0.4f, 0.5f}, d[3] = {0.5f, 0.6f, 0.5f};
    assert_true(ms_tri_cube_overlap(c, 0.5f, a, b, d));
    float big1[3] = {-5, -5, 0.5f}, big2[3] = {5, -5, 0.5f}, big3[3] = {0, 5, 0.5f};
    assert_true(ms_tri_cube_overlap(c, 0.5f, big1, big2, big3));
    float f1[3] = {1.0f, 0.2f, 0.2f}, f2[3] = {1.5f, 0.8f, 0.2f}, f3[3] = {1.5f, 0.2f, 0.8f};
    assert_true(ms_tri_cube_overlap(c, 0.5f, f1, f2, f3));
    float g1[3] = {1.01f, 0.2f, 0.2f}, g2[3] = {1.5f, 0.8f, 0.2f}, g3[3] = {1.5f, 0.2f, 0.8f};
    assert_false(ms_tri_cube_overlap(c, 0.5f, g1, g2, g3));
    /* Bounding boxes overlap, triangle misses the corner (separated by an edge
     * cross-product axis or the triangle's plane). */
    float h1[3] = {1.3f, 0.9f, 0.5f}, h2[3] = {0.9f, 1.3f, 0.5f}, h3[3] = {1.3f, 1.3f, 0.5f};
    assert_false(ms_tri_cube_overlap(c, 0.5f, h1, h2, h3));
    float p1[3] = {2.0f, 0.0f, 0.0f}, p2[3] = {0.0f, 2.0f, 0.0f}, p3[3] = {0.0f, 0.0f, 2.0f};
    assert_true(ms_tri_cube_overlap(c, 0.5f, p1, p2, p3));  /* plane x+y+z = 2 cuts the cube */
    float q1[3] = {3.1f, 0.0f, 0.0f}, q2[3] = {0.0f, 3.1f, 0.0f}, q3[3] = {0.0f, 0.0f, 3.1f};
    assert_false(ms_tri_cube_overlap(c, 0.5f, q1, q2, q3)); /* x+y+z = 3.1 misses it */
}

static void test_simplify(void **state)
{
    (void)state;
    ms_mesh big, small;
    ms_test_demo_mesh(24, &big);
    ms_simplify_report r;
    assert_int_equal(ms_simplify(&big, 1000, &small, &r, NULL), MS_OK);
    assert_int_equal(r.input_triangles, big.triangle_count);
    assert_int_equal(r.refused_faces, 0);
    assert_true(small.triangle_count <= 1000 && small.triangle_count >= 990);
    assert_int_equal(r.output_triangles, small.triangle_count);
    for (size_t i = 0; i < 3 * small.triangle_count; ++i)
        assert_true(small.triangles[i] < small.vertex_count);
    /* Closed sphere stays a sphere: V - E + F = 2 with E = 3F/2. */
    assert_int_equal((long)small.vertex_count - (long)(3 * small.triangle_count / 2) + (long)small.triangle_count, 2);
    ms_mesh_free(&small);
    assert_int_equal(ms_simplify(&big, 0, &small, &r, NULL), MS_ERR_ARG);
    ms_mesh empty;
    memset(&empty, 0, sizeof empty);
    assert_int_equal(ms_simplify(&empty, 10, &small, &r, NULL), MS_ERR_EMPTY);
    ms_mesh_free(&big);
}

/* A flat cell: M's normals do not spread, so the root stays a leaf (one texel)
 * whatever the depth cap, and its normal is the plane's. */
static void test_flat_cell_is_one_leaf(void **state)
{
    (void)state;
    const double square[2][3][3] = {{{0.1, 0.2, 0.4}, {0.9, 0.2, 0.4}, {0.9, 0.8, 0.4}},
                                    {{0.1, 0.2, 0.4}, {0.9, 0.8, 0.4}, {0.1, 0.8, 0.4}}};
    ms_mesh m;
    triangles(&m, square, 2);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    o.max_depth = 12;
    o.tolerance = 0.01;
    o.threads = 1;
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&m, &m, &o, &t, &st);
    assert_int_equal(t.node_count, 1);
    assert_int_equal(t.level_count, 1);
    assert_int_equal(t.nodes[0].child_mask, 0);
    const float up[3] = {0, 0, 1};
    assert_int_equal(ms_apo_normal_encode(t.nodes[0].normal), ms_apo_normal_encode(up));
    assert_int_equal(st.samples, 2); /* the leaf touches both triangles */
    ms_apo_tree_free(&t);
    ms_mesh_free(&m);
}

/* A fan of 20,000 triangles around one hub, raised into a cone so that the
 * octree refines around the hub, where every leaf touches thousands of them:
 * each leaf samples at most MS_APO_SAMPLES_PER_LEAF of its m-triangles (2 rays
 * each, at most one closest-point query per leaf), so the work follows the
 * leaves, not the hub's valence (the former rule cast 2 rays per (leaf,
 * m-triangle): 40,000 for each leaf at the hub). h is given (distance_bound)
 * as the baker gives it; measuring it costs point queries that grow with the
 * valence. */
static void test_fan_rays_bounded_by_leaves(void **state)
{
    (void)state;
    const uint32_t n = 20000;
    ms_mesh fan;
    memset(&fan, 0, sizeof fan);
    assert_int_equal(ms_mesh_reserve(&fan, n + 1, n, NULL), MS_OK);
    fan.positions[0] = 0.0, fan.positions[1] = 0.0, fan.positions[2] = 0.5;
    for (uint32_t i = 0; i < n; ++i) {
        double a = 2.0 * M_PI * i / n;
        fan.positions[3 * (i + 1)] = cos(a);
        fan.positions[3 * (i + 1) + 1] = sin(a);
        fan.positions[3 * (i + 1) + 2] = 0.0;
        fan.triangles[3 * i] = 0;
        fan.triangles[3 * i + 1] = 1 + i;
        fan.triangles[3 * i + 2] = 1 + (i + 1) % n;
    }
    fan.vertex_count = n + 1;
    fan.triangle_count = n;
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    o.cube_origin[0] = o.cube_origin[1] = -1.0;
    o.cube_origin[2] = -0.5;
    o.cube_size = 2.0;
    o.max_depth = 8;
    o.tolerance = 0.2;
    o.distance_bound = 1.0 / 256;
    o.threads = 2;
    ms_apo_tree t;
    ms_apo_build_stats st;
    build(&fan, &fan, &o, &t, &st);
    assert_int_equal(t.level_count, 9); /* refined to the cap at the hub */
    assert_true(st.leaves > 0);
    assert_true(st.samples <= MS_APO_SAMPLES_PER_LEAF * st.leaves);
    assert_true(st.rays <= 2 * MS_APO_SAMPLES_PER_LEAF * st.leaves);
    assert_true(st.point_queries <= st.leaves);
    assert_true(st.rays < 2 * (uint64_t)n); /* less than one hub leaf of the former rule */
    assert_true(st.m_to_M_distance == 1.0 / 256);
    ms_apo_tree_free(&t);
    ms_mesh_free(&fan);
}


/* The wavy fan of issue 31: n slivers around one hub, the rim waving out of its
 * plane (z = 0.1 sin 7a), so that the normals turn around the hub and the
 * octree refines there. Embree's boxes of the slivers all hold the hub, so one
 * of its queries visits a good part of them: the former build cast 2 rays per
 * sample through them (36-145 s for a 100,000-triangle bake). */
static void wavy_fan(ms_mesh *fan, uint32_t n)
{
    memset(fan, 0, sizeof *fan);
    assert_int_equal(ms_mesh_reserve(fan, n + 1, n, NULL), MS_OK);
    fan->positions[0] = fan->positions[1] = fan->positions[2] = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double a = 2.0 * M_PI * i / n;
        fan->positions[3 * (i + 1)] = cos(a);
        fan->positions[3 * (i + 1) + 1] = sin(a);
        fan->positions[3 * (i + 1) + 2] = 0.1 * sin(7.0 * a);
        fan->triangles[3 * i] = 0;
        fan->triangles[3 * i + 1] = 1 + i;
        fan->triangles[3 * i + 2] = 1 + (i + 1) % n;
    }
    fan->vertex_count = n + 1;
    fan->triangle_count = n;
}

/* The work of the build, counted without clocks: the triangles it looks at one
 * by one, plus every Embree query charged as a visit of all of M (what one
 * costs on a fan). */
static uint64_t fan_work(uint32_t n, ms_apo_build_stats *st)
{
    ms_mesh fan;
    wavy_fan(&fan, n);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    o.cube_origin[0] = o.cube_origin[1] = -1.0;
    o.cube_origin[2] = -1.0;
    o.cube_size = 2.0;
    o.max_depth = 8;
    o.tolerance = 0.2;
    o.distance_bound = sqrt(3.0) / 128; /* the baker's bound for a grid one level above the leaves */
    o.threads = 2;
    ms_apo_tree t;
    build(&fan, &fan, &o, &t, st);
    ms_apo_tree_free(&t);
    ms_mesh_free(&fan);
    return st->triangle_visits + (st->rays + st->point_queries) * (uint64_t)n;
}

/* Linear in the input on a crowded M: the leaves answer their queries from
 * their own M-triangles, and what is left for Embree is a small part; the work
 * per input triangle and level stays bounded and 4x the triangles costs about
 * 4x the work. */
static void test_wavy_fan_work_linear(void **state)
{
    (void)state;
    ms_apo_build_stats small, large;
    uint64_t w_small = fan_work(3000, &small), w_large = fan_work(12000, &large);
    print_message("wavy fan: 3000 -> %llu (leaves %zu, rays %llu, local %llu), 12000 -> %llu (leaves %zu, rays %llu, local %llu)\n",
                  (unsigned long long)w_small, small.leaves, (unsigned long long)small.rays,
                  (unsigned long long)small.local_answers, (unsigned long long)w_large, large.leaves,
                  (unsigned long long)large.rays, (unsigned long long)large.local_answers);
    assert_true(small.crowding > 64.0 && large.crowding > 64.0);
    assert_true(large.local_answers > 0);
    /* Embree answers at most one query per four leaves (the former build:
     * about 16 rays per leaf, each charged 12,000 visits here: over 10^8) */
    assert_true(large.rays + large.point_queries <= large.leaves / 4);
    assert_true(w_large <= 256 * 12000ull * large.levels); /* 4.8 x 10^6 x 4 measured */
    assert_true(w_large <= 5 * w_small);                   /* 4.0 measured */
    /* the leaves answer from their (capped) lists alone: Embree is never asked */
    assert_int_equal(small.rays + small.point_queries + large.rays + large.point_queries, 0);
}

/* Adaptive sampling on a smooth model (the demo sculpture): the same tree,
 * most leaves settled by their two nearest samples, so the rays per leaf fall
 * below a bound (counts, not clocks), and the leaf normals stay close to those
 * of every sample. */
static void test_adaptive_sampling_rays_per_leaf(void **state)
{
    (void)state;
    ms_mesh big, m;
    ms_test_demo_mesh(40, &big);
    ms_test_demo_mesh(30, &m);
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_test_apo_cube_around(&big, &o);
    o.max_depth = 5;
    o.tolerance = 0.1;
    ms_apo_tree all, adaptive;
    ms_apo_build_stats sa, sd;
    build(&m, &big, &o, &all, &sa);
    o.sample_agreement = 0.5 * o.tolerance;
    build(&m, &big, &o, &adaptive, &sd);
    print_message("all: %zu leaves, %llu samples, %llu rays; adaptive: %zu agreed, %llu samples, %llu rays\n",
                  sa.sampled_leaves, (unsigned long long)sa.samples, (unsigned long long)sa.rays, sd.agreed_leaves,
                  (unsigned long long)sd.samples, (unsigned long long)sd.rays);
    assert_int_equal(adaptive.node_count, all.node_count);
    assert_int_equal(sa.sampled_leaves, sa.leaves);
    assert_int_equal(sd.sampled_leaves, sa.leaves);
    assert_int_equal(sa.agreed_leaves, 0);
    assert_true(sa.samples > 6 * sa.leaves);       /* every sample: up to 8 per leaf */
    assert_true(sd.agreed_leaves > 0.9 * sd.leaves);
    assert_true(sd.samples <= 5 * sd.leaves / 2); /* at most 2.5 samples per leaf */
    assert_true(sd.rays <= 5 * sd.leaves);        /* 2 rays per sample at most */
    assert_true(sd.rays <= sa.rays / 3);
    double sum = 0.0, worst = 0.0;
    for (size_t i = 0; i < all.node_count; ++i) {
        const float *p = all.nodes[i].normal, *q = adaptive.nodes[i].normal;
        double dot = (double)p[0] * q[0] + (double)p[1] * q[1] + (double)p[2] * q[2];
        double angle = acos(dot > 1.0 ? 1.0 : dot < -1.0 ? -1.0 : dot);
        sum += angle;
        worst = angle > worst ? angle : worst;
    }
    print_message("leaf normals: mean %.4f rad, largest %.4f rad apart\n", sum / (double)all.node_count, worst);
    assert_true(sum / (double)all.node_count < 0.02);
    ms_apo_tree_free(&all);
    ms_apo_tree_free(&adaptive);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

/* A leaf with an M list samples fewer of its m-triangles the longer the list:
 * one pass over the list per sample, at most MS_APO_LOCAL_TESTS tests in all
 * (at least one sample); without a list (Embree), all of them. */
static void test_leaf_samples_follow_the_list(void **state)
{
    (void)state;
    assert_int_equal(ms_apo_leaf_samples(0), MS_APO_SAMPLES_PER_LEAF);
    assert_int_equal(ms_apo_leaf_samples(1), MS_APO_SAMPLES_PER_LEAF);
    assert_int_equal(ms_apo_leaf_samples(MS_APO_LOCAL_TESTS / MS_APO_SAMPLES_PER_LEAF), MS_APO_SAMPLES_PER_LEAF);
    assert_int_equal(ms_apo_leaf_samples(MS_APO_LOCAL_TESTS / 4), 4);
    assert_int_equal(ms_apo_leaf_samples(MS_APO_LOCAL_TESTS), 1);
    assert_int_equal(ms_apo_leaf_samples(100000), 1);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_demo_structure_and_normals),
        cmocka_unit_test(test_leaf_samples_follow_the_list),
        cmocka_unit_test(test_adaptive_sampling_rays_per_leaf),
        cmocka_unit_test(test_same_output_whatever_the_threads),
        cmocka_unit_test(test_cell_chunk),
        cmocka_unit_test(test_tiny_extent_and_huge_offset),
        cmocka_unit_test(test_measure_density),
        cmocka_unit_test(test_leaf_without_hit_or_nearby_triangle),
        cmocka_unit_test(test_degenerate_m_triangle),
        cmocka_unit_test(test_closest_point_fallback),
        cmocka_unit_test(test_rays_hit_both_ways),
        cmocka_unit_test(test_render_top_view),
        cmocka_unit_test(test_empty_and_bad_input),
        cmocka_unit_test(test_triangle_cube_overlap),
        cmocka_unit_test(test_simplify),
        cmocka_unit_test(test_flat_cell_is_one_leaf),
        cmocka_unit_test(test_fan_rays_bounded_by_leaves),
        cmocka_unit_test(test_wavy_fan_work_linear),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
