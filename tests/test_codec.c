/* Codec: quantisation, range coder, hard cases, stream handling (synthetic meshes). */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_codec_model.h"
#include "support/ms_codec_check.h"
#include "ms_quant.h"
#include "ms_rangecoder.h"

static void make_mesh(ms_mesh *m, const double *pos, size_t nv, const uint32_t *tris, size_t nt)
{
    ms_error err;
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_mesh_reserve(m, nv ? nv : 1, nt ? nt : 1, &err), MS_OK);
    if (nv)
        memcpy(m->positions, pos, nv * 3 * sizeof *pos);
    if (nt)
        memcpy(m->triangles, tris, nt * 3 * sizeof *tris);
    m->vertex_count = nv;
    m->triangle_count = nt;
}

/* ---- quantisation ---- */

static void test_key_interleave(void **state)
{
    (void)state;
    assert_true(ms_quant_key(1, 0, 0, 1) == 4);
    assert_true(ms_quant_key(0, 1, 0, 1) == 2);
    assert_true(ms_quant_key(0, 0, 1, 1) == 1);
    assert_true(ms_quant_key(2, 0, 0, 2) == 32);
    uint32_t xyz[3];
    uint32_t m = (1u << 20) - 1;
    ms_quant_unkey(ms_quant_key(m, 12345, 999999, 20), 20, xyz);
    assert_int_equal(xyz[0], m);
    assert_int_equal(xyz[1], 12345);
    assert_int_equal(xyz[2], 999999);
}

static void test_weld_counts(void **state)
{
    (void)state;
    /* vertices 0 and 3 coincide; triangle (0,1,3) degenerates; (3,1,2) duplicates
     * (0,1,2) after welding; vertex 4 is isolated. */
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 1};
    const uint32_t tris[] = {0, 1, 2, 0, 1, 3, 3, 2, 1};
    ms_mesh m;
    make_mesh(&m, pos, 5, tris, 3);
    ms_qmesh q;
    ms_weld_report r;
    ms_error err;
    assert_int_equal(ms_quantise_mesh(&m, 12, &q, &r, &err), MS_OK);
    assert_int_equal(q.vertex_count, 4);
    assert_int_equal(q.tri_count, 1);
    assert_int_equal(r.welded_vertices, 1);
    assert_int_equal(r.degenerate_triangles, 1);
    assert_int_equal(r.duplicate_triangles, 1);
    assert_int_equal(r.isolated_vertices, 1);
    assert_true(q.box.size == 1.0);
    /* max coordinate lands in the last cell */
    for (size_t i = 0; i < q.vertex_count; ++i)
        for (int a = 0; a < 3; ++a)
            assert_true(q.coords[3 * i + a] == 0 || q.coords[3 * i + a] == 4095);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

static void test_quant_errors(void **state)
{
    (void)state;
    ms_mesh m;
    ms_qmesh q;
    ms_error err;
    make_mesh(&m, NULL, 0, NULL, 0);
    assert_int_equal(ms_quantise_mesh(&m, 12, &q, NULL, &err), MS_ERR_EMPTY);
    assert_non_null(strstr(err.text, "empty"));
    ms_mesh_free(&m);
    const double pos[] = {0, 0, 0, NAN, 1, 0, 0, 1, 0};
    const uint32_t tri[] = {0, 1, 2};
    make_mesh(&m, pos, 3, tri, 1);
    assert_int_equal(ms_quantise_mesh(&m, 12, &q, NULL, &err), MS_ERR_RANGE);
    m.positions[3] = 1;
    assert_int_equal(ms_quantise_mesh(&m, 7, &q, NULL, &err), MS_ERR_ARG);
    assert_int_equal(ms_quantise_mesh(&m, 21, &q, NULL, &err), MS_ERR_ARG);
    m.triangles[1] = 9;
    assert_int_equal(ms_quantise_mesh(&m, 12, &q, NULL, &err), MS_ERR_RANGE);
    ms_mesh_free(&m);
}

/* ---- contexts ---- */

/* The "which half" bucket: the centroid's offset from the split plane in child
 * cells, |offset| against 1/8, 1/4, 1/2, 1, 2, 4 (format, docs/CODEC.md §4),
 * checked at every threshold and either side of it, for several widths and
 * neighbour counts, against the definition written out. */
static unsigned bucket_by_definition(int64_t diff, int64_t unit)
{
    int64_t a = 8 * (diff < 0 ? -diff : diff);
    unsigned m = 0;
    for (int64_t t = unit; t <= 32 * unit; t *= 2)
        m += a >= t;
    return diff < 0 ? 6 - m : 7 + m;
}

