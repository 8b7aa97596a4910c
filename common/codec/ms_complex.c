#include "ms_complex.h"

#include "ms_big_alloc.h"
#include "ms_quant.h"

#include <assert.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(sizeof(ms_cx_vert) == 64, "a vertex record is one cache line");

ms_status ms_cx_init(ms_complex *cx, unsigned P, uint32_t max_v, uint32_t max_t, uint32_t max_e,
                     ms_error *err)
{
    memset(cx, 0, sizeof *cx);
    cx->P = P;
    cx->D = 3 * P;
    cx->max_v = max_v;
    cx->max_t = max_t;
    cx->max_e = max_e;
    cx->cur = 1;
    cx->cur2 = 1;
    return ms_cx_reserve(cx, 16 < max_v ? 16 : max_v, 16 < max_t ? 16 : max_t,
                         16 < max_e ? 16 : max_e, err);
}

void ms_cx_free(ms_complex *cx)
{
    if (!cx)
        return;
    if (cx->v)
        for (uint32_t i = 0; i < cx->nv; ++i)
            if (cx->v[i].cap) {
                free(cx->v[i].ext);
                free(cx->v[i].where);
            }
    free(cx->v);
    free(cx->cen);
    free(cx->ahead);
    free(cx->rep);
    free(cx->tri);
    free(cx->edge);
    free(cx->free_v);
    free(cx->free_t);
    free(cx->free_e);
    free(cx->mark);
    free(cx->stamp);
    free(cx->mark2);
    free(cx->stamp2);
    memset(cx, 0, sizeof *cx);
}

/* Grows an array of `item` byte elements from *cap to at least want (capped). */
static int grow(void **p, uint32_t *cap, uint32_t want, uint32_t hard, size_t item)
{
    if (want <= *cap)
        return 1;
    uint64_t c = *cap ? *cap : 16;
    while (c < want)
        c *= 2;
    if (c > hard)
        c = hard;
    if (c < want)
        return 0;
    void *n = ms_big_realloc(*p, (size_t)c * item);
    if (!n)
        return 0;
    *p = n;
    *cap = (uint32_t)c;
    return 1;
}

