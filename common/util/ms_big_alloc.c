/* Large working arrays with a transparent-huge-page hint: see ms_big_alloc.h. */
#include "ms_big_alloc.h"

#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

static void *hint_huge(void *p, size_t bytes)
{
#ifdef MADV_HUGEPAGE
    if (p && bytes >= MS_BIG_ALLOC_HINT) {
        const uintptr_t huge = (uintptr_t)2 << 20;
        uintptr_t lo = ((uintptr_t)p + huge - 1) & ~(huge - 1);
        uintptr_t hi = ((uintptr_t)p + bytes) & ~(huge - 1);
        if (hi > lo)
            (void)madvise((void *)lo, hi - lo, MADV_HUGEPAGE); /* a hint: failure is harmless */
    }
#else
    (void)bytes;
#endif
    return p;
}

void *ms_big_malloc(size_t bytes)
{
    return hint_huge(malloc(bytes), bytes);
}

void *ms_big_realloc(void *p, size_t bytes)
{
    return hint_huge(realloc(p, bytes), bytes);
}
