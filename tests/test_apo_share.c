/* The APO bake's work cut without changing its output (issue 31, the APO share
 * of the bake): an internal cell's m from the encoder's own pass, the children's
 * union unifying only the triangles that can repeat, the samples that share a
 * direction sharing their rays. Counts and exact outcomes, not clocks. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_apo_build.h"
#include "ms_apo_testtree.h"
#include "ms_bake_apo.h"
#include "ms_codec.h"
#include "ms_demo_model.h"
#include "ms_quant.h"
#include "ms_tri_unify.h"


/* ms_codec_encode_params.mesh is the mesh a decoder gives at the stream's full
 * precision, vertex for vertex and triangle for triangle: from one vertex and
 * from a start state, without and with geometry ahead, with the compact header
 * of an archive's cells. */
static void test_encoder_mesh_is_the_decoded_mesh(void **state)
{
    (void)state;
    ms_mesh model;
    ms_test_demo_mesh(12, &model);
    ms_qmesh q;
    ms_error err;
    assert_int_equal(ms_quantise_mesh(&model, 9, &q, NULL, &err), MS_OK);
    ms_codec_state full;
    assert_int_equal(ms_codec_state_from_qmesh(&q, &full, &err), MS_OK);
    const unsigned p_min[] = {0, 4, 4}, ahead[] = {0, 0, 2};
    for (int c = 0; c < 3; ++c) {
        ms_mesh given;
        memset(&given, 0, sizeof given);
        ms_codec_encode_params par = {.p_min = p_min[c], .box = q.box, .compact_header = true, .ahead = ahead[c],
                                      .mesh = &given};
        uint8_t *buf = NULL;
        size_t size = 0;
        ms_codec_state start;
        assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, &start, &err), MS_OK);
        ms_codec_decoder_options o = {.box = &q.box};
        ms_codec_decoder *d = NULL;
        ms_mesh decoded;
        memset(&decoded, 0, sizeof decoded);
        assert_int_equal(ms_codec_decoder_create(buf, size, p_min[c] ? &start : NULL, &o, &d, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_set_level(d, 3 * 9, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_mesh(d, &decoded, &err), MS_OK);
        assert_true(decoded.triangle_count > 1000);
        assert_int_equal(given.vertex_count, decoded.vertex_count);
        assert_int_equal(given.triangle_count, decoded.triangle_count);
        assert_memory_equal(given.positions, decoded.positions, 3 * decoded.vertex_count * sizeof(double));
        assert_memory_equal(given.triangles, decoded.triangles, 3 * decoded.triangle_count * sizeof(uint32_t));
        ms_codec_decoder_destroy(d);
        ms_mesh_free(&decoded);
        ms_mesh_free(&given);
        ms_codec_state_free(&start);
        free(buf);
    }
    ms_codec_state_free(&full);
    ms_qmesh_free(&q);
    ms_mesh_free(&model);
}

/* A grid of quads over [0,1]^2 (z from the seed) cut into parts of 2x2 quads,
 * each part with its own copies of its border vertices and, where `repeat`,
 * its right neighbour's first triangle too (a triangle in two parts). */
static void grid_parts(ms_bake_apo_part *parts, size_t *count, bool repeat, bool join_inside)
{
    const int n = 8, per = 2; /* 8x8 quads, parts of 2x2: 16 parts */
    size_t k = 0;
    for (int py = 0; py < n / per; ++py)
        for (int px = 0; px < n / per; ++px, ++k) {
            ms_bake_apo_part *pt = &parts[k];
            memset(pt, 0, sizeof *pt);
            int w = per + 1 + (px + 1 < n / per ? 1 : 0); /* a column more: the right neighbour's first triangle */
            size_t nv = (size_t)(w * (per + 1));
            ms_error err;
            assert_int_equal(ms_mesh_reserve(&pt->mesh, nv, 2 * (size_t)per * per + 1, &err), MS_OK);
            pt->weight = malloc(nv * sizeof *pt->weight);
            for (int y = 0; y <= per; ++y)
                for (int x = 0; x < w; ++x) {
                    size_t v = (size_t)(y * w + x);
                    double gx = (px * per + x) / (double)n, gy = (py * per + y) / (double)n;
                    pt->mesh.positions[3 * v] = 0.01 + 0.98 * gx;
                    pt->mesh.positions[3 * v + 1] = 0.01 + 0.98 * gy;
                    pt->mesh.positions[3 * v + 2] = 0.5 + 0.1 * sin(7.0 * gx + 3.0 * gy);
                    pt->weight[v] = 1;
                }
            if (join_inside && k == 5) /* two of its vertices in one grid cell */
                memcpy(&pt->mesh.positions[3], &pt->mesh.positions[0], 3 * sizeof(double));
            size_t t = 0;
            for (int y = 0; y < per; ++y)
                for (int x = 0; x < per + (repeat && px + 1 < n / per ? 1 : 0); ++x) {
                    uint32_t a = (uint32_t)(y * w + x), b = a + 1, c = a + (uint32_t)w, d = c + 1;
                    uint32_t quad[6] = {a, b, d, a, d, c};
                    int tris = x < per ? 2 : (y == 0 ? 1 : 0);
                    for (int i = 0; i < tris; ++i, ++t)
                        memcpy(&pt->mesh.triangles[3 * t], &quad[3 * i], sizeof quad / 2);
                }
            pt->mesh.vertex_count = nv;
            pt->mesh.triangle_count = t;
            pt->bits = 5;
            pt->origin[0] = px * per / (double)n;
            pt->origin[1] = py * per / (double)n;
            pt->size = per / (double)n;
        }
    *count = k;
}

