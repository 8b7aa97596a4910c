/* Buffered sequential input from a file that may be gzip-compressed.
 *
 * The mesh readers parse straight out of one large buffer: fill() guarantees a
 * number of bytes are contiguous in memory (or reports the end of the input), and
 * the parser advances `pos` itself. Compressed and plain files are read the same
 * way through zlib (gzopen detects gzip by its magic and passes other files
 * through). Offsets are in uncompressed bytes from the start of the input.
 *
 * Ownership: the source owns its buffer and file handle; ms_byte_source_close
 * releases both. Not thread-safe per object.
 */
#ifndef MS_BYTE_SOURCE_H
#define MS_BYTE_SOURCE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_byte_source {
    const char *path;   /* borrowed, for messages */
    void *gz;           /* gzFile */
    char *buf;          /* capacity + 1 bytes, so a text line can be NUL-terminated */
    size_t capacity;
    size_t pos;         /* next unread byte */
    size_t end;         /* one past the last valid byte */
    uint64_t base;      /* input offset of buf[0] */
    uint64_t file_size; /* on-disk size (compressed size for gzip), 0 if unknown */
    bool eof;           /* no more bytes will arrive after `end` */
    bool gzip;          /* input is gzip-compressed */
    bool mapped;        /* buf is a read-only mapping of the whole file */
    size_t map_size;
    size_t released;    /* mapped bytes already given back (page multiple) */
} ms_byte_source;

/* Opens path for reading with a buffer of `capacity` bytes (at least 64 KiB is
 * sensible). MS_ERR_IO if the file cannot be opened. */
ms_status ms_byte_source_open(ms_byte_source *src, const char *path, size_t capacity,
                              ms_error *err);

/* Makes at least `want` unread bytes contiguous at buf + pos, moving the unread
 * tail to the front of the buffer and reading more as needed. Returns MS_OK also
 * when the input ends first (then src->eof is set and fewer bytes are available);
 * MS_ERR_ARG if want exceeds the capacity; MS_ERR_IO on a read or decompression
 * error. */
ms_status ms_byte_source_fill(ms_byte_source *src, size_t want, ms_error *err);

/* Unread bytes now in the buffer. */
static inline size_t ms_byte_source_available(const ms_byte_source *src)
{
    return src->end - src->pos;
}

/* Input offset of the next unread byte. */
static inline uint64_t ms_byte_source_offset(const ms_byte_source *src)
{
    return src->base + src->pos;
}

/* For binary parsing of an uncompressed file: replaces the buffer by a read-only
 * memory mapping of the whole file, keeping the current offset, which saves the
 * copy from the page cache. Afterwards the buffer must not be written to and
 * fill() never reads. Does nothing (and returns MS_OK) for gzip input or when
 * mapping is not possible. */
ms_status ms_byte_source_map_rest(ms_byte_source *src, ms_error *err);

/* How far through the file on disk the reading is (compressed bytes for gzip). */
uint64_t ms_byte_source_disk_offset(const ms_byte_source *src);

/* For a mapped file, gives the pages already parsed back to the kernel, so that a
 * huge input does not stay resident (and counted in the process's RSS) behind
 * the read position. No effect on buffered reads. */
void ms_byte_source_release_consumed(ms_byte_source *src);

void ms_byte_source_close(ms_byte_source *src);

#endif
