/* User-named input files: see ms_input_file.h. */
#include "ms_input_file.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static const char *kind_of(mode_t mode)
{
    if (S_ISFIFO(mode))
        return "a FIFO";
    if (S_ISDIR(mode))
        return "a directory";
    if (S_ISCHR(mode) || S_ISBLK(mode))
        return "a device";
    if (S_ISSOCK(mode))
        return "a socket";
    return "not a plain file";
}

ms_status ms_input_open(const char *path, int *out, ms_error *err)
{
    *out = -1;
    /* O_NONBLOCK: a FIFO opens at once instead of waiting for a writer */
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0)
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    struct stat st;
    if (fstat(fd, &st) != 0) {
        int saved = errno;
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    if (!S_ISREG(st.st_mode)) {
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: not a regular file (%s)", path,
                            kind_of(st.st_mode));
    }
    int flags = fcntl(fd, F_GETFL);
    if (flags < 0 || fcntl(fd, F_SETFL, flags & ~O_NONBLOCK) != 0) {
        int saved = errno;
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    *out = fd;
    return MS_OK;
}

ms_status ms_input_fopen(const char *path, FILE **out, ms_error *err)
{
    *out = NULL;
    int fd;
    ms_status st = ms_input_open(path, &fd, err);
    if (st != MS_OK)
        return st;
    FILE *f = fdopen(fd, "rb");
    if (!f) {
        int saved = errno;
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(saved));
    }
    *out = f;
    return MS_OK;
}

ms_status ms_input_read_most(const char *path, size_t max, char **text, size_t *length, ms_error *err)
{
    *text = NULL;
    *length = 0;
    FILE *f;
    ms_status st = ms_input_fopen(path, &f, err);
    if (st != MS_OK)
        return st;
    char *buf = malloc(max + 1);
    size_t got = buf ? fread(buf, 1, max + 1, f) : 0;
    int failed = ferror(f);
    fclose(f);
    if (!buf)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    if (failed) {
        free(buf);
        return ms_error_set(err, MS_ERR_IO, "%s: read failed", path);
    }
    *text = buf;
    *length = got;
    return MS_OK;
}
