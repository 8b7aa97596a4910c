/* The edge counts of `meshbake --info` (ms_mesh_edges.h): exact counts on
 * small meshes written here: a closed cube (18 manifold edges), the cube with
 * one triangle flipped (its 3 edges become inconsistently oriented), with a
 * fin (a triangle on one of its edges: non-manifold), an open strip (boundary
 * edges), and the same figures from the program, text and JSON; and the
 * program's vertex colour report (present, alpha, distinct colours). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_mesh.h"
#include "ms_mesh_edges.h"
#include "ms_mesh_io.h"
#include "ms_test.h"

/* corners 0..7 of the unit cube (bit 0 x, bit 1 y, bit 2 z), wound outwards */
static const uint32_t cube[12][3] = {
    {0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5},
};

static ms_mesh_edge_counts count(const uint32_t (*tris)[3], size_t n)
{
    ms_mesh_edge_counts c;
    ms_error err;
    assert_int_equal(ms_mesh_count_edges(tris ? &tris[0][0] : NULL, n, &c, &err), MS_OK);
    return c;
}

static void test_counts(void **state)
{
    (void)state;
    ms_mesh_edge_counts c = count(cube, 12);
    assert_int_equal(c.edges, 18);
    assert_int_equal(c.manifold, 18);
    assert_int_equal(c.flipped + c.boundary + c.non_manifold, 0);

    uint32_t t[14][3];
    memcpy(t, cube, sizeof cube);
    t[0][1] = 3, t[0][2] = 2; /* one triangle flipped */
    c = count(t, 12);
    assert_int_equal(c.edges, 18);
    assert_int_equal(c.flipped, 3);
    assert_int_equal(c.manifold, 15);

    t[3][1] = 6, t[3][2] = 7; /* and another, sharing no edge with the first */
    c = count(t, 12);
    assert_int_equal(c.flipped, 6);

    memcpy(t, cube, sizeof cube);
    t[12][0] = 0, t[12][1] = 3, t[12][2] = 8; /* a fin on the diagonal 0-3: vertex 8 */
    c = count(t, 13);
    assert_int_equal(c.edges, 20);
    assert_int_equal(c.non_manifold, 1);
    assert_int_equal(c.boundary, 2);
    assert_int_equal(c.manifold, 17);

    static const uint32_t strip[2][3] = {{0, 1, 2}, {2, 1, 3}};
    c = count(strip, 2);
    assert_int_equal(c.edges, 5);
    assert_int_equal(c.boundary, 4);
    assert_int_equal(c.manifold, 1);

    static const uint32_t degenerate[1][3] = {{4, 4, 5}};
    c = count(degenerate, 1);
    assert_int_equal(c.edges, 1); /* 4-5 twice, in opposite directions */
    assert_int_equal(c.manifold, 1);
    c = count(NULL, 0);
    assert_int_equal(c.edges, 0);
}

static void test_meshbake_info(void **state)
{
    (void)state;
    char dir[512], path[600], bin[600], command[2048], out[8192];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/flipped.ply", dir);
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, 9, 13, &err), MS_OK);
    for (uint32_t v = 0; v < 8; ++v) {
        m.positions[3 * v] = v & 1, m.positions[3 * v + 1] = (v >> 1) & 1, m.positions[3 * v + 2] = (v >> 2) & 1;
    }
    m.positions[24] = -1, m.positions[25] = -1, m.positions[26] = 0.5;
    m.vertex_count = 9;
    memcpy(m.triangles, cube, sizeof cube);
    m.triangles[1] = 3, m.triangles[2] = 2;           /* flipped: 3 edges */
    m.triangles[36] = 0, m.triangles[37] = 5, m.triangles[38] = 8; /* a fin on 0-5 */
    m.triangle_count = 13;
    assert_int_equal(ms_ply_write(path, &m, true, false, &err), MS_OK);
    ms_mesh_free(&m);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(command, sizeof command, "%s --info --json %s", bin, path);
    json_t *report = ms_test_run_json(command, 0);
    json_t *edges = json_object_get(report, "edges");
    assert_int_equal(json_integer_value(json_object_get(edges, "total")), 20);
    assert_int_equal(json_integer_value(json_object_get(edges, "inconsistently_oriented")), 3);
    assert_int_equal(json_integer_value(json_object_get(edges, "non_manifold")), 1);
    assert_int_equal(json_integer_value(json_object_get(edges, "boundary")), 2);
    assert_int_equal(json_integer_value(json_object_get(edges, "manifold")), 14);
    json_t *colour = json_object_get(report, "colour");
    assert_true(json_is_false(json_object_get(colour, "present")));
    assert_true(json_is_false(json_object_get(colour, "alpha")));
    assert_int_equal(json_integer_value(json_object_get(colour, "distinct")), 0);
    json_decref(report);
    snprintf(command, sizeof command, "%s --info %s", bin, path);
    assert_int_equal(ms_test_run(command, out, sizeof out), 0);
    assert_non_null(strstr(out, "edges:             20 (2 boundary, 14 manifold)"));
    assert_non_null(strstr(out, "flipped edges:     3 "));
    assert_non_null(strstr(out, "non-manifold:      1 edges"));
    assert_non_null(strstr(out, "vertex colour:     none\n"));
    ms_test_rmdir(dir);
}

/* The colour line of `meshbake --info`: with and without alpha, the exact count
 * of distinct colours (alpha counts). */
static void test_meshbake_info_colour(void **state)
{
    (void)state;
    char dir[512], path[600], bin[600], command[2048], out[8192];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/coloured.ply", dir);
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, 8, 12, &err), MS_OK);
    for (uint32_t v = 0; v < 8; ++v) {
        m.positions[3 * v] = v & 1, m.positions[3 * v + 1] = (v >> 1) & 1, m.positions[3 * v + 2] = (v >> 2) & 1;
    }
    m.vertex_count = 8;
    memcpy(m.triangles, cube, sizeof cube);
    m.triangle_count = 12;
    assert_int_equal(ms_mesh_add_colours(&m, true, &err), MS_OK);
    /* 8 vertices: red twice, red with alpha 0 once, green, blue, and white three times */
    static const uint8_t rgba[8][4] = {{255, 0, 0, 255}, {255, 0, 0, 255}, {255, 0, 0, 0},
                                       {0, 255, 0, 255}, {0, 0, 255, 255}, {255, 255, 255, 255},
                                       {255, 255, 255, 255}, {255, 255, 255, 255}};
    memcpy(m.colours, rgba, sizeof rgba);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    for (int alpha = 1; alpha >= 0; --alpha) {
        m.colour_alpha = alpha;
        assert_int_equal(ms_ply_write(path, &m, true, false, &err), MS_OK);
        snprintf(command, sizeof command, "%s --info --json %s", bin, path);
        json_t *report = ms_test_run_json(command, 0);
        json_t *colour = json_object_get(report, "colour");
        assert_true(json_is_true(json_object_get(colour, "present")));
        assert_int_equal(json_is_true(json_object_get(colour, "alpha")), alpha);
        assert_int_equal(json_integer_value(json_object_get(colour, "distinct")), alpha ? 5 : 4);
        json_decref(report);
        snprintf(command, sizeof command, "%s --info %s", bin, path);
        assert_int_equal(ms_test_run(command, out, sizeof out), 0);
        assert_non_null(strstr(out, alpha ? "vertex colour:     rgba, 5 distinct\n"
                                          : "vertex colour:     rgb, 4 distinct\n"));
    }
    ms_mesh_free(&m);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_counts),
        cmocka_unit_test(test_meshbake_info),
        cmocka_unit_test(test_meshbake_info_colour),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
