#include "ms_codec_check.h"

#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_ref_coarsen.h"

void ms_test_torus(ms_mesh *m, unsigned nu, unsigned nv, double R, double r)
{
    memset(m, 0, sizeof *m);
    ms_error err;
    assert_int_equal(ms_mesh_reserve(m, (size_t)nu * nv, 2 * (size_t)nu * nv, &err), MS_OK);
    const double pi = 3.14159265358979323846;
    for (unsigned i = 0; i < nu; ++i)
        for (unsigned j = 0; j < nv; ++j) {
            double u = 2 * pi * i / nu, v = 2 * pi * j / nv;
            double *p = &m->positions[3 * (i * nv + j)];
            p[0] = (R + r * cos(v)) * cos(u);
            p[1] = (R + r * cos(v)) * sin(u);
            p[2] = r * sin(v);
        }
    size_t t = 0;
    for (unsigned i = 0; i < nu; ++i)
        for (unsigned j = 0; j < nv; ++j) {
            uint32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                     d = i * nv + (j + 1) % nv;
            uint32_t *x = &m->triangles[3 * t];
            x[0] = a, x[1] = b, x[2] = c;
            x[3] = a, x[4] = c, x[5] = d;
            t += 2;
        }
    m->vertex_count = (size_t)nu * nv;
    m->triangle_count = t;
}

static int cmp_u32x3(const void *a, const void *b)
{
    return memcmp(a, b, 3 * sizeof(uint32_t));
}

/* A decoded complex is valid: indices in range, no repeated vertex inside a
 * simplex, no two simplices with the same vertex set, cells distinct. */
static void assert_valid_complex(const ms_codec_state *s)
{
    for (size_t i = 1; i < s->vertex_count; ++i)
        assert_true(s->cells[i - 1] < s->cells[i]);
    uint32_t *t = malloc((s->tri_count + 1) * 3 * sizeof *t);
    assert_non_null(t);
    for (size_t k = 0; k < 3 * s->tri_count; ++k) {
        assert_true(s->tris[k] < s->vertex_count);
        t[k] = s->tris[k];
    }
    for (size_t k = 0; k < s->tri_count; ++k) {
        uint32_t *x = &t[3 * k], y;
        if (x[0] > x[1]) y = x[0], x[0] = x[1], x[1] = y;
        if (x[1] > x[2]) y = x[1], x[1] = x[2], x[2] = y;
        if (x[0] > x[1]) y = x[0], x[0] = x[1], x[1] = y;
        assert_true(x[0] < x[1] && x[1] < x[2]);
    }
    qsort(t, s->tri_count, 3 * sizeof *t, cmp_u32x3);
    for (size_t k = 1; k < s->tri_count; ++k)
        assert_true(memcmp(&t[3 * k - 3], &t[3 * k], 3 * sizeof *t) != 0);
    free(t);
    for (size_t k = 0; k < s->edge_count; ++k) {
        assert_true(s->edges[2 * k] < s->edges[2 * k + 1]);
        assert_true(s->edges[2 * k + 1] < s->vertex_count);
        if (k > 0)
            assert_true(s->edges[2 * k - 2] != s->edges[2 * k] ||
                        s->edges[2 * k - 1] != s->edges[2 * k + 1]);
    }
}

/* The level down to which a cell at kd-level L knows its descendants, with
 * geometry ahead by k stopping at kd-level E (the window's end D, or 3 times
 * the stop's bits): min(L + k, E), L itself at the stream's first level (0)
 * and from E on. */
static unsigned known_level(unsigned L, unsigned k, unsigned E)
{
    return L == 0 || L >= E ? L : L + k < E ? L + k : E;
}

/* With geometry ahead by k, every vertex of state a (kd-level L) is drawn at
 * the barycentre of the cells at level known_level(L, k, E) that hold vertices of the
 * full complex canon inside it (up to the decoder's rounding to half a grid
 * unit: at D, its own centre; at level 0, before the first chunk's prelude,
 * too); with k = 0 the state has no points. */