ms_status ms_cx_reserve(ms_complex *cx, uint32_t v, uint32_t t, uint32_t e, ms_error *err)
{
    if ((uint64_t)cx->live_v + v > cx->max_v || (uint64_t)cx->live_t + t > cx->max_t ||
        (uint64_t)cx->live_e + e > cx->max_e)
        return ms_error_set(err, MS_ERR_CORRUPT,
                            "complex exceeds its declared size (%u vertices, %u triangles, "
                            "%u edges)", cx->max_v, cx->max_t, cx->max_e);
    uint32_t want_v = cx->nfree_v >= v ? cx->nv : cx->nv + (v - cx->nfree_v);
    uint32_t want_t = cx->nfree_t >= t ? cx->nt : cx->nt + (t - cx->nfree_t);
    uint32_t want_e = cx->nfree_e >= e ? cx->ne : cx->ne + (e - cx->nfree_e);
    if (want_v > cx->cv) {
        uint32_t cap = cx->cv;
        void *p = cx->v;
        if (!grow(&p, &cap, want_v, cx->max_v, sizeof *cx->v))
            goto nomem;
        cx->v = p;
        int32_t (*cen)[4] = ms_big_realloc(cx->cen, (size_t)cap * sizeof *cx->cen);
        if (!cen)
            goto nomem;
        cx->cen = cen;
        if (cx->with_ahead) { /* (also below, when set after the first growth) */
            uint64_t *ahead = ms_big_realloc(cx->ahead, (size_t)cap * sizeof *cx->ahead);
            if (ahead)
                cx->ahead = ahead;
            int32_t (*rep)[4] = ms_big_realloc(cx->rep, (size_t)cap * sizeof *cx->rep);
            if (rep)
                cx->rep = rep;
            if (!ahead || !rep)
                goto nomem;
        }
        uint32_t c2 = cx->cv;
        p = cx->free_v;
        if (!grow(&p, &c2, cap, cap, sizeof(uint32_t)))
            goto nomem;
        cx->free_v = p;
        uint32_t *arrays[4] = {cx->mark, cx->stamp, cx->mark2, cx->stamp2};
        for (int i = 0; i < 4; ++i) {
            uint32_t *n = ms_big_realloc(arrays[i], (size_t)cap * sizeof(uint32_t));
            if (!n)
                goto nomem;
            if (i == 1 || i == 3)
                memset(n + cx->cv, 0, (size_t)(cap - cx->cv) * sizeof(uint32_t));
            arrays[i] = n;
            if (i == 0) cx->mark = n;
            if (i == 1) cx->stamp = n;
            if (i == 2) cx->mark2 = n;
            if (i == 3) cx->stamp2 = n;
        }
        cx->cv = cap;
    }
    if (cx->with_ahead && !cx->ahead && cx->cv) {
        cx->ahead = ms_big_realloc(NULL, (size_t)cx->cv * sizeof *cx->ahead);
        cx->rep = ms_big_realloc(NULL, (size_t)cx->cv * sizeof *cx->rep);
        if (!cx->ahead || !cx->rep)
            goto nomem;
    }
    if (want_t > cx->ct) {
        uint32_t cap = cx->ct;
        void *p = cx->tri;
        if (!grow(&p, &cap, want_t, cx->max_t, sizeof *cx->tri))
            goto nomem;
        cx->tri = p;
        uint32_t c2 = cx->ct;
        p = cx->free_t;
        if (!grow(&p, &c2, cap, cap, sizeof(uint32_t)))
            goto nomem;
        cx->free_t = p;
        cx->ct = cap;
    }
    if (want_e > cx->ce) {
        uint32_t cap = cx->ce;
        void *p = cx->edge;
        if (!grow(&p, &cap, want_e, cx->max_e, sizeof *cx->edge))
            goto nomem;
        cx->edge = p;
        uint32_t c2 = cx->ce;
        p = cx->free_e;
        if (!grow(&p, &c2, cap, cap, sizeof(uint32_t)))
            goto nomem;
        cx->free_e = p;
        cx->ce = cap;
    }
    return MS_OK;
nomem:
    return ms_error_set(err, MS_ERR_NOMEM, "out of memory growing the complex");
}

void ms_cx_new_marks(ms_complex *cx)
{
    if (++cx->cur == 0) {
        memset(cx->stamp, 0, (size_t)cx->cv * sizeof *cx->stamp);
        cx->cur = 1;
    }
}

void ms_cx_new_marks2(ms_complex *cx)
{
    if (++cx->cur2 == 0) {
        memset(cx->stamp2, 0, (size_t)cx->cv * sizeof *cx->stamp2);
        cx->cur2 = 1;
    }
}

void ms_cx_star_free(ms_cx_star *st)
{
    free(st->nbr);
    free(st->adj);
    free(st->both);
    free(st->pairs);
    free(st->perm);
    free(st->sortbuf);
    memset(st, 0, sizeof *st);
}

static int star_room(ms_cx_star *st, size_t n, size_t p)
{
    if (n > st->cap_n) {
        size_t c = st->cap_n ? st->cap_n : 64;
        while (c < n)
            c *= 2;
        uint32_t *a = realloc(st->nbr, c * sizeof *a);
        if (!a)
            return 0;
        st->nbr = a;
        uint8_t *b = realloc(st->adj, c);
        if (!b)
            return 0;
        st->adj = b;
        a = realloc(st->both, c * sizeof *a);
        if (!a)
            return 0;
        st->both = a;
        a = realloc(st->perm, (c + 1) * sizeof *a);
        if (!a)
            return 0;
        st->perm = a;
        st->cap_n = c;
    }
    if (p > st->cap_p) {
        size_t c = st->cap_p ? st->cap_p : 64;
        while (c < p)
            c *= 2;
        ms_cx_pair *a = realloc(st->pairs, c * sizeof *a);
        if (!a)
            return 0;
        st->pairs = a;
        st->cap_p = c;
    }
    size_t s = n > p ? n : p;
    if (s > st->cap_sort) {
        size_t c = st->cap_sort ? st->cap_sort : 64;
        while (c < s)
            c *= 2;
        uint64_t *a = realloc(st->sortbuf, c * sizeof *a);
        if (!a)
            return 0;
        st->sortbuf = a;
        st->cap_sort = c;
    }
    return 1;
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : (x > y);
}

