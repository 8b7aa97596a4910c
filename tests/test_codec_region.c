/* Streams that own a region (ms_codec_region): the foreign vertices of an
 * nSP-like cell of a 12-bit torus freeze at their model-wide lone level. Exact
 * outcomes: which vertices freeze and at which kd-level, the decoded complex (a
 * frozen vertex as its lone kd-cell's first key), refine/coarsen identity at
 * every level, a smaller stream than without the region, each invalid freeze
 * level or region refused by the encoder, and damaged region bytes refused by
 * the decoder. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>
#include <zlib.h>

#include "ms_codec.h"
#include "ms_codec_internal.h"
#include "ms_nsp_lone.h"
#include "ms_quant.h"
#include "support/ms_codec_check.h"

#define BITS 12
#define PMIN 5
#define D (3 * BITS)
#define LMIN (3 * PMIN)
/* full header with a region: fixed part, region, chunk table, CRC */
#define REGION_HEADER (72 + 16 + 8 * (BITS - PMIN) + 4)

typedef struct cell_case {
    ms_codec_state full;    /* the cell's complex at full precision */
    uint8_t *freeze;        /* per vertex of full */
    ms_codec_region region; /* the octant x, y, z < 2^11 */
    ms_quant_box box;
    size_t foreign, frozen; /* foreign vertices; those with a freeze level */
    unsigned ahead;         /* geometry ahead of the streams encoded */
    unsigned ahead_until;   /* where it stops, bits (0: the window's end) */
} cell_case;

static bool inside(const ms_codec_region *r, uint64_t key)
{
    uint32_t c[3];
    ms_quant_unkey(key, BITS, c);
    return !ms_codec_outside(r, c);
}

/* The triangles of a torus with a vertex in the octant, with their foreign
 * vertices; lone levels from the whole torus. */
static void make_cell(cell_case *k)
{
    memset(k, 0, sizeof *k);
    ms_mesh m;
    ms_test_torus(&m, 60, 30, 1.0, 0.35);
    ms_qmesh q;
    ms_error err;
    assert_int_equal(ms_quantise_mesh(&m, BITS, &q, NULL, &err), MS_OK);
    k->box = q.box;
    ms_codec_state all;
    assert_int_equal(ms_codec_state_from_qmesh(&q, &all, &err), MS_OK);
    uint8_t *lone;
    assert_int_equal(ms_nsp_lone_levels(all.cells, all.vertex_count, D, &lone, &err), MS_OK);
    k->region.log2_side = BITS - 1;
    uint32_t *map = malloc(all.vertex_count * sizeof *map);
    assert_non_null(map);
    memset(map, 0xFF, all.vertex_count * sizeof *map);
    k->full.bits = BITS;
    k->full.level = D;
    k->full.cells = malloc(all.vertex_count * sizeof *k->full.cells);
    k->full.tris = malloc(3 * all.tri_count * sizeof *k->full.tris);
    k->full.edges = malloc(sizeof *k->full.edges);
    k->freeze = malloc(all.vertex_count);
    assert_true(k->full.cells && k->full.tris && k->full.edges && k->freeze);
    for (size_t t = 0; t < all.tri_count; ++t) {
        const uint32_t *x = &all.tris[3 * t];
        if (!inside(&k->region, all.cells[x[0]]) && !inside(&k->region, all.cells[x[1]]) &&
            !inside(&k->region, all.cells[x[2]]))
            continue;
        for (int j = 0; j < 3; ++j) {
            if (map[x[j]] == UINT32_MAX) {
                size_t v = k->full.vertex_count++;
                map[x[j]] = (uint32_t)v;
                k->full.cells[v] = all.cells[x[j]];
                bool foreign = !inside(&k->region, all.cells[x[j]]);
                unsigned f = lone[x[j]] < LMIN ? LMIN : lone[x[j]];
                k->freeze[v] = foreign && f < D ? (uint8_t)f : MS_CODEC_NO_FREEZE;
                k->foreign += foreign;
                k->frozen += k->freeze[v] != MS_CODEC_NO_FREEZE;
            }
            k->full.tris[3 * k->full.tri_count + (size_t)j] = map[x[j]];
        }
        k->full.tri_count++;
    }
    free(map);
    free(lone);
    ms_codec_state_free(&all);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
}

