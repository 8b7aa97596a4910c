/* Opening a file a person named (a model, a scene, a camera path, a config,
 * an archive): the one place every program opens its user-named inputs, so
 * that each refuses what is not a regular file the same way.
 *
 * Why: open(2) on a FIFO blocks until a writer comes, and reading a device or
 * a directory never ends or fails late; a program given one must say so at
 * once instead of hanging. The file is opened with O_NONBLOCK (a FIFO then
 * opens at once), checked with fstat on the descriptor (no race with a rename
 * between a check and the open), and put back in blocking mode.
 *
 * Errors: MS_ERR_IO with one line: "PATH: cannot open: <strerror>" or
 * "PATH: not a regular file (a FIFO|a directory|a device|a socket)".
 * Thread-safety: none shared. */
#ifndef MS_INPUT_FILE_H
#define MS_INPUT_FILE_H

#include <stddef.h>
#include <stdio.h>

#include "ms_error.h"

/* A read-only descriptor (O_CLOEXEC) of the regular file at path, in *fd
 * (the caller closes it); -1 on error. */
ms_status ms_input_open(const char *path, int *fd, ms_error *err);

/* The same as a stdio stream opened for reading ("rb"); NULL on error. The
 * caller fcloses it. */
ms_status ms_input_fopen(const char *path, FILE **file, ms_error *err);

/* Reads at most max + 1 bytes of the regular file at path (ms_input_fopen's
 * checks) into *text (malloc'd, max + 1 bytes; the caller frees it) and their
 * count into *length: a length past max tells the caller the file is larger
 * than it takes. MS_ERR_NOMEM, MS_ERR_IO ("PATH: read failed") or
 * ms_input_fopen's errors, with *text NULL. */
ms_status ms_input_read_most(const char *path, size_t max, char **text, size_t *length, ms_error *err);

#endif