void ms_cx_sort_keys(uint64_t *a, size_t n)
{
    if (n > 24) {
        qsort(a, n, sizeof *a, cmp_u64);
        return;
    }
    for (size_t i = 1; i < n; ++i) {
        uint64_t x = a[i];
        size_t j = i;
        while (j > 0 && a[j - 1] > x) {
            a[j] = a[j - 1];
            --j;
        }
        a[j] = x;
    }
}

static int cmp_pair(const void *a, const void *b)
{
    const ms_cx_pair *x = a, *y = b;
    if (x->i != y->i)
        return x->i < y->i ? -1 : 1;
    return x->j < y->j ? -1 : (x->j > y->j);
}

/* Adds neighbour slot s (not a centre) to the star if new; returns local index. */
static inline uint32_t star_touch(ms_complex *cx, ms_cx_star *st, uint32_t s)
{
    if (cx->stamp[s] == cx->cur)
        return cx->mark[s];
    cx->stamp[s] = cx->cur;
    cx->mark[s] = st->nn;
    st->nbr[st->nn] = s;
    st->adj[st->nn] = 0;
    st->both[st->nn] = MS_CX_NONE;
    return st->nn++;
}

/* Local index of neighbour slot s in a small star, added if new (linear search:
 * cheaper than the slot-indexed marks, which cost two cache misses, for the
 * usual handful of neighbours). */
static inline uint32_t small_star_touch(ms_cx_star *st, uint32_t s)
{
    /* no early exit and no branch on the outcome: where a neighbour is found,
     * and whether it is new, are unpredictable; the loop length is not. The
     * candidate is written past the end either way (room: star_room's
     * 2 * MS_CX_SMALL_STAR + 2) and kept when new. */
    uint32_t n = st->nn, found = n;
    for (uint32_t i = 0; i < n; ++i)
        found = st->nbr[i] == s ? i : found;
    st->nbr[n] = s;
    st->nn = n + (found == n);
    return found;
}

/* Bit i of a 10-bit value moved to bit 3 i (a constant table: 4 KiB). */
#define SPREAD10(x)                                                                         \
    (((x)&1u) | (((x)&2u) << 2) | (((x)&4u) << 4) | (((x)&8u) << 6) | (((x)&16u) << 8) |   \
     (((x)&32u) << 10) | (((x)&64u) << 12) | (((x)&128u) << 14) | (((x)&256u) << 16) |     \
     (((x)&512u) << 18))
#define SPREAD10_4(b) SPREAD10(b), SPREAD10(b + 1), SPREAD10(b + 2), SPREAD10(b + 3)
#define SPREAD10_16(b) SPREAD10_4(b), SPREAD10_4(b + 4), SPREAD10_4(b + 8), SPREAD10_4(b + 12)
#define SPREAD10_64(b) SPREAD10_16(b), SPREAD10_16(b + 16), SPREAD10_16(b + 32), SPREAD10_16(b + 48)
#define SPREAD10_256(b) SPREAD10_64(b), SPREAD10_64(b + 64), SPREAD10_64(b + 128), SPREAD10_64(b + 192)
static const uint32_t spread10[1024] = {SPREAD10_256(0u), SPREAD10_256(256u), SPREAD10_256(512u),
                                        SPREAD10_256(768u)};

/* Sort keys of the n neighbours nbr of a small star: keys that order them as
 * their cells' keys do. That is the Morton order of their doubled centres on
 * the doubled (P + 1 bit) grid, where each lies inside its cell's key range
 * as its corner does on the grid, so distinct (disjoint) cells sort as their
 * keys do. The centres of a star nearly always differ only within ten
 * consecutive bit positions; the bits above and below those are common to
 * all and cannot change the order, so the ten are interleaved from a table.
 * Wider stars take the full 63-bit interleave. Returns whether the keys are
 * the narrow ones (below 2^30). */
