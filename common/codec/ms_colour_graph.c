/* The neighbour graph of the colour codec (docs/COLOUR.md, "Prediction"): the
 * cells of one kd-level joined when a triangle or an edge of a finer complex
 * joins their descendants, i.e. the 1-skeleton of the complex at that level. */
#include "ms_colour_internal.h"

#include <stdlib.h>
#include <string.h>


void cc_graph_free(cc_graph *g)
{
    free(g->off);
    free(g->adj);
    free(g->deg);
    memset(g, 0, sizeof *g);
}

/* Whether cell x of the sorted cells is one of two children of a split. */
static bool split_child(const uint64_t *cells, size_t n, size_t x)
{
    uint64_t c = cells[x];
    if (c & 1)
        return x > 0 && cells[x - 1] == (c ^ 1);
    return x + 1 < n && cells[x + 1] == (c | 1);
}

/* One side (a, b) of the complex: counted (fill = false) or stored. */
static void side(cc_graph *g, const uint8_t *want, uint32_t *fill_at, uint32_t a, uint32_t b)
{
    if (a == b)
        return;
    if (want[a]) {
        if (fill_at)
            g->adj[fill_at[a]++] = b;
        else
            g->off[a + 1]++;
    }
    if (want[b]) {
        if (fill_at)
            g->adj[fill_at[b]++] = a;
        else
            g->off[b + 1]++;
    }
}

ms_status cc_graph_build(const ms_codec_state *cx, unsigned level, const uint64_t *cells, size_t n,
                         cc_graph *g, ms_error *err)
{
    size_t nv = cx->vertex_count, nt = cx->tri_count, ne = cx->edge_count;
    cc_graph_free(g);
    uint32_t *rank = malloc((nv ? nv : 1) * sizeof *rank);
    uint8_t *want = malloc(n ? n : 1);
    uint32_t *fill_at = malloc((n ? n : 1) * sizeof *fill_at);
    g->off = calloc(n + 1, sizeof *g->off);
    g->deg = calloc(n ? n : 1, sizeof *g->deg);
    g->n = n;
    ms_status st = MS_OK;
    if (!rank || !want || !fill_at || !g->off || !g->deg) {
        st = ms_error_set(err, MS_ERR_NOMEM, "colour codec: out of memory for the neighbour graph");
        goto done;
    }
    unsigned shift = cx->level - level;
    size_t j = 0;
    for (size_t i = 0; i < nv; ++i) {
        uint64_t p = cx->cells[i] >> shift;
        while (j < n && cells[j] < p)
            ++j;
        if (j == n || cells[j] != p) {
            st = ms_error_set(err, MS_ERR_ARG, "colour codec: the complex's cells do not match "
                              "the cells at kd-level %u", level);
            goto done;
        }
        rank[i] = (uint32_t)j;
    }
    for (size_t x = 0; x < n; ++x)
        want[x] = split_child(cells, n, x);
    for (int pass = 0; pass < 2; ++pass) {
        uint32_t *at = pass ? fill_at : NULL;
        for (size_t t = 0; t < nt; ++t) {
            const uint32_t *v = cx->tris + 3 * t;
            side(g, want, at, rank[v[0]], rank[v[1]]);
            side(g, want, at, rank[v[1]], rank[v[2]]);
            side(g, want, at, rank[v[2]], rank[v[0]]);
        }
        for (size_t e = 0; e < ne; ++e)
            side(g, want, at, rank[cx->edges[2 * e]], rank[cx->edges[2 * e + 1]]);
        if (pass == 0) {
            for (size_t x = 0; x < n; ++x)
                g->off[x + 1] += g->off[x];
            memcpy(fill_at, g->off, n * sizeof *fill_at);
            g->adj = malloc((g->off[n] ? g->off[n] : 1) * sizeof *g->adj);
            if (!g->adj) {
                st = ms_error_set(err, MS_ERR_NOMEM,
                                  "colour codec: out of memory for the neighbour graph");
                goto done;
            }
        }
    }
    /* distinct neighbours, in first-seen order: fill_at[y] marks y as seen
     * from cell x + 1 (its last use above is over) */
    memset(fill_at, 0, n * sizeof *fill_at);
    for (size_t x = 0; x < n; ++x) {
        uint32_t *v = g->adj + g->off[x];
        size_t k = g->off[x + 1] - g->off[x], u = 0;
        for (size_t i = 0; i < k; ++i)
            if (fill_at[v[i]] != x + 1) {
                fill_at[v[i]] = (uint32_t)(x + 1);
                v[u++] = v[i];
            }
        g->deg[x] = (uint32_t)u;
    }
done:
    free(rank);
    free(want);
    free(fill_at);
    if (st != MS_OK)
        cc_graph_free(g);
    return st;
}
