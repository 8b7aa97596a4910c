/* The bake's smoothing (docs/CODEC.md §4.4, ARCHIVE.md header bytes 122 and
 * 123):
 *   - the precision below which a client smooths, from lone-level histograms
 *     worked by hand;
 *   - on the baked demo model: the header's rounds (the default) and
 *     precision, the latter equal to the rule applied to the whole model's
 *     lone levels (ms_nsp_lone_levels, the reference the out-of-core bake
 *     must agree with);
 *   - the view draws a coarse cell's vertices smoothed, each inside its
 *     kd-cell, and a bake with --smooth 0 draws exactly the stream's own
 *     points;
 *   - geometry ahead stops where the default says (docs/CODEC.md §4.1): the
 *     root's stream header, and no geometry ahead in the cells below it. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_mesh_io.h"
#include "ms_nsp.h"
#include "ms_nsp_check.h"
#include "ms_nsp_lone.h"
#include "ms_quant.h"
#include "ms_test.h"
#include "ms_view_decoder.h"

static void test_smooth_bits_by_hand(void **state)
{
    (void)state;
    uint64_t h[3 * 4 + 1] = {0};
    /* 100 vertices, 4 bits: 10 alone at kd-level 3 (bit 1), 30 at 6, 60 at 12:
     * half are alone only at bit 4 */
    h[3] = 10, h[6] = 30, h[12] = 60;
    assert_int_equal(ms_bake_smooth_bits(h, 4), 4);
    /* a level inside a bit counts from the bit that contains it: 50 alone at
     * kd-level 7, which bit 3 (kd-level 9) includes */
    memset(h, 0, sizeof h);
    h[7] = 50, h[12] = 50;
    assert_int_equal(ms_bake_smooth_bits(h, 4), 3);
    /* one vertex: alone from the start (level 0) */
    memset(h, 0, sizeof h);
    h[0] = 1;
    assert_int_equal(ms_bake_smooth_bits(h, 4), 1);
    memset(h, 0, sizeof h);
    assert_int_equal(ms_bake_smooth_bits(h, 4), 0); /* no vertices: no smoothing */
}

static int key_order(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* The rule over the whole model: ply quantised to `bits` in its fitted box,
 * its distinct keys' lone levels. */
static unsigned reference_smooth_bits(const char *ply, unsigned bits)
{
    ms_mesh m;
    memset(&m, 0, sizeof m);
    ms_error err;
    assert_int_equal(ms_mesh_load(ply, &m, NULL, &err), MS_OK);
    ms_qmesh q;
    memset(&q, 0, sizeof q);
    assert_int_equal(ms_quantise_mesh(&m, bits, &q, NULL, &err), MS_OK);
    uint64_t *keys = malloc(q.vertex_count * sizeof *keys);
    assert_non_null(keys);
    for (size_t i = 0; i < q.vertex_count; ++i)
        keys[i] = ms_quant_key(q.coords[3 * i], q.coords[3 * i + 1], q.coords[3 * i + 2], bits);
    qsort(keys, q.vertex_count, sizeof *keys, key_order);
    size_t n = 0;
    for (size_t i = 0; i < q.vertex_count; ++i)
        if (n == 0 || keys[i] != keys[n - 1])
            keys[n++] = keys[i];
    uint8_t *levels;
    assert_int_equal(ms_nsp_lone_levels(keys, n, 3 * bits, &levels, &err), MS_OK);
    uint64_t hist[3 * MS_CODEC_MAX_BITS + 1] = {0};
    for (size_t i = 0; i < n; ++i)
        hist[levels[i]]++;
    free(levels);
    free(keys);
    ms_qmesh_free(&q);
    ms_mesh_free(&m);
    return ms_bake_smooth_bits(hist, bits);
}

/* Opens dir/name.msa, shows its root at `bits` and stitches it; asserts every
 * stitched vertex lies inside its kd-cell; *max_moved: the largest distance
 * (world units) of a drawn vertex from the point the stream gives it, *moved:
 * how many of the *count vertices moved at all. */
static void root_drawn(const char *dir, const char *name, unsigned bits, ms_archive_header *header,
                       double *max_moved, size_t *moved, size_t *count)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    *header = *ms_archive_get_header(a);
    ms_view *v;
    assert_int_equal(ms_view_create_from_archive(a, &v, &err), MS_OK);
    size_t len;
    const uint8_t *g = ms_archive_geometry(a, 0, &len);
    assert_int_equal(ms_view_set_bytes(v, 0, g, len, &err), MS_OK);
    assert_int_equal(ms_view_set_bits(v, 0, bits, &err), MS_OK);
    ms_view_mesh m = {0};
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    ms_codec_state st;
    assert_int_equal(ms_view_cell_state_copy(v, 0, &st, &err), MS_OK);
    assert_int_equal(m.vertex_count, st.vertex_count);
    double unit = header->box_side / (double)(1u << header->bits);
    *max_moved = 0, *moved = 0, *count = m.vertex_count;
    for (size_t i = 0; i < m.vertex_count; ++i) {
        unsigned level = m.levels[i], shift = 3u * header->bits - level;
        uint64_t prefix = m.keys[i] >> shift;
        size_t k = 0;
        while (k < st.vertex_count && st.cells[k] != prefix)
            ++k;
        assert_true(k < st.vertex_count);
        uint32_t xyz[3];
        ms_quant_unkey(m.keys[i], header->bits, xyz);
        double d2 = 0;
        for (int c = 0; c < 3; ++c) {
            double width = (double)(1u << (header->bits - (level + 2u - (unsigned)c) / 3u)) * unit;
            double lo = header->box_origin[c] + xyz[c] * unit, p = m.positions[3 * i + c];
            double stream = lo + (st.rep ? st.rep[3 * k + c] / 65536.0 : 0.5) * width;
            assert_true(p >= lo - 1e-12 && p <= lo + width + 1e-12); /* inside its kd-cell */
            d2 += (p - stream) * (p - stream);
        }
        *max_moved = fmax(*max_moved, sqrt(d2));
        *moved += d2 > 0;
    }
    ms_codec_state_free(&st);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    ms_archive_close(a);
}

