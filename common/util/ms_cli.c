/* Command lines: see ms_cli.h. */
#include "ms_cli.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

int ms_cli_usage_error(const char *program, const char *message, const char *detail)
{
    fprintf(stderr, "%s: %s%s%s (see %s --help)\n", program, message, detail ? ": " : "",
            detail ? detail : "", program);
    return MS_CLI_USAGE;
}

int ms_cli_usage_errorf(const char *program, const char *format, ...)
{
    char message[512];
    va_list ap;
    va_start(ap, format);
    vsnprintf(message, sizeof message, format, ap);
    va_end(ap);
    return ms_cli_usage_error(program, message, NULL);
}

int ms_cli_next(const char *program, int argc, char **argv, const char *shortopts,
                const struct option *longopts)
{
    /* a leading ':' makes getopt tell a missing value (':') from an unknown
     * option ('?'); opterr = 0 keeps its own messages off */
    char spec[64] = ":";
    size_t n = strlen(shortopts);
    if (n > sizeof spec - 2)
        n = sizeof spec - 2;
    memcpy(spec + 1, shortopts[0] == ':' ? shortopts + 1 : shortopts, n);
    spec[n + 1] = 0;
    opterr = 0;
    int c = getopt_long(argc, argv, spec, longopts, NULL);
    if (c != '?' && c != ':')
        return c;
    char shown[3] = {'-', (char)optopt, 0};
    /* a long option is named by its word (argv[optind - 1]); a short one by
     * optopt, since it may sit inside a cluster such as -xq */
    const char *word = optind > 0 && optind <= argc ? argv[optind - 1] : "";
    const char *name = strncmp(word, "--", 2) == 0 || !(optopt > 0 && optopt < 128) ? word : shown;
    ms_cli_usage_error(program, c == ':' ? "option needs a value" : "unknown option", name);
    return MS_CLI_ERROR;
}
