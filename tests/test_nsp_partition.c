/* ms_nsp_partition_state on hand-built complexes: which child gets which simplex
 * (every child holding one of its vertices, with the foreign vertices), isolated
 * vertices, edges, and the cell geometry helpers. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_nsp.h"
#include "ms_quant.h"

/* p = 8, n = 2, p_r = 2: the root's children are the octants; the root's complex
 * at 2 bits (kd-level 6) has 4x4x4 cells. */
static uint64_t cell_at(unsigned x, unsigned y, unsigned z)
{
    /* kd prefix at level 6 of the point with 2-bit coordinates x, y, z */
    return ms_quant_key(x, y, z, 2);
}

static void test_windows_and_offsets(void **state)
{
    (void)state;
    ms_nsp_shape s;
    ms_error err;
    assert_int_equal(ms_nsp_shape_init(&s, 16, 4, 7, &err), MS_OK);
    unsigned lo, hi;
    ms_nsp_window(&s, 0, false, &lo, &hi);
    assert_true(lo == 0 && hi == 7);
    ms_nsp_window(&s, 1, false, &lo, &hi);
    assert_true(lo == 7 && hi == 9);
    ms_nsp_window(&s, 4, false, &lo, &hi);
    assert_true(lo == 13 && hi == 15);
    ms_nsp_window(&s, 5, false, &lo, &hi);
    assert_true(lo == 15 && hi == 16);
    ms_nsp_window(&s, 2, true, &lo, &hi);
    assert_true(lo == 9 && hi == 16);
    assert_true(ms_nsp_can_split(&s, 4));
    assert_false(ms_nsp_can_split(&s, 5));
    uint32_t xyz[3] = {65535, 0, 16384};
    assert_int_equal(ms_nsp_child_offset(&s, 0, xyz), 3 + 4 * (0 + 4 * 1));
    uint32_t pos[3] = {3, 0, 1};
    uint64_t key = ms_quant_key(xyz[0], xyz[1], xyz[2], 16);
    assert_true(ms_nsp_prefix_inside(&s, key >> 42, 6, 1, pos));
    assert_false(ms_nsp_prefix_inside(&s, key >> 43, 5, 1, pos)); /* too coarse */
    assert_int_equal(ms_nsp_shape_init(&s, 16, 3, 7, &err), MS_ERR_ARG);
    assert_int_equal(ms_nsp_shape_init(&s, 16, 8, 2, &err), MS_ERR_ARG);
    assert_int_equal(ms_nsp_shape_init(&s, 30, 4, 7, &err), MS_ERR_ARG);
}

static void test_partition(void **state)
{
    (void)state;
    ms_nsp_shape s;
    ms_error err;
    assert_int_equal(ms_nsp_shape_init(&s, 8, 2, 2, &err), MS_OK);
    /* vertices: a, b in octant 0; c in octant 1 (x high); d in octant 7; e
     * isolated in octant 2 (y high) */
    uint64_t cells[5] = {cell_at(0, 0, 0), cell_at(1, 1, 0), cell_at(2, 0, 0), cell_at(3, 3, 3),
                         cell_at(0, 2, 0)};
    uint32_t tris[6] = {0, 1, 2, /* octants 0 and 1 */ 1, 0, 3 /* octants 0 and 7 */};
    uint32_t edges[2] = {2, 3}; /* octants 1 and 7 */
    ms_codec_state parent = {.bits = 2, .level = 6, .vertex_count = 5, .tri_count = 2,
                             .edge_count = 1, .cells = cells, .tris = tris, .edges = edges};
    ms_codec_state child[8];
    uint32_t root[3] = {0, 0, 0};
    assert_int_equal(ms_nsp_partition_state(&s, &parent, 0, root, 3, child, &err), MS_OK);
    /* octant 0: both triangles, with their foreign vertices c and d */
    assert_int_equal(child[0].vertex_count, 4);
    assert_int_equal(child[0].tri_count, 2);
    assert_int_equal(child[0].edge_count, 0);
    assert_int_equal(child[0].bits, 3);
    assert_int_equal(child[0].level, 6);
    /* octant 1: the first triangle and the edge (with foreign a, b, d) */
    assert_int_equal(child[1].vertex_count, 4);
    assert_int_equal(child[1].tri_count, 1);
    assert_int_equal(child[1].edge_count, 1);
    /* octant 2: the isolated vertex alone */
    assert_int_equal(child[2].vertex_count, 1);
    assert_int_equal(child[2].tri_count + child[2].edge_count, 0);
    assert_true(child[2].cells[0] == cells[4]);
    /* octant 7: the second triangle and the edge */
    assert_int_equal(child[7].vertex_count, 4);
    assert_int_equal(child[7].tri_count, 1);
    assert_int_equal(child[7].edge_count, 1);
    for (int k = 3; k < 7; ++k)
        assert_int_equal(child[k].vertex_count, 0);
    /* canonical: vertices sorted, orientation of (1, 0, 3) kept */
    for (size_t i = 1; i < child[7].vertex_count; ++i)
        assert_true(child[7].cells[i - 1] < child[7].cells[i]);
    const uint32_t *t = child[7].tris;
    uint64_t ka = child[7].cells[t[0]], kb = child[7].cells[t[1]], kc = child[7].cells[t[2]];
    /* cyclic order b -> a -> d */
    bool ok = (ka == cells[1] && kb == cells[0] && kc == cells[3]) ||
              (ka == cells[0] && kb == cells[3] && kc == cells[1]) ||
              (ka == cells[3] && kb == cells[1] && kc == cells[0]);
    assert_true(ok);
    for (int k = 0; k < 8; ++k)
        ms_codec_state_free(&child[k]);

    /* A child's own split: octant 7 of the root at level 6 = its 1-bit sub-cells;
     * the foreign vertices a and b are outside it and own nothing. */
    uint32_t oct7[3] = {1, 1, 1};
    ms_codec_state sub[8];
    assert_int_equal(ms_nsp_partition_state(&s, &parent, 1, oct7, 3, sub, &err), MS_OK);
    unsigned holding = 0;
    for (int k = 0; k < 8; ++k)
        holding += sub[k].vertex_count > 0;
    assert_int_equal(holding, 1);
    assert_int_equal(sub[7].tri_count, 1);
    assert_int_equal(sub[7].edge_count, 1);
    for (int k = 0; k < 8; ++k)
        ms_codec_state_free(&sub[k]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_windows_and_offsets),
        cmocka_unit_test(test_partition),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
