/* Error reporting shared by every meshstream module.
 *
 * Functions that can fail return an ms_status (0 on success, a negative code
 * otherwise) and, when given a non-NULL ms_error, fill it with one line of text
 * that names the file and the offset or line where that makes sense. The text
 * never ends with a newline. ms_error is a plain value owned by the caller: no
 * allocation, safe to use from any thread as long as each thread has its own.
 */
#ifndef MS_ERROR_H
#define MS_ERROR_H

#include <stddef.h>

typedef enum ms_status {
    MS_OK = 0,
    MS_ERR_IO = -1,          /* open/read/write failed */
    MS_ERR_FORMAT = -2,      /* input does not follow its format */
    MS_ERR_NOMEM = -3,       /* allocation failed or a declared size is too large */
    MS_ERR_RANGE = -4,       /* a value is outside its valid range */
    MS_ERR_CORRUPT = -5,     /* checksum mismatch or inconsistent coded stream */
    MS_ERR_ARG = -6,         /* bad parameter from the caller */
    MS_ERR_UNSUPPORTED = -7, /* valid but not handled (unknown version, format) */
    MS_ERR_EMPTY = -8        /* nothing to work on (empty mesh) */
} ms_status;

#define MS_ERROR_TEXT_MAX 512

typedef struct ms_error {
    ms_status code;
    char text[MS_ERROR_TEXT_MAX];
} ms_error;

/* Records code and a printf-style message in err (if non-NULL); returns code so
 * callers can write `return ms_error_set(err, MS_ERR_FORMAT, "...")`. */
ms_status ms_error_set(ms_error *err, ms_status code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

/* Clears err to MS_OK and an empty text. Accepts NULL. */
void ms_error_clear(ms_error *err);

/* A short constant name for a status code ("format error", ...). */
const char *ms_status_name(ms_status code);

#endif
