/* Decimal number parsing for the text mesh formats and for option values.
 *
 * The hot loop of an ascii reader is number parsing, so these avoid locale
 * look-ups and errno. Doubles are correctly rounded: the fast path is exact
 * (at most 19 significant digits with a mantissa below 2^53 and a power of ten
 * up to 1e22, one IEEE multiply or divide) and anything else goes to strtod.
 * Thread-safe (no state).
 */
#ifndef MS_PARSE_NUMBER_H
#define MS_PARSE_NUMBER_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"

/* True for the bytes that may end a number token in a NUL-terminated line. */
static inline bool ms_is_token_end(char c)
{
    return c == ' ' || c == '\t' || c == '\r' || c == '\0' || c == '\n' || c == '\v' ||
           c == '\f';
}

/* Parses one number token starting at s, which must lie in a NUL-terminated
 * string. The token must be followed by whitespace or the NUL. Accepts what
 * strtod accepts (so also "nan" and "inf"; the caller rejects non-finite values).
 * Returns the first byte after the token, or NULL if s does not start a number
 * token. */
const char *ms_parse_double(const char *s, double *out);

/* Parses an optionally signed decimal integer at s. Returns the first byte after
 * the digits (the caller checks what follows), or NULL if there are no digits or
 * the value does not fit in int64_t. */
const char *ms_parse_int64(const char *s, int64_t *out);

/* Option values ("--name VALUE" on a command line, "key = value" in a
 * configuration file): the whole text must be one number in [min, max]. On
 * failure err (MS_ERR_RANGE) holds the one wording every program uses:
 *   "NAME wants an integer in [MIN, MAX], got 'TEXT'"
 *   "NAME wants a number in [MIN, MAX], got 'TEXT'"
 * (the caller prefixes its program name or file position). `name` is the
 * option as the user wrote it ("--tolerance", "port"). */
ms_status ms_option_int(const char *name, const char *text, int64_t min, int64_t max,
                        int64_t *out, ms_error *err);
/* Finite decimal numbers only (no nan, no inf). */
ms_status ms_option_double(const char *name, const char *text, double min, double max,
                           double *out, ms_error *err);

#endif
