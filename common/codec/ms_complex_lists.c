/* The complex's incidence lists (ms_complex.h): their growth, the hash
 * position index a long list keeps (so that taking one entry out of a
 * high-valence vertex's list is O(1), not a scan), and the adding and
 * removing of vertices, triangles and edges that keeps the lists right. */
#include "ms_complex.h"

#include <assert.h>
#include <stdlib.h>
#include <string.h>

/* Home slot of `tagged` in a position index of `size` pairs (2 cap: not a
 * power of two, since cap is MS_CX_INLINE times one). */
static uint32_t index_home(uint32_t tagged, uint32_t size)
{
    uint32_t h = tagged;
    h ^= h >> 16;
    h *= 0x7feb352du;
    h ^= h >> 15;
    h *= 0x846ca68bu;
    h ^= h >> 16;
    return h % size;
}

/* Slot of v's position index where `tagged` is, or the empty one where it
 * would go (at most half the slots are used, so one is found). */
static uint32_t index_slot(const ms_cx_vert *v, uint32_t tagged)
{
    uint32_t size = 2 * v->cap;
    for (uint32_t i = index_home(tagged, size);; i = i + 1 == size ? 0 : i + 1) {
        uint32_t k = v->where[2 * i];
        if (k == tagged || k == MS_CX_NONE)
            return i;
    }
}

void ms_cx_index_put(ms_cx_vert *v, uint32_t tagged, uint32_t pos)
{
    uint32_t i = index_slot(v, tagged);
    v->where[2 * i] = tagged;
    v->where[2 * i + 1] = pos;
}

/* Empties slot i of v's index: backward-shift deletion, so that no
 * tombstones accumulate however many entries come and go. */
static void index_del(ms_cx_vert *v, uint32_t i)
{
    uint32_t size = 2 * v->cap;
    uint32_t j = i;
    for (;;) {
        v->where[2 * i] = MS_CX_NONE;
        for (;;) {
            j = j + 1 == size ? 0 : j + 1;
            uint32_t k = v->where[2 * j];
            if (k == MS_CX_NONE)
                return;
            /* home slot of k: may it move back to the hole at i? Only when the
             * hole lies cyclically between its home and j. */
            uint32_t home = index_home(k, size);
            bool stays = i <= j ? (i < home && home <= j) : (i < home || home <= j);
            if (!stays)
                break;
        }
        v->where[2 * i] = v->where[2 * j];
        v->where[2 * i + 1] = v->where[2 * j + 1];
        i = j;
    }
}

void ms_cx_list_reindex(ms_cx_vert *v)
{
    if (v->cap < MS_CX_INDEXED)
        return;
    memset(v->where, 0xFF, (size_t)v->cap * 2 * 2 * sizeof *v->where);
    const uint32_t *l = v->ext;
    for (uint32_t i = 0; i < v->n; ++i)
        ms_cx_index_put(v, l[i], i);
}

bool ms_cx_list_grow(ms_complex *cx, ms_cx_vert *v)
{
    uint32_t cap = v->cap ? v->cap : MS_CX_INLINE;
    uint32_t ncap = cap * 2;
    uint32_t *n;
    uint32_t *where = NULL;
    if (ncap >= MS_CX_INDEXED) {
        where = malloc((size_t)ncap * 2 * 2 * sizeof *where);
        if (!where) {
            cx->nomem = 1;
            return false;
        }
    }
    if (v->cap) {
        n = realloc(v->ext, (size_t)ncap * sizeof *n);
    } else {
        n = malloc((size_t)ncap * sizeof *n);
        if (n)
            memcpy(n, v->inl, sizeof v->inl);
    }
    if (!n) {
        free(where);
        cx->nomem = 1;
        return false;
    }
    if (v->cap)
        free(v->where);
    v->ext = n;
    v->where = where;
    v->cap = ncap;
    ms_cx_list_reindex(v);
    return true;
}

