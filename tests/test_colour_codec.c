/* The colour codec (common/codec/ms_colour.h, docs/COLOUR.md): lossless round
 * trips on synthetic coloured tori (every channel value, alpha present and
 * absent, 8, 5 and 1 bits per channel) and on the colour trefoil fixture,
 * decoded in lockstep with the geometry decoder, every kd-level's colours
 * against an independent recursive reference of the rule; every prefix of the
 * stream; coarser and finer queries; header, chunk and body damage. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_colour.h"
#include "ms_mesh_io.h"
#include "ms_quant.h"
#include "ms_test.h"

/* ---- a coloured model, quantised, with its geometry stream and the complex
 * at every kd-level ---- */

typedef struct model {
    ms_qmesh q;
    ms_codec_state full;     /* canonical, level 3 P */
    uint8_t *rgba;           /* welded colours, full.cells order */
    ms_codec_state *levels;  /* the geometry decoder's state at every kd-level */
    unsigned D;
} model;

static void model_from_mesh(model *m, const ms_mesh *mesh, unsigned bits)
{
    ms_error err;
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_quantise_mesh(mesh, bits, &m->q, NULL, &err), MS_OK);
    assert_int_equal(ms_colour_weld(mesh, &m->q, &m->rgba, &err), MS_OK);
    assert_int_equal(ms_codec_state_from_qmesh(&m->q, &m->full, &err), MS_OK);
    for (size_t i = 1; i < m->full.vertex_count; ++i)
        assert_true(m->full.cells[i - 1] < m->full.cells[i]); /* q's order is key order */
    m->D = 3 * bits;
    ms_codec_encode_params par = {0};
    par.box = m->q.box;
    uint8_t *geo = NULL;
    size_t geo_size = 0;
    assert_int_equal(ms_codec_encode(&m->full, &par, &geo, &geo_size, NULL, &err), MS_OK);
    ms_codec_decoder *d = NULL;
    assert_int_equal(ms_codec_decoder_create(geo, geo_size, NULL, NULL, &d, &err), MS_OK);
    m->levels = calloc(m->D + 1, sizeof *m->levels);
    assert_non_null(m->levels);
    for (unsigned L = 0; L <= m->D; ++L) {
        assert_int_equal(ms_codec_decoder_set_level(d, L, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_state(d, &m->levels[L], &err), MS_OK);
    }
    ms_codec_decoder_destroy(d);
    free(geo);
}

static void model_free(model *m)
{
    for (unsigned L = 0; m->levels && L <= m->D; ++L)
        ms_codec_state_free(&m->levels[L]);
    free(m->levels);
    free(m->rgba);
    ms_codec_state_free(&m->full);
    ms_qmesh_free(&m->q);
}

/* A torus of nu x nv vertices, vertex i coloured so that every channel takes
 * every value 0..255 (odd multipliers mod 256 over 384 vertices). */
static void torus_mesh(ms_mesh *mesh, unsigned nu, unsigned nv)
{
    ms_error err;
    memset(mesh, 0, sizeof *mesh);
    assert_int_equal(ms_mesh_reserve(mesh, nu * nv, 2 * nu * nv, &err), MS_OK);
    assert_int_equal(ms_mesh_add_colours(mesh, true, &err), MS_OK);
    for (unsigned i = 0; i < nu; ++i)
        for (unsigned j = 0; j < nv; ++j) {
            double u = 2 * M_PI * i / nu, v = 2 * M_PI * j / nv;
            size_t k = (size_t)i * nv + j;
            double *p = mesh->positions + 3 * k;
            p[0] = (1.0 + 0.4 * cos(v)) * cos(u);
            p[1] = (1.0 + 0.4 * cos(v)) * sin(u);
            p[2] = 0.4 * sin(v);
            uint8_t *c = mesh->colours + 4 * k;
            c[0] = (uint8_t)(k * 37);
            c[1] = (uint8_t)(k * 11 + 3);
            c[2] = (uint8_t)(255 - (k * 5 & 255));
            c[3] = (uint8_t)(k * 3);
            uint32_t a = (uint32_t)k, b = (uint32_t)(((i + 1) % nu) * nv + j),
                     cc = (uint32_t)(((i + 1) % nu) * nv + (j + 1) % nv),
                     d = (uint32_t)(i * nv + (j + 1) % nv);
            uint32_t *t = mesh->triangles + 6 * k;
            t[0] = a, t[1] = b, t[2] = cc, t[3] = a, t[4] = cc, t[5] = d;
        }
    mesh->vertex_count = (size_t)nu * nv;
    mesh->triangle_count = 2 * (size_t)nu * nv;
}