static void free_cell(cell_case *k)
{
    ms_codec_state_free(&k->full);
    free(k->freeze);
}

static ms_status encode_with(const cell_case *k, const ms_codec_region *region,
                             const uint8_t *freeze, bool compact, uint8_t **buf, size_t *size,
                             ms_codec_state *start, ms_error *err)
{
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box = k->box;
    par.p_min = PMIN;
    par.region = region;
    par.freeze_level = freeze;
    par.compact_header = compact;
    par.ahead = k->ahead;
    par.ahead_until = k->ahead_until;
    return ms_codec_encode(&k->full, &par, buf, size, start, err);
}

static ms_status encode(const cell_case *k, const ms_codec_region *region, const uint8_t *freeze,
                        uint8_t **buf, size_t *size, ms_codec_state *start, ms_error *err)
{
    return encode_with(k, region, freeze, false, buf, size, start, err);
}

/* With geometry ahead, every own vertex is drawn inside its cell (at the last
 * level, and from where geometry ahead stops, at its centre), a foreign one
 * (which never runs ahead) at its centre. */
static void check_points(const cell_case *k, const ms_codec_state *s)
{
    unsigned end = k->ahead_until ? 3 * k->ahead_until : D;
    if (k->ahead == 0) {
        assert_null(s->rep);
        return;
    }
    assert_non_null(s->rep);
    size_t off_centre = 0;
    for (size_t i = 0; i < s->vertex_count; ++i) {
        bool own = inside(&k->region, s->cells[i] << (D - s->level));
        for (int a = 0; a < 3; ++a) {
            if (!own || s->level >= end)
                assert_int_equal(s->rep[3 * i + (size_t)a], 32768);
            off_centre += s->rep[3 * i + (size_t)a] != 32768;
        }
    }
    assert_true((off_centre > 0) == (s->level < end));
}