/* The default bake's geometry ahead stops at MS_BAKE_DEFAULT_AHEAD_UNTIL bits:
 * the root's stream (window [0, 7]) says so in its header, and every other
 * cell's window starts past it, so runs no geometry ahead at all. */
static void assert_ahead_stops(const char *dir, const char *name)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    unsigned cells = 0;
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, i, &len);
        if (!g || len == 0)
            continue;
        ms_codec_header ch;
        assert_int_equal(ms_codec_read_header(g, len, &ch, &err), MS_OK);
        assert_true(i == 0 ? ch.p_min == 0 && ch.p_max > MS_BAKE_DEFAULT_AHEAD_UNTIL
                           : ch.p_min >= MS_BAKE_DEFAULT_AHEAD_UNTIL);
        assert_int_equal(ch.ahead, i == 0 ? MS_CODEC_DEFAULT_AHEAD : 0);
        assert_int_equal(ch.ahead_until, i == 0 ? MS_BAKE_DEFAULT_AHEAD_UNTIL : 0);
        cells++;
    }
    assert_true(cells > 1);
    ms_archive_close(a);
}

static void test_demo_smoothing(void **state)
{
    (void)state;
    char dir[512], ply[700];
    ms_test_tmpdir(dir, sizeof dir);
    assert_int_equal(ms_nsp_test_bake_demo(dir, 20000, dir, "smooth", 1500, false), 0);
    snprintf(ply, sizeof ply, "%s/demo.ply", dir);
    ms_bake_options o;
    ms_nsp_test_bake_options(ply, dir, "plain", &o);
    o.min_triangles = 1500;
    o.smooth_rounds = 0;
    ms_bake_report r;
    ms_error err;
    assert_int_equal(ms_bake(&o, &r, &err), MS_OK);
    assert_int_equal(r.smooth_rounds, 0);

    ms_archive_header h;
    double max_moved;
    size_t moved, count;
    unsigned ref = reference_smooth_bits(ply, 16);
    root_drawn(dir, "smooth", 5, &h, &max_moved, &moved, &count);
    print_message("smoothing below %u bits (reference %u); root at 5 bits: %zu of %zu vertices moved, "
                  "at most %.4g\n", h.smooth_bits, ref, moved, count, max_moved);
    assert_int_equal(h.smooth_rounds, MS_BAKE_DEFAULT_SMOOTH_ROUNDS);
    assert_int_equal(h.smooth_bits, ref);
    assert_true(ref > 5);
    assert_true(moved > count / 2);
    /* never farther than the kd-cell's diagonal at 5 bits */
    assert_true(max_moved > 0 && max_moved <= sqrt(3.0) * ldexp(h.box_side, -5));

    root_drawn(dir, "plain", 5, &h, &max_moved, &moved, &count);
    assert_int_equal(h.smooth_rounds, 0);
    assert_int_equal(h.smooth_bits, 0);
    assert_true(max_moved < 1e-12 * h.box_side);
    assert_ahead_stops(dir, "smooth");
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_smooth_bits_by_hand),
        cmocka_unit_test(test_demo_smoothing),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