static bool small_star_keys(const ms_complex *cx, const uint32_t *nbr, uint32_t n, uint64_t *key)
{
    if (n == 0)
        return true;
    const int32_t *first = cx->cen[nbr[0]];
    uint32_t differ = 0;
    for (uint32_t i = 1; i < n; ++i) {
        const int32_t *c = cx->cen[nbr[i]];
        differ |= (uint32_t)((c[0] ^ first[0]) | (c[1] ^ first[1]) | (c[2] ^ first[2]));
    }
    unsigned low = differ ? (unsigned)__builtin_ctz(differ) : 0;
    if ((differ >> low) < 1024u) {
        for (uint32_t i = 0; i < n; ++i) {
            const uint32_t *c = (const uint32_t *)cx->cen[nbr[i]];
            key[i] = spread10[(c[0] >> low) & 1023] << 2 | spread10[(c[1] >> low) & 1023] << 1 |
                     spread10[(c[2] >> low) & 1023];
        }
        return true;
    }
    for (uint32_t i = 0; i < n; ++i) {
        const int32_t *c = cx->cen[nbr[i]];
        key[i] = ms_quant_key((uint32_t)c[0], (uint32_t)c[1], (uint32_t)c[2], cx->P + 1);
    }
    return false;
}

/* Compare-exchange of v[a] and v[b], the smaller to a (selects, no branch). */
static inline void sort_exchange(uint64_t *v, int a, int b)
{
    uint64_t x = v[a], y = v[b];
    v[a] = x < y ? x : y;
    v[b] = x < y ? y : x;
}

/* Sorts eight values with the 19-comparator network of depth 6 (Knuth, TAOCP
 * 5.3.4): a fixed sequence of selections, where a comparison sort branches
 * unpredictably. */
static inline void sort8_u64(uint64_t v[8])
{
    sort_exchange(v, 0, 2);
    sort_exchange(v, 1, 3);
    sort_exchange(v, 4, 6);
    sort_exchange(v, 5, 7);
    sort_exchange(v, 0, 4);
    sort_exchange(v, 1, 5);
    sort_exchange(v, 2, 6);
    sort_exchange(v, 3, 7);
    sort_exchange(v, 0, 1);
    sort_exchange(v, 2, 3);
    sort_exchange(v, 4, 5);
    sort_exchange(v, 6, 7);
    sort_exchange(v, 2, 4);
    sort_exchange(v, 3, 5);
    sort_exchange(v, 1, 4);
    sort_exchange(v, 3, 6);
    sort_exchange(v, 1, 2);
    sort_exchange(v, 3, 4);
    sort_exchange(v, 5, 6);
}

/* rank[i] = number of values of x[0..n) (distinct) below x[i]: a count, with
 * no branch on the comparisons. */
static void rank_distinct_u64(const uint64_t *x, uint32_t n, uint32_t *rank)
{
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t r = 0;
        for (uint32_t j = 0; j < n; ++j)
            r += x[j] < x[i];
        rank[i] = r;
    }
}

/* Sorts x[0..n) (distinct, below UINT64_MAX) ascending in place; x has room
 * for eight at least. Up to eight (most stars) go through the network, the
 * room past n padded with values that sort last; more are ranked by
 * counting, also without branches on the comparisons. */
static void sort_distinct_u64(uint64_t *x, uint32_t n)
{
    if (n <= 8) {
        for (uint32_t i = n; i < 8; ++i)
            x[i] = UINT64_MAX;
        sort8_u64(x);
        return;
    }
    uint64_t in[2 * MS_CX_SMALL_STAR];
    uint32_t rank[2 * MS_CX_SMALL_STAR];
    memcpy(in, x, (size_t)n * sizeof *x);
    rank_distinct_u64(in, n, rank);
    for (uint32_t i = 0; i < n; ++i)
        x[rank[i]] = in[i];
}

/* ms_cx_gather for one centre with at most MS_CX_SMALL_STAR incident simplices:
 * the same star, built without the per-slot marks. */
