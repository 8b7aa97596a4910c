/* The complex's merge of two sibling cells (the encoder's coarsening step)
 * and its compaction (ms_complex.h). */
#include "ms_complex.h"

#include <assert.h>
#include <stdlib.h>
#include <string.h>

static bool tri_has(const uint32_t *t, uint32_t s)
{
    return t[0] == s || t[1] == s || t[2] == s;
}

/* The two vertices of triangle t other than s, smaller slot first. */
static uint64_t tri_other_pair(const uint32_t *t, uint32_t s)
{
    uint32_t a = MS_CX_NONE, b = MS_CX_NONE;
    for (int m = 0; m < 3; ++m) {
        if (t[m] == s)
            continue;
        if (a == MS_CX_NONE)
            a = t[m];
        else
            b = t[m];
    }
    if (a > b) {
        uint32_t x = a;
        a = b;
        b = x;
    }
    return (uint64_t)a << 32 | b;
}

static bool bsearch_u64(const uint64_t *a, size_t n, uint64_t k)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = (lo + hi) / 2;
        if (a[mid] < k)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < n && a[lo] == k;
}

/* Stamps (new marks) the vertices that share a maximal edge with c0. */
static void mark_edge_neighbours(ms_complex *cx, uint32_t c0)
{
    ms_cx_new_marks(cx);
    ms_cx_vert *v0 = &cx->v[c0];
    const uint32_t *l0 = ms_cx_list(v0);
    for (uint32_t i = 0; i < v0->n; ++i) {
        if (l0[i] & 1) {
            uint32_t e = l0[i] >> 1;
            uint32_t o = cx->edge[e][0] == c0 ? cx->edge[e][1] : cx->edge[e][0];
            cx->stamp[o] = cx->cur;
        }
    }
}

/* Stamps (stamp2, new marks) the triangle neighbours of c0 and deletes c0's
 * maximal edges a triangle now covers. */
static void drop_covered_edges(ms_complex *cx, uint32_t c0)
{
    ms_cx_new_marks2(cx); /* stamp2: triangle neighbours of c0 */
    ms_cx_vert *v0 = &cx->v[c0];
    uint32_t *l0 = ms_cx_list(v0);
    for (uint32_t i = 0; i < v0->n; ++i) {
        if (!(l0[i] & 1)) {
            const uint32_t *t = cx->tri[l0[i] >> 1];
            for (int m = 0; m < 3; ++m)
                cx->stamp2[t[m]] = cx->cur2;
        }
    }
    for (uint32_t i = 0; i < v0->n;) {
        if (l0[i] & 1) {
            uint32_t e = l0[i] >> 1;
            uint32_t o = cx->edge[e][0] == c0 ? cx->edge[e][1] : cx->edge[e][0];
            if (cx->stamp2[o] == cx->cur2) {
                ms_cx_del_edge(cx, e); /* swaps the last entry into i */
                l0 = ms_cx_list(&cx->v[c0]);
                continue;
            }
        }
        ++i;
    }
}

