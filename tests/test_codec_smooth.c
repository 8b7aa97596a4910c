/* The smoothed points of a coarse state (ms_codec_state_smooth, docs/CODEC.md
 * §4.4):
 *   - a tilted plane's staircase of cell centres comes back towards the plane
 *     (RMS distance at most half, every point still inside its kd-cell);
 *   - worked by hand: one round over a lone triangle, each step clamped;
 *   - the result does not depend on the vertices' order (exact integers);
 *   - no rounds, no change; bad arguments and a triangle naming no vertex are
 *     refused with the state left as it was. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_quant.h"

#define BITS 8u
#define SIDE 16u /* cells per axis at kd-level 3 * 4 */
#define LEVEL 12u

/* The plane z = 0.3 x + 0.2 y + 40 (grid units) sampled at the centres of a
 * SIDE x SIDE grid of columns, each vertex in the kd-cell (level LEVEL) that
 * holds its point; two triangles per grid square. */
static void tilted_plane(ms_codec_state *s)
{
    memset(s, 0, sizeof *s);
    s->bits = BITS;
    s->level = LEVEL;
    s->vertex_count = SIDE * SIDE;
    s->tri_count = 2 * (SIDE - 1) * (SIDE - 1);
    s->cells = malloc(s->vertex_count * sizeof *s->cells);
    s->tris = malloc(3 * s->tri_count * sizeof *s->tris);
    assert_non_null(s->cells);
    assert_non_null(s->tris);
    unsigned width = 1u << (BITS - LEVEL / 3);
    for (unsigned j = 0; j < SIDE; ++j)
        for (unsigned i = 0; i < SIDE; ++i) {
            double x = (i + 0.5) * width, y = (j + 0.5) * width, z = 0.3 * x + 0.2 * y + 40;
            uint64_t key = ms_quant_key((uint32_t)x, (uint32_t)y, (uint32_t)z, BITS);
            s->cells[j * SIDE + i] = key >> (3 * BITS - LEVEL);
        }
    size_t t = 0;
    for (unsigned j = 0; j + 1 < SIDE; ++j)
        for (unsigned i = 0; i + 1 < SIDE; ++i) {
            uint32_t a = j * SIDE + i, b = a + 1, c = a + SIDE, d = c + 1;
            uint32_t tri[6] = {a, b, d, a, d, c};
            memcpy(s->tris + 3 * t, tri, sizeof tri);
            t += 2;
        }
}

/* Vertex i's drawn point (rep, or its centre), grid units. */
static void drawn(const ms_codec_state *s, size_t i, double p[3])
{
    uint32_t xyz[3];
    ms_quant_unkey(s->cells[i] << (3 * s->bits - s->level), s->bits, xyz);
    for (int a = 0; a < 3; ++a) {
        double width = (double)(1u << (s->bits - (s->level + 2 - (unsigned)a) / 3));
        p[a] = xyz[a] + (s->rep ? s->rep[3 * i + a] / 65536.0 : 0.5) * width;
    }
}

/* RMS distance of the interior points (a border vertex has half a ring of
 * neighbours) from the plane. */
static double plane_rms(const ms_codec_state *s)
{
    double sum = 0;
    size_t n = 0;
    for (unsigned j = 1; j + 1 < SIDE; ++j)
        for (unsigned i = 1; i + 1 < SIDE; ++i) {
            double p[3];
            drawn(s, j * SIDE + i, p);
            double d = (0.3 * p[0] + 0.2 * p[1] + 40 - p[2]) / sqrt(1 + 0.09 + 0.04);
            sum += d * d, ++n;
        }
    return sqrt(sum / (double)n);
}

static void test_plane_staircase(void **state)
{
    (void)state;
    ms_codec_state s;
    tilted_plane(&s);
    double before = plane_rms(&s);
    ms_error err;
    assert_int_equal(ms_codec_state_smooth(&s, 3, &err), MS_OK);
    assert_non_null(s.rep);
    double after = plane_rms(&s);
    print_message("plane: RMS %.3f -> %.3f grid units\n", before, after);
    assert_true(before > 1.0);
    assert_true(after <= 0.5 * before);
    /* most coordinates left their cell's centre (every one stays in its cell:
     * a uint16 of its width) */
    size_t moved = 0;
    for (size_t i = 0; i < 3 * s.vertex_count; ++i)
        moved += s.rep[i] != 32768;
    assert_true(moved > s.vertex_count / 2);
    ms_codec_state_free(&s);
}