static void gather_small(ms_complex *cx, uint32_t c0, ms_cx_star *st)
{
    const ms_cx_vert *v = &cx->v[c0];
    const uint32_t *l = v->cap ? v->ext : v->inl;
    uint32_t nl = v->n, np = 0;
    uint32_t pi[MS_CX_SMALL_STAR], pj[MS_CX_SMALL_STAR], pt[MS_CX_SMALL_STAR];
    st->nn = 0;
    for (uint32_t k = 0; k < nl; ++k) {
        uint32_t id = l[k] >> 1;
        if (l[k] & 1) {
            const uint32_t *e = cx->edge[id];
            small_star_touch(st, e[0] == c0 ? e[1] : e[0]);
            continue;
        }
        const uint32_t *t = cx->tri[id];
        /* the two corners other than c0, selected by masks (no branch) */
        uint32_t m0 = 0u - (uint32_t)(t[0] == c0), m2 = 0u - (uint32_t)(t[2] == c0);
        uint32_t a = (t[1] & m0) | (t[0] & ~m0);
        uint32_t b = (t[1] & m2) | (t[2] & ~m2);
        pi[np] = small_star_touch(st, a);
        pj[np] = small_star_touch(st, b);
        pt[np++] = id;
    }
    uint32_t n = st->nn;
    /* order the neighbours by key: perm[new] = old, rank[old] = new */
    uint64_t key[2 * MS_CX_SMALL_STAR];
    uint32_t perm[2 * MS_CX_SMALL_STAR], rank[2 * MS_CX_SMALL_STAR], slot[2 * MS_CX_SMALL_STAR];
    if (small_star_keys(cx, st->nbr, n, key)) {
        /* narrow keys leave room for the old index below them */
        for (uint32_t i = 0; i < n; ++i)
            key[i] = key[i] << 6 | i;
        sort_distinct_u64(key, n);
        for (uint32_t r = 0; r < n; ++r) {
            perm[r] = (uint32_t)(key[r] & 63);
            rank[perm[r]] = r;
        }
    } else {
        rank_distinct_u64(key, n, rank); /* the keys of distinct cells are distinct */
        for (uint32_t i = 0; i < n; ++i)
            perm[rank[i]] = i;
    }
    memcpy(slot, st->nbr, (size_t)n * sizeof *slot);
    for (uint32_t i = 0; i < n; ++i) {
        st->nbr[i] = slot[perm[i]];
        st->adj[i] = 1;
        st->both[i] = MS_CX_NONE;
    }
    /* pairs sorted by (i, j): per smaller index i a mask of the larger ones,
     * read back in order; a repeated pair (a duplicate triangle) keeps the
     * later triangle, as the general gather does */
    uint64_t row[2 * MS_CX_SMALL_STAR];
    uint32_t tri_of[2 * MS_CX_SMALL_STAR][2 * MS_CX_SMALL_STAR];
    memset(row, 0, (size_t)n * sizeof *row);
    for (uint32_t p = 0; p < np; ++p) {
        uint32_t i = rank[pi[p]], j = rank[pj[p]];
        uint32_t lo = i < j ? i : j, hi = i < j ? j : i;
        row[lo] |= 1ull << hi;
        tri_of[lo][hi] = pt[p];
    }
    uint32_t w = 0;
    for (uint32_t i = 0; i < n; ++i)
        for (uint64_t r = row[i]; r; r &= r - 1) {
            uint32_t j = (uint32_t)__builtin_ctzll(r);
            st->pairs[w++] = (ms_cx_pair){i, j, tri_of[i][j], MS_CX_NONE};
        }
    st->np = w;
}

ms_status ms_cx_gather(ms_complex *cx, uint32_t c0, uint32_t c1, ms_cx_star *st, ms_error *err)
{
    if (c1 == MS_CX_NONE && cx->v[c0].n <= MS_CX_SMALL_STAR) {
        if (!star_room(st, 2 * MS_CX_SMALL_STAR + 2, MS_CX_SMALL_STAR + 1))
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory gathering a star");
        st->adj01 = false;
        st->edge01 = MS_CX_NONE;
        gather_small(cx, c0, st);
        return MS_OK;
    }
    return ms_cx_gather_general(cx, c0, c1, st, err);
}

/* Pass 1 of a star: the neighbours of the centres into st->nbr, st->adj
 * (which centres each is adjacent to) and st->both, and whether the two
 * centres are adjacent (st->adj01, st->edge01). */
