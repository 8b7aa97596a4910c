/* Removing repeated triangles from an index list, shared by the nSP encoder (a
 * cell's complex from its leaves or children) and the APO sampling surfaces.
 *
 * Reentrant; no global state.
 */
#ifndef MS_TRI_UNIFY_H
#define MS_TRI_UNIFY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* The three indices of t in increasing order. */
void ms_tri_sort3(const uint32_t *t, uint32_t s[3]);

/* Removes from tris (3 vertex indices each, *count triangles) every triangle
 * whose vertex set repeats an earlier one: the earliest copy stays and the
 * others keep their order. When conflict is non-NULL, a repeat with the other
 * cyclic order sets *conflict to true. *count becomes the new count; *removed
 * (may be NULL) grows by the number removed. Any index values (a radix sort of
 * packed keys below 2^21, a comparison sort above). MS_ERR_NOMEM leaves the
 * list unchanged. */
ms_status ms_tri_unify(uint32_t *tris, size_t *count, bool *conflict, size_t *removed,
                       ms_error *err);

#endif