/* One triangle, three vertices at kd-level 3 (one cell per axis halving):
 * cells (0,0,0), (1,0,0) and (0,1,0) of a 2-per-axis grid, in units of 1/65536
 * of a cell: x of the first is 32768, its neighbours' mean (98304 + 32768) / 2
 * = 65536; lambda moves it by floor(32768 * 161 / 256) = 20608 to 53376; mu
 * then from the neighbours' new mean. Worked through for every coordinate
 * below. */
static void test_lone_triangle_by_hand(void **state)
{
    (void)state;
    ms_codec_state s;
    memset(&s, 0, sizeof s);
    s.bits = 1;
    s.level = 3;
    s.vertex_count = 3;
    s.tri_count = 1;
    uint64_t cells[3] = {0, 4, 2}; /* keys x y z: 100 is x = 1, 010 is y = 1 */
    uint32_t tris[3] = {0, 1, 2};
    s.cells = malloc(sizeof cells);
    s.tris = malloc(sizeof tris);
    memcpy(s.cells, cells, sizeof cells);
    memcpy(s.tris, tris, sizeof tris);
    ms_error err;
    assert_int_equal(ms_codec_state_smooth(&s, 1, &err), MS_OK);
    /* x (units): v0 32768, v1 98304, v2 32768.
     * lambda: v0 mean 65536 -> 32768 + 20608 = 53376; v1 mean 32768 -> 98304 -
     *   41216 = 57088, clamped to its cell [65536, 131071]: 65536; v2 as v0:
     *   53376.
     * mu (-172/256): v0 mean (65536 + 53376) / 2 = 59456, delta 6080, moves
     *   floor(-6080 * 172 / 256) = -4085 to 49291; v1 mean 53376, delta -12160,
     *   moves +8170 to 73706; v2 as v0: 49291.
     * y is x with v1 and v2 swapped; z: every point at 32768, unmoved. */
    static const uint16_t expect[9] = {49291, 49291, 32768, 73706 - 65536, 49291, 32768, 49291, 73706 - 65536, 32768};
    for (int i = 0; i < 9; ++i)
        assert_int_equal(s.rep[i], expect[i]);
    ms_codec_state_free(&s);
}

/* The plane's vertices reversed (and the triangles renumbered): the same point
 * for every vertex, to the unit. */
static void test_order_independent(void **state)
{
    (void)state;
    ms_codec_state a, b;
    tilted_plane(&a);
    tilted_plane(&b);
    size_t n = b.vertex_count;
    for (size_t i = 0; i < n; ++i)
        b.cells[i] = a.cells[n - 1 - i];
    for (size_t t = 0; t < 3 * b.tri_count; ++t)
        b.tris[t] = (uint32_t)(n - 1 - a.tris[t]);
    ms_error err;
    assert_int_equal(ms_codec_state_smooth(&a, 2, &err), MS_OK);
    assert_int_equal(ms_codec_state_smooth(&b, 2, &err), MS_OK);
    for (size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c)
            assert_int_equal(a.rep[3 * i + c], b.rep[3 * (n - 1 - i) + c]);
    ms_codec_state_free(&a);
    ms_codec_state_free(&b);
}

static void test_refusals(void **state)
{
    (void)state;
    ms_codec_state s;
    tilted_plane(&s);
    ms_error err;
    assert_int_equal(ms_codec_state_smooth(&s, 0, &err), MS_OK);
    assert_null(s.rep); /* no rounds: drawn at the centres as before */
    assert_int_equal(ms_codec_state_smooth(&s, MS_CODEC_SMOOTH_ROUNDS_MAX + 1, &err), MS_ERR_ARG);
    print_message("%s\n", err.text);
    s.level = 3 * s.bits + 1;
    assert_int_equal(ms_codec_state_smooth(&s, 1, &err), MS_ERR_ARG);
    s.level = LEVEL;
    s.tris[4] = (uint32_t)s.vertex_count;
    assert_int_equal(ms_codec_state_smooth(&s, 1, &err), MS_ERR_CORRUPT);
    print_message("%s\n", err.text);
    assert_null(s.rep);
    ms_codec_state_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_plane_staircase),
        cmocka_unit_test(test_lone_triangle_by_hand),
        cmocka_unit_test(test_order_independent),
        cmocka_unit_test(test_refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
