/* Removing repeated triangles: see ms_tri_unify.h. */
#include "ms_tri_unify.h"

#include <stdlib.h>
#include <string.h>

#include "ms_radix_sort.h"

void ms_tri_sort3(const uint32_t *t, uint32_t s[3])
{
    uint32_t a = t[0], b = t[1], c = t[2], x;
    if (a > b)
        x = a, a = b, b = x;
    if (b > c)
        x = b, b = c, c = x;
    if (a > b)
        x = a, a = b, b = x;
    s[0] = a, s[1] = b, s[2] = c;
}

/* Same cyclic order. */
static bool same_orientation(const uint32_t *a, const uint32_t *b)
{
    for (int r = 0; r < 3; ++r)
        if (a[0] == b[r] && a[1] == b[(r + 1) % 3] && a[2] == b[(r + 2) % 3])
            return true;
    return false;
}

typedef struct keyed_triangle {
    uint32_t v[3]; /* sorted vertex indices */
    uint32_t seq;  /* position in the list */
} keyed_triangle;

static int cmp_keyed(const void *x, const void *y)
{
    const keyed_triangle *a = x, *b = y;
    for (int i = 0; i < 3; ++i)
        if (a->v[i] != b->v[i])
            return a->v[i] < b->v[i] ? -1 : 1;
    return a->seq < b->seq ? -1 : (a->seq > b->seq);
}

/* seq[0..n): the triangles grouped by vertex set, each group in list order. */
static ms_status group_by_vertex_set(const uint32_t *tris, size_t n, uint32_t *seq,
                                     ms_error *err)
{
    uint32_t top = 0;
    for (size_t i = 0; i < 3 * n; ++i)
        top = tris[i] > top ? tris[i] : top;
    if (top < (1u << 21)) {
        uint64_t *key = malloc((n ? n : 1) * sizeof *key);
        if (!key)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory unifying triangles");
        for (size_t i = 0; i < n; ++i) {
            uint32_t v[3];
            ms_tri_sort3(&tris[3 * i], v);
            key[i] = (uint64_t)v[0] << 42 | (uint64_t)v[1] << 21 | v[2];
            seq[i] = (uint32_t)i;
        }
        ms_status s = ms_radix_sort_pairs(key, seq, n, 63, err);
        free(key);
        return s;
    }
    keyed_triangle *kt = malloc((n ? n : 1) * sizeof *kt);
    if (!kt)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory unifying triangles");
    for (size_t i = 0; i < n; ++i) {
        ms_tri_sort3(&tris[3 * i], kt[i].v);
        kt[i].seq = (uint32_t)i;
    }
    qsort(kt, n, sizeof *kt, cmp_keyed);
    for (size_t i = 0; i < n; ++i)
        seq[i] = kt[i].seq;
    free(kt);
    return MS_OK;
}

ms_status ms_tri_unify(uint32_t *tris, size_t *count, bool *conflict, size_t *removed,
                       ms_error *err)
{
    size_t n = *count;
    uint32_t *seq = malloc((n ? n : 1) * sizeof *seq);
    uint8_t *drop = calloc(n ? n : 1, 1);
    ms_status s = seq && drop ? group_by_vertex_set(tris, n, seq, err)
                              : ms_error_set(err, MS_ERR_NOMEM, "out of memory unifying triangles");
    for (size_t i = 1; s == MS_OK && i < n; ++i) {
        uint32_t a[3], b[3];
        ms_tri_sort3(&tris[3 * (size_t)seq[i - 1]], a);
        ms_tri_sort3(&tris[3 * (size_t)seq[i]], b);
        if (memcmp(a, b, sizeof a) != 0)
            continue;
        size_t g = i - 1; /* the group's first: the earliest copy */
        while (drop[seq[g]])
            --g;
        drop[seq[i]] = 1;
        if (conflict && !same_orientation(&tris[3 * (size_t)seq[g]], &tris[3 * (size_t)seq[i]]))
            *conflict = true;
    }
    size_t w = 0;
    for (size_t i = 0; s == MS_OK && i < n; ++i)
        if (!drop[i]) {
            if (w != i)
                memcpy(&tris[3 * w], &tris[3 * i], 12);
            w++;
        }
    if (s == MS_OK) {
        if (removed)
            *removed += n - w;
        *count = w;
    }
    free(seq);
    free(drop);
    return s;
}
