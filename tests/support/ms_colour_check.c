/* Colour checks shared by the colour tests (ms_colour_check.h). */
#include "ms_colour_check.h"

#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_colour.h"
#include "ms_mesh_io.h"
#include "ms_quant.h"


static int cmp_key(const void *x, const void *y)
{
    const uint64_t *a = x, *b = y; /* key, input index */
    return a[0] != b[0] ? (a[0] < b[0] ? -1 : 1) : (a[1] < b[1] ? -1 : a[1] > b[1]);
}

void ms_colour_test_weld(const char *path, const ms_archive_header *h, ms_colour_test_welded *w)
{
    ms_mesh mesh;
    ms_error err;
    if (ms_mesh_load(path, &mesh, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_non_null(mesh.colours);
    ms_quant_box box = {{h->box_origin[0], h->box_origin[1], h->box_origin[2]}, h->box_side};
    size_t V = mesh.vertex_count;
    uint64_t *pairs = malloc(2 * V * sizeof *pairs);
    for (size_t v = 0; v < V; ++v) {
        uint32_t q[3];
        for (int a = 0; a < 3; ++a)
            q[a] = ms_quantise(&box, h->bits, a, mesh.positions[3 * v + (size_t)a]);
        pairs[2 * v] = ms_quant_key(q[0], q[1], q[2], h->bits);
        pairs[2 * v + 1] = v;
    }
    qsort(pairs, V, 2 * sizeof *pairs, cmp_key);
    w->keys = malloc(V * sizeof *w->keys);
    w->rgba = malloc(4 * V);
    w->n = 0;
    w->alpha = mesh.colour_alpha;
    for (size_t i = 0; i < V;) {
        size_t j = i;
        unsigned sum[4] = {0, 0, 0, 0};
        for (; j < V && pairs[2 * j] == pairs[2 * i]; ++j)
            for (int k = 0; k < 4; ++k)
                sum[k] += mesh.colours[4 * pairs[2 * j + 1] + (size_t)k];
        unsigned cnt = (unsigned)(j - i);
        w->keys[w->n] = pairs[2 * i];
        for (int k = 0; k < 4; ++k)
            w->rgba[4 * w->n + (size_t)k] = (uint8_t)((2 * sum[k] + cnt) / (2 * cnt));
        w->n++;
        i = j;
    }
    free(pairs);
    ms_mesh_free(&mesh);
}

void ms_colour_test_welded_free(ms_colour_test_welded *w)
{
    free(w->keys);
    free(w->rgba);
}

/* The rule, level by level: the colour (c-bit channels) of the vertices
 * [lo, hi) lying in one kd-cell of level L (3p-bit keys). */
void ms_colour_test_rule(const ms_colour_test_welded *w, unsigned p, unsigned c, size_t lo, size_t hi, unsigned L,
                     unsigned out[4])
{
    if (L == 3 * p) {
        assert_int_equal(hi - lo, 1);
        for (int k = 0; k < 4; ++k)
            out[k] = w->rgba[4 * lo + (size_t)k] >> (8 - c);
        return;
    }
    unsigned bit = 3 * p - 1 - L;
    size_t m = lo;
    while (m < hi && !((w->keys[m] >> bit) & 1))
        ++m;
    if (m == lo || m == hi) {
        ms_colour_test_rule(w, p, c, lo, hi, L + 1, out);
        return;
    }
    unsigned a[4], b[4];
    ms_colour_test_rule(w, p, c, lo, m, L + 1, a);
    ms_colour_test_rule(w, p, c, m, hi, L + 1, b);
    for (int k = 0; k < 4; ++k)
        out[k] = (a[k] + b[k]) / 2;
}

/* Every stitched vertex's colour is its kd-cell's by the rule at c bits,
 * widened (alpha 255 without alpha in the input). */
void ms_colour_test_check(const ms_view_mesh *m, const ms_colour_test_welded *w, unsigned p, unsigned c)
{
    assert_non_null(m->colours);
    for (size_t k = 0; k < m->vertex_count; ++k) {
        unsigned shift = 3 * p - m->levels[k];
        uint64_t first = m->keys[k], end = first + (1ull << shift);
        size_t lo = 0;
        while (lo < w->n && w->keys[lo] < first)
            ++lo;
        size_t hi = lo;
        while (hi < w->n && w->keys[hi] < end)
            ++hi;
        assert_true(hi > lo);
        unsigned want[4];
        ms_colour_test_rule(w, p, c, lo, hi, m->levels[k], want);
        for (int ch = 0; ch < 4; ++ch) {
            unsigned expect = ch == 3 && !w->alpha ? 255 : ms_colour_widen(want[ch], c);
            if (m->colours[4 * k + (size_t)ch] != expect)
                fail_msg("vertex %zu (level %u) channel %d: %u, expected %u", k, m->levels[k],
                         ch, m->colours[4 * k + (size_t)ch], expect);
        }
    }
}

