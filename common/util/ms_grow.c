/* Growing a realloc'd array: see ms_grow.h. */
#include "ms_grow.h"

#include <stdint.h>
#include <stdlib.h>

bool ms_grow(void **array, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return true;
    if (size == 0 || need > SIZE_MAX / size)
        return false;
    size_t c = *cap > MS_GROW_FIRST ? *cap : MS_GROW_FIRST;
    while (c < need)
        c = c > SIZE_MAX / 2 ? need : 2 * c;
    if (c > SIZE_MAX / size)
        c = need;
    void *grown = realloc(*array, c * size);
    if (!grown)
        return false;
    *array = grown;
    *cap = c;
    return true;
}