static void test_geo_bucket_thresholds(void **state)
{
    (void)state;
    const int64_t widths[] = {1, 2, 8, 1 << 20};
    const int64_t counts[] = {1, 2, 3, 7, 1000};
    unsigned seen[GEO_BUCKETS] = {0};
    for (size_t wi = 0; wi < sizeof widths / sizeof *widths; ++wi) {
        for (size_t ni = 0; ni < sizeof counts / sizeof *counts; ++ni) {
            int64_t wp = widths[wi], n = counts[ni], plane2 = 4 * wp + 6;
            for (int64_t t = n * wp; t <= 64 * n * wp; t *= 2) {
                /* offsets around the threshold t / 8 of a*8 = t, both signs */
                for (int64_t e = -2; e <= 2; ++e) {
                    for (int sign = -1; sign <= 1; sign += 2) {
                        int64_t diff = sign * (t / 8 + e);
                        int64_t sum = diff + n * plane2;
                        unsigned b = geo_bucket(sum, n, wp, plane2);
                        assert_int_equal(b, bucket_by_definition(diff, n * wp));
                        seen[b]++;
                    }
                }
            }
        }
    }
    for (unsigned b = 0; b < GEO_DIST; ++b)
        assert_true(seen[b] > 0); /* every bucket but "no neighbour" reached */
    assert_int_equal(geo_bucket(12345, 0, 8, 77), GEO_DIST);
    /* exact values, one neighbour, cell width 8 (child 4 grid units, 8 in the
     * doubled units of centres): on the plane 7; half a child cell above 7 + 3
     * (1/8, 1/4, 1/2 reached), one child cell above 7 + 4, below 6 - 4 */
    assert_int_equal(geo_bucket(100, 1, 8, 100), 7);
    assert_int_equal(geo_bucket(104, 1, 8, 100), 10);
    assert_int_equal(geo_bucket(108, 1, 8, 100), 11);
    assert_int_equal(geo_bucket(92, 1, 8, 100), 2);
    assert_int_equal(geo_bucket(100 + 1000, 1, 8, 100), 13);
    assert_int_equal(geo_bucket(100 - 1000, 1, 8, 100), 0);
}

/* ---- range coder ---- */

/* From any start inside [MS_RC_PROB_MIN, MS_RC_PROB_MAX], long runs of one
 * symbol drive both estimates to their fixed points and no further: P(0) stays
 * inside [71, 65464] / 65536, which is why the coder needs no clamp. */
static void test_rangecoder_probability_bounds(void **state)
{
    (void)state;
    for (uint32_t start = MS_RC_PROB_MIN; start <= MS_RC_PROB_MAX; start += 1009) {
        for (int bit = 0; bit < 2; ++bit) {
            ms_rc_prob p = {(uint16_t)start, (uint16_t)start};
            for (int i = 0; i < 4000; ++i) {
                ms_rc_update(&p, bit);
                uint32_t q = ms_rc_p0(&p);
                assert_true(q >= 71 && q <= 65464);
                assert_true(p.fast >= 15 && p.fast <= 65520);
                assert_true(p.slow >= 127 && p.slow <= 65408);
            }
            assert_int_equal(p.fast, bit ? 15 : 65520);
            assert_int_equal(p.slow, bit ? 127 : 65408);
            assert_int_equal(ms_rc_p0(&p), bit ? 71 : 65464);
            /* and a run of the other symbol leaves the fixed point at once */
            ms_rc_update(&p, !bit);
            assert_true(bit ? p.fast > 15 : p.fast < 65520);
        }
    }
}

/* The branch-free decode is the same coder: same bits, same probabilities,
 * same position, on skewed and on even decisions. */
static void test_rangecoder_unpredictable_decode(void **state)
{
    (void)state;
    ms_rc_encoder e;
    ms_rc_encoder_init(&e);
    ms_rc_prob p[3] = {MS_RC_PROB_INIT, MS_RC_PROB_INIT, {60000, 61000}};
    uint32_t x = 777;
    enum { N = 200000 };
    for (int i = 0; i < N; ++i) {
        x = x * 1103515245u + 12345u;
        int ctx = i % 3;
        int bit = ((x >> 16) % 100) < (unsigned)(ctx == 0 ? 50 : ctx == 1 ? 10 : 97);
        ms_rc_encode(&e, &p[ctx], bit);
    }
    ms_rc_encoder_flush(&e);
    assert_false(e.failed);
    ms_rc_prob a[3] = {MS_RC_PROB_INIT, MS_RC_PROB_INIT, {60000, 61000}};
    ms_rc_prob b[3] = {MS_RC_PROB_INIT, MS_RC_PROB_INIT, {60000, 61000}};
    ms_rc_decoder da, db;
    ms_rc_decoder_init(&da, e.buf, e.size);
    ms_rc_decoder_init(&db, e.buf, e.size);
    x = 777;
    unsigned ones = 0;
    for (int i = 0; i < N; ++i) {
        x = x * 1103515245u + 12345u;
        int ctx = i % 3;
        int bit = ((x >> 16) % 100) < (unsigned)(ctx == 0 ? 50 : ctx == 1 ? 10 : 97);
        int ba = ms_rc_decode(&da, &a[ctx]);
        int bb = ms_rc_decode_unpredictable(&db, &b[ctx]);
        assert_int_equal(ba, bit);
        assert_int_equal(bb, bit);
        assert_int_equal(da.range, db.range);
        assert_int_equal(da.code, db.code);
        assert_int_equal(a[ctx].fast, b[ctx].fast);
        assert_int_equal(a[ctx].slow, b[ctx].slow);
        ones += (unsigned)bb;
    }
    assert_true(ms_rc_decoder_clean_end(&db));
    assert_int_equal(da.pos, db.pos);
    assert_true(ones > N / 3 && ones < 2 * N / 3); /* both symbols decoded often */
    ms_rc_encoder_free(&e);
}

