#include "ms_error.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

ms_status ms_error_set(ms_error *err, ms_status code, const char *fmt, ...)
{
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->text, sizeof err->text, fmt, ap);
        va_end(ap);
        /* Keep the promise of one line: fold any newline the message carried. */
        for (char *c = err->text; *c; ++c)
            if (*c == '\n' || *c == '\r')
                *c = ' ';
        err->code = code;
    }
    return code;
}

void ms_error_clear(ms_error *err)
{
    if (err) {
        err->code = MS_OK;
        err->text[0] = '\0';
    }
}

const char *ms_status_name(ms_status code)
{
    switch (code) {
    case MS_OK: return "ok";
    case MS_ERR_IO: return "i/o error";
    case MS_ERR_FORMAT: return "format error";
    case MS_ERR_NOMEM: return "out of memory";
    case MS_ERR_RANGE: return "value out of range";
    case MS_ERR_CORRUPT: return "corrupted data";
    case MS_ERR_ARG: return "bad argument";
    case MS_ERR_UNSUPPORTED: return "unsupported";
    case MS_ERR_EMPTY: return "empty input";
    }
    return "unknown error";
}
