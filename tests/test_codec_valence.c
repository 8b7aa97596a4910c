/* High valence in the codec (issue 19, item 12): a vertex or an edge shared by
 * very many simplices. The complex's position index for long incidence lists
 * keeps exactly the order the plain swap-with-last removal gives (checked
 * against a reference list through additions, removals, compaction and a
 * merge), and meshes that cost O(k^2) before it round-trip exactly: a fan of
 * 100,000 triangles, a book of 20,000 pages sharing one edge, and one OBJ
 * polygon of 60,000 corners (fan-triangulated by the reader). Times are
 * measured by scripts/bench-valence (docs/PERFORMANCE.md), not here. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_codec.h"
#include "ms_complex.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_quant.h"
#include "ms_test.h"
#include "support/ms_codec_check.h"

#define P 10
#define PI 3.14159265358979323846

/* ---- the position index against a reference list ---- */

typedef struct ref_list {
    uint32_t *e;
    uint32_t n;
} ref_list;

static void ref_remove(ref_list *r, uint32_t tagged)
{
    for (uint32_t i = 0; i < r->n; ++i)
        if (r->e[i] == tagged) {
            r->e[i] = r->e[--r->n];
            return;
        }
    fail_msg("entry %u not in the reference list", tagged);
}

static void list_equals(ms_complex *cx, uint32_t s, const ref_list *r)
{
    assert_int_equal(cx->v[s].n, r->n);
    assert_memory_equal(ms_cx_list(&cx->v[s]), r->e, r->n * sizeof *r->e);
}

static uint32_t add_point(ms_complex *cx, uint32_t x, uint32_t y, uint32_t z)
{
    uint32_t c[3] = {x, y, z};
    return ms_cx_add_vertex(cx, ms_quant_key(x, y, z, P), 3 * P, c);
}

static void test_index_keeps_list_order(void **state)
{
    (void)state;
    enum { K = 3000 };
    ms_complex cx;
    ms_error err;
    assert_int_equal(ms_cx_init(&cx, P, K + 2, 2 * K, K, &err), MS_OK);
    assert_int_equal(ms_cx_reserve(&cx, K + 2, 2 * K, K, &err), MS_OK);
    uint32_t hub = add_point(&cx, 512, 512, 512);
    uint32_t rim[K];
    for (uint32_t i = 0; i < K; ++i)
        rim[i] = add_point(&cx, i % 1000, i / 1000, 7);
    ref_list r = {malloc(4 * K * sizeof(uint32_t)), 0};
    uint32_t *tri_of = malloc(K * sizeof *tri_of); /* triangle (hub, rim i, rim i+1) */
    assert_non_null(r.e);
    assert_non_null(tri_of);
    for (uint32_t i = 0; i + 1 < K; ++i) {
        tri_of[i] = ms_cx_add_tri(&cx, hub, rim[i], rim[i + 1]);
        r.e[r.n++] = tri_of[i] << 1;
    }
    tri_of[K - 1] = MS_CX_NONE;
    assert_true(cx.v[hub].cap >= MS_CX_INDEXED); /* the index is in use */
    list_equals(&cx, hub, &r);
    /* random removals, interleaved with additions that reuse the freed slots
     * and with maximal edges of the hub */
    uint64_t rng = 42;
    uint32_t edges[64], ne = 0;
    for (int round = 0; round < 4000; ++round) {
        uint32_t i = (uint32_t)(ms_test_random(&rng) % (K - 1));
        if (tri_of[i] != MS_CX_NONE) {
            ms_cx_del_tri(&cx, tri_of[i]);
            ref_remove(&r, tri_of[i] << 1);
            tri_of[i] = MS_CX_NONE;
        } else {
            tri_of[i] = ms_cx_add_tri(&cx, rim[i + 1], hub, rim[i]);
            r.e[r.n++] = tri_of[i] << 1;
        }
        if (round % 97 == 0 && ne < 64) {
            edges[ne] = ms_cx_add_edge(&cx, hub, rim[K - 1 - ne]);
            r.e[r.n++] = edges[ne] << 1 | 1;
            ne++;
        } else if (round % 131 == 0 && ne > 0) {
            uint32_t e = edges[--ne];
            ms_cx_del_edge(&cx, e);
            ref_remove(&r, e << 1 | 1);
        }
        if (round % 500 == 0)
            list_equals(&cx, hub, &r);
    }
    list_equals(&cx, hub, &r);
    assert_int_equal(cx.nomem, 0);

    /* after a compaction (entries renamed in place) removal still finds them:
     * take every triangle off by its renumbered id */
    uint32_t *order = malloc((size_t)cx.live_v * sizeof *order);
    assert_non_null(order);
    uint32_t n = 0;
    for (uint32_t s = 0; s < cx.nv; ++s)
        if (cx.v[s].alive)
            order[n++] = s;
    assert_int_equal(ms_cx_compact(&cx, order, n, &err), MS_OK);
    uint32_t hub2 = 0; /* slot order kept: the hub was added first */
    assert_int_equal(cx.v[hub2].n, r.n);
    while (cx.v[hub2].n > 0) {
        uint32_t tagged = ms_cx_list(&cx.v[hub2])[cx.v[hub2].n / 2];
        if (tagged & 1)
            ms_cx_del_edge(&cx, tagged >> 1);
        else
            ms_cx_del_tri(&cx, tagged >> 1);
    }
    assert_int_equal(cx.live_t, 0);
    assert_int_equal(cx.live_e, 0);
    free(order);
    free(tri_of);
    free(r.e);
    ms_cx_free(&cx);
}