/* The union keeps exactly what unifying all of M keeps (the earliest copy of
 * each vertex set, in order): the triangles repeated across parts go, and
 * where two vertices of one part join, the whole of M is unified. */
static void test_union_unifies_what_can_repeat(void **state)
{
    (void)state;
    const ms_quant_box box = {{0, 0, 0}, 1.0};
    for (int c = 0; c < 4; ++c) {
        ms_bake_apo_part parts[16];
        size_t count;
        grid_parts(parts, &count, c & 1, c & 2);
        ms_mesh u;
        uint32_t *owned;
        ms_error err;
        assert_int_equal(ms_bake_apo_union(parts, count, &box, &u, &owned, &err), MS_OK);
        /* the reference: the same M unified whole */
        size_t nt = u.triangle_count, before = nt;
        uint32_t *again = malloc((3 * nt + 1) * sizeof *again);
        memcpy(again, u.triangles, 3 * nt * sizeof *again);
        assert_int_equal(ms_tri_unify(again, &nt, NULL, NULL, &err), MS_OK);
        assert_int_equal(nt, before); /* nothing left to drop */
        free(again);
        size_t input = 0;
        for (size_t k = 0; k < count; ++k)
            input += parts[k].mesh.triangle_count;
        /* 128 distinct triangles of the grid; with repeat, 12 more in the input */
        assert_int_equal(input, (c & 1) ? 140 : 128);
        /* joined inside part 5, its first triangle's copy in part 4 no longer
         * repeats it: one more */
        assert_int_equal(u.triangle_count, c == 3 ? 129 : 128);
        ms_mesh_free(&u);
        free(owned);
        for (size_t k = 0; k < count; ++k)
            ms_bake_apo_part_free(&parts[k]);
    }
}

/* Two samples of a leaf whose directions are equal (their closest point is a
 * shared vertex) cast their rays once: on the demo sculpture the rays fall
 * below two per sample, by the samples that shared them. */
static void test_samples_share_rays(void **state)
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
    o.sample_agreement = 0.05;
    ms_apo_builder *b;
    ms_error err;
    assert_int_equal(ms_apo_builder_create(&b, &err), MS_OK);
    ms_apo_tree t;
    ms_apo_build_stats st;
    assert_int_equal(ms_apo_builder_build_tree(b, &m, &big, &o, &t, &st, &err), MS_OK);
    print_message("samples %llu, rays %llu, hits %llu, closest %llu, unsampled %llu\n",
                  (unsigned long long)st.samples, (unsigned long long)st.rays, (unsigned long long)st.ray_hits,
                  (unsigned long long)st.closest_points, (unsigned long long)st.unsampled);
    assert_true(st.samples > 1000);
    /* every sample is answered (hit, closest point or unsampled) */
    assert_int_equal(st.ray_hits + st.closest_points + st.unsampled, st.samples);
    assert_true(st.rays < 2 * st.samples);
    ms_apo_tree_free(&t);
    ms_apo_builder_destroy(b);
    ms_mesh_free(&big);
    ms_mesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_encoder_mesh_is_the_decoded_mesh),
        cmocka_unit_test(test_union_unifies_what_can_repeat),
        cmocka_unit_test(test_samples_share_rays),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
