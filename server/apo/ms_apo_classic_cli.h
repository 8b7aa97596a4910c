/* The command line of meshbake's classic mode (`meshbake IN --apo-classic ...`,
 * docs/APO.md "Classic whole-model mode"): parses its options, runs
 * ms_apo_classic_run and prints the report (text or --json) on stdout. Errors are
 * one line on stderr, prefixed "meshbake: ".
 *
 * Returns the exit status: 0 on success, 1 for an input or runtime error, 2 for
 * a usage error. Thread-safety: uses getopt's globals; one call per process at a
 * time.
 */
#ifndef MS_APO_CLASSIC_CLI_H
#define MS_APO_CLASSIC_CLI_H

#include <stdio.h>

int ms_apo_classic_cli(int argc, char **argv);

/* The mode's part of meshbake --help. */
void ms_apo_classic_cli_usage(FILE *out);

#endif