static void check_frozen_levels(unsigned ahead, unsigned until)
{
    cell_case k;
    make_cell(&k);
    k.ahead = ahead;
    k.ahead_until = until;
    assert_true(k.foreign > 20 && k.frozen == k.foreign); /* every foreign one freezes */
    ms_error err;
    uint8_t *with, *without;
    size_t nwith, nwithout;
    ms_codec_state start, start2;
    assert_int_equal(encode(&k, &k.region, k.freeze, &with, &nwith, &start, &err), MS_OK);
    assert_int_equal(encode(&k, NULL, NULL, &without, &nwithout, &start2, &err), MS_OK);
    /* the same start state; fewer bytes once foreign vertices stop */
    assert_true(ms_codec_state_equal(&start, &start2, true));
    assert_true(nwith < nwithout);
    ms_codec_header h;
    assert_int_equal(ms_codec_read_header(with, nwith, &h, &err), MS_OK);
    assert_true(h.has_region);
    assert_int_equal(h.region.log2_side, BITS - 1);
    assert_int_equal(h.header_size, REGION_HEADER);

    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(with, nwith, &start, NULL, &d, &err), MS_OK);
    /* every level on the way up, kept to compare after coarsening */
    ms_codec_state up[D + 1];
    memset(up, 0, sizeof up);
    assert_int_equal(ms_codec_decoder_state(d, &up[LMIN], &err), MS_OK);
    for (unsigned L = LMIN + 1; L <= D; ++L) {
        assert_int_equal(ms_codec_decoder_set_level(d, L, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_state(d, &up[L], &err), MS_OK);
        check_points(&k, &up[L]);
    }
    /* final: foreign vertices at their freeze level, as the first key of it */
    size_t n = ms_codec_decoder_vertex_count(d);
    assert_int_equal(n, k.full.vertex_count);
    uint8_t *levels = malloc(n);
    assert_non_null(levels);
    assert_int_equal(ms_codec_decoder_vertex_levels(d, levels), k.frozen);
    ms_codec_state want = {0};
    want.bits = BITS;
    want.level = D;
    want.vertex_count = n;
    want.tri_count = k.full.tri_count;
    want.cells = malloc(n * sizeof *want.cells);
    want.tris = malloc(3 * want.tri_count * sizeof *want.tris);
    want.edges = malloc(sizeof *want.edges);
    uint8_t *want_level = malloc(n);
    uint64_t *order = malloc(n * sizeof *order);
    assert_true(want.cells && want.tris && want.edges && want_level && order);
    for (size_t v = 0; v < n; ++v) {
        unsigned f = k.freeze[v] == MS_CODEC_NO_FREEZE ? D : k.freeze[v];
        want.cells[v] = k.full.cells[v] >> (D - f) << (D - f);
        order[v] = k.full.cells[v] << 8 | f; /* keys are at most 36 bits */
    }
    memcpy(want.tris, k.full.tris, 3 * want.tri_count * sizeof *want.tris);
    assert_int_equal(ms_codec_state_canonicalise(&want, &err), MS_OK);
    assert_true(ms_codec_state_equal(&up[D], &want, true));
    /* levels in key order (a frozen key keeps the order of the vertex it stands for) */
    for (size_t i = 1; i < n; ++i)
        for (size_t j = i; j > 0 && order[j - 1] > order[j]; --j) {
            uint64_t t = order[j];
            order[j] = order[j - 1], order[j - 1] = t;
        }
    for (size_t i = 0; i < n; ++i)
        want_level[i] = (uint8_t)(order[i] & 0xFF);
    assert_memory_equal(levels, want_level, n);
    /* coarsen to every level and back: the same states */
    for (unsigned L = D; L-- > LMIN;) {
        assert_int_equal(ms_codec_decoder_set_level(d, L, &err), MS_OK);
        ms_codec_state got;
        assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
        assert_true(ms_codec_state_equal(&got, &up[L], true));
        assert_true((got.rep == NULL) == (up[L].rep == NULL));
        if (got.rep) /* the same points too */
            assert_memory_equal(got.rep, up[L].rep, 3 * got.vertex_count * sizeof *got.rep);
        ms_codec_state_free(&got);
    }
    assert_int_equal(ms_codec_decoder_vertex_levels(d, levels), 0);
    assert_int_equal(ms_codec_decoder_set_level(d, D, &err), MS_OK);
    ms_codec_state again;
    assert_int_equal(ms_codec_decoder_state(d, &again, &err), MS_OK);
    assert_true(ms_codec_state_equal(&again, &want, true));
    ms_codec_state_free(&again);
    for (unsigned L = LMIN; L <= D; ++L)
        ms_codec_state_free(&up[L]);
    ms_codec_decoder_destroy(d);
    free(levels);
    free(want_level);
    free(order);
    ms_codec_state_free(&want);
    ms_codec_state_free(&start);
    ms_codec_state_free(&start2);
    free(with);
    free(without);
    free_cell(&k);
}

static void test_frozen_levels_and_state(void **state)
{
    (void)state;
    check_frozen_levels(0, 0);
}

/* The same with geometry ahead: foreign cells keep coding their geometry as
 * they go, own ones run ahead (to the window's end, or to where it stops);
 * frozen levels, states and points survive coarsening and refining again. */
static void test_frozen_levels_with_geometry_ahead(void **state)
{
    (void)state;
    check_frozen_levels(MS_CODEC_DEFAULT_AHEAD, 0);
    check_frozen_levels(MS_CODEC_MAX_AHEAD, 0);
    /* stopping inside the window [PMIN, BITS]: own cells inline from there */
    check_frozen_levels(MS_CODEC_DEFAULT_AHEAD, PMIN + 2);
}

static void expect_refused(const cell_case *k, const ms_codec_region *region, const uint8_t *freeze,
                           const char *why)
{
    uint8_t *buf = NULL;
    size_t size = 0;
    ms_error err;
    assert_int_equal(encode(k, region, freeze, &buf, &size, NULL, &err), MS_ERR_ARG);
    if (!strstr(err.text, why))
        fail_msg("expected \"%s\" in: %s", why, err.text);
    assert_null(buf);
}

