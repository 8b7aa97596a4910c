/* The browser pages' files deflated once, not at every request (the side
 * door's /view and /web routes, ms_http_pages.c; docs/BROWSER.md, "Serve").
 * Deflating the threaded module took about 18 ms of the door's thread per
 * request, the viewer's two scripts about 10 ms more: some 40 ms of the
 * server for each visitor's page, and as long before the module's first
 * byte. A file is known by its path and what stat says of it (device,
 * inode, size, modification time): a file rewritten in place, or replaced,
 * is deflated again at its next request.
 *
 * Ownership: the cache owns copies of the deflated bytes, at most max_bytes
 * of them in all (the oldest go first); the evbuffer a lookup returns is
 * the caller's. Errors: a file that cannot be read, is not a regular file,
 * is empty, larger than MS_PAGE_CACHE_FILE_MAX or would not shrink gives
 * NULL (the caller sends it as it is); so does a lack of memory.
 * Thread-safety: one thread (the side door's). */
#ifndef MS_PAGE_CACHE_H
#define MS_PAGE_CACHE_H

#include <stddef.h>
#include <stdint.h>

struct evbuffer;

typedef struct ms_page_cache ms_page_cache;

/* The largest file deflated (bytes). */
#define MS_PAGE_CACHE_FILE_MAX (4u << 20)

/* A cache holding at most max_bytes of deflated bytes (0: none kept, every
 * lookup deflates). NULL when out of memory. */
ms_page_cache *ms_page_cache_new(size_t max_bytes);
void ms_page_cache_free(ms_page_cache *cache);

/* The file at path deflated (zlib, RFC 1950: HTTP's "deflate", level 6) in a
 * new evbuffer, *length its size; NULL as above. */
struct evbuffer *ms_page_cache_deflated(ms_page_cache *cache, const char *path, uint64_t *length);

/* Lookups answered from the cache, and files deflated, so far. */
void ms_page_cache_counts(const ms_page_cache *cache, uint64_t *hits, uint64_t *deflated);

#endif