ms_status ms_cx_merge(ms_complex *cx, uint32_t c0, uint32_t c1, ms_error *err)
{
    ms_cx_vert *v1 = &cx->v[c1];
    uint32_t n1 = v1->n;
    uint32_t n0 = cx->v[c0].n;
    /* Scratch: copy of c1's list, c0's triangle pairs, collapsed third vertices. */
    uint32_t stack[64];
    uint64_t stack64[64];
    uint32_t *l1 = n1 * 2 <= 64 ? stack : malloc((size_t)n1 * 2 * sizeof *l1);
    uint64_t *pairs = n0 <= 64 ? stack64 : malloc((size_t)n0 * sizeof *pairs);
    if (!l1 || !pairs) {
        if (l1 != stack)
            free(l1);
        if (pairs != stack64)
            free(pairs);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory merging cells");
    }
    uint32_t *collapsed = l1 + n1;
    memcpy(l1, ms_cx_list(v1), (size_t)n1 * sizeof *l1);
    uint32_t ncol = 0;
    /* a. triangles holding both centres collapse to edges (c0, x). */
    for (uint32_t i = 0; i < n1; ++i) {
        if (l1[i] & 1)
            continue;
        uint32_t t = l1[i] >> 1;
        if (tri_has(cx->tri[t], c0)) {
            for (int m = 0; m < 3; ++m)
                if (cx->tri[t][m] != c0 && cx->tri[t][m] != c1)
                    collapsed[ncol++] = cx->tri[t][m];
            ms_cx_del_tri(cx, t);
            l1[i] = MS_CX_NONE;
        }
    }
    /* b. c1's other triangles move to c0 unless c0 already has the same one. */
    ms_cx_vert *v0 = &cx->v[c0];
    uint32_t *l0 = ms_cx_list(v0);
    uint32_t np = 0;
    for (uint32_t i = 0; i < v0->n; ++i)
        if (!(l0[i] & 1))
            pairs[np++] = tri_other_pair(cx->tri[l0[i] >> 1], c0);
    ms_cx_sort_keys(pairs, np);
    for (uint32_t i = 0; i < n1; ++i) {
        if (l1[i] == MS_CX_NONE || (l1[i] & 1))
            continue;
        uint32_t t = l1[i] >> 1;
        if (bsearch_u64(pairs, np, tri_other_pair(cx->tri[t], c1))) {
            ms_cx_del_tri(cx, t);
        } else {
            for (int m = 0; m < 3; ++m)
                if (cx->tri[t][m] == c1)
                    cx->tri[t][m] = c0;
            ms_cx_list_remove(cx, c1, t << 1);
            ms_cx_list_add(cx, c0, t << 1);
        }
    }
    /* c. maximal edges of c1. Mark c0's edge neighbours first. */
    mark_edge_neighbours(cx, c0);
    for (uint32_t i = 0; i < n1; ++i) {
        if (l1[i] == MS_CX_NONE || !(l1[i] & 1))
            continue;
        uint32_t e = l1[i] >> 1;
        uint32_t o = cx->edge[e][0] == c1 ? cx->edge[e][1] : cx->edge[e][0];
        if (o == c0 || cx->stamp[o] == cx->cur) {
            ms_cx_del_edge(cx, e);
        } else {
            if (cx->edge[e][0] == c1)
                cx->edge[e][0] = c0;
            else
                cx->edge[e][1] = c0;
            ms_cx_list_remove(cx, c1, e << 1 | 1);
            ms_cx_list_add(cx, c0, e << 1 | 1);
            cx->stamp[o] = cx->cur;
        }
    }
    /* d. c0's maximal edges covered by a triangle are no longer maximal; e. the
     * collapsed triangles leave maximal edges where nothing covers them. */
    drop_covered_edges(cx, c0);
    mark_edge_neighbours(cx, c0); /* now */
    ms_status st = ms_cx_reserve(cx, 0, 0, ncol, err);
    for (uint32_t i = 0; i < ncol && st == MS_OK; ++i) {
        uint32_t x = collapsed[i];
        if (cx->stamp2[x] == cx->cur2 || cx->stamp[x] == cx->cur)
            continue;
        ms_cx_add_edge(cx, c0, x);
        cx->stamp[x] = cx->cur;
    }
    /* f. c1 is gone. Any entry left in its list would be a bug. */
    assert(cx->v[c1].n == 0 || cx->nomem);
    ms_cx_free_vertex(cx, c1);
    if (l1 != stack)
        free(l1);
    if (pairs != stack64)
        free(pairs);
    if (st != MS_OK)
        return st;
    if (cx->nomem)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory merging cells");
    return MS_OK;
}

/* Puts element src[i] of array a (and of b, when not NULL) at i, src a
 * permutation of [0, n), in place with one copy per element by following
 * cycles; src becomes the identity. Inlined so that each caller's element
 * sizes are constants and the copies plain moves. */
static inline __attribute__((always_inline)) void permute_in_place(uint32_t *src, uint32_t n,
                                                                   unsigned char *a, size_t sa,
                                                                   unsigned char *b, size_t sb)
{
    unsigned char ta[sizeof(ms_cx_vert)], tb[sizeof(ms_cx_vert)];
    assert(sa <= sizeof ta && sb <= sizeof tb);
    for (uint32_t i = 0; i < n; ++i) {
        if (src[i] == i)
            continue;
        memcpy(ta, a + (size_t)i * sa, sa);
        if (b)
            memcpy(tb, b + (size_t)i * sb, sb);
        uint32_t j = i;
        for (;;) {
            uint32_t k = src[j];
            src[j] = j;
            if (k == i)
                break;
            memcpy(a + (size_t)j * sa, a + (size_t)k * sa, sa);
            if (b)
                memcpy(b + (size_t)j * sb, b + (size_t)k * sb, sb);
            j = k;
        }
        memcpy(a + (size_t)j * sa, ta, sa);
        if (b)
            memcpy(b + (size_t)j * sb, tb, sb);
    }
}

