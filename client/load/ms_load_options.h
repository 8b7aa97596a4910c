/* meshload's command line: the options of one load run (streaming clients
 * along a camera path, or the Draco baseline), their defaults, the checks
 * across them, and the --help text.
 *
 * Ownership: the strings of an ms_load_options point into argv (or, for
 * host, into the struct itself); argv must outlive it.
 * Errors: ms_load_options_parse prints one line to stderr and returns 2 (the
 * usage-error exit status); 0 otherwise, with help set after -h/--help (the
 * caller prints ms_load_usage to stdout and exits 0).
 * Thread-safety: parsing uses getopt_long's globals; call it once, from main.
 */
#ifndef MS_LOAD_OPTIONS_H
#define MS_LOAD_OPTIONS_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

typedef struct ms_load_options {
    const char *host, *model, *path_file, *token, *baseline, *draco_decoder, *tmp_dir;
    const char *archive; /* local archive file instead of a server */
    uint16_t port;
    unsigned clients, apo_levels, decode_threads;
    double bandwidth; /* bytes per second per client; 0 = unlimited */
    double tolerance, duration, keyframe_timeout, width, height; /* px, s, s, px, px */
    double memory_target, memory_ceiling; /* MB; 0 = none */
    double hysteresis, culled_less;       /* bits */
    bool json, skip_cold, raw_index;
    bool whole_index;   /* take the whole index at open (no subtrees) */
    bool help;          /* -h/--help was given */
    char host_text[64]; /* what host points to */
} ms_load_options;

/* The --help text. */
void ms_load_usage(FILE *out);

/* Fills *o from argv (defaults for what is not given); 0 or 2 (see above). */
int ms_load_options_parse(int argc, char **argv, ms_load_options *o);

#endif
