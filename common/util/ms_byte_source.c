#include "ms_byte_source.h"
#include "ms_input_file.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

ms_status ms_byte_source_open(ms_byte_source *src, const char *path, size_t capacity,
                              ms_error *err)
{
    memset(src, 0, sizeof *src);
    src->path = path;
    int fd;
    ms_status opened = ms_input_open(path, &fd, err); /* a FIFO or a directory: refused */
    if (opened != MS_OK)
        return opened;
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int saved = errno;
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    src->file_size = (uint64_t)st.st_size;
    src->buf = malloc(capacity + 1);
    if (!src->buf) {
        close(fd);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for input buffer", path);
    }
    src->capacity = capacity;
    gzFile gz = gzdopen(fd, "rb");
    if (!gz) {
        int saved = errno;
        close(fd);
        free(src->buf);
        src->buf = NULL;
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path,
                            saved ? strerror(saved) : "zlib could not open it");
    }
    /* zlib reads a plain file straight into our buffer for requests of at least
     * twice this size (else it copies through its own); our fills ask for at
     * least 1 MiB. */
    gzbuffer(gz, 128 * 1024);
    src->gz = gz;
    return MS_OK;
}

ms_status ms_byte_source_fill(ms_byte_source *src, size_t want, ms_error *err)
{
    if (src->end - src->pos >= want || src->eof)
        return MS_OK;
    if (want > src->capacity)
        return ms_error_set(err, MS_ERR_ARG, "%s: internal: request of %zu bytes exceeds buffer",
                            src->path, want);
    if (src->pos > 0) {
        size_t keep = src->end - src->pos;
        memmove(src->buf, src->buf + src->pos, keep);
        src->base += src->pos;
        src->pos = 0;
        src->end = keep;
    }
    while (src->end - src->pos < want && !src->eof) {
        size_t room = src->capacity - src->end;
        size_t missing = want - (src->end - src->pos);
        /* Big steps, but not the whole buffer for a small request (the first
         * look at a file that will then be memory-mapped). */
        size_t step = missing > (1u << 20) ? missing : (1u << 20);
        unsigned ask = (unsigned)(step < room ? step : room);
        int got = gzread((gzFile)src->gz, src->buf + src->end, ask);
        if (got < 0) {
            int zerr = 0;
            const char *msg = gzerror((gzFile)src->gz, &zerr);
            return ms_error_set(err, MS_ERR_IO, "%s: byte offset %llu: read failed: %s",
                                src->path, (unsigned long long)(src->base + src->end),
                                zerr == Z_ERRNO ? strerror(errno) : msg);
        }
        if (got == 0) {
            /* zlib reports a truncated gzip stream as an error only through
             * gzerror after the final read. */
            int zerr = 0;
            const char *msg = gzerror((gzFile)src->gz, &zerr);
            if (zerr != Z_OK && zerr != Z_STREAM_END)
                return ms_error_set(err, MS_ERR_IO, "%s: byte offset %llu: read failed: %s",
                                    src->path, (unsigned long long)(src->base + src->end), msg);
            src->eof = true;
        }
        src->end += (size_t)got;
        if (!src->gzip && src->base == 0 && src->end > 0)
            src->gzip = gzdirect((gzFile)src->gz) == 0;
    }
    return MS_OK;
}

ms_status ms_byte_source_map_rest(ms_byte_source *src, ms_error *err)
{
    (void)err;
    if (src->gzip || src->mapped || src->file_size == 0 || src->file_size > SIZE_MAX)
        return MS_OK;
    uint64_t offset = ms_byte_source_offset(src);
    int fd;
    ms_error ignored;
    if (ms_input_open(src->path, &fd, &ignored) != MS_OK)
        return MS_OK; /* keep reading through the buffer */
    struct stat st;
    void *map = MAP_FAILED;
    /* Only map what we opened before: the file must not have changed size. */
    if (fstat(fd, &st) == 0 && (uint64_t)st.st_size == src->file_size && offset <= src->file_size)
        map = mmap(NULL, (size_t)src->file_size, PROT_READ, MAP_PRIVATE, fd, 0);
    close(fd);
    if (map == MAP_FAILED)
        return MS_OK;
    madvise(map, (size_t)src->file_size, MADV_SEQUENTIAL | MADV_WILLNEED);
    free(src->buf);
    src->buf = map;
    src->mapped = true;
    src->map_size = (size_t)src->file_size;
    src->capacity = src->map_size;
    src->base = 0;
    src->pos = (size_t)offset;
    src->end = src->map_size;
    src->eof = true;
    return MS_OK;
}

uint64_t ms_byte_source_disk_offset(const ms_byte_source *src)
{
    if (src->mapped)
        return ms_byte_source_offset(src);
    if (!src->gz)
        return 0;
    z_off_t off = gzoffset((gzFile)src->gz);
    return off < 0 ? 0 : (uint64_t)off;
}

void ms_byte_source_release_consumed(ms_byte_source *src)
{
    if (!src->mapped)
        return;
    long page = sysconf(_SC_PAGESIZE);
    if (page <= 0)
        return;
    size_t upto = src->pos / (size_t)page * (size_t)page;
    /* in steps of 8 MiB at least, to keep system calls rare */
    if (upto < src->released + ((size_t)8 << 20))
        return;
    madvise(src->buf + src->released, upto - src->released, MADV_DONTNEED);
    src->released = upto;
}

void ms_byte_source_close(ms_byte_source *src)
{
    if (src->gz)
        gzclose((gzFile)src->gz);
    if (src->mapped)
        munmap(src->buf, src->map_size);
    else
        free(src->buf);
    memset(src, 0, sizeof *src);
}