ms_status ms_cx_compact(ms_complex *cx, uint32_t *order, uint32_t n, ms_error *err)
{
    assert(n == cx->live_v);
    /* maps old -> new and new -> old */
    uint32_t *vmap = malloc((size_t)(cx->nv ? cx->nv : 1) * sizeof *vmap);
    uint32_t *vsrc = malloc((size_t)(cx->nv ? cx->nv : 1) * sizeof *vsrc);
    uint32_t *tmap = malloc((size_t)(cx->nt ? cx->nt : 1) * sizeof *tmap);
    uint32_t *tsrc = malloc((size_t)(cx->nt ? cx->nt : 1) * sizeof *tsrc);
    if (!vmap || !vsrc || !tmap || !tsrc) {
        free(vmap), free(vsrc), free(tmap), free(tsrc);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory compacting the complex");
    }
    /* Vertex slots: live ones in the given order, free ones after them. */
    memset(vmap, 0xFF, (size_t)cx->nv * sizeof *vmap);
    for (uint32_t i = 0; i < n; ++i) {
        vmap[order[i]] = i;
        vsrc[i] = order[i];
    }
    uint32_t next = n;
    for (uint32_t s = 0; s < cx->nv; ++s)
        if (vmap[s] == MS_CX_NONE) {
            vsrc[next] = s;
            vmap[s] = next++;
        }
    /* Triangles: numbered as first met along the new vertex order, free ones
     * after; the lists and simplices get the new numbers before anything moves. */
    memset(tmap, 0xFF, (size_t)cx->nt * sizeof *tmap);
    uint32_t nt = 0;
    for (uint32_t i = 0; i < n; ++i) {
        ms_cx_vert *v = &cx->v[order[i]];
        uint32_t *l = ms_cx_list(v);
        for (uint32_t k = 0; k < v->n; ++k) {
            if (l[k] & 1)
                continue;
            /* first met or not is a coin toss: numbered by selection */
            uint32_t t = l[k] >> 1, m = tmap[t];
            uint32_t fresh = m == MS_CX_NONE;
            m = fresh ? nt : m;
            nt += fresh;
            tmap[t] = m;
            l[k] = m << 1;
        }
        ms_cx_list_reindex(v); /* the entries were renamed */
    }
    uint32_t live_t = nt;
    for (uint32_t t = 0; t < cx->nt; ++t) {
        if (tmap[t] == MS_CX_NONE)
            tmap[t] = nt++;
        tsrc[tmap[t]] = t;
        if (tmap[t] >= live_t)
            continue;
        for (int m = 0; m < 3; ++m)
            cx->tri[t][m] = vmap[cx->tri[t][m]];
    }
    for (uint32_t e = 0; e < cx->ne; ++e)
        if (cx->edge[e][0] != MS_CX_NONE) {
            cx->edge[e][0] = vmap[cx->edge[e][0]];
            cx->edge[e][1] = vmap[cx->edge[e][1]];
        }
    permute_in_place(tsrc, cx->nt, (unsigned char *)cx->tri, sizeof *cx->tri, NULL, 0);
    if (cx->ahead) /* the same permutation on a copy (vmap is spent): the next call consumes vsrc */
        memcpy(vmap, vsrc, (size_t)cx->nv * sizeof *vsrc);
    permute_in_place(vsrc, cx->nv, (unsigned char *)cx->v, sizeof *cx->v,
                     (unsigned char *)cx->cen, sizeof *cx->cen);
    if (cx->ahead)
        permute_in_place(vmap, cx->nv, (unsigned char *)cx->ahead, sizeof *cx->ahead,
                         (unsigned char *)cx->rep, sizeof *cx->rep);
    cx->nv = n;
    cx->nfree_v = 0;
    cx->nt = live_t;
    cx->nfree_t = 0;
    memset(cx->stamp, 0, (size_t)cx->cv * sizeof *cx->stamp);
    memset(cx->stamp2, 0, (size_t)cx->cv * sizeof *cx->stamp2);
    cx->cur = cx->cur2 = 1;
    for (uint32_t i = 0; i < n; ++i)
        order[i] = i;
    free(vmap);
    free(vsrc);
    free(tmap);
    free(tsrc);
    return MS_OK;
}
