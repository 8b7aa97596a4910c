/* meshgen: writes the built-in demo sculpture as a PLY file. */
#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_demo_model.h"
#include "ms_cli.h"
#include "ms_json_out.h"
#include "ms_mesh_io.h"
#include "ms_progress.h"
#include "ms_version.h"

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: meshgen -o OUT.ply [--triangles N] [--seed S] [--ascii] [--json]\n"
            "Writes meshstream's built-in demo model: a closed sculpture-like surface with\n"
            "fine relief (a displaced cubed sphere), 12 n^2 triangles for the grid n nearest\n"
            "to the requested count.\n\n"
            "  -o, --output FILE    PLY file to write (binary little-endian unless --ascii)\n"
            "  -t, --triangles N    approximate triangle count, 48 to 200000000 (default 200000)\n"
            "  -s, --seed S         relief variant, an unsigned integer (default 0)\n"
            "      --ascii          write ascii PLY\n"
            "      --json           print the summary as one JSON object\n"
            "  -h, --help           show this help\n"
            "      --version        show the version\n");
}

/* Parses an unsigned decimal integer within [min, max]; false on anything else. */
static bool parse_u64(const char *text, uint64_t min, uint64_t max, uint64_t *out)
{
    if (!text || !*text || *text == '-')
        return false;
    char *end;
    errno = 0;
    unsigned long long v = strtoull(text, &end, 10);
    if (errno || *end || v < min || v > max)
        return false;
    *out = v;
    return true;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshgen");
    const char *output = NULL;
    uint64_t triangles = 200000, seed = 0;
    bool ascii = false, json = false;
    enum { OPT_ASCII = 256, OPT_JSON };
    static const struct option options[] = {
        {"output", required_argument, NULL, 'o'}, {"triangles", required_argument, NULL, 't'},
        {"seed", required_argument, NULL, 's'},   {"ascii", no_argument, NULL, OPT_ASCII},
        {"json", no_argument, NULL, OPT_JSON},    {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    int c;
    while ((c = ms_cli_next("meshgen", argc, argv, "o:t:s:h", options)) != -1) {
        switch (c) {
        case 'o': output = optarg; break;
        case 't':
            if (!parse_u64(optarg, 48, 200000000, &triangles)) {
                return ms_cli_usage_error("meshgen", "--triangles wants an integer in [48, 200000000]", optarg);
            }
            break;
        case 's':
            if (!parse_u64(optarg, 0, UINT64_MAX, &seed)) {
                return ms_cli_usage_error("meshgen", "--seed wants an unsigned integer", optarg);
            }
            break;
        case OPT_ASCII: ascii = true; break;
        case OPT_JSON: json = true; break;
        case 'h': usage(stdout); return 0;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
    }
    if (optind < argc) {
        return ms_cli_usage_error("meshgen", "unexpected argument", argv[optind]);
    }
    if (!output) {
        return ms_cli_usage_error("meshgen", "missing -o OUT.ply", NULL);
    }

    ms_demo_model model = {.grid = ms_demo_grid_for_triangles(triangles), .seed = seed};
    uint64_t nv = ms_demo_vertex_count(&model), nt = ms_demo_triangle_count(&model);
    double start = ms_now_seconds();
    ms_error err;
    ms_ply_writer *w;
    ms_status st = ms_ply_writer_open(output, nv, nt, !ascii, false, &w, &err);
    ms_progress progress;
    ms_progress_init(&progress, stderr, "meshgen", nv + nt);
    for (uint64_t v = 0; st == MS_OK && v < nv; ++v) {
        double p[3];
        ms_demo_vertex(&model, v, p);
        st = ms_ply_writer_vertex(w, p, &err);
        if ((v & 0xffff) == 0)
            ms_progress_update(&progress, v);
    }
    for (uint64_t t = 0; st == MS_OK && t < nt; ++t) {
        uint32_t tri[3];
        ms_demo_triangle(&model, t, tri);
        st = ms_ply_writer_triangle(w, tri, &err);
        if ((t & 0xffff) == 0)
            ms_progress_update(&progress, nv + t);
    }
    if (st == MS_OK)
        st = ms_ply_writer_finish(w, &err);
    ms_progress_finish(&progress);
    if (st != MS_OK) {
        fprintf(stderr, "meshgen: %s\n", err.text);
        return 1;
    }
    double seconds = ms_now_seconds() - start;
    if (json)
        ms_json_print(stdout, json_pack("{s:o, s:i, s:I, s:I, s:I, s:o}", "output", ms_json_text(output), "grid",
                                        (int)model.grid, "seed", (json_int_t)seed, "vertices", (json_int_t)nv,
                                        "triangles", (json_int_t)nt, "seconds", ms_json_fixed(seconds, 3)),
                      MS_JSON_SPACED);
    else
        printf("meshgen: wrote %s: %" PRIu64 " vertices, %" PRIu64
               " triangles (grid %u, seed %" PRIu64 ") in %.2f s\n",
               output, nv, nt, model.grid, seed, seconds);
    return 0;
}
