/* meshsynth: writes a synthetic archive with realistic payload sizes into an
 * archive directory, for load tests and benchmarks of meshserve. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_parse_number.h"
#include "ms_cli.h"
#include "ms_synthetic_archive.h"
#include "ms_version.h"

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: meshsynth ARCHIVE_DIR NAME [options]\n"
            "Writes ARCHIVE_DIR/NAME.msa, a synthetic model (a complete nSP tree with\n"
            "pseudo-random payloads of realistic sizes, not viewable geometry), and adds it to\n"
            "ARCHIVE_DIR/catalog.json. For load tests and benchmarks of meshserve.\n\n"
            "  --levels L           nSP levels below the root, 0..3 (1, 65, 4161 or 266305\n"
            "                       cells; default 2)\n"
            "  --bits P             precision bits, 8..20 (default 12)\n"
            "  --geometry-bytes B   mean geometry payload per cell (default 24576)\n"
            "  --apo-bytes B        mean APO chunk per cell, 0 = none (default 16384)\n"
            "  --apo-levels N       APO levels per cell, 1..12 (default 5)\n"
            "  --public-bits B      precision open without a token (default: all)\n"
            "  --seed S             changes every payload byte (default 1)\n"
            "  -h, --help           show this help\n"
            "      --version        show the version\n");
}


int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshsynth");
    static const struct option options[] = {
        {"levels", required_argument, NULL, 'l'},     {"bits", required_argument, NULL, 'b'},
        {"geometry-bytes", required_argument, NULL, 'g'},
        {"apo-bytes", required_argument, NULL, 'a'},  {"apo-levels", required_argument, NULL, 'L'},
        {"public-bits", required_argument, NULL, 'p'}, {"seed", required_argument, NULL, 's'},
        {"help", no_argument, NULL, 'h'},             {NULL, 0, NULL, 0},
    };
    ms_synthetic_spec spec = {2, 12, 24576, 16384, 5, 1, 255};
    int c;
    int64_t v = 0;
    ms_error e;
    while ((c = ms_cli_next("meshsynth", argc, argv, "h", options)) != -1) {
        ms_status bad = MS_OK;
        switch (c) {
        case 'l': bad = ms_option_int("--levels", optarg, 0, 3, &v, &e); spec.levels = (unsigned)v; break;
        case 'b': bad = ms_option_int("--bits", optarg, 0, 20, &v, &e); spec.bits = (unsigned)v; break;
        case 'g':
            bad = ms_option_int("--geometry-bytes", optarg, 0, 64 << 20, &v, &e);
            spec.geometry_bytes = (uint32_t)v;
            break;
        case 'a':
            bad = ms_option_int("--apo-bytes", optarg, 0, 64 << 20, &v, &e);
            spec.apo_bytes = (uint32_t)v;
            break;
        case 'L':
            bad = ms_option_int("--apo-levels", optarg, 0, 12, &v, &e);
            spec.apo_levels = (unsigned)v;
            break;
        case 'p':
            bad = ms_option_int("--public-bits", optarg, 0, 20, &v, &e);
            spec.public_max_bits = (uint8_t)v;
            break;
        case 's': bad = ms_option_int("--seed", optarg, 0, UINT32_MAX, &v, &e); spec.seed = (uint32_t)v; break;
        case 'h': usage(stdout); return 0;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
        if (bad != MS_OK) {
            return ms_cli_usage_error("meshsynth", e.text, NULL);
        }
    }
    if (optind != argc - 2) {
        fprintf(stderr, "meshsynth: expected ARCHIVE_DIR NAME (try 'meshsynth --help')\n");
        return 2;
    }
    ms_error err;
    if (ms_synthetic_archive_write(argv[optind], argv[optind + 1], &spec, &err) != MS_OK) {
        fprintf(stderr, "meshsynth: %s\n", err.text);
        return 1;
    }
    return 0;
}