/* Merging two hubs that share many triangles' rims: the result is the same
 * as the one a plain scan gives (c0 keeps its triangles, c1's move over unless
 * c0 has the same one; shared ones collapse to edges kept only when maximal). */
static void test_index_merge_hubs(void **state)
{
    (void)state;
    enum { K = 2000 };
    ms_complex cx;
    ms_error err;
    assert_int_equal(ms_cx_init(&cx, P, K + 2, 3 * K, 2 * K, &err), MS_OK);
    assert_int_equal(ms_cx_reserve(&cx, K + 2, 3 * K, 2 * K, &err), MS_OK);
    uint32_t a = add_point(&cx, 100, 100, 100), b = add_point(&cx, 101, 100, 100);
    uint32_t rim[K];
    for (uint32_t i = 0; i < K; ++i)
        rim[i] = add_point(&cx, 200 + i % 500, i / 500, 9);
    for (uint32_t i = 0; i + 1 < K; ++i) {
        ms_cx_add_tri(&cx, a, rim[i], rim[i + 1]);
        if (i % 2 == 0)
            ms_cx_add_tri(&cx, b, rim[i + 1], rim[i]); /* same set as a's: dropped */
        else
            ms_cx_add_tri(&cx, a, b, rim[i]); /* a book: collapses to edge (a, rim i) */
    }
    assert_int_equal(ms_cx_merge(&cx, a, b, &err), MS_OK);
    /* a keeps its K - 1 triangles; each collapsed book page leaves edge (a, rim
     * i), covered by a's triangle (a, rim i, rim i+1): none stays maximal */
    assert_int_equal(cx.v[a].n, K - 1);
    assert_int_equal(cx.live_t, K - 1);
    assert_int_equal(cx.live_e, 0);
    assert_false(cx.v[b].alive);
    const uint32_t *l = ms_cx_list(&cx.v[a]);
    for (uint32_t i = 0; i < cx.v[a].n; ++i) {
        assert_int_equal(l[i] & 1, 0);
        const uint32_t *t = cx.tri[l[i] >> 1];
        assert_true(t[0] == a || t[1] == a || t[2] == a);
    }
    ms_cx_free(&cx);
}

/* ---- high-valence meshes through the codec ---- */

static void mesh_new(ms_mesh *m, size_t nv, size_t nt)
{
    ms_error err;
    memset(m, 0, sizeof *m);
    assert_int_equal(ms_mesh_reserve(m, nv, nt, &err), MS_OK);
    m->vertex_count = nv;
    m->triangle_count = nt;
}

static void set_vertex(ms_mesh *m, size_t i, double x, double y, double z)
{
    m->positions[3 * i] = x;
    m->positions[3 * i + 1] = y;
    m->positions[3 * i + 2] = z;
}

