/* A growable array of uint32_t for the APO octree builder's lists
 * (ms_apo_build.c): the common push inline, the growth out of line. */
#ifndef MS_APO_U32VEC_H
#define MS_APO_U32VEC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ms_grow.h"

typedef struct u32vec {
    uint32_t *v;
    size_t n, cap;
} u32vec;

static inline bool u32vec_grow(u32vec *a, uint32_t x)
{
    if (!ms_grow((void **)&a->v, &a->cap, a->n + 1, sizeof *a->v))
        return false;
    a->v[a->n++] = x;
    return true;
}

/* The common case inline, the growth out of line. */
static inline bool u32vec_push(u32vec *a, uint32_t x)
{
    if (a->n < a->cap) {
        a->v[a->n++] = x;
        return true;
    }
    return u32vec_grow(a, x);
}

static inline bool u32vec_append(u32vec *a, const uint32_t *x, size_t n)
{
    if (!ms_grow((void **)&a->v, &a->cap, a->n + n, sizeof *a->v))
        return false;
    if (n)
        memcpy(&a->v[a->n], x, n * sizeof *x);
    a->n += n;
    return true;
}

static inline void u32vec_free(u32vec *a)
{
    free(a->v);
    memset(a, 0, sizeof *a);
}

#endif
