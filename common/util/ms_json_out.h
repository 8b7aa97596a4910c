/* JSON reports on stdout built with jansson: the pieces every program's --json
 * output shares, so that no program writes JSON by hand.
 *
 * Strings: C strings from the command line or the file system are bytes of no
 * known encoding, while JSON text is UTF-8 and jansson refuses anything else.
 * ms_json_text keeps valid UTF-8 exactly (quotes, backslashes and control
 * characters are escaped by jansson on output) and writes each byte that is not
 * part of a valid UTF-8 sequence as U+FFFD, so a report is always valid JSON.
 *
 * Numbers: JSON has no NaN or infinity; ms_json_number writes them as null.
 *
 * Ownership: the constructors return a new reference (NULL only when memory
 * runs out, which jansson's setters then ignore); ms_json_print steals root.
 * Thread-safety: reentrant; ms_json_print is as stdio's. */
#ifndef MS_JSON_OUT_H
#define MS_JSON_OUT_H

#include <jansson.h>
#include <stdio.h>

/* A JSON string from bytes s (NUL-terminated; NULL gives null), lossless for UTF-8. */
json_t *ms_json_text(const char *s);

/* A JSON real, or null when v is NaN or infinite. */
json_t *ms_json_number(double v);

/* v rounded to the given number of decimals (0..9), as a JSON real (null when
 * not finite): for figures read by people and by scripts/bench-* tables, which
 * would otherwise show every digit of a timing. */
json_t *ms_json_fixed(double v, int decimals);

/* How a report is written on its line: MS_JSON_SPACED or MS_JSON_COMPACT, to
 * which MS_JSON_EXACT may be added (a bit set). */
typedef enum {
    MS_JSON_SPACED = 0,  /* "key": value, items separated by ", " */
    MS_JSON_COMPACT = 1, /* "key":value, items separated by ","; kept for the
                            reports that scripts/bench-* read with sed
                            (meshbake's bake report, the APO classic report) */
    MS_JSON_EXACT = 2,   /* reals with 17 significant digits, so that every
                            double reads back exactly (default: 15, so that a
                            decimal of up to 15 digits, such as an
                            ms_json_fixed value, reads back as written) */
} ms_json_layout;

/* Writes root as one line in the given layout, then a newline, to out, and
 * releases root. Returns 0, or -1 when root is NULL or the write failed. */
int ms_json_print(FILE *out, json_t *root, int layout);

#endif
