/* A C string written as a JSON string literal (quotes, backslashes and control
 * characters escaped), for the command lines' hand-written JSON reports.
 * Thread-safety: as stdio's. */
#ifndef MS_JSON_STRING_H
#define MS_JSON_STRING_H

#include <stdio.h>

void ms_json_print_string(FILE *out, const char *s);

#endif
