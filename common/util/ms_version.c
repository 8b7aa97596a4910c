#include "ms_version.h"

#include <stdio.h>
#include <string.h>

#ifndef MS_VERSION
#error "MS_VERSION comes from the VERSION file through the Makefile"
#endif

const char *ms_version(void)
{
    return MS_VERSION;
}

bool ms_version_asked(int argc, char *const *argv)
{
    for (int i = 1; i < argc && argv[i]; ++i) {
        if (strcmp(argv[i], "--") == 0)
            return false;
        if (strcmp(argv[i], "--version") == 0)
            return true;
    }
    return false;
}

int ms_version_print(const char *program)
{
    if (printf("%s %s\n", program, MS_VERSION) < 0 || fflush(stdout) != 0)
        return 1;
    return 0;
}
