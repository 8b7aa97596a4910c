/* The encoder's measured surface error (docs/CODEC.md §4.3,
 * ms_codec_encode_params.surface_error), against values worked out by hand:
 *   - a cube's corners, each alone in its kd-cell from bit 1 on, drawn at the
 *     centre of the one descendant a bit down that geometry ahead knows: the
 *     whole distance from the corner, exactly;
 *   - a flat square sampled on a grid: its vertices slide along it, and only
 *     how far the drawn points leave its plane counts (at most half a
 *     descendant's height), far below the half-diagonal;
 *   - the same square folded at a right angle: the vertices on the fold are
 *     sharp, so theirs is the whole distance again;
 *   - the summary a parent measures against: per start vertex its extremes;
 *   - with smoothing (docs/CODEC.md §4.4): the cube's corners measured from
 *     the points a client draws, the decoded state smoothed.
 * Exact at full precision: 0. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_mesh.h"
#include "ms_quant.h"

#define BITS 10u

/* Measures mesh's surface error at every bit (errors[BITS + 1], grid units),
 * geometry ahead 3 kd-levels as the bake draws, smoothed by `rounds` below full
 * precision; *summary when not NULL; the stream into *stream (the caller
 * frees it) and the quantised mesh into *qm when not NULL. */
static void measure_smoothed(const ms_mesh *mesh, unsigned rounds, double *errors, ms_codec_truth *summary,
                             uint8_t **stream, size_t *stream_size, ms_qmesh *qm)
{
    ms_error err;
    ms_qmesh q;
    memset(&q, 0, sizeof q);
    if (ms_quantise_mesh(mesh, BITS, &q, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_codec_state full;
    assert_int_equal(ms_codec_state_from_qmesh(&q, &full, &err), MS_OK);
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box = q.box;
    par.ahead = 3;
    par.surface_error = errors;
    par.summary = summary;
    par.smooth_rounds = rounds;
    par.smooth_level = 3 * BITS;
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_codec_state start;
    if (ms_codec_encode(&full, &par, &buf, &size, summary ? &start : NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    if (summary)
        ms_codec_state_free(&start);
    if (stream)
        *stream = buf, *stream_size = size;
    else
        free(buf);
    ms_codec_state_free(&full);
    if (qm)
        *qm = q;
    else
        ms_qmesh_free(&q);
}

static void measure(const ms_mesh *mesh, double *errors, ms_codec_truth *summary)
{
    measure_smoothed(mesh, 0, errors, summary, NULL, NULL, NULL);
}

static void add_vertex(ms_mesh *m, double x, double y, double z)
{
    double *p = m->positions + 3 * m->vertex_count++;
    p[0] = x, p[1] = y, p[2] = z;
}

static void add_triangle(ms_mesh *m, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t *t = m->triangles + 3 * m->triangle_count++;
    t[0] = a, t[1] = b, t[2] = c;
}

static void unit_cube(ms_mesh *m)
{
    memset(m, 0, sizeof *m);
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, 8, 12, &err), MS_OK);
    for (int v = 0; v < 8; ++v)
        add_vertex(m, v & 1, (v >> 1) & 1, (v >> 2) & 1);
    static const uint32_t faces[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                                          {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
    for (int f = 0; f < 12; ++f)
        add_triangle(m, faces[f][0], faces[f][1], faces[f][2]);
}

static void test_cube_corners(void **state)
{
    (void)state;
    ms_mesh m;
    unit_cube(&m);
    double errors[BITS + 1];
    measure(&m, errors, NULL);
    /* a corner's grid point is 0.5 inside its extreme cell; the descendant a
     * bit down is 2^(P - b - 1) cells wide */
    for (unsigned b = 1; b + 2 <= BITS; ++b)
        assert_float_equal(errors[b], sqrt(3.0) * (ldexp(1.0, (int)(BITS - b) - 2) - 0.5), 1e-9);
    /* a bit short, geometry ahead knows the grid point itself */
    assert_float_equal(errors[BITS - 1], 0.0, 0.0);
    assert_float_equal(errors[BITS], 0.0, 0.0);
    ms_mesh_free(&m);
}

/* The cube smoothed (3 rounds below full precision): each corner is sharp and
 * alone in its kd-cell, so the error is the largest whole distance from a
 * corner to the point drawn for it, here worked out from the stream decoded
 * at every bit and its state smoothed as a client does. */
static void test_smoothed_cube_corners(void **state)
{
    (void)state;
    ms_mesh m;
    unit_cube(&m);
    double plain[BITS + 1], smoothed[BITS + 1];
    measure(&m, plain, NULL);
    uint8_t *stream;
    size_t size;
    ms_qmesh q;
    measure_smoothed(&m, 3, smoothed, NULL, &stream, &size, &q);
    ms_codec_decoder *d;
    ms_error err;
    assert_int_equal(ms_codec_decoder_create(stream, size, NULL, NULL, &d, &err), MS_OK);
    for (unsigned b = 1; b < BITS; ++b) {
        assert_int_equal(ms_codec_decoder_set_level(d, 3 * b, &err), MS_OK);
        ms_codec_state st;
        assert_int_equal(ms_codec_decoder_state(d, &st, &err), MS_OK);
        assert_int_equal(ms_codec_state_smooth(&st, 3, &err), MS_OK);
        assert_int_equal(st.vertex_count, 8);
        double worst = 0;
        for (size_t k = 0; k < st.vertex_count; ++k) {
            uint32_t xyz[3];
            ms_quant_unkey(st.cells[k] << (3 * BITS - st.level), BITS, xyz);
            double p[3], best = INFINITY;
            for (int a = 0; a < 3; ++a)
                p[a] = xyz[a] + st.rep[3 * k + a] / 65536.0 * (double)(1u << (BITS - b));
            /* the corner in this kd-cell: the grid point nearest its centre */
            for (size_t v = 0; v < q.vertex_count; ++v) {
                double d2 = 0;
                for (int a = 0; a < 3; ++a) {
                    double c = q.coords[3 * v + a] + 0.5 - p[a];
                    d2 += c * c;
                }
                if ((ms_quant_key(q.coords[3 * v], q.coords[3 * v + 1], q.coords[3 * v + 2], BITS) >>
                     (3 * (BITS - b))) == st.cells[k])
                    best = sqrt(d2);
            }
            assert_true(isfinite(best));
            worst = best > worst ? best : worst;
        }
        assert_float_equal(smoothed[b], worst, 1e-9);
        print_message("bit %u: %.3f plain, %.3f smoothed\n", b, plain[b], smoothed[b]);
        /* bits 1 and 2: lambda's pull wins, the corner is drawn farther in;
         * from bit 3 mu's push takes it to its cell's outer corner, half a
         * grid cell from the vertex's point on every axis */
        if (b < 3)
            assert_true(smoothed[b] > plain[b]);
        else
            assert_float_equal(smoothed[b], 0.5 * sqrt(3.0), 1e-9);
        ms_codec_state_free(&st);
    }
    assert_float_equal(smoothed[BITS], 0.0, 0.0);
    ms_codec_decoder_destroy(d);
    free(stream);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

/* A square of n x n quads in the plane z = 0.5 of the unit box; with `fold`,
 * its half x > 0.5 turned up into the plane x = 0.5 (a right-angled fold). */
static void square(ms_mesh *m, unsigned n, bool fold)
{
    ms_error err;
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_mesh_reserve(m, (size_t)(n + 1) * (n + 1), 2 * (size_t)n * n, &err), MS_OK);
    for (unsigned j = 0; j <= n; ++j)
        for (unsigned i = 0; i <= n; ++i) {
            double x = (double)i / n, y = (double)j / n;
            if (fold && x > 0.5)
                add_vertex(m, 0.5, y, 0.5 + (x - 0.5));
            else
                add_vertex(m, x, y, 0.5);
        }
    for (unsigned j = 0; j < n; ++j)
        for (unsigned i = 0; i < n; ++i) {
            uint32_t a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
            add_triangle(m, a, b, d);
            add_triangle(m, a, d, c);
        }
}

static void test_flat_and_folded(void **state)
{
    (void)state;
    ms_mesh flat, folded;
    square(&flat, 64, false);
    square(&folded, 64, true);
    double e_flat[BITS + 1], e_folded[BITS + 1];
    measure(&flat, e_flat, NULL);
    measure(&folded, e_folded, NULL);
    for (unsigned b = 2; b + 2 <= BITS; ++b) {
        double half_diagonal = 0.5 * sqrt(3.0) * ldexp(1.0, (int)(BITS - b));
        /* off the plane by at most half a descendant's height (its own grid
         * cell's half included) */
        assert_true(e_flat[b] <= ldexp(1.0, (int)(BITS - b) - 2) + 0.5);
        assert_true(e_flat[b] < 0.35 * half_diagonal);
        /* the fold's vertices lie 16 grid cells apart along it, each alone in
         * its kd-cell from bit 6 on: their whole distance, as the cube's */
        if (b >= 6) {
            assert_true(e_folded[b] >= sqrt(3.0) * (ldexp(1.0, (int)(BITS - b) - 2) - 0.5) - 1e-9);
            assert_true(e_folded[b] > e_flat[b]);
        }
    }
    assert_float_equal(e_flat[BITS], 0.0, 0.0);
    assert_float_equal(e_folded[BITS], 0.0, 0.0);
    ms_mesh_free(&flat);
    ms_mesh_free(&folded);
}

/* The summary: at most four points per start vertex (from p_min 0: the one
 * root vertex), inside the box, the sharp ones with zero normals. */
static void test_summary(void **state)
{
    (void)state;
    ms_mesh folded;
    square(&folded, 16, true);
    double errors[BITS + 1];
    ms_codec_truth summary;
    memset(&summary, 0, sizeof summary);
    measure(&folded, errors, &summary);
    /* the root's one vertex: two extremes along the summed normal, and two
     * of the fold's sharp vertices */
    assert_int_equal(summary.n, 4);
    unsigned sharp = 0;
    for (size_t i = 0; i < summary.n; ++i) {
        const float *nv = summary.normals + 3 * i;
        sharp += nv[0] == 0 && nv[1] == 0 && nv[2] == 0;
        for (int a = 0; a < 3; ++a)
            assert_true(summary.positions[3 * i + a] >= 0 && summary.positions[3 * i + a] <= 1 << BITS);
    }
    assert_int_equal(sharp, 2);
    ms_codec_truth_free(&summary);
    ms_mesh_free(&folded);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_cube_corners),
        cmocka_unit_test(test_smoothed_cube_corners),
        cmocka_unit_test(test_flat_and_folded),
        cmocka_unit_test(test_summary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
