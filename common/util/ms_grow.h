/* Growing a realloc'd array: the one way the project makes room in a list
 * whose length is not known in advance.
 *
 * ms_grow makes *array (room for *cap items of `size` bytes) hold at least
 * `need` items: the capacity doubles from max(*cap, MS_GROW_FIRST) until it
 * suffices, so n pushes cost O(n) copies in all. Returns false, with *array
 * and *cap unchanged, when memory runs out or the byte size would overflow.
 * Ownership: *array stays the caller's (free it with free()).
 * Thread-safety: none of its own; the array is the caller's. */
#ifndef MS_GROW_H
#define MS_GROW_H

#include <stdbool.h>
#include <stddef.h>

#define MS_GROW_FIRST 64u

bool ms_grow(void **array, size_t *cap, size_t need, size_t size);

#endif