static void test_rangecoder_roundtrip(void **state)
{
    (void)state;
    ms_rc_encoder e;
    ms_rc_encoder_init(&e);
    ms_rc_prob p[4] = {MS_RC_PROB_INIT, MS_RC_PROB_INIT, MS_RC_PROB_INIT, MS_RC_PROB_INIT};
    uint32_t x = 12345;
    size_t ends[2];
    for (int chunk = 0; chunk < 2; ++chunk) {
        for (int i = 0; i < 100000; ++i) {
            x = x * 1103515245u + 12345u;
            int ctx = i & 3;
            int bit = ((x >> 16) % 100) < (unsigned)(ctx * 30 + 2);
            ms_rc_encode(&e, &p[ctx], bit);
        }
        ms_rc_encoder_flush(&e);
        ends[chunk] = e.size;
    }
    assert_false(e.failed);
    ms_rc_prob q[4] = {MS_RC_PROB_INIT, MS_RC_PROB_INIT, MS_RC_PROB_INIT, MS_RC_PROB_INIT};
    x = 12345;
    size_t start = 0;
    for (int chunk = 0; chunk < 2; ++chunk) {
        ms_rc_decoder d;
        ms_rc_decoder_init(&d, e.buf + start, ends[chunk] - start);
        for (int i = 0; i < 100000; ++i) {
            x = x * 1103515245u + 12345u;
            int ctx = i & 3;
            int bit = ((x >> 16) % 100) < (unsigned)(ctx * 30 + 2);
            assert_int_equal(ms_rc_decode(&d, &q[ctx]), bit);
        }
        assert_true(ms_rc_decoder_clean_end(&d));
        start = ends[chunk];
    }
    /* A truncated chunk reads zeros and reports the overrun. */
    ms_rc_decoder d;
    ms_rc_decoder_init(&d, e.buf, ends[0] / 2);
    for (int i = 0; i < 100000; ++i)
        (void)ms_rc_decode(&d, &q[i & 3]);
    assert_false(ms_rc_decoder_clean_end(&d));
    ms_rc_encoder_free(&e);
}

/* ---- hard cases ---- */

/* Round trip of m at `bits` (ms_codec_check_roundtrip, level step 1), which must
 * keep want_v vertices and want_t triangles; *r gets the figures. */
static void check_counts(const ms_mesh *m, unsigned bits, size_t want_v, size_t want_t, ms_codec_check_result *r)
{
    ms_codec_check_roundtrip(m, bits, 1, r);
    assert_int_equal(r->vertices, want_v);
    assert_int_equal(r->triangles, want_t);
}

static void check_case(const double *pos, size_t nv, const uint32_t *tris, size_t nt,
                       unsigned bits, size_t want_v, size_t want_t)
{
    ms_mesh m;
    make_mesh(&m, pos, nv, tris, nt);
    ms_codec_check_result r;
    check_counts(&m, bits, want_v, want_t, &r);
    ms_mesh_free(&m);
}

static void test_single_triangle(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t t[] = {0, 1, 2};
    check_case(pos, 3, t, 1, 12, 3, 1);
    check_case(pos, 3, t, 1, 16, 3, 1);
}

static void test_two_disjoint_triangles(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5, 6, 5, 5, 5, 6, 5.5};
    const uint32_t t[] = {0, 1, 2, 3, 5, 4};
    check_case(pos, 6, t, 2, 12, 6, 2);
}

static void test_nonmanifold_edge_four_triangles(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 0, 0, 1, 1, 0, .5, -1, 0, .5, 0, 1, .5, 0, -1, .5};
    const uint32_t t[] = {0, 1, 2, 1, 0, 3, 0, 1, 4, 1, 0, 5};
    check_case(pos, 6, t, 4, 12, 6, 4);
}