static void assert_ahead_points(const ms_codec_state *a, const ms_codec_state *canon, unsigned L,
                                unsigned k, unsigned E)
{
    /* at the stream's first level (0) nothing is known ahead yet: the
     * prelude is part of refining it; nothing past E, where geometry ahead stops */
    unsigned P = canon->bits, D = 3 * P, M = known_level(L, k, E);
    if (k == 0) {
        assert_null(a->rep);
        return;
    }
    assert_non_null(a->rep);
    size_t j = 0;
    for (size_t i = 0; i < a->vertex_count; ++i) {
        uint64_t prefix = a->cells[i];
        while (j < canon->vertex_count && (canon->cells[j] >> (D - L)) < prefix)
            j++;
        double sum[3] = {0, 0, 0};
        size_t n = 0;
        uint64_t last = UINT64_MAX;
        for (size_t t = j; t < canon->vertex_count && (canon->cells[t] >> (D - L)) == prefix; ++t) {
            uint64_t cell = canon->cells[t] >> (D - M);
            if (cell == last)
                continue;
            last = cell;
            uint32_t c[3];
            ms_quant_unkey(canon->cells[t], P, c);
            for (int ax = 0; ax < 3; ++ax) {
                uint32_t w = 1u << (P - (M + 2 - (unsigned)ax) / 3);
                sum[ax] += (c[ax] & ~(w - 1)) + 0.5 * w;
            }
            n++;
        }
        assert_true(n > 0);
        uint32_t c[3];
        ms_quant_unkey(canon->cells[j], P, c);
        for (int ax = 0; ax < 3; ++ax) {
            uint32_t w = 1u << (P - (L + 2 - (unsigned)ax) / 3);
            double want = (sum[ax] / (double)n - (c[ax] & ~(w - 1))) / w * 65536.0;
            double got = a->rep[3 * i + (size_t)ax];
            if (fabs(got - want) > 16384.0 / w + 1.0)
                fail_msg("level %u (ahead %u), vertex %zu, axis %d: drawn at %.0f/65536 of its "
                         "cell, the barycentre of its descendants is at %.1f", L, k, i, ax, got,
                         want);
        }
    }
}

/* The error bound of every vertex of state a (kd-level L; docs/CODEC.md §4.1,
 * "The error of a drawn point"), computed here independently: the point is
 * drawn where a renderer puts it (its cell's corner plus rep / 65536 of its
 * width, else its centre), the cells it knows are those at level M = min(L +
 * k, D) holding vertices of the full complex canon inside it (M = L at level 0
 * and with k = 0), and the bound is the largest distance from the point to a
 * corner of one of them: the state's float must be that value rounded up
 * (within a float's precision). Every full-precision vertex inside the cell,
 * its whole grid cell even, then lies within the bound (checked too), and the
 * bound never exceeds the cell's whole diagonal; without anything known below
 * the cell it is exactly the half-diagonal. */