/* ---- the reference: the rule, recursively over the sorted full keys ---- */

static void ref_rec(const model *m, size_t lo, size_t hi, unsigned level, unsigned c,
                    int out[4])
{
    if (level == m->D) {
        assert_int_equal(hi, lo + 1);
        for (int k = 0; k < 4; ++k)
            out[k] = m->rgba[4 * lo + (unsigned)k] >> (8 - c);
        return;
    }
    unsigned bit = m->D - 1 - level;
    size_t mid = lo;
    while (mid < hi && !((m->full.cells[mid] >> bit) & 1))
        ++mid;
    if (mid == lo || mid == hi) {
        ref_rec(m, lo, hi, level + 1, c, out);
        return;
    }
    int a[4], b[4];
    ref_rec(m, lo, mid, level + 1, c, a);
    ref_rec(m, mid, hi, level + 1, c, b);
    for (int k = 0; k < 4; ++k)
        out[k] = (a[k] + b[k]) / 2;
}

static size_t lower_bound(const uint64_t *keys, size_t n, uint64_t x)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < x)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The expected 8-bit colour of kd-cell p at level L. */
static void ref_colour(const model *m, uint64_t p, unsigned L, unsigned c, bool alpha,
                       uint8_t out[4])
{
    unsigned shift = m->D - L;
    size_t lo = lower_bound(m->full.cells, m->full.vertex_count, p << shift);
    size_t hi = lower_bound(m->full.cells, m->full.vertex_count, (p + 1) << shift);
    assert_true(lo < hi);
    int v[4];
    ref_rec(m, lo, hi, L, c, v);
    for (int k = 0; k < 4; ++k)
        out[k] = ms_colour_widen((unsigned)v[k], c);
    if (!alpha)
        out[3] = 255;
}

static void check_level(const model *m, ms_colour_decoder *d, unsigned L, unsigned c, bool alpha)
{
    ms_error err;
    const ms_codec_state *s = &m->levels[L];
    uint8_t *got = malloc(4 * s->vertex_count);
    assert_non_null(got);
    assert_int_equal(ms_colour_decoder_colours(d, s->cells, s->vertex_count, L, got, &err), MS_OK);
    for (size_t i = 0; i < s->vertex_count; ++i) {
        uint8_t want[4];
        ref_colour(m, s->cells[i], L, c, alpha, want);
        if (memcmp(got + 4 * i, want, 4) != 0)
            fail_msg("level %u cell %zu: got %u %u %u %u, want %u %u %u %u", L, i, got[4 * i],
                     got[4 * i + 1], got[4 * i + 2], got[4 * i + 3], want[0], want[1], want[2],
                     want[3]);
    }
    free(got);
}

static void encode(const model *m, unsigned c, bool alpha, uint8_t **buf, size_t *size)
{
    ms_error err;
    ms_colour_encode_params par = {.p_min = 0, .colour_bits = c, .alpha = alpha};
    assert_int_equal(ms_colour_encode(&m->full, m->rgba, &par, buf, size, &err), MS_OK);
}

/* Lockstep with the geometry: refine one level at a time, check every level. */
static void lockstep(const model *m, const uint8_t *buf, size_t size, unsigned c, bool alpha)
{
    ms_error err;
    ms_colour_decoder *d = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_available_level(d), m->D);
    for (unsigned L = 0; L <= m->D; ++L) {
        assert_int_equal(ms_colour_decoder_refine(d, &m->levels[L], L, &err), MS_OK);
        assert_int_equal(ms_colour_decoder_level(d), L);
        check_level(m, d, L, c, alpha);
    }
    /* coarser than decoded: the rule upwards, at every level */
    for (unsigned L = 0; L < m->D; ++L)
        check_level(m, d, L, c, alpha);
    ms_colour_decoder_destroy(d);
}