static void test_bowtie(void **state)
{
    (void)state;
    /* two cones (fans of 4 triangles) sharing only their apex */
    const double pos[] = {0, 0, 0,  1, 1, 1, -1, 1, 1, -1, -1, 1, 1, -1, 1,
                          1, 1, -1, -1, 1, -1, -1, -1, -1, 1, -1, -1};
    const uint32_t t[] = {0, 1, 2, 0, 2, 3, 0, 3, 4, 0, 4, 1,
                          0, 6, 5, 0, 7, 6, 0, 8, 7, 0, 5, 8};
    check_case(pos, 9, t, 8, 12, 9, 8);
}

static void test_isolated_vertices(void **state)
{
    (void)state;
    const double pos[] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 3, 3, 3, 2, 0, 1, 0, 2, 2};
    const uint32_t t[] = {0, 1, 2};
    ms_mesh m;
    make_mesh(&m, pos, 6, t, 1);
    ms_codec_check_result r;
    check_counts(&m, 12, 6, 1, &r);
    assert_int_equal(r.weld.isolated_vertices, 3);
    ms_mesh_free(&m);
    /* only isolated vertices: a point cloud */
    make_mesh(&m, pos, 6, NULL, 0);
    check_counts(&m, 12, 6, 0, &r);
    ms_mesh_free(&m);
}

static void test_all_coincident(void **state)
{
    (void)state;
    const double pos[] = {2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2, 2};
    const uint32_t t[] = {0, 1, 2, 1, 2, 3};
    ms_mesh m;
    make_mesh(&m, pos, 4, t, 2);
    ms_codec_check_result r;
    check_counts(&m, 12, 1, 0, &r);
    assert_int_equal(r.weld.welded_vertices, 3);
    assert_int_equal(r.weld.degenerate_triangles, 2);
    assert_int_equal(r.weld.isolated_vertices, 1);
    ms_mesh_free(&m);
}

static void grid(ms_mesh *m, unsigned n, double ox, double oy, double oz, double step, int flat_axes)
{
    ms_error err;
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_mesh_reserve(m, n * n, 2 * (n - 1) * (n - 1), &err), MS_OK);
    for (unsigned i = 0; i < n; ++i)
        for (unsigned j = 0; j < n; ++j) {
            double *p = &m->positions[3 * (i * n + j)];
            p[0] = ox + i * step;
            p[1] = oy + (flat_axes >= 2 ? 0 : j * step);
            p[2] = oz + (flat_axes >= 1 ? 0 : (double)((i * 7 + j * 3) % 5) * step);
            if (flat_axes >= 2)
                p[0] = ox + (i * n + j) * step;
        }
    size_t t = 0;
    for (unsigned i = 0; i + 1 < n; ++i)
        for (unsigned j = 0; j + 1 < n; ++j) {
            uint32_t a = i * n + j, b = a + n, c = a + n + 1, d = a + 1;
            uint32_t *x = &m->triangles[3 * t];
            x[0] = a, x[1] = b, x[2] = c, x[3] = a, x[4] = c, x[5] = d;
            t += 2;
        }
    m->vertex_count = n * n;
    m->triangle_count = t;
}

/* An n x n unit grid at the origin with flat_axes axes flattened, at 12 bits. */
static void check_flat_grid(unsigned n, int flat_axes, size_t want_v, size_t want_t)
{
    ms_mesh m;
    grid(&m, n, 0, 0, 0, 1, flat_axes);
    ms_codec_check_result r;
    check_counts(&m, 12, want_v, want_t, &r);
    ms_mesh_free(&m);
}

static void test_flat_model(void **state)
{
    (void)state;
    check_flat_grid(10, 1, 100, 162);
}

static void test_needle(void **state)
{
    (void)state;
    /* every point on the x axis: triangles are zero-area but have distinct vertices */
    check_flat_grid(6, 2, 36, 50);
}