static void test_encoder_refuses(void **state)
{
    (void)state;
    cell_case k;
    make_cell(&k);
    size_t n = k.full.vertex_count;
    uint8_t *f = malloc(n);
    assert_non_null(f);
    expect_refused(&k, NULL, k.freeze, "need a region");
    size_t own = 0, foreign = 0;
    while (k.freeze[own] != MS_CODEC_NO_FREEZE)
        own++;
    while (k.freeze[foreign] == MS_CODEC_NO_FREEZE)
        foreign++;
    memcpy(f, k.freeze, n);
    f[own] = 30;
    expect_refused(&k, &k.region, f, "only a foreign vertex");
    memcpy(f, k.freeze, n);
    f[foreign] = LMIN - 1;
    expect_refused(&k, &k.region, f, "outside [15, 36)");
    f[foreign] = D;
    expect_refused(&k, &k.region, f, "outside [15, 36)");
    /* two foreign vertices sharing their kd-cell at the level asked */
    size_t a = SIZE_MAX, b = 0;
    unsigned shared = 0;
    for (size_t i = 0; i < n && a == SIZE_MAX; ++i)
        for (size_t j = 0; j < n; ++j)
            if (i != j && k.freeze[i] != MS_CODEC_NO_FREEZE && k.freeze[j] != MS_CODEC_NO_FREEZE) {
                unsigned l = ms_key_lcp(k.full.cells[i], k.full.cells[j], D);
                if (l >= LMIN && l < D) {
                    a = i, b = j, shared = l;
                    break;
                }
            }
    assert_true(a != SIZE_MAX);
    (void)b;
    memcpy(f, k.freeze, n);
    f[a] = (uint8_t)shared;
    expect_refused(&k, &k.region, f, "in a cell it shares");
    ms_codec_region bad = k.region;
    bad.min[0] = 1;
    expect_refused(&k, &bad, k.freeze, "region invalid");
    bad = k.region;
    bad.log2_side = 2; /* cells of the window would straddle it */
    expect_refused(&k, &bad, NULL, "region invalid");
    free(f);
    free_cell(&k);
}

static void reseal(uint8_t *buf, size_t header_size)
{
    uint32_t crc = (uint32_t)crc32(0L, buf, (uInt)(header_size - 4));
    for (int i = 0; i < 4; ++i)
        buf[header_size - 4 + (size_t)i] = (uint8_t)(crc >> (8 * i));
}

/* The torus cell coded with its region (full header), its start state, and a
 * scratch buffer of the stream's size. */
static void encoded_cell(cell_case *k, uint8_t **buf, size_t *size, ms_codec_state *start,
                         uint8_t **scratch)
{
    make_cell(k);
    ms_error err;
    assert_int_equal(encode(k, &k->region, k->freeze, buf, size, start, &err), MS_OK);
    *scratch = malloc(*size);
    assert_non_null(*scratch);
}

static void test_damaged_region_bytes(void **state)
{
    (void)state;
    cell_case k;
    uint8_t *buf, *x;
    size_t size;
    ms_codec_state start;
    ms_error err;
    encoded_cell(&k, &buf, &size, &start, &x);
    const size_t hs = REGION_HEADER;
    ms_codec_decoder *d = NULL;
    struct {
        size_t at;
        uint8_t value;
        const char *why;
    } cases[] = { /* the last: the flags are read before the header CRC is checked */
        {72 + 12, BITS + 1, "does not fit the window"}, /* side over the grid */
        {72 + 12, 3, "does not fit the window"},        /* too fine for p_min */
        {72 + 13, 1, "reserved bytes"},
        {72 + 0, 1, "not aligned"},                     /* min x = 1 */
        {72 + 1, 0x10, "not aligned"},                  /* min x = 4096: off the grid */
        {7, 0x21, "ahead by 0 kd-levels stopping at 1"},  /* a stop (bits 5-7) without ahead */
        {7, 0x6D, "stopping at 3 bits, in a window [5"}, /* ahead 3 stopping before the window */
        {7, 0x1D, "at most 6"},                         /* geometry ahead by 7 */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        memcpy(x, buf, size);
        x[cases[i].at] = cases[i].value;
        if (cases[i].at != 7) /* the header CRC first */
            assert_int_equal(ms_codec_decoder_create(x, size, &start, NULL, &d, &err),
                             MS_ERR_CORRUPT);
        reseal(x, hs);
        assert_int_equal(ms_codec_decoder_create(x, size, &start, NULL, &d, &err), MS_ERR_FORMAT);
        if (!strstr(err.text, cases[i].why))
            fail_msg("case %zu: expected \"%s\" in: %s", i, cases[i].why, err.text);
        assert_null(d);
    }
    /* without its region the same bytes are another (shorter) header: refused */
    memcpy(x, buf, size);
    x[7] = 0;
    reseal(x, hs);
    assert_int_not_equal(ms_codec_decoder_create(x, size, &start, NULL, &d, &err), MS_OK);
    free(x);
    free(buf);
    ms_codec_state_free(&start);
    free_cell(&k);
}