static void roundtrip_torus(unsigned c, bool alpha, size_t want_size)
{
    ms_mesh mesh;
    torus_mesh(&mesh, 24, 16);
    model m;
    model_from_mesh(&m, &mesh, 10);
    assert_int_equal(m.full.vertex_count, 384); /* nothing welded */
    uint8_t *buf = NULL;
    size_t size = 0;
    encode(&m, c, alpha, &buf, &size);
    if (want_size)
        assert_int_equal(size, want_size);
    ms_colour_header h;
    ms_error err;
    assert_int_equal(ms_colour_read_header(buf, size, &h, &err), MS_OK);
    assert_int_equal(h.colour_bits, c);
    assert_int_equal(h.alpha, alpha);
    assert_int_equal(h.start_cells, 1);
    assert_int_equal(h.end_cells, 384);
    lockstep(&m, buf, size, c, alpha);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

static void test_torus_8_alpha(void **state)
{
    (void)state;
    roundtrip_torus(8, true, 0);
}

static void test_torus_8_no_alpha(void **state)
{
    (void)state;
    roundtrip_torus(8, false, 0);
}

static void test_torus_fewer_bits(void **state)
{
    (void)state;
    roundtrip_torus(5, true, 0);
    roundtrip_torus(1, false, 0);
}

/* The input's every channel value reaches the decoder: 0 and 255 included. */
static void test_every_value(void **state)
{
    (void)state;
    ms_mesh mesh;
    torus_mesh(&mesh, 24, 16);
    model m;
    model_from_mesh(&m, &mesh, 10);
    bool seen[4][256] = {{false}};
    for (size_t i = 0; i < m.full.vertex_count; ++i)
        for (int k = 0; k < 4; ++k)
            seen[k][m.rgba[4 * i + (unsigned)k]] = true;
    for (int k = 0; k < 4; ++k)
        for (int v = 0; v < 256; ++v)
            assert_true(seen[k][v]);
    model_free(&m);
    ms_mesh_free(&mesh);
}

static void test_widen_and_weld(void **state)
{
    (void)state;
    assert_int_equal(ms_colour_widen(0, 1), 0);
    assert_int_equal(ms_colour_widen(1, 1), 255);
    assert_int_equal(ms_colour_widen(5, 3), 182); /* 101 101 10 */
    assert_int_equal(ms_colour_widen(31, 5), 255);
    assert_int_equal(ms_colour_widen(200, 8), 200);
    /* two vertices welded at 8 bits: the rounded mean, halves up */
    const double pos[] = {0, 0, 0, 1e-9, 0, 0, 1, 0, 0, 0, 1, 0};
    const uint32_t tris[] = {0, 2, 3};
    ms_mesh mesh;
    ms_error err;
    memset(&mesh, 0, sizeof mesh);
    assert_int_equal(ms_mesh_reserve(&mesh, 4, 1, &err), MS_OK);
    assert_int_equal(ms_mesh_add_colours(&mesh, false, &err), MS_OK);
    memcpy(mesh.positions, pos, sizeof pos);
    memcpy(mesh.triangles, tris, sizeof tris);
    mesh.vertex_count = 4;
    mesh.triangle_count = 1;
    const uint8_t cols[] = {10, 0, 255, 255, 11, 1, 254, 255, 7, 8, 9, 255, 1, 2, 3, 255};
    memcpy(mesh.colours, cols, sizeof cols);
    ms_qmesh q;
    assert_int_equal(ms_quantise_mesh(&mesh, 8, &q, NULL, &err), MS_OK);
    assert_int_equal(q.vertex_count, 3);
    uint8_t *rgba = NULL;
    assert_int_equal(ms_colour_weld(&mesh, &q, &rgba, &err), MS_OK);
    const uint8_t want[] = {11, 1, 255, 255};
    assert_memory_equal(rgba, want, 4); /* key 0: the welded pair */
    free(rgba);
    ms_qmesh_free(&q);
    ms_mesh_free(&mesh);
}

/* The trefoil fixture at 12 bits: lossless, every level in lockstep, and the
 * exact stream size (a change of format or model shows here). */
static void test_trefoil(void **state)
{
    (void)state;
    ms_mesh mesh;
    ms_error err;
    memset(&mesh, 0, sizeof mesh);
    assert_int_equal(ms_mesh_load("tests/data/trefoil_color.ply.gz", &mesh, NULL, &err), MS_OK);
    assert_non_null(mesh.colours);
    assert_true(mesh.colour_alpha);
    model m;
    model_from_mesh(&m, &mesh, 12);
    assert_int_equal(m.full.vertex_count, 5120);
    uint8_t *buf = NULL;
    size_t size = 0;
    encode(&m, 8, false, &buf, &size);
    assert_int_equal(size, 6852);
    lockstep(&m, buf, size, 8, false);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* A small model for the stream-handling tests: the torus at 10 bits. */
static void small_model(model *m, ms_mesh *mesh)
{
    torus_mesh(mesh, 24, 16);
    model_from_mesh(m, mesh, 10);
}

/* Every prefix: the available level is the last complete chunk's; decoding
 * to it gives the reference colours, one level more is refused as truncated;
 * a decoder extended byte by byte decodes alike. */
static void test_prefixes(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_error err;
    encode(&m, 8, true, &buf, &size);
    ms_colour_header h;
    assert_int_equal(ms_colour_read_header(buf, size, &h, &err), MS_OK);
    ms_colour_decoder *grown = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, h.header_size - 1, NULL, &grown, &err),
                     MS_ERR_FORMAT);
    assert_null(grown);
    assert_int_equal(ms_colour_decoder_create(buf, h.header_size, NULL, &grown, &err), MS_OK);
    assert_false(ms_colour_decoder_has_base(grown));
    for (size_t n = h.header_size; n <= size; ++n) {
        ms_colour_decoder *d = NULL;
        assert_int_equal(ms_colour_decoder_create(buf, n, NULL, &d, &err), MS_OK);
        assert_int_equal(ms_colour_decoder_extend(grown, buf, n, &err), MS_OK);
        unsigned avail = ms_colour_decoder_available_level(d);
        unsigned want = 0;
        for (unsigned i = 1; i <= h.p_max - h.p_min; ++i)
            if (h.header_size + h.chunk_end[i] <= n)
                want = 3 * i;
        assert_int_equal(avail, want);
        if (!ms_colour_decoder_has_base(d)) {
            assert_int_equal(ms_colour_decoder_refine(d, &m.levels[0], 0, &err), MS_ERR_FORMAT);
            ms_colour_decoder_destroy(d);
            continue;
        }
        if (avail < m.D)
            assert_int_equal(ms_colour_decoder_refine(d, &m.levels[avail + 1], avail + 1, &err),
                             MS_ERR_FORMAT);
        assert_int_equal(ms_colour_decoder_refine(d, &m.levels[avail], avail, &err), MS_OK);
        check_level(&m, d, avail, 8, true);
        /* finer cells than decoded take their ancestor's colour */
        uint8_t *got = malloc(4 * m.full.vertex_count);
        assert_int_equal(ms_colour_decoder_colours(d, m.full.cells, m.full.vertex_count, m.D, got,
                                                   &err), MS_OK);
        for (size_t i = 0; i < m.full.vertex_count; ++i) {
            uint8_t w[4];
            ref_colour(&m, m.full.cells[i] >> (m.D - avail), avail, 8, true, w);
            assert_memory_equal(got + 4 * i, w, 4);
        }
        free(got);
        /* the grown decoder follows, level by level */
        while (ms_colour_decoder_level(grown) < avail) {
            unsigned L = ms_colour_decoder_level(grown) + 1;
            assert_int_equal(ms_colour_decoder_refine(grown, &m.levels[L], L, &err), MS_OK);
            check_level(&m, grown, L, 8, true);
        }
        ms_colour_decoder_destroy(d);
    }
    assert_int_equal(ms_colour_decoder_level(grown), m.D);
    ms_colour_decoder_destroy(grown);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* Refining several levels at once from a finer complex equals lockstep. */
static void test_jumps(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_error err;
    encode(&m, 8, false, &buf, &size);
    ms_colour_decoder *d = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    const unsigned steps[] = {4, 5, 17, 29, 30};
    for (size_t i = 0; i < sizeof steps / sizeof *steps; ++i) {
        assert_int_equal(ms_colour_decoder_refine(d, &m.levels[m.D], steps[i], &err), MS_OK);
        check_level(&m, d, steps[i], 8, false);
    }
    /* a level at or below the decoded one only checks */
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[12], 12, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_level(d), 30);
    ms_colour_decoder_destroy(d);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* Cells that do not continue the stream are refused, the decoder still works. */
static void test_wrong_cells(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_error err;
    encode(&m, 8, true, &buf, &size);
    ms_colour_decoder *d = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[15], 15, &err), MS_OK);
    ms_codec_state bad = m.levels[18];
    bad.vertex_count--; /* one cell missing */
    assert_int_equal(ms_colour_decoder_refine(d, &bad, 18, &err), MS_ERR_ARG);
    assert_null(strchr(err.text, '\n'));
    uint64_t *cells = malloc(m.levels[18].vertex_count * sizeof *cells);
    memcpy(cells, m.levels[18].cells, m.levels[18].vertex_count * sizeof *cells);
    bad = m.levels[18];
    bad.cells = cells;
    cells[3] = cells[2]; /* not increasing */
    assert_int_equal(ms_colour_decoder_refine(d, &bad, 18, &err), MS_ERR_ARG);
    memcpy(cells, m.levels[18].cells, m.levels[18].vertex_count * sizeof *cells);
    cells[bad.vertex_count - 1] += 1ull << 17; /* another cell, same count */
    if (cells[bad.vertex_count - 1] < (1ull << 18))
        assert_int_equal(ms_colour_decoder_refine(d, &bad, 18, &err), MS_ERR_ARG);
    bad = m.levels[18];
    uint32_t *tris = malloc(3 * bad.tri_count * sizeof *tris);
    memcpy(tris, bad.tris, 3 * bad.tri_count * sizeof *tris);
    tris[0] = (uint32_t)bad.vertex_count;
    bad.tris = tris;
    assert_int_equal(ms_colour_decoder_refine(d, &bad, 18, &err), MS_ERR_ARG);
    bad = m.levels[18];
    assert_int_equal(ms_colour_decoder_refine(d, &bad, 19, &err), MS_ERR_ARG); /* above cells */
    assert_int_equal(ms_colour_decoder_level(d), 15);
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[m.D], m.D, &err), MS_OK);
    check_level(&m, d, m.D, 8, true);
    free(cells);
    free(tris);
    ms_colour_decoder_destroy(d);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