static void star_neighbours(ms_complex *cx, const uint32_t *centres, int nc, ms_cx_star *st)
{
    for (int k = 0; k < nc; ++k) {
        ms_cx_vert *v = &cx->v[centres[k]];
        uint32_t *l = ms_cx_list(v);
        for (uint32_t i = 0; i < v->n; ++i) {
            uint32_t id = l[i] >> 1;
            if (l[i] & 1) {
                uint32_t o = cx->edge[id][0] == centres[k] ? cx->edge[id][1] : cx->edge[id][0];
                if (nc == 2 && o == centres[1 - k]) {
                    st->adj01 = true;
                    st->edge01 = id;
                    continue;
                }
                st->adj[star_touch(cx, st, o)] |= (uint8_t)(1 << k);
            } else {
                const uint32_t *t = cx->tri[id];
                bool has_other = nc == 2 && (t[0] == centres[1 - k] || t[1] == centres[1 - k] ||
                                             t[2] == centres[1 - k]);
                for (int m = 0; m < 3; ++m) {
                    uint32_t o = t[m];
                    if (o == centres[k] || (nc == 2 && o == centres[1 - k]))
                        continue;
                    uint32_t li = star_touch(cx, st, o);
                    st->adj[li] |= (uint8_t)(1 << k);
                    if (has_other)
                        st->both[li] = id;
                }
                if (has_other)
                    st->adj01 = true;
            }
        }
    }
}

/* The order of the star's n neighbours by key (keys are unique among live
 * cells): perm[i] is the old index of the i-th; insertion sort of (key, old
 * index) for the usual small stars, qsort beyond. */
static void neighbour_order(const ms_complex *cx, const ms_cx_star *st, uint32_t n)
{
    uint64_t *keys = st->sortbuf;         /* n keys */
    uint32_t *perm = st->perm;            /* n old indices */
    for (uint32_t i = 0; i < n; ++i) {
        keys[i] = cx->v[st->nbr[i]].key;
        perm[i] = i;
    }
    if (n <= 48) {
        for (uint32_t i = 1; i < n; ++i) {
            uint64_t k = keys[i];
            uint32_t p = perm[i], j = i;
            while (j > 0 && keys[j - 1] > k) {
                keys[j] = keys[j - 1];
                perm[j] = perm[j - 1];
                --j;
            }
            keys[j] = k;
            perm[j] = p;
        }
    } else {
        ms_cx_sort_keys(keys, n);
        for (uint32_t i = 0; i < n; ++i) {
            uint64_t k = cx->v[st->nbr[i]].key;
            uint32_t lo = 0, hi = n;
            while (lo < hi) {
                uint32_t mid = (lo + hi) / 2;
                if (keys[mid] < k)
                    lo = mid + 1;
                else
                    hi = mid;
            }
            perm[lo] = i;
        }
    }
}

/* Puts the star's n neighbours in the order of st->perm, and cx->mark of
 * each at its new index. */
static ms_status permute_neighbours(ms_complex *cx, ms_cx_star *st, uint32_t n, ms_error *err)
{
    const uint32_t *perm = st->perm;
    uint8_t adj_stack[64];
    uint32_t both_stack[64], nbr_stack[64];
    uint8_t *adj_tmp = adj_stack;
    uint32_t *both_tmp = both_stack, *nbr_tmp = nbr_stack;
    if (n > 64) {
        adj_tmp = malloc(n);
        both_tmp = malloc((size_t)n * sizeof *both_tmp);
        nbr_tmp = malloc((size_t)n * sizeof *nbr_tmp);
        if (!adj_tmp || !both_tmp || !nbr_tmp) {
            free(adj_tmp);
            free(both_tmp);
            free(nbr_tmp);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory sorting a star");
        }
    }
    memcpy(adj_tmp, st->adj, n);
    memcpy(both_tmp, st->both, (size_t)n * sizeof *both_tmp);
    memcpy(nbr_tmp, st->nbr, (size_t)n * sizeof *nbr_tmp);
    for (uint32_t i = 0; i < n; ++i) {
        uint32_t o = perm[i];
        st->nbr[i] = nbr_tmp[o];
        st->adj[i] = adj_tmp[o];
        st->both[i] = both_tmp[o];
        cx->mark[nbr_tmp[o]] = i;
    }
    if (n > 64) {
        free(adj_tmp);
        free(both_tmp);
        free(nbr_tmp);
    }
    return MS_OK;
}

