/* The baker's key file and its bounded page cache (ms_nsp_build.h).
 *
 * The key file holds every input vertex's 3p-bit key (p <= 20, so at most 60
 * bits), 8 bytes each in input order. While the triangles are distributed, a
 * triangle's three vertex numbers are turned into keys through a cache of
 * MS_NSP_KEY_PAGE_KEYS-key pages, 8-way set-associative (the set from a hash of
 * the page number, least recently used out): with a spatially coherent
 * numbering, as scanners and meshgen write, each page is read about once (a grid
 * walked across its rows needs two rows of pages, walked along its columns one
 * page per row: 4 KiB pages keep that in the cache); a random numbering reads a
 * page per corner, slower but in the same memory. A vertex used by a kept triangle gets the MS_NSP_KEY_USED mark
 * in its entry; marked pages are written back when evicted and by
 * ms_nsp_key_cache_write_back, after which the file tells the isolated vertices.
 *
 * Memory: the slots (bytes, at least MS_NSP_KEY_CACHE_MIN, at most the file).
 * Errors: MS_ERR_IO, MS_ERR_NOMEM, with one line. Thread-safety: one thread per
 * cache.
 */
#ifndef MS_NSP_KEY_CACHE_H
#define MS_NSP_KEY_CACHE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_nsp_build.h"

#define MS_NSP_KEY_PAGE_KEYS 512u              /* keys per page (4 KiB) */
#define MS_NSP_KEY_USED (UINT64_C(1) << 63)    /* a kept triangle uses the vertex */

typedef struct ms_nsp_key_cache ms_nsp_key_cache;

/* A cache over the key file fd of vertex_count keys. io (its pages read back
 * and written) and page_misses are increased as it works; both must outlive it. */
ms_status ms_nsp_key_cache_new(int fd, uint64_t vertex_count, size_t bytes, ms_nsp_io *io,
                               uint64_t *page_misses, ms_nsp_key_cache **cache, ms_error *err);

/* A triangle's three vertices' keys (each v[j] < vertex_count) into keys[],
 * without the mark; when the three keys are distinct, the vertices are marked
 * used (a degenerate triangle marks nothing). */
ms_status ms_nsp_key_cache_triangle(ms_nsp_key_cache *cache, const uint32_t v[3], uint64_t keys[3],
                                    ms_error *err);

/* Writes every marked page not yet on disk back to the file. */
ms_status ms_nsp_key_cache_write_back(ms_nsp_key_cache *cache, ms_error *err);

/* Frees the cache (not the file; marks not written back are lost). NULL is a no-op. */
void ms_nsp_key_cache_free(ms_nsp_key_cache *cache);

#endif
