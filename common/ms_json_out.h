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

/* How a report is laid out on its line. */
typedef enum {
    MS_JSON_SPACED,  /* "key": value, items separated by ", " */
    MS_JSON_COMPACT, /* "key":value, items separated by ","; kept for the reports
                        that scripts/bench-* read with sed (meshbake's bake
                        report, the APO classic report) */
} ms_json_layout;

/* Writes root as one line in the given layout, reals with 17 significant digits
 * so that they read back exactly, then a newline, to out, and releases root.
 * Returns 0, or -1 when root is NULL or the write failed. */
int ms_json_print(FILE *out, json_t *root, ms_json_layout layout);

#endif