static void test_large_offset_small_extent(void **state)
{
    (void)state;
    ms_mesh m;
    grid(&m, 8, 1e7, -1e7, 1e7, 1e-3 / 7, 0);
    ms_codec_check_result r;
    check_counts(&m, 16, 64, 98, &r);
    /* dequantised points lie within half a cell of the input */
    ms_qmesh q;
    ms_error err;
    assert_int_equal(ms_quantise_mesh(&m, 16, &q, NULL, &err), MS_OK);
    assert_true(fabs(q.box.size - 1e-3) < 1e-8);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

static void test_precision_8_and_20(void **state)
{
    (void)state;
    ms_mesh m;
    ms_test_torus(&m, 24, 16, 1.0, 0.3);
    ms_codec_check_result r;
    check_counts(&m, 20, 384, 768, &r);
    check_counts(&m, 8, 384, 768, &r);
    ms_mesh_free(&m);
    /* a dense torus at 8 bits welds vertices and drops collapsed triangles */
    ms_test_torus(&m, 400, 100, 1.0, 0.3);
    ms_codec_check_roundtrip(&m, 8, 3, &r);
    assert_true(r.weld.welded_vertices > 0);
    assert_int_equal(r.vertices, 40000 - r.weld.welded_vertices);
    assert_int_equal(r.triangles, 80000 - r.weld.degenerate_triangles - r.weld.duplicate_triangles);
    ms_mesh_free(&m);
}

static void test_empty_mesh_errors(void **state)
{
    (void)state;
    ms_codec_state s;
    memset(&s, 0, sizeof s);
    s.bits = 12;
    s.level = 36;
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1;
    uint8_t *buf;
    size_t size;
    ms_error err;
    assert_int_equal(ms_codec_encode(&s, &par, &buf, &size, NULL, &err), MS_ERR_EMPTY);
    assert_non_null(strstr(err.text, "empty"));
    assert_null(buf);
}

/* A mixed-dimension complex given directly as a state: a triangle, a dangling
 * edge, an isolated edge and an isolated vertex, all carried losslessly; and the
 * encoder's input checks. */
static void test_edges_in_input_complex(void **state)
{
    (void)state;
    ms_error err;
    uint64_t cells[7];
    const uint32_t q[7][3] = {{0, 0, 0}, {100, 0, 0}, {0, 100, 0}, {200, 200, 0},
                              {900, 900, 900}, {950, 880, 870}, {500, 20, 700}};
    for (int i = 0; i < 7; ++i)
        cells[i] = ms_quant_key(q[i][0], q[i][1], q[i][2], 10);
    uint32_t tris[3] = {0, 1, 2};
    uint32_t edges[4] = {2, 3, 4, 5};
    ms_codec_state full = {.bits = 10, .level = 30, .vertex_count = 7, .tri_count = 1,
                           .edge_count = 2, .cells = cells, .tris = tris, .edges = edges};
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1;
    uint8_t *buf;
    size_t size;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_OK);
    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(buf, size, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(d, 30, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_vertex_count(d), 7);
    assert_int_equal(ms_codec_decoder_tri_count(d), 1);
    assert_int_equal(ms_codec_decoder_edge_count(d), 2);
    ms_codec_state got, want = {0};
    assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
    want.bits = 10, want.level = 30, want.vertex_count = 7, want.tri_count = 1,
    want.edge_count = 2;
    want.cells = malloc(sizeof cells);
    want.tris = malloc(sizeof tris);
    want.edges = malloc(sizeof edges);
    memcpy(want.cells, cells, sizeof cells);
    memcpy(want.tris, tris, sizeof tris);
    memcpy(want.edges, edges, sizeof edges);
    assert_int_equal(ms_codec_state_canonicalise(&want, &err), MS_OK);
    assert_true(ms_codec_state_equal(&got, &want, true));
    /* at level 0 everything is one vertex */
    assert_int_equal(ms_codec_decoder_set_level(d, 0, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_vertex_count(d), 1);
    assert_int_equal(ms_codec_decoder_tri_count(d), 0);
    assert_int_equal(ms_codec_decoder_edge_count(d), 0);
    ms_codec_state_free(&got);
    ms_codec_state_free(&want);
    ms_codec_decoder_destroy(d);
    free(buf);
    /* invalid inputs */
    edges[0] = 0, edges[1] = 1; /* a face of the triangle: not maximal */
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
    edges[0] = 2, edges[1] = 3;
    uint32_t two[6] = {0, 1, 2, 2, 1, 0};
    full.tris = two;
    full.tri_count = 2;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "duplicate"));
    full.tri_count = 1;
    cells[1] = cells[0];
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
    cells[1] = 1ull << 30;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
}

/* The encoder's duplicate check looks at the triangles grouped by their
 * smallest vertex: an open fan of 23 triangles round vertex 0, the smallest key
 * (every other vertex lies above it on each axis), a group past the short one's
 * pairwise comparison, encodes; the same fan with one triangle repeated in the
 * same or the opposite orientation is refused, and so is a repeat in a short
 * group. */
