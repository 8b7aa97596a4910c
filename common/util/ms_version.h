/* The one version of meshstream: the VERSION file at the repository root,
 * which the build passes to ms_version.c alone (so a new version relinks, it
 * does not recompile). Every program answers --version with it, and the
 * client library (msc_version) reports the same string.
 * Pure functions; thread-safe. */
#ifndef MS_VERSION_H
#define MS_VERSION_H

#include <stdbool.h>

/* "0.1.0": a static string, never NULL. */
const char *ms_version(void);

/* True when argv (argc entries, argv[0] the program) holds the argument
 * "--version" before any "--". Programs call it before parsing their options,
 * so that --version is answered whatever else is on the line. */
bool ms_version_asked(int argc, char *const *argv);

/* Prints "PROGRAM VERSION" and a newline on stdout; returns 0 (the exit status
 * for main), or 1 when stdout cannot be written. */
int ms_version_print(const char *program);

#endif