static void set_tri(ms_mesh *m, size_t t, uint32_t a, uint32_t b, uint32_t c)
{
    m->triangles[3 * t] = a;
    m->triangles[3 * t + 1] = b;
    m->triangles[3 * t + 2] = c;
}

/* Before the position index its encoding took 1.2 s of CPU in a release build
 * (a 400,000-triangle fan 18.8 s), growing with the square of the valence. */
static void test_fan_roundtrip(void **state)
{
    (void)state;
    enum { N = 100000 };
    ms_mesh m;
    mesh_new(&m, N + 1, N);
    set_vertex(&m, 0, 0, 0, 0);
    for (uint32_t i = 0; i < N; ++i) {
        set_vertex(&m, 1 + i, cos(2 * PI * i / N), sin(2 * PI * i / N), 0);
        set_tri(&m, i, 0, 1 + i, 1 + (i + 1) % N);
    }
    ms_codec_check_result res;
    ms_codec_check_roundtrip_ex(&m, 20, 0, false, MS_CHECK_AHEAD_BOTH, &res);
    assert_int_equal(res.vertices, N + 1);
    assert_int_equal(res.triangles, N);
    assert_int_equal(res.weld.welded_vertices, 0);
    ms_mesh_free(&m);
}

/* Many triangles on one edge: before the encoder's one-pass votes, 20,000 pages
 * took 1.5 s of CPU in a release build, 40,000 pages 6.0 s (O(k^2)). */
static void test_book_roundtrip(void **state)
{
    (void)state;
    enum { N = 20000 };
    ms_mesh m;
    mesh_new(&m, N + 2, N);
    set_vertex(&m, 0, 0, 0, 0);
    set_vertex(&m, 1, 3e-6, 0, 0); /* the spine: two cells apart at 20 bits */
    for (uint32_t i = 0; i < N; ++i) {
        set_vertex(&m, 2 + i, 0.5, cos(2 * PI * i / N), sin(2 * PI * i / N));
        set_tri(&m, i, 0, 1, 2 + i);
    }
    ms_codec_check_result res;
    ms_codec_check_roundtrip_ex(&m, 20, 0, false, MS_CHECK_AHEAD_BOTH, &res);
    assert_int_equal(res.vertices, N + 2);
    assert_int_equal(res.triangles, N);
    ms_mesh_free(&m);
}

/* One OBJ face of 60,000 corners (continued lines), fan-triangulated by the
 * reader into 59,998 triangles around its first corner, then coded. */
static void test_obj_polygon_roundtrip(void **state)
{
    (void)state;
    enum { N = 60000 };
    char dir[1024], path[1200];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/polygon.obj", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    for (uint32_t i = 0; i < N; ++i)
        fprintf(f, "v %.9f %.9f 0\n", cos(2 * PI * i / N), sin(2 * PI * i / N));
    fputs("f", f);
    for (uint32_t i = 0; i < N; ++i)
        fprintf(f, " %u%s", i + 1, i % 1000 == 999 && i + 1 < N ? " \\\n" : "");
    fputs("\n", f);
    assert_int_equal(fclose(f), 0);
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_error err;
    assert_int_equal(ms_mesh_load(path, &m, NULL, &err), MS_OK);
    assert_int_equal(m.vertex_count, N);
    assert_int_equal(m.triangle_count, N - 2);
    for (size_t t = 0; t < m.triangle_count; ++t) {
        assert_int_equal(m.triangles[3 * t], 0);
        assert_int_equal(m.triangles[3 * t + 1], t + 1);
        assert_int_equal(m.triangles[3 * t + 2], t + 2);
    }
    ms_codec_check_result res;
    ms_codec_check_roundtrip_ex(&m, 20, 0, false, MS_CHECK_AHEAD_BOTH, &res);
    assert_int_equal(res.vertices, N);
    assert_int_equal(res.triangles, N - 2);
    ms_mesh_free(&m);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_index_keeps_list_order),
        cmocka_unit_test(test_index_merge_hubs),
        cmocka_unit_test(test_fan_roundtrip),
        cmocka_unit_test(test_book_roundtrip),
        cmocka_unit_test(test_obj_polygon_roundtrip),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