/* Random damage to the body of a region stream (CRCs skipped, so the decoder's
 * own checks meet it): every decode ends in a documented status, and the frozen
 * cells' bookkeeping survives coarsening and refining again (ASan, UBSan). */
static void test_damaged_bodies(void **state)
{
    (void)state;
    cell_case k;
    uint8_t *buf, *x;
    size_t size;
    ms_codec_state start;
    ms_error err;
    encoded_cell(&k, &buf, &size, &start, &x);
    const size_t hs = REGION_HEADER;
    uint64_t rng = 12345;
    unsigned ok = 0, refused = 0;
    ms_codec_decoder_options opt = {.skip_crc = true};
    for (int round = 0; round < 300; ++round) {
        memcpy(x, buf, size);
        for (int flips = 0; flips < 1 + round % 3; ++flips) {
            rng = rng * 6364136223846793005ull + 1442695040888963407ull;
            size_t at = hs + (size_t)(rng >> 33) % (size - hs);
            x[at] ^= (uint8_t)(1u << ((rng >> 20) & 7));
        }
        ms_codec_decoder *d;
        assert_int_equal(ms_codec_decoder_create(x, size, &start, &opt, &d, &err), MS_OK);
        ms_status s = ms_codec_decoder_set_level(d, D, &err);
        if (s == MS_OK)
            s = ms_codec_decoder_set_level(d, LMIN + 7, &err);
        if (s == MS_OK)
            s = ms_codec_decoder_set_level(d, D, &err);
        assert_true(s == MS_OK || s == MS_ERR_CORRUPT || s == MS_ERR_FORMAT);
        ok += s == MS_OK;
        refused += s != MS_OK;
        ms_codec_decoder_destroy(d);
    }
    assert_int_equal(ok + refused, 300);
    assert_true(refused > 200); /* most damage is caught by the counts and chunk ends */
    free(x);
    free(buf);
    ms_codec_state_free(&start);
    free_cell(&k);
}

static size_t varint_len(uint32_t v)
{
    size_t n = 1;
    while (v >= 128)
        v >>= 7, n++;
    return n;
}

/* The compact header (an archive's streams): the same fields but the box, the
 * same body byte for byte, a size that is the sum of its varints; a decoder
 * without the box gives the complex but no world mesh, with it the same mesh;
 * every truncation, an overlong and an unterminated number are refused. */
