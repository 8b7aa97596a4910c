/* The one way every program reads its command line and reports a bad one.
 *
 * Options are parsed with getopt_long through ms_cli_next, which silences
 * getopt's own messages; every usage error, getopt's or the program's own
 * checks, goes through ms_cli_usage_error: exactly one line on stderr,
 *
 *     PROGRAM: MESSAGE[: DETAIL] (see PROGRAM --help)
 *
 * and the usage exit status 2 (README "Programs"). Not thread-safe (getopt's
 * state is the C library's); call from main only. */
#ifndef MS_CLI_H
#define MS_CLI_H

#include <getopt.h>

#define MS_CLI_USAGE 2    /* the exit status of a usage error */
#define MS_CLI_ERROR (-2) /* ms_cli_next: a bad option, already reported */

/* Prints the one line (detail may be NULL) and returns MS_CLI_USAGE. */
int ms_cli_usage_error(const char *program, const char *message, const char *detail);

/* Like ms_cli_usage_error with a printf-style message. */
int ms_cli_usage_errorf(const char *program, const char *format, ...)
    __attribute__((format(printf, 2, 3)));

/* getopt_long(argc, argv, shortopts, longopts, NULL) without getopt's own
 * messages: returns the next option's value, -1 after the last option, or
 * MS_CLI_ERROR after reporting "unknown option: X" or "option needs a value:
 * X" (the caller returns MS_CLI_USAGE). shortopts at most 62 characters. */
int ms_cli_next(const char *program, int argc, char **argv, const char *shortopts,
                const struct option *longopts);

#endif
