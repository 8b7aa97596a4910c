/* meshconv: converts any mesh ms_mesh_load reads into PLY (binary by default). */
#include <float.h>
#include <getopt.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_mesh_io.h"
#include "ms_cli.h"
#include "ms_version.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

static void print_usage(FILE *out)
{
    fputs("usage: meshconv IN -o OUT.ply [--binary | --ascii] [--double]\n"
          "\n"
          "Reads IN (PLY ascii/binary, OBJ or OFF, optionally gzip-compressed), applies\n"
          "the input cleaning policy, and writes OUT as PLY.\n"
          "\n"
          "  -o, --output FILE  where to write (replaced atomically)\n"
          "  --binary           binary little-endian PLY (default)\n"
          "  --ascii            ascii PLY\n"
          "  --double           double-precision coordinates (default float; a coordinate\n"
          "                     a float cannot hold is refused without it)\n"
          "  -h, --help         print this help and exit\n"
          "      --version      print the version and exit\n",
          out);
}

static int usage_error(const char *message, const char *detail)
{
    return ms_cli_usage_error("meshconv", message, detail);
}

/* A float PLY must not turn a coordinate into Inf: refuse the first one past
 * FLT_MAX (the reader gives finite values only). */
static ms_status check_fits_float(const ms_mesh *mesh, ms_error *err)
{
    for (size_t i = 0; i < 3 * mesh->vertex_count; ++i)
        if (fabs(mesh->positions[i]) > FLT_MAX)
            return ms_error_set(err, MS_ERR_RANGE,
                                "vertex %zu: coordinate %g does not fit a float; use --double",
                                i / 3, mesh->positions[i]);
    return MS_OK;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshconv");
    static const struct option long_options[] = {
        {"output", required_argument, NULL, 'o'}, {"binary", no_argument, NULL, 'b'},
        {"ascii", no_argument, NULL, 'a'},        {"double", no_argument, NULL, 'd'},
        {"help", no_argument, NULL, 'h'},         {NULL, 0, NULL, 0},
    };
    const char *output = NULL;
    bool binary = true, use_double = false;
    int c;
    while ((c = ms_cli_next("meshconv", argc, argv, "o:h", long_options)) != -1) {
        switch (c) {
        case 'o': output = optarg; break;
        case 'b': binary = true; break;
        case 'a': binary = false; break;
        case 'd': use_double = true; break;
        case 'h': print_usage(stdout); return EXIT_SUCCESS;
        default: return EXIT_USAGE; /* reported by ms_cli_next */
        }
    }
    if (optind >= argc)
        return usage_error("missing input file", NULL);
    const char *input = argv[optind++];
    if (optind < argc)
        return usage_error("unexpected argument", argv[optind]);
    if (!output)
        return usage_error("missing -o OUT.ply", NULL);
    ms_mesh mesh = {0};
    ms_error err;
    ms_error_clear(&err);
    ms_status st = ms_mesh_load(input, &mesh, NULL, &err);
    if (st == MS_OK && !use_double)
        st = check_fits_float(&mesh, &err);
    if (st == MS_OK)
        st = ms_ply_write(output, &mesh, binary, use_double, &err);
    ms_mesh_free(&mesh);
    if (st != MS_OK) {
        fprintf(stderr, "meshconv: %s\n", err.text);
        return EXIT_INPUT;
    }
    return EXIT_SUCCESS;
}