static void test_encoder_arguments(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    ms_error err;
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_colour_encode_params par = {.colour_bits = 9};
    assert_int_equal(ms_colour_encode(&m.full, m.rgba, &par, &buf, &size, &err), MS_ERR_ARG);
    par.colour_bits = 8;
    par.p_min = 11;
    assert_int_equal(ms_colour_encode(&m.full, m.rgba, &par, &buf, &size, &err), MS_ERR_ARG);
    par.p_min = 0;
    ms_codec_state s = m.full;
    s.level--;
    assert_int_equal(ms_colour_encode(&s, m.rgba, &par, &buf, &size, &err), MS_ERR_ARG);
    s = m.full;
    uint64_t *cells = malloc(s.vertex_count * sizeof *cells);
    memcpy(cells, s.cells, s.vertex_count * sizeof *cells);
    uint64_t t = cells[0];
    cells[0] = cells[1];
    cells[1] = t;
    s.cells = cells;
    assert_int_equal(ms_colour_encode(&s, m.rgba, &par, &buf, &size, &err), MS_ERR_ARG);
    s = m.full;
    s.vertex_count = 0;
    assert_int_equal(ms_colour_encode(&s, m.rgba, &par, &buf, &size, &err), MS_ERR_EMPTY);
    assert_null(buf);
    free(cells);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* A stream over [p_min, P]: starts from the cells at 3 p_min. */
static void test_window(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    ms_error err;
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_colour_encode_params par = {.p_min = 4, .colour_bits = 8, .alpha = true};
    assert_int_equal(ms_colour_encode(&m.full, m.rgba, &par, &buf, &size, &err), MS_OK);
    ms_colour_decoder *d = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_min_level(d), 12);
    assert_int_equal(ms_colour_decoder_header(d)->start_cells, m.levels[12].vertex_count);
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[11], 11, &err), MS_ERR_ARG);
    for (unsigned L = 12; L <= m.D; ++L) {
        assert_int_equal(ms_colour_decoder_refine(d, &m.levels[L], L, &err), MS_OK);
        check_level(&m, d, L, 8, true);
    }
    ms_colour_decoder_destroy(d);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* A window whose base colours the caller gives (base_given, as an archive
 * cell's parent gives them): smaller, decodes exactly once given, refused
 * without them, with other cells, twice, or on a stream that codes its own. */
static void test_base_given(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    ms_error err;
    uint8_t *own = NULL, *buf = NULL;
    size_t own_size = 0, size = 0;
    ms_colour_encode_params par = {.p_min = 4, .colour_bits = 7, .alpha = true};
    assert_int_equal(ms_colour_encode(&m.full, m.rgba, &par, &own, &own_size, &err), MS_OK);
    par.base_given = true;
    assert_int_equal(ms_colour_encode(&m.full, m.rgba, &par, &buf, &size, &err), MS_OK);
    assert_true(size < own_size);
    const ms_codec_state *base = &m.levels[12];
    uint8_t *rgba = malloc(4 * base->vertex_count);
    for (size_t i = 0; i < base->vertex_count; ++i) /* the rule's colours, 8 bits */
        ref_colour(&m, base->cells[i], 12, 8, true, rgba + 4 * i);
    ms_colour_decoder *d = NULL;
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    assert_true(ms_colour_decoder_header(d)->base_given);
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[12], 12, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "base colours were not given"));
    assert_int_equal(ms_colour_decoder_set_base(d, base->cells, base->vertex_count - 1, rgba, &err),
                     MS_ERR_ARG);
    assert_int_equal(ms_colour_decoder_set_base(d, base->cells, base->vertex_count, rgba, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_set_base(d, base->cells, base->vertex_count, rgba, &err),
                     MS_ERR_ARG);
    for (unsigned L = 12; L <= m.D; ++L) {
        assert_int_equal(ms_colour_decoder_refine(d, &m.levels[L], L, &err), MS_OK);
        check_level(&m, d, L, 7, true);
    }
    ms_colour_decoder_destroy(d);
    /* other cells than the geometry's first level */
    assert_int_equal(ms_colour_decoder_create(buf, size, NULL, &d, &err), MS_OK);
    uint64_t *shifted = malloc(base->vertex_count * sizeof *shifted);
    for (size_t i = 0; i < base->vertex_count; ++i)
        shifted[i] = base->cells[i] + 1000000;
    assert_int_equal(ms_colour_decoder_set_base(d, shifted, base->vertex_count, rgba, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_refine(d, &m.levels[13], 13, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "not the cells' at its first level"));
    ms_colour_decoder_destroy(d);
    /* a stream that codes its own base takes none */
    assert_int_equal(ms_colour_decoder_create(own, own_size, NULL, &d, &err), MS_OK);
    assert_int_equal(ms_colour_decoder_set_base(d, base->cells, base->vertex_count, rgba, &err),
                     MS_ERR_ARG);
    ms_colour_decoder_destroy(d);
    free(shifted);
    free(rgba);
    free(buf);
    free(own);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* ---- hostile streams ---- */

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static ms_status create_status(const uint8_t *buf, size_t size, bool skip_crc, ms_error *err)
{
    ms_colour_decoder_options opt = {.skip_crc = skip_crc};
    ms_colour_decoder *d = NULL;
    ms_status st = ms_colour_decoder_create(buf, size, &opt, &d, err);
    ms_colour_decoder_destroy(d);
    if (st != MS_OK)
        assert_null(strchr(err->text, '\n'));
    return st;
}

static void test_header_fields(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    ms_error err;
    uint8_t *buf = NULL;
    size_t size = 0;
    encode(&m, 8, true, &buf, &size);
    uint8_t *b = malloc(size);
    struct {
        size_t at;
        uint8_t value;
        ms_status want;
    } cases[] = {
        {0, 'X', MS_ERR_FORMAT},       /* magic */
        {4, 2, MS_ERR_UNSUPPORTED},    /* version */
        {5, 0, MS_ERR_FORMAT},         /* p_max 0 */
        {5, 21, MS_ERR_FORMAT},        /* p_max 21 */
        {6, 11, MS_ERR_FORMAT},        /* p_min > p_max */
        {7, 4, MS_ERR_FORMAT},         /* unknown flag (bit 1: base given) */
        {8, 0, MS_ERR_FORMAT},         /* colour bits 0 */
        {8, 9, MS_ERR_FORMAT},         /* colour bits 9 */
        {9, 1, MS_ERR_FORMAT},         /* reserved */
        {12, 2, MS_ERR_FORMAT},        /* p_min 0 with 2 start cells */
        {19, 0x80, MS_ERR_FORMAT},     /* final count over the cap */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        memcpy(b, buf, size);
        b[cases[i].at] = cases[i].value;
        assert_int_equal(create_status(b, size, true, &err), cases[i].want);
    }
    /* header CRC */
    memcpy(b, buf, size);
    b[16] ^= 1;
    assert_int_equal(create_status(b, size, false, &err), MS_ERR_CORRUPT);
    /* chunk table: a chunk shorter than 4 bytes, a count that cannot follow */
    ms_colour_header h;
    assert_int_equal(ms_colour_read_header(buf, size, &h, &err), MS_OK);
    memcpy(b, buf, size);
    put32(b + 28, h.chunk_end[0] + 2); /* chunk 1 ends 2 bytes after the base */
    assert_int_equal(create_status(b, size, true, &err), MS_ERR_FORMAT);
    memcpy(b, buf, size);
    put32(b + 28 + 8, 9); /* chunk 1: 9 cells after 1 */
    assert_int_equal(create_status(b, size, true, &err), MS_ERR_FORMAT);
    /* more bytes than declared */
    uint8_t *longer = malloc(size + 1);
    memcpy(longer, buf, size);
    longer[size] = 0;
    assert_int_equal(create_status(longer, size + 1, false, &err), MS_ERR_FORMAT);
    free(longer);
    free(b);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

/* Decodes to the end in lockstep; returns the first failure's status. */
static ms_status decode_all(const model *m, const uint8_t *buf, size_t size, bool skip_crc)
{
    ms_colour_decoder_options opt = {.skip_crc = skip_crc};
    ms_colour_decoder *d = NULL;
    ms_error err;
    ms_status st = ms_colour_decoder_create(buf, size, &opt, &d, &err);
    uint8_t *got = malloc(4 * m->full.vertex_count);
    for (unsigned L = 0; st == MS_OK && L <= m->D; ++L) {
        st = ms_colour_decoder_refine(d, &m->levels[L], L, &err);
        if (st == MS_OK)
            st = ms_colour_decoder_colours(d, m->levels[L].cells, m->levels[L].vertex_count, L,
                                           got, &err);
    }
    if (st != MS_OK) {
        assert_true(err.text[0] != '\0');
        assert_null(strchr(err.text, '\n'));
        if (d) /* after a corrupted chunk the decoder refuses further work */
            assert_int_not_equal(ms_colour_decoder_refine(d, &m->levels[m->D], m->D, &err), MS_OK);
    }
    free(got);
    ms_colour_decoder_destroy(d);
    return st;
}

static void test_body_damage(void **state)
{
    (void)state;
    ms_mesh mesh;
    model m;
    small_model(&m, &mesh);
    uint8_t *buf = NULL;
    size_t size = 0;
    encode(&m, 8, true, &buf, &size);
    ms_colour_header h;
    ms_error err;
    assert_int_equal(ms_colour_read_header(buf, size, &h, &err), MS_OK);
    uint8_t *b = malloc(size);
    /* with CRCs: every single-bit flip of the body is refused as corrupt */
    unsigned refused = 0;
    for (size_t at = h.header_size; at < size; at += 7) {
        memcpy(b, buf, size);
        b[at] ^= (uint8_t)(1u << (at % 8));
        assert_int_equal(decode_all(&m, b, size, false), MS_ERR_CORRUPT);
        refused++;
    }
    assert_true(refused > 10);
    /* without CRCs: 300 random damages decode or fail cleanly, never crash */
    uint64_t rng = 0x9E3779B97F4A7C15ull;
    unsigned failed = 0;
    for (int i = 0; i < 300; ++i) {
        memcpy(b, buf, size);
        int flips = 1 + (int)(ms_test_random(&rng) % 4);
        for (int f = 0; f < flips; ++f) {
            size_t at = h.header_size + ms_test_random(&rng) % (size - h.header_size);
            b[at] = (uint8_t)ms_test_random(&rng);
        }
        failed += decode_all(&m, b, size, true) != MS_OK;
    }
    assert_true(failed > 150); /* nearly every damage is caught by the chunk's end */
    free(b);
    free(buf);
    model_free(&m);
    ms_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_every_value),
        cmocka_unit_test(test_torus_8_alpha),
        cmocka_unit_test(test_torus_8_no_alpha),
        cmocka_unit_test(test_torus_fewer_bits),
        cmocka_unit_test(test_widen_and_weld),
        cmocka_unit_test(test_trefoil),
        cmocka_unit_test(test_base_given),
        cmocka_unit_test(test_prefixes),
        cmocka_unit_test(test_jumps),
        cmocka_unit_test(test_wrong_cells),
        cmocka_unit_test(test_encoder_arguments),
        cmocka_unit_test(test_window),
        cmocka_unit_test(test_header_fields),
        cmocka_unit_test(test_body_damage),
    };
    return cmocka_run_group_tests_name("colour_codec", tests, NULL, NULL);
}
