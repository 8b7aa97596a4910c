/* Allocation of large working arrays (the codec's complex, the decoder's cell
 * order, the encoder's decision buffer).
 *
 * Same contract as malloc/realloc/free (NULL on failure, the old block kept),
 * plus a hint: a block of MS_BIG_ALLOC_HINT bytes or more asks the kernel
 * (madvise MADV_HUGEPAGE, where the system has it) to back its 2 MiB-aligned part
 * with transparent huge pages. Touching a fresh megabyte-scale array page by
 * page was 12-16 % of a full dragon decode or encode on the VMs we measure on;
 * huge pages take 512 times fewer faults. Where the hint is not available or is
 * refused nothing changes. Thread-safety: as malloc.
 */
#ifndef MS_BIG_ALLOC_H
#define MS_BIG_ALLOC_H

#include <stddef.h>

#define MS_BIG_ALLOC_HINT ((size_t)4 << 20)

void *ms_big_malloc(size_t bytes);
void *ms_big_realloc(void *p, size_t bytes);

#endif