static void test_compact_header(void **state)
{
    (void)state;
    cell_case k;
    make_cell(&k);
    ms_error err;
    uint8_t *full, *compact;
    size_t nfull, ncompact;
    ms_codec_state start;
    assert_int_equal(encode(&k, &k.region, k.freeze, &full, &nfull, &start, &err), MS_OK);
    assert_int_equal(encode_with(&k, &k.region, k.freeze, true, &compact, &ncompact, NULL, &err),
                     MS_OK);
    ms_codec_header hf, hc;
    assert_int_equal(ms_codec_read_header(full, nfull, &hf, &err), MS_OK);
    assert_int_equal(ms_codec_read_header(compact, ncompact, &hc, &err), MS_OK);
    assert_true(hc.compact && !hf.compact && hc.has_region);
    assert_int_equal(hc.box.size, 0);
    assert_memory_equal(&hc.region, &hf.region, sizeof hc.region);
    assert_int_equal(hc.start_vertices, hf.start_vertices);
    assert_int_equal(hc.end_tris, hf.end_tris);
    assert_int_equal(hc.start_checksum, hf.start_checksum);
    assert_memory_equal(hc.chunk_end, hf.chunk_end, sizeof hc.chunk_end);
    assert_memory_equal(hc.chunk_crc, hf.chunk_crc, sizeof hc.chunk_crc);
    size_t want = 8 + varint_len(hc.start_vertices) + varint_len(hc.start_tris) +
                  varint_len(hc.start_edges) + 8 + varint_len(hc.end_vertices) +
                  varint_len(hc.end_tris) + varint_len(hc.end_edges) + 1 + 4;
    for (int a = 0; a < 3; ++a)
        want += varint_len(hc.region.min[a] >> hc.region.log2_side);
    for (unsigned i = 0; i < BITS - PMIN; ++i)
        want += varint_len(hc.chunk_end[i] - (i ? hc.chunk_end[i - 1] : 0)) + 4;
    assert_int_equal(hc.header_size, want);
    assert_true(hc.header_size < hf.header_size - 40);
    assert_int_equal(ncompact - hc.header_size, nfull - hf.header_size);
    assert_memory_equal(compact + hc.header_size, full + hf.header_size, nfull - hf.header_size);
    /* decoding */
    ms_codec_decoder *dc, *df;
    assert_int_equal(ms_codec_decoder_create(compact, ncompact, &start, NULL, &dc, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(dc, D, &err), MS_OK);
    ms_mesh mc = {0}, mf = {0};
    assert_int_equal(ms_codec_decoder_mesh(dc, &mc, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "box"));
    ms_codec_decoder_destroy(dc);
    ms_codec_decoder_options o = {.box = &k.box};
    assert_int_equal(ms_codec_decoder_create(compact, ncompact, &start, &o, &dc, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_create(full, nfull, &start, NULL, &df, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(dc, D, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_set_level(df, D, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_mesh(dc, &mc, &err), MS_OK);
    assert_int_equal(ms_codec_decoder_mesh(df, &mf, &err), MS_OK);
    assert_int_equal(mc.vertex_count, mf.vertex_count);
    assert_int_equal(mc.triangle_count, mf.triangle_count);
    assert_memory_equal(mc.positions, mf.positions, 3 * mc.vertex_count * sizeof *mc.positions);
    assert_memory_equal(mc.triangles, mf.triangles, 3 * mc.triangle_count * sizeof *mc.triangles);
    ms_mesh_free(&mc);
    ms_mesh_free(&mf);
    ms_codec_decoder_destroy(dc);
    ms_codec_decoder_destroy(df);
    /* hostile headers */
    for (size_t cut = 0; cut < hc.header_size; ++cut)
        assert_int_equal(ms_codec_read_header(compact, cut, &hc, &err), MS_ERR_FORMAT);
    uint8_t *x = malloc(ncompact);
    assert_non_null(x);
    size_t at_end_v = 8 + varint_len(hf.start_vertices) + varint_len(hf.start_tris) +
                      varint_len(hf.start_edges) + 8;
    assert_true(varint_len(hf.end_vertices) == 2);
    memcpy(x, compact, ncompact);
    x[at_end_v + 1] = 0; /* the low 7 bits alone, spelt in two bytes */
    x[at_end_v] = (uint8_t)(x[at_end_v] | 0x80);
    assert_int_equal(ms_codec_parse_header(x, ncompact, &hc, false, &err), MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "malformed number"));
    memcpy(x, compact, ncompact);
    memset(x + 8, 0xFF, 5); /* a number that never ends */
    assert_int_equal(ms_codec_parse_header(x, ncompact, &hc, false, &err), MS_ERR_FORMAT);
    memcpy(x, compact, ncompact);
    x[7] = 2; /* compact without the region: the fields shift, the CRC is elsewhere */
    assert_int_not_equal(ms_codec_read_header(x, ncompact, &hc, &err), MS_OK);
    free(x);
    free(full);
    free(compact);
    ms_codec_state_free(&start);
    free_cell(&k);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frozen_levels_and_state),
        cmocka_unit_test(test_frozen_levels_with_geometry_ahead),
        cmocka_unit_test(test_encoder_refuses),
        cmocka_unit_test(test_damaged_region_bytes),
        cmocka_unit_test(test_damaged_bodies),
        cmocka_unit_test(test_compact_header),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