static void test_duplicate_in_wide_group(void **state)
{
    (void)state;
    enum { RIM = 24, FAN = RIM - 1 };
    uint64_t cells[RIM + 1];
    cells[0] = ms_quant_key(5, 5, 5, 10);
    for (unsigned i = 0; i < RIM; ++i) { /* a quarter circle above the centre */
        double a = 1.5707963267949 * i / (RIM - 1);
        cells[i + 1] = ms_quant_key((uint32_t)(5 + 400 * cos(a)), (uint32_t)(5 + 400 * sin(a)),
                                    5 + i, 10);
    }
    uint32_t tris[3 * (FAN + 1)];
    for (unsigned i = 0; i < FAN; ++i) {
        tris[3 * i] = 0;
        tris[3 * i + 1] = 1 + i;
        tris[3 * i + 2] = 2 + i;
    }
    ms_codec_state full = {.bits = 10, .level = 30, .vertex_count = RIM + 1, .tri_count = FAN,
                           .cells = cells, .tris = tris};
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1;
    uint8_t *buf;
    size_t size;
    ms_error err;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_OK);
    free(buf);
    const uint32_t repeats[3][3] = {{0, 9, 8},   /* triangle 7, opposite orientation */
                                    {11, 12, 0}, /* triangle 10, rotated */
                                    {4, 3, 0}};  /* triangle 2, reversed */
    full.tri_count = FAN + 1;
    for (int r = 0; r < 3; ++r) {
        memcpy(&tris[3 * FAN], repeats[r], sizeof repeats[r]);
        assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
        assert_non_null(strstr(err.text, "duplicate triangle"));
    }
    /* a repeat in a short group: one triangle of the fan, another twice */
    uint32_t three[9] = {1, 2, 3, 3, 2, 1, 0, 1, 2};
    full.tris = three;
    full.tri_count = 3;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "duplicate triangle"));
}

/* ---- streams ---- */

typedef struct coded {
    ms_codec_state full, canon;
    uint8_t *buf;
    size_t size;
    unsigned bits;
} coded;