static void assert_bounds(const ms_codec_state *a, const ms_codec_state *canon, unsigned L,
                          unsigned k, unsigned E)
{
    unsigned P = canon->bits, D = 3 * P;
    unsigned M = known_level(L, k, E);
    assert_non_null(a->bound);
    size_t j = 0;
    for (size_t i = 0; i < a->vertex_count; ++i) {
        uint64_t prefix = a->cells[i];
        while (j < canon->vertex_count && (canon->cells[j] >> (D - L)) < prefix)
            j++;
        uint32_t c[3];
        ms_quant_unkey(canon->cells[j], P, c);
        double p[3], w[3], diag = 0;
        for (int ax = 0; ax < 3; ++ax) {
            w[ax] = (double)(1u << (P - (L + 2 - (unsigned)ax) / 3));
            double corner = (double)(c[ax] & ~((uint32_t)w[ax] - 1));
            p[ax] = corner + (a->rep ? a->rep[3 * i + (size_t)ax] / 65536.0 : 0.5) * w[ax];
            diag += w[ax] * w[ax];
        }
        double want = 0, worst_vertex = 0;
        for (size_t t = j; t < canon->vertex_count && (canon->cells[t] >> (D - L)) == prefix; ++t) {
            uint32_t v[3];
            ms_quant_unkey(canon->cells[t], P, v);
            double dk = 0, dv = 0;
            for (int ax = 0; ax < 3; ++ax) {
                uint32_t wm = 1u << (P - (M + 2 - (unsigned)ax) / 3);
                double lo = (double)(v[ax] & ~(wm - 1)), hi = lo + wm;
                double e = fmax(fabs(p[ax] - lo), fabs(p[ax] - hi));
                dk += e * e;
                double ev = fmax(fabs(p[ax] - v[ax]), fabs(p[ax] - (v[ax] + 1.0)));
                dv += ev * ev;
            }
            want = fmax(want, sqrt(dk));
            worst_vertex = fmax(worst_vertex, sqrt(dv));
        }
        double got = a->bound[i];
        if (!(got >= want && got <= want * (1.0 + 0x1p-20)))
            fail_msg("level %u (ahead %u), vertex %zu: error bound %.9g, its known cells' "
                     "farthest corner at %.9g", L, k, i, got, want);
        assert_true(worst_vertex <= got);
        assert_true(got <= sqrt(diag) * (1.0 + 0x1p-20));
        if (M == L)
            assert_true(fabs(got - 0.5 * sqrt(diag)) <= 0.5 * sqrt(diag) * 0x1p-20);
    }
}

static void check_roundtrip_ahead(const ms_mesh *mesh, unsigned bits, unsigned level_step,
                                  bool twice, unsigned ahead, unsigned until, ms_codec_check_result *res);

void ms_codec_check_roundtrip_ex(const ms_mesh *mesh, unsigned bits, unsigned level_step,
                                 bool twice, unsigned aheads, ms_codec_check_result *res)
{
    assert_true(aheads != 0);
    for (unsigned k = 0; k <= MS_CODEC_MAX_AHEAD; ++k)
        if (aheads & (1u << k))
            check_roundtrip_ahead(mesh, bits, level_step, twice, k, 0, res);
    /* the default ahead stopping halfway: levels past the stop coded inline */
    if (aheads & MS_CHECK_AHEAD_UNTIL)
        check_roundtrip_ahead(mesh, bits, level_step, twice, MS_CODEC_DEFAULT_AHEAD,
                              bits / 2 < MS_CODEC_MAX_AHEAD_UNTIL ? bits / 2 : MS_CODEC_MAX_AHEAD_UNTIL, res);
}