/* Pass 2 of a star: the pairs (triangles with exactly one centre) into
 * st->pairs, in list order; returns their count. */
static uint32_t star_pairs(ms_complex *cx, const uint32_t *centres, int nc, ms_cx_star *st)
{
    uint32_t np = 0;
    for (int k = 0; k < nc; ++k) {
        ms_cx_vert *v = &cx->v[centres[k]];
        uint32_t *l = ms_cx_list(v);
        for (uint32_t i = 0; i < v->n; ++i) {
            if (l[i] & 1)
                continue;
            uint32_t id = l[i] >> 1;
            const uint32_t *t = cx->tri[id];
            if (nc == 2 && (t[0] == centres[1 - k] || t[1] == centres[1 - k] ||
                            t[2] == centres[1 - k]))
                continue;
            uint32_t a = MS_CX_NONE, b = MS_CX_NONE;
            for (int m = 0; m < 3; ++m) {
                if (t[m] == centres[k])
                    continue;
                if (a == MS_CX_NONE)
                    a = cx->mark[t[m]];
                else
                    b = cx->mark[t[m]];
            }
            if (a > b) {
                uint32_t tmp = a;
                a = b;
                b = tmp;
            }
            st->pairs[np].i = a;
            st->pairs[np].j = b;
            st->pairs[np].t0 = k == 0 ? id : MS_CX_NONE;
            st->pairs[np].t1 = k == 1 ? id : MS_CX_NONE;
            np++;
        }
    }
    return np;
}

static void sort_pairs(ms_cx_pair *pairs, uint32_t np)
{
    if (np > 32) {
        qsort(pairs, np, sizeof *pairs, cmp_pair);
    } else {
        for (uint32_t a = 1; a < np; ++a) {
            ms_cx_pair x = pairs[a];
            uint32_t b = a;
            while (b > 0 && cmp_pair(&pairs[b - 1], &x) > 0) {
                pairs[b] = pairs[b - 1];
                --b;
            }
            pairs[b] = x;
        }
    }
}

/* Combines the (c0,x,y) and (c1,x,y) entries of the sorted pairs; returns
 * how many are left. */
static uint32_t combine_pairs(ms_cx_pair *pairs, uint32_t np)
{
    uint32_t w = 0;
    for (uint32_t r = 0; r < np; ++r) {
        if (w > 0 && pairs[w - 1].i == pairs[r].i && pairs[w - 1].j == pairs[r].j) {
            if (pairs[r].t0 != MS_CX_NONE)
                pairs[w - 1].t0 = pairs[r].t0;
            if (pairs[r].t1 != MS_CX_NONE)
                pairs[w - 1].t1 = pairs[r].t1;
            continue;
        }
        pairs[w++] = pairs[r];
    }
    return w;
}

ms_status ms_cx_gather_general(ms_complex *cx, uint32_t c0, uint32_t c1, ms_cx_star *st,
                               ms_error *err)
{
    uint32_t centres[2] = {c0, c1};
    int nc = c1 == MS_CX_NONE ? 1 : 2;
    size_t total = cx->v[c0].n + (nc == 2 ? cx->v[c1].n : 0);
    if (!star_room(st, 2 * total + 2, total + 1))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory gathering a star");
    st->nn = 0;
    st->np = 0;
    st->adj01 = false;
    st->edge01 = MS_CX_NONE;
    ms_cx_new_marks(cx);
    star_neighbours(cx, centres, nc, st);
    if (st->nn > 1) {
        neighbour_order(cx, st, st->nn);
        ms_status s = permute_neighbours(cx, st, st->nn, err);
        if (s != MS_OK)
            return s;
    }
    uint32_t np = star_pairs(cx, centres, nc, st);
    sort_pairs(st->pairs, np);
    st->np = combine_pairs(st->pairs, np);
    return MS_OK;
}