void ms_cx_list_remove(ms_complex *cx, uint32_t s, uint32_t tagged)
{
    ms_cx_vert *v = &cx->v[s];
    uint32_t *l = ms_cx_list(v);
    if (v->cap >= MS_CX_INDEXED) {
        uint32_t slot = index_slot(v, tagged);
        if (v->where[2 * slot] != tagged)
            return; /* only after a list growth failure (cx->nomem already set) */
        uint32_t i = v->where[2 * slot + 1];
        index_del(v, slot);
        uint32_t last = l[--v->n];
        l[i] = last;
        if (i != v->n)
            ms_cx_index_put(v, last, i);
        return;
    }
    for (uint32_t i = 0; i < v->n; ++i) {
        if (l[i] == tagged) {
            l[i] = l[--v->n];
            return;
        }
    }
    /* Not found only after a list growth failure (cx->nomem already set). */
}

uint32_t ms_cx_add_vertex(ms_complex *cx, uint64_t key, unsigned level, const uint32_t c[3])
{
    uint32_t s;
    if (cx->nfree_v)
        s = cx->free_v[--cx->nfree_v];
    else {
        assert(cx->nv < cx->cv);
        s = cx->nv++;
        cx->stamp[s] = 0;
        cx->stamp2[s] = 0;
    }
    ms_cx_vert *v = &cx->v[s];
    memset(v, 0, sizeof *v);
    v->key = key;
    v->alive = 1;
    for (int a = 0; a < 3; ++a)
        cx->cen[s][a] = (int32_t)(2 * c[a] + ms_cx_width(cx, level, a));
    cx->cen[s][3] = (int32_t)level;
    ms_cx_rep_follow(cx, s);
    if (cx->ahead)
        cx->ahead[s] = 0;
    cx->live_v++;
    return s;
}

void ms_cx_free_vertex(ms_complex *cx, uint32_t s)
{
    ms_cx_vert *v = &cx->v[s];
    if (v->cap) {
        free(v->ext);
        free(v->where);
    }
    v->cap = 0;
    v->ext = NULL;
    v->where = NULL;
    v->n = 0;
    v->alive = 0;
    cx->free_v[cx->nfree_v++] = s;
    cx->live_v--;
}

uint32_t ms_cx_add_tri(ms_complex *cx, uint32_t a, uint32_t b, uint32_t c)
{
    uint32_t t;
    if (cx->nfree_t)
        t = cx->free_t[--cx->nfree_t];
    else {
        assert(cx->nt < cx->ct);
        t = cx->nt++;
    }
    cx->tri[t][0] = a;
    cx->tri[t][1] = b;
    cx->tri[t][2] = c;
    ms_cx_list_add(cx, a, t << 1);
    ms_cx_list_add(cx, b, t << 1);
    ms_cx_list_add(cx, c, t << 1);
    cx->live_t++;
    return t;
}

uint32_t ms_cx_add_edge(ms_complex *cx, uint32_t a, uint32_t b)
{
    uint32_t e;
    if (cx->nfree_e)
        e = cx->free_e[--cx->nfree_e];
    else {
        assert(cx->ne < cx->ce);
        e = cx->ne++;
    }
    cx->edge[e][0] = a;
    cx->edge[e][1] = b;
    ms_cx_list_add(cx, a, e << 1 | 1);
    ms_cx_list_add(cx, b, e << 1 | 1);
    cx->live_e++;
    return e;
}

void ms_cx_del_tri(ms_complex *cx, uint32_t t)
{
    for (int k = 0; k < 3; ++k)
        ms_cx_list_remove(cx, cx->tri[t][k], t << 1);
    cx->tri[t][0] = cx->tri[t][1] = cx->tri[t][2] = MS_CX_NONE;
    cx->free_t[cx->nfree_t++] = t;
    cx->live_t--;
}

void ms_cx_del_edge(ms_complex *cx, uint32_t e)
{
    ms_cx_list_remove(cx, cx->edge[e][0], e << 1 | 1);
    ms_cx_list_remove(cx, cx->edge[e][1], e << 1 | 1);
    cx->edge[e][0] = cx->edge[e][1] = MS_CX_NONE;
    cx->free_e[cx->nfree_e++] = e;
    cx->live_e--;
}
