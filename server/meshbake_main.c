/* meshbake: the baker's command line. For now one mode, --info, which parses a
 * mesh completely and reports what it holds; the baking modes will be added as
 * further modes of the same option parser. */
#include <getopt.h>
#include <inttypes.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "ms_mesh_reader.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

typedef enum bake_mode { MODE_NONE, MODE_INFO } bake_mode;

typedef struct bake_options {
    bake_mode mode;
    bool json;
    const char *input;
} bake_options;

static void print_usage(FILE *out)
{
    fputs("usage: meshbake --info FILE [--json]\n"
          "\n"
          "Reads a mesh (PLY ascii/binary, OBJ or OFF, optionally gzip-compressed).\n"
          "\n"
          "  --info        parse FILE completely and report format, counts, bounding box,\n"
          "                faces dropped by the cleaning policy, isolated vertices, bytes\n"
          "                parsed and parse time\n"
          "  --json        print the report as one JSON object on stdout\n"
          "  -h, --help    print this help and exit\n"
          "\n"
          "Exit status: 0 on success, 1 for an input error, 2 for a usage error.\n",
          out);
}

static int usage_error(const char *message, const char *detail)
{
    fprintf(stderr, "meshbake: %s%s%s (see meshbake --help)\n", message, detail ? ": " : "",
            detail ? detail : "");
    return EXIT_USAGE;
}

/* Returns -1 to go on, or the exit status to end with. */
static int parse_options(int argc, char **argv, bake_options *options)
{
    static const struct option long_options[] = {
        {"info", no_argument, NULL, 'i'},
        {"json", no_argument, NULL, 'j'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    memset(options, 0, sizeof *options);
    opterr = 0;
    int c;
    while ((c = getopt_long(argc, argv, ":h", long_options, NULL)) != -1) {
        switch (c) {
        case 'i': options->mode = MODE_INFO; break;
        case 'j': options->json = true; break;
        case 'h': print_usage(stdout); return EXIT_SUCCESS;
        default:
            return usage_error("unknown option", argv[optind - 1]);
        }
    }
    if (optind < argc)
        options->input = argv[optind++];
    if (optind < argc)
        return usage_error("unexpected argument", argv[optind]);
    if (options->mode == MODE_NONE)
        return usage_error("no mode given; baking is not implemented yet, use --info", NULL);
    if (!options->input)
        return usage_error("missing input file", NULL);
    return -1;
}

typedef struct progress_state {
    const char *path;
    struct timespec start;
    int last_percent;
    bool shown;
} progress_state;

static double seconds_since(const struct timespec *start)
{
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (double)(now.tv_sec - start->tv_sec) + 1e-9 * (double)(now.tv_nsec - start->tv_nsec);
}

/* A percentage on the terminal, only for reads that take a while. */
static void show_progress(void *context, uint64_t done, uint64_t total)
{
    progress_state *p = context;
    if (total == 0 || (!p->shown && seconds_since(&p->start) < 0.5))
        return;
    int percent = (int)(100.0 * (double)done / (double)total);
    if (percent == p->last_percent)
        return;
    p->last_percent = percent;
    p->shown = true;
    fprintf(stderr, "\rmeshbake: reading %s: %3d%%", p->path, percent);
    fflush(stderr);
}

static void print_json_string(const char *s)
{
    putchar('"');
    for (const unsigned char *c = (const unsigned char *)s; *c; ++c) {
        if (*c == '"' || *c == '\\')
            printf("\\%c", *c);
        else if (*c < 0x20)
            printf("\\u%04x", *c);
        else
            putchar(*c);
    }
    putchar('"');
}

static void print_json(const char *path, const ms_mesh_read_report *r, double seconds)
{
    fputs("{\"file\": ", stdout);
    print_json_string(path);
    printf(", \"format\": \"%s\", \"gzip\": %s", ms_mesh_format_name(r->format),
           r->gzip ? "true" : "false");
    printf(", \"vertices\": %" PRIu64 ", \"triangles\": %" PRIu64 ", \"input_faces\": %" PRIu64,
           r->vertices, r->triangles, r->input_faces);
    printf(", \"bbox_min\": [%.17g, %.17g, %.17g], \"bbox_max\": [%.17g, %.17g, %.17g]",
           r->bbox_min[0], r->bbox_min[1], r->bbox_min[2], r->bbox_max[0], r->bbox_max[1],
           r->bbox_max[2]);
    printf(", \"dropped_faces\": %" PRIu64 ", \"isolated_vertices\": %" PRIu64, r->dropped_faces,
           r->isolated_vertices);
    printf(", \"bytes\": %" PRIu64 ", \"seconds\": %.9f}\n", r->input_bytes, seconds);
}

static void print_text(const char *path, const ms_mesh_read_report *r, double seconds)
{
    printf("file:              %s\n", path);
    printf("format:            %s%s\n", ms_mesh_format_name(r->format),
           r->gzip ? " (gzip)" : "");
    printf("vertices:          %" PRIu64 "\n", r->vertices);
    printf("triangles:         %" PRIu64 " (from %" PRIu64 " faces or strips)\n", r->triangles,
           r->input_faces);
    printf("bounding box:      min %.9g %.9g %.9g\n", r->bbox_min[0], r->bbox_min[1],
           r->bbox_min[2]);
    printf("                   max %.9g %.9g %.9g\n", r->bbox_max[0], r->bbox_max[1],
           r->bbox_max[2]);
    printf("dropped faces:     %" PRIu64 " (repeated vertex)\n", r->dropped_faces);
    printf("isolated vertices: %" PRIu64 "\n", r->isolated_vertices);
    printf("bytes parsed:      %" PRIu64 "\n", r->input_bytes);
    printf("parse time:        %.3f s (%.1f MB/s)\n", seconds,
           seconds > 0 ? (double)r->input_bytes / seconds / 1e6 : 0.0);
}

static int run_info(const bake_options *options)
{
    progress_state progress = {.path = options->input, .last_percent = -1, .shown = false};
    const ms_mesh_sink sink = {
        .context = &progress,
        .progress = isatty(STDERR_FILENO) ? show_progress : NULL,
    };
    ms_mesh_read_report report;
    ms_error err;
    ms_error_clear(&err);
    clock_gettime(CLOCK_MONOTONIC, &progress.start);
    ms_status st = ms_mesh_read(options->input, &sink, &report, &err);
    double seconds = seconds_since(&progress.start);
    if (progress.shown)
        fputs("\r\033[K", stderr);
    if (st != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    if (options->json)
        print_json(options->input, &report, seconds);
    else
        print_text(options->input, &report, seconds);
    return fflush(stdout) == 0 ? EXIT_SUCCESS : EXIT_INPUT;
}

int main(int argc, char **argv)
{
    bake_options options;
    int status = parse_options(argc, argv, &options);
    if (status >= 0)
        return status;
    switch (options.mode) {
    case MODE_INFO: return run_info(&options);
    case MODE_NONE: break;
    }
    return EXIT_USAGE;
}