static void check_roundtrip_ahead(const ms_mesh *mesh, unsigned bits, unsigned level_step,
                                  bool twice, unsigned ahead, unsigned until, ms_codec_check_result *res)
{
    ms_error err;
    ms_qmesh q;
    memset(res, 0, sizeof *res);
    assert_int_equal(ms_quantise_mesh(mesh, bits, &q, &res->weld, &err), MS_OK);
    ms_codec_state full, canon;
    assert_int_equal(ms_codec_state_from_qmesh(&q, &full, &err), MS_OK);
    assert_int_equal(ms_codec_state_from_qmesh(&q, &canon, &err), MS_OK);
    assert_int_equal(ms_codec_state_canonicalise(&canon, &err), MS_OK);
    ms_codec_encode_params par;
    memset(&par, 0, sizeof par);
    par.box = q.box;
    par.ahead = ahead;
    par.ahead_until = until;
    uint8_t *buf = NULL, *buf2 = NULL;
    size_t size = 0, size2 = 0;
    assert_int_equal(ms_codec_encode(&full, &par, &buf, &size, NULL, &err), MS_OK);
    if (twice) {
        assert_int_equal(ms_codec_encode(&full, &par, &buf2, &size2, NULL, &err), MS_OK);
        assert_int_equal(size, size2);
        assert_memory_equal(buf, buf2, size);
        free(buf2);
    }

    ms_codec_decoder *d;
    assert_int_equal(ms_codec_decoder_create(buf, size, NULL, NULL, &d, &err), MS_OK);
    unsigned D = 3 * bits, E = until > 0 && until < bits ? 3 * until : D;
    assert_int_equal(ms_codec_decoder_available_level(d), D);
    if (ms_codec_decoder_set_level(d, D, &err) != MS_OK)
        fail_msg("decode failed: %s", err.text);
    ms_codec_state got;
    assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
    assert_valid_complex(&got);
    assert_true(ms_codec_state_equal(&got, &canon, true));
    ms_codec_state_free(&got);

    /* The renderer's view: positions are the dequantised welded points. */
    ms_mesh rm;
    memset(&rm, 0, sizeof rm);
    assert_int_equal(ms_codec_decoder_mesh(d, &rm, &err), MS_OK);
    assert_int_equal(rm.vertex_count, q.vertex_count);
    assert_int_equal(rm.triangle_count, q.tri_count);
    for (size_t i = 0; i < q.vertex_count; ++i)
        for (int a = 0; a < 3; ++a)
            assert_true(rm.positions[3 * i + a] ==
                        ms_dequantise(&q.box, bits, a, q.coords[3 * i + a]));
    ms_mesh_free(&rm);

    if (level_step > 0) {
        for (unsigned L = D; L-- > 0;) {
            if (ms_codec_decoder_set_level(d, L, &err) != MS_OK)
                fail_msg("coarsen to %u failed: %s", L, err.text);
            if (L % level_step != 0 && L > 2)
                continue;
            ms_codec_state a, r;
            assert_int_equal(ms_codec_decoder_state(d, &a, &err), MS_OK);
            assert_valid_complex(&a);
            assert_ahead_points(&a, &canon, L, ahead, E);
            assert_bounds(&a, &canon, L, ahead, E);
            ms_ref_coarsen(&canon, L, &r);
            if (!ms_codec_state_equal(&a, &r, false))
                fail_msg("level %u differs from the reference: V %zu/%zu T %zu/%zu E %zu/%zu", L,
                         a.vertex_count, r.vertex_count, a.tri_count, r.tri_count, a.edge_count,
                         r.edge_count);
            ms_codec_state_free(&a);
            ms_codec_state_free(&r);
        }
        /* Refine again level by level: the final state is identical. Also
         * refine/coarsen one level in the middle and compare states. */
        unsigned mid = D / 2;
        assert_int_equal(ms_codec_decoder_set_level(d, mid, &err), MS_OK);
        ms_codec_state s1, s2;
        assert_int_equal(ms_codec_decoder_state(d, &s1, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_set_level(d, mid + 1, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_set_level(d, mid, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_state(d, &s2, &err), MS_OK);
        assert_true(ms_codec_state_equal(&s1, &s2, true));
        assert_true((s1.rep == NULL) == (s2.rep == NULL));
        if (s1.rep)
            assert_memory_equal(s1.rep, s2.rep, 3 * s1.vertex_count * sizeof *s1.rep);
        assert_ahead_points(&s1, &canon, mid, ahead, E);
        assert_bounds(&s1, &canon, mid, ahead, E);
        ms_codec_state_free(&s1);
        ms_codec_state_free(&s2);
        assert_int_equal(ms_codec_decoder_set_level(d, D, &err), MS_OK);
        assert_int_equal(ms_codec_decoder_state(d, &got, &err), MS_OK);
        assert_true(ms_codec_state_equal(&got, &canon, true));
        ms_codec_state_free(&got);
    }
    res->vertices = q.vertex_count;
    res->triangles = q.tri_count;
    res->bytes = size;
    ms_codec_decoder_destroy(d);
    free(buf);
    ms_codec_state_free(&full);
    ms_codec_state_free(&canon);
    ms_qmesh_free(&q);
}