static void code_torus(coded *c, unsigned bits, unsigned p_min, ms_codec_state *start)
{
    ms_mesh m;
    ms_test_torus(&m, 60, 30, 1.0, 0.35);
    ms_qmesh q;
    ms_error err;
    assert_int_equal(ms_quantise_mesh(&m, bits, &q, NULL, &err), MS_OK);
    assert_int_equal(ms_codec_state_from_qmesh(&q, &c->full, &err), MS_OK);
    assert_int_equal(ms_codec_state_from_qmesh(&q, &c->canon, &err), MS_OK);
    assert_int_equal(ms_codec_state_canonicalise(&c->canon, &err), MS_OK);
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box = q.box;
    par.p_min = p_min;
    assert_int_equal(ms_codec_encode(&c->full, &par, &c->buf, &c->size, start, &err), MS_OK);
    c->bits = bits;
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

static void free_coded(coded *c)
{
    ms_codec_state_free(&c->full);
    ms_codec_state_free(&c->canon);
    free(c->buf);
}

/* d decoded to `level` holds exactly want (canonical state, orientation included). */
static void expect_decoded(ms_codec_decoder *d, unsigned level, const ms_codec_state *want)
{
    ms_error err;
    assert_int_equal(ms_codec_decoder_set_level(d, level, &err), MS_OK);
    ms_codec_state got;
    assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
    assert_true(ms_codec_state_equal(&got, want, true));
    ms_codec_state_free(&got);
}

static void test_subrange_from_start_state(void **state)
{
    (void)state;
    ms_error err;
    coded all, part;
    ms_codec_state start;
    code_torus(&all, 12, 0, NULL);
    code_torus(&part, 12, 5, &start);
    assert_int_equal(start.level, 15);
    /* the start state is what the full stream's decoder gives at 5 bits */
    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(all.buf, all.size, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(d, 15, &err), MS_OK);
    ms_codec_state at5;
    assert_int_equal(ms_codec_decoder_state(d, &at5, &err), MS_OK);
    assert_true(ms_codec_state_equal(&at5, &start, true));
    ms_codec_decoder_destroy(d);
    /* the sub-range stream continues from it to the full mesh */
    assert_int_equal(ms_codec_decoder_create(part.buf, part.size, &at5, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_min_level(d), 15);
    expect_decoded(d, 36, &part.canon);
    /* cannot coarsen below the window */
    assert_int_equal(ms_codec_decoder_set_level(d, 14, &err), MS_ERR_ARG);
    ms_codec_decoder_destroy(d);
    /* a different start state is refused */
    at5.cells[0] ^= 1;
    assert_int_equal(ms_codec_decoder_create(part.buf, part.size, &at5, NULL, &d, &err),
                     MS_ERR_ARG);
    assert_int_equal(ms_codec_decoder_create(part.buf, part.size, NULL, NULL, &d, &err),
                     MS_ERR_ARG);
    ms_codec_state_free(&at5);
    ms_codec_state_free(&start);
    free_coded(&all);
    free_coded(&part);
}

/* The nSP-tree chain: a parent stream over [0, 5] codes the complex at 5 bits;
 * its decoder's final state starts the child stream over [5, 12]. */
static void test_parent_child_chain(void **state)
{
    (void)state;
    ms_error err;
    coded child;
    ms_codec_state start;
    code_torus(&child, 12, 5, &start);
    ms_codec_state parent_full = start; /* the complex at 5 bits, in a 15-bit key space */
    parent_full.bits = 5;
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box.size = 1;
    uint8_t *pbuf;
    size_t psize;
    assert_int_equal(ms_codec_encode(&parent_full, &par, &pbuf, &psize, NULL, &err), MS_OK);
    ms_codec_decoder *pd, *cd;
    assert_int_equal(ms_codec_decoder_create(pbuf, psize, NULL, NULL, &pd, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(pd, 15, &err), MS_OK);
    ms_codec_state handoff;
    assert_int_equal(ms_codec_decoder_state(pd, &handoff, &err), MS_OK);
    assert_int_equal(handoff.bits, 5);
    assert_int_equal(handoff.level, 15);
    assert_true(ms_codec_state_equal(&handoff, &start, true));
    assert_int_equal(ms_codec_decoder_create(child.buf, child.size, &handoff, NULL, &cd, &err),
                     MS_OK);
    expect_decoded(cd, 36, &child.canon);
    ms_codec_state_free(&handoff);
    ms_codec_decoder_destroy(pd);
    ms_codec_decoder_destroy(cd);
    free(pbuf);
    ms_codec_state_free(&start);
    free_coded(&child);
}

/* The torus coded at 12 bits from the start, and its stream's header. */
static void code_torus_with_header(coded *c, ms_codec_header *h)
{
    code_torus(c, 12, 0, NULL);
    ms_error err;
    assert_int_equal(ms_codec_read_header(c->buf, c->size, h, &err), MS_OK);
}

static void test_prefix_and_truncation(void **state)
{
    (void)state;
    ms_error err;
    coded c;
    ms_codec_header h;
    code_torus_with_header(&c, &h);
    assert_int_equal(h.p_max, 12);
    assert_int_equal(h.header_size + h.body_size, c.size);
    /* a prefix ending inside bit 8 decodes exactly up to 7 bits */
    size_t cut = h.header_size + h.chunk_end[6] + 2;
    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(c.buf, cut, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_available_level(d), 21);
    assert_int_equal(ms_codec_decoder_set_level(d, 21, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(d, 22, &err), MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "truncated"));
    ms_codec_state a;
    assert_int_equal(ms_codec_decoder_state(d, &a, &err), MS_OK);
    assert_int_equal(a.level, 21);
    ms_codec_state_free(&a);
    ms_codec_decoder_destroy(d);
    /* header cut short */
    assert_int_equal(ms_codec_decoder_create(c.buf, 40, NULL, NULL, &d, &err), MS_ERR_FORMAT);
    assert_int_equal(ms_codec_decoder_create(c.buf, h.header_size - 1, NULL, NULL, &d, &err),
                     MS_ERR_FORMAT);
    free_coded(&c);
}

static void test_corruption_detected(void **state)
{
    (void)state;
    ms_error err;
    coded c;
    ms_codec_header h;
    code_torus_with_header(&c, &h);
    ms_codec_decoder *d;
    /* bad magic */
    c.buf[0] = 'X';
    assert_int_equal(ms_codec_decoder_create(c.buf, c.size, NULL, NULL, &d, &err), MS_ERR_FORMAT);
    c.buf[0] = 'M';
    /* unknown version */
    assert_int_equal(c.buf[4], MS_CODEC_VERSION);
    c.buf[4] = MS_CODEC_VERSION + 1;
    assert_int_equal(ms_codec_decoder_create(c.buf, c.size, NULL, NULL, &d, &err),
                     MS_ERR_UNSUPPORTED);
    c.buf[4] = MS_CODEC_VERSION;
    /* header byte flipped: header CRC */
    c.buf[61] ^= 0x40;
    assert_int_equal(ms_codec_decoder_create(c.buf, c.size, NULL, NULL, &d, &err),
                     MS_ERR_CORRUPT);
    c.buf[61] ^= 0x40;
    /* body byte flipped: chunk CRC, or (CRC skipped) a structural failure or a
     * different complex, never a crash */
    size_t pos = h.header_size + h.chunk_end[8] + 3;
    c.buf[pos] ^= 0x10;
    assert_int_equal(ms_codec_decoder_create(c.buf, c.size, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(d, 36, &err), MS_ERR_CORRUPT);
    assert_non_null(strstr(err.text, "checksum"));
    assert_int_equal(ms_codec_decoder_set_level(d, 3, &err), MS_ERR_CORRUPT);
    assert_int_equal(ms_codec_decoder_extend(d, c.buf, c.size, &err), MS_ERR_CORRUPT);
    ms_codec_decoder_destroy(d);
    ms_codec_decoder_options opt = {.skip_crc = true};
    assert_int_equal(ms_codec_decoder_create(c.buf, c.size, NULL, &opt, &d, &err), MS_OK);
    ms_status st = ms_codec_decoder_set_level(d, 36, &err);
    if (st == MS_OK) {
        ms_codec_state got;
        assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
        assert_false(ms_codec_state_equal(&got, &c.canon, true));
        ms_codec_state_free(&got);
    } else {
        assert_int_equal(st, MS_ERR_CORRUPT);
    }
    ms_codec_decoder_destroy(d);
    free_coded(&c);
}

/* A decoder extended bit by bit with longer prefixes decodes exactly what a fresh
 * decoder over the same prefix does, at every level (also from mid-chunk levels),
 * and refuses bytes that do not continue its stream. */
static void test_extend_with_longer_prefixes(void **state)
{
    (void)state;
    ms_error err;
    coded c;
    ms_codec_header h;
    code_torus_with_header(&c, &h);
    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(c.buf, h.header_size, NULL, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_available_level(d), 0);
    for (unsigned k = 0; k < h.p_max; ++k) {
        size_t prefix = h.header_size + h.chunk_end[k];
        /* a shorter prefix, or one with another header, is not a continuation */
        assert_int_equal(ms_codec_decoder_extend(d, c.buf, h.header_size - 1, &err), MS_ERR_ARG);
        c.buf[40] ^= 1;
        assert_int_equal(ms_codec_decoder_extend(d, c.buf, prefix, &err), MS_ERR_ARG);
        c.buf[40] ^= 1;
        assert_int_equal(ms_codec_decoder_extend(d, c.buf, prefix, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_available_level(d), 3 * (k + 1));
        /* stop mid-chunk once, so the range decoder is inside the moved bytes */
        unsigned target = 3 * (k + 1) - (k % 2 ? 1 : 0);
        assert_int_equal(ms_codec_decoder_set_level(d, target, &err), MS_OK);
        ms_codec_decoder *fresh;
        assert_int_equal(ms_codec_decoder_create(c.buf, prefix, NULL, NULL, &fresh, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_set_level(fresh, target, &err), MS_OK);
        ms_codec_state a, b;
        assert_int_equal(ms_codec_decoder_state(d, &a, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_state(fresh, &b, &err), MS_OK);
        assert_true(ms_codec_state_equal(&a, &b, true));
        ms_codec_state_free(&a);
        ms_codec_state_free(&b);
        ms_codec_decoder_destroy(fresh);
    }
    expect_decoded(d, 36, &c.canon);
    /* the same bytes again: nothing to do */
    assert_int_equal(ms_codec_decoder_extend(d, c.buf, c.size, &err), MS_OK);
    ms_codec_decoder_destroy(d);
    free_coded(&c);
}

static void test_torus_levels_and_size(void **state)
{
    (void)state;
    ms_mesh m;
    ms_test_torus(&m, 60, 30, 1.0, 0.35);
    ms_codec_check_result r;
    check_counts(&m, 16, 1800, 3600, &r);
    /* a smooth closed surface must code well below raw 16-bit coordinates */
    print_message("torus 1800 vertices at 16 bits: %zu bytes, %.2f bits/vertex\n", r.bytes,
                  8.0 * r.bytes / r.vertices);
    assert_true(r.bytes * 8 < 40 * r.vertices);
    ms_mesh_free(&m);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_key_interleave),
        cmocka_unit_test(test_weld_counts),
        cmocka_unit_test(test_quant_errors),
        cmocka_unit_test(test_geo_bucket_thresholds),
        cmocka_unit_test(test_rangecoder_probability_bounds),
        cmocka_unit_test(test_rangecoder_roundtrip),
        cmocka_unit_test(test_rangecoder_unpredictable_decode),
        cmocka_unit_test(test_single_triangle),
        cmocka_unit_test(test_two_disjoint_triangles),
        cmocka_unit_test(test_nonmanifold_edge_four_triangles),
        cmocka_unit_test(test_bowtie),
        cmocka_unit_test(test_isolated_vertices),
        cmocka_unit_test(test_all_coincident),
        cmocka_unit_test(test_flat_model),
        cmocka_unit_test(test_needle),
        cmocka_unit_test(test_large_offset_small_extent),
        cmocka_unit_test(test_precision_8_and_20),
        cmocka_unit_test(test_empty_mesh_errors),
        cmocka_unit_test(test_edges_in_input_complex),
        cmocka_unit_test(test_duplicate_in_wide_group),
        cmocka_unit_test(test_subrange_from_start_state),
        cmocka_unit_test(test_parent_child_chain),
        cmocka_unit_test(test_prefix_and_truncation),
        cmocka_unit_test(test_corruption_detected),
        cmocka_unit_test(test_extend_with_longer_prefixes),
        cmocka_unit_test(test_torus_levels_and_size),
    };
    return cmocka_run_group_tests_name("codec", tests, NULL, NULL);
}
