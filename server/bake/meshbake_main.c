/* meshbake: the baker's command line. Modes: baking (IN -o ARCHIVE_DIR), which
 * turns a mesh into an archive of nSP cells with their APO chunks (ms_bake.h);
 * --info, which parses a mesh completely and reports what it holds; --list
 * and --remove, the archive directory as a collection (its catalogue, every
 * archive's checksums; taking a model out); and
 * --apo-classic, one whole-model APO for comparison with the published method
 * (ms_apo_classic_cli.h). */
#include <errno.h>
#include <getopt.h>
#include <inttypes.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include <jansson.h>

#include "ms_codec.h"

#include "ms_apo_classic_cli.h"
#include "ms_cli.h"
#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_bake_collection.h"
#include "ms_study_thumbnail.h"
#include "ms_catalog.h"
#include "ms_json_out.h"
#include "ms_mesh_colour.h"
#include "ms_mesh_edges.h"
#include "ms_mesh_reader.h"
#include "ms_parse_number.h"
#include "ms_version.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

typedef enum bake_mode {
    MODE_NONE, MODE_INFO, MODE_BAKE, MODE_SET_PUBLIC, MODE_LIST, MODE_REMOVE, MODE_THUMBNAIL,
    MODE_ANNOTATIONS
} bake_mode;

typedef struct bake_options {
    bake_mode mode;
    bool json;
    const char *input;
    ms_bake_options bake;
    unsigned set_public_bits; /* MODE_SET_PUBLIC */
    const char *list_dir;     /* MODE_LIST */
    const char *remove_name;  /* MODE_REMOVE */
    const char *thumbnail_name; /* MODE_THUMBNAIL */
    const char *metadata_path;  /* --metadata */
    const char *annotations_path; /* MODE_ANNOTATIONS */
} bake_options;

static void print_usage(FILE *out)
{
    fputs("usage: meshbake IN -o ARCHIVE_DIR [--name NAME] [--bits 16] [--n 4]\n"
          "                [--root-bits 7] [--min-tris T] [--threads N] [--mem MB]\n"
          "                [--tmp DIR] [--public-bits B] [--no-apo] [--apo-lead 1]\n"
          "                [--apo-max-depth 10] [--apo-tol 0.2] [--apo-budget 1]\n"
          "                [--apo-init-depth 0]\n"
          "                [--apo-verify] [--apo-accuracy] [--subtree-levels S] [--ahead 3]\n"
          "                [--ahead-until 5] [--smooth 5] [--colour-bits 8] [--no-colour] [--metadata FILE.json]\n"
          "                [--no-thumbnail] [--up x|y|z] [--json]\n"
          "       meshbake --info FILE [--json]\n"
          "       meshbake --set-public-bits B -o ARCHIVE_DIR --name NAME\n"
          "       meshbake --thumbnail NAME -o ARCHIVE_DIR [--up x|y|z] [--json]\n"
          "       meshbake --annotations FILE -o ARCHIVE_DIR --name NAME [--json]\n"
          "       meshbake --list ARCHIVE_DIR [--json]\n"
          "       meshbake --remove NAME -o ARCHIVE_DIR\n"
          "\n"
          "Reads a mesh (PLY ascii/binary, OBJ or OFF, optionally gzip-compressed).\n"
          "\n"
          "Baking: quantises IN, distributes its triangles into an nSP-tree out of core and\n"
          "encodes every cell as an independent progressive stream into ARCHIVE_DIR/NAME.msa,\n"
          "renders its thumbnail ARCHIVE_DIR/NAME.thumb.png (160x120, meshview's home view,\n"
          "at the preview's precision) and adds NAME to ARCHIVE_DIR/catalog.json.\n"
          "  -o, --output DIR  archive directory (must exist)\n"
          "  --name NAME       model name (default: the input file name without extensions)\n"
          "  --bits P          bits per coordinate, 8..20 (default 16)\n"
          "  --n N             nSP children per axis: 2, 4 or 8 (default 4)\n"
          "  --root-bits R     precision window of the root cell, log2(n)..P (default 7)\n"
          "  --min-tris T      a cell splits when it holds T triangles (default: 8000 up\n"
          "                    to 4 M input triangles, then 8000 x (triangles / 4 M)^(1/4)\n"
          "                    in hundreds, at most 24000: 10000 at 10 M, 17800 at 100 M)\n"
          "  --public-bits B   preview: precision anyone may read, 0..P; beyond it a\n"
          "                    client needs meshserve's token (default P: all public)\n"
          "  --threads N       encoding threads (default: the CPUs online)\n"
          "  --mem MB          memory budget (default 512): a quarter caches vertex keys,\n"
          "                    an eighth buffers leaf content, the rest is for encoding;\n"
          "                    refused below 2 MB + one leaf's working set per thread\n"
          "                    (about 512 bytes per --min-tris triangle; 24000 for the\n"
          "                    default)\n"
          "  --tmp DIR         temporary files (default: ARCHIVE_DIR); unlinked at creation\n"
          "  --subtree-levels S  levels of the nSP tree per index subtree, the pieces a\n"
          "                    client fetches the index in, 1..8 (default 1 for --n 4 or\n"
          "                    8, 2 for --n 2)\n"
          "  --ahead K         geometry ahead of connectivity by K kd-levels, 0..6\n"
          "                    (default 3): a coarse level draws each vertex at the\n"
          "                    barycentre of its known descendants, not at its kd-cell's\n"
          "                    centre (no staircase); 0 draws cell centres\n"
          "  --ahead-until B   geometry ahead stops at B bits, 0..7 (default 5; 0: at\n"
          "                    each cell's last bit): finer precisions code their geometry\n"
          "                    with their connectivity and are drawn by the smoothing\n"
          "                    alone, so their cuts cost no byte more than without it\n"
          "  --smooth R        a client draws the coarse precisions (below the one where\n"
          "                    half the vertices are alone in their kd-cell) smoothed:\n"
          "                    R rounds over each cell's complex, every point kept in\n"
          "                    its kd-cell, 0..8 (default 5; 0: none)\n"
          "  --colour-bits C   per-vertex colour (when the input has it), C bits per\n"
          "                    channel, 1..8 (default 8); --no-colour leaves it out\n"
          "  --metadata FILE   a sidecar JSON object of title, creator, date, licence,\n"
          "                    description and unit (um, mm, cm, m, in, ft) strings, kept\n"
          "                    in the catalogue entry (default: what an earlier bake of\n"
          "                    NAME had)\n"
          "  --no-thumbnail    make no thumbnail\n"
          "  --up x|y|z        the thumbnail's world up, as meshview's --up (default: the\n"
          "                    model's earlier picture's, else z)\n"
          "  --apo, --no-apo   give every cell an APO chunk of normals (default: on)\n"
          "  --apo-lead L      chunk depth: L levels below the cell's finest geometric\n"
          "                    precision, 0..16 (default 1)\n"
          "  --apo-max-depth D cap on the chunk depth, 0..24 (default 10)\n"
          "  --apo-tol T       split while the normals of the original mesh in a node\n"
          "                    spread more than T radians (default 0.2)\n"
          "  --apo-correction C  keep a texel only where its normal differs from the\n"
          "                    client's smooth normal by more than C radians (default 0.2)\n"
          "  --apo-budget R    APO bytes at most R times the geometry bytes, the finest\n"
          "                    levels dropped first where the chunks hold more; 0: no\n"
          "                    budget (default 1)\n"
          "  --apo-init-depth D  split unconditionally above depth D (default 0)\n"
          "  --apo-verify      decode every chunk back and check it gives the built tree\n"
          "  --apo-accuracy    measure the internal cells' chunks against the full-precision\n"
          "                    triangles below them (degrees; a diagnostic: it holds\n"
          "                    those triangles, so its memory grows with the model)\n"
          "\n"
          "  --set-public-bits B  change the preview of the baked model NAME in\n"
          "                    ARCHIVE_DIR/catalog.json (0..its P); SIGHUP a running\n"
          "                    meshserve to apply it\n"
          "  --thumbnail NAME  render the thumbnail of the baked model NAME again\n"
          "  --annotations FILE  check FILE against the annotations format\n"
          "                    (docs/ANNOTATIONS.md) and install it beside the baked model\n"
          "                    NAME as ARCHIVE_DIR/NAME.annotations.json, which both doors\n"
          "                    serve and meshview reads and edits\n"
          "  --list DIR        the collection: every model of DIR/catalog.json (name,\n"
          "                    triangles, cells, file size, preview precision) with each\n"
          "                    archive opened and every payload checked against its CRC;\n"
          "                    exit status 1 when one fails\n"
          "  --remove NAME     take model NAME out of ARCHIVE_DIR: its catalogue entry\n"
          "                    first (a rescan no longer offers it), then its file; SIGHUP\n"
          "                    a running meshserve to apply it (UNKNOWN_MODEL from then)\n"
          "  --info            parse FILE completely and report format, counts, bounding box,\n"
          "                    faces dropped by the cleaning policy, isolated vertices, the\n"
          "                    edges (boundary, inconsistently oriented: used twice in the\n"
          "                    same direction, non-manifold: three or more faces), bytes\n"
          "                    parsed and parse time\n"
          "  --json            print the report as one JSON object on stdout\n"
          "  -h, --help        print this help and exit\n"
          "      --version     print the version and exit\n"
          "\n",
          out);
    ms_apo_classic_cli_usage(out);
    fputs("\nExit status: 0 on success, 1 for an input or bake error, 2 for a usage error.\n", out);
}

static int usage_error(const char *message, const char *detail)
{
    return ms_cli_usage_error("meshbake", message, detail);
}

/* The integer value of option c (its long name from opts) in [min, max];
 * false after printing the one-line usage error. */
static bool option_int(const struct option *opts, int c, const char *text, int64_t min,
                       int64_t max, int64_t *value, int *status)
{
    char name[48] = "--?";
    for (const struct option *o = opts; o->name; ++o)
        if (o->val == c)
            snprintf(name, sizeof name, "--%s", o->name);
    ms_error e;
    if (ms_option_int(name, text, min, max, value, &e) == MS_OK)
        return true;
    *status = usage_error(e.text, NULL);
    return false;
}

/* After the options: what the mode needs, and what it refuses. Returns -1 to
 * go on, or the exit status to end with. */
static int check_mode(int argc, char **argv, bake_options *options)
{
    if (options->metadata_path && options->mode != MODE_NONE)
        return usage_error("--metadata goes with a bake (IN -o ARCHIVE_DIR)", NULL);
    if (options->mode == MODE_LIST || options->mode == MODE_REMOVE ||
        options->mode == MODE_THUMBNAIL) {
        if (options->mode == MODE_REMOVE && !options->bake.archive_dir)
            return usage_error("--remove needs -o ARCHIVE_DIR", NULL);
        if (options->mode == MODE_THUMBNAIL && !options->bake.archive_dir)
            return usage_error("--thumbnail needs -o ARCHIVE_DIR", NULL);
        if (options->mode == MODE_LIST && options->bake.archive_dir)
            return usage_error("--list and -o are two different modes", NULL);
        if (optind < argc)
            return usage_error("unexpected argument", argv[optind]);
        return -1;
    }
    if (options->mode == MODE_SET_PUBLIC || options->mode == MODE_ANNOTATIONS) {
        if (!options->bake.archive_dir || !options->bake.name)
            return usage_error(options->mode == MODE_SET_PUBLIC
                                   ? "--set-public-bits needs -o ARCHIVE_DIR and --name NAME"
                                   : "--annotations needs -o ARCHIVE_DIR and --name NAME",
                               NULL);
        if (optind < argc)
            return usage_error("unexpected argument", argv[optind]);
        return -1;
    }
    if (options->bake.public_bits > (int)options->bake.bits) {
        char detail[64];
        snprintf(detail, sizeof detail, "%d", options->bake.public_bits);
        char message[80];
        snprintf(message, sizeof message, "--public-bits must be at most --bits (%u)",
                 options->bake.bits);
        return usage_error(message, detail);
    }
    if (options->bake.archive_dir) {
        if (options->mode == MODE_INFO)
            return usage_error("--info and -o are two different modes", NULL);
        options->mode = MODE_BAKE;
    }
    if (optind < argc)
        options->input = argv[optind++];
    if (optind < argc)
        return usage_error("unexpected argument", argv[optind]);
    if (options->mode == MODE_NONE)
        return usage_error("no mode given: bake with -o ARCHIVE_DIR, or use --info", NULL);
    if (options->metadata_path && options->mode != MODE_BAKE)
        return usage_error("--metadata goes with a bake (IN -o ARCHIVE_DIR)", NULL);
    if (!options->input)
        return usage_error("missing input file", NULL);
    return -1;
}

/* The thumbnail's and the sidecars' options (--thumbnail, --metadata,
 * --annotations, --no-thumbnail, --up): -1 to go on, or the exit status to
 * end with. */
static int picture_option(int c, const char *arg, bake_options *options)
{
    switch (c) {
    case 'B': options->mode = MODE_THUMBNAIL; options->thumbnail_name = arg; break;
    case 'X': options->metadata_path = arg; break;
    case 'W': options->mode = MODE_ANNOTATIONS; options->annotations_path = arg; break;
    case 'O': options->bake.no_thumbnail = true; break;
    default:
        if (strlen(arg) != 1 || arg[0] < 'x' || arg[0] > 'z')
            return usage_error("--up wants x, y or z", arg);
        options->bake.thumbnail_up = arg[0] - 'x';
        break;
    }
    return -1;
}

/* Returns -1 to go on, or the exit status to end with. */
/* --apo-tol (E), --apo-correction (G), --apo-budget (F): false with *status
 * set on a bad value. */
static bool apo_real_option(int c, const char *arg, ms_bake_apo_params *apo, int *status)
{
    ms_error e;
    ms_status s = c == 'E'   ? ms_option_double("--apo-tol", arg, 0, 1e12, &apo->tolerance, &e)
                  : c == 'G' ? ms_option_double("--apo-correction", arg, 0, 3.2, &apo->correction, &e)
                             : ms_option_double("--apo-budget", arg, 0, MS_BAKE_APO_MAX_BUDGET, &apo->budget, &e);
    if (s != MS_OK)
        *status = usage_error(e.text, NULL);
    return s == MS_OK;
}

static int parse_options(int argc, char **argv, bake_options *options)
{
    static const struct option long_options[] = {
        {"info", no_argument, NULL, 'i'},
        {"json", no_argument, NULL, 'j'},
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"name", required_argument, NULL, 'N'},
        {"bits", required_argument, NULL, 'b'},
        {"n", required_argument, NULL, 'n'},
        {"root-bits", required_argument, NULL, 'r'},
        {"min-tris", required_argument, NULL, 'm'},
        {"threads", required_argument, NULL, 't'},
        {"mem", required_argument, NULL, 'M'},
        {"tmp", required_argument, NULL, 'T'},
        {"apo", no_argument, NULL, 'A'},
        {"no-apo", no_argument, NULL, 'a'},
        {"apo-lead", required_argument, NULL, 'L'},
        {"apo-max-depth", required_argument, NULL, 'D'},
        {"apo-init-depth", required_argument, NULL, 'I'},
        {"apo-tol", required_argument, NULL, 'E'},
        {"apo-correction", required_argument, NULL, 'G'},
        {"apo-budget", required_argument, NULL, 'F'},
        {"apo-verify", no_argument, NULL, 'V'},
        {"apo-accuracy", no_argument, NULL, 'C'},
        {"public-bits", required_argument, NULL, 'P'},
        {"set-public-bits", required_argument, NULL, 'U'},
        {"list", required_argument, NULL, 'l'},
        {"remove", required_argument, NULL, 'R'},
        {"subtree-levels", required_argument, NULL, 'Y'},
        {"ahead", required_argument, NULL, 'K'},
        {"ahead-until", required_argument, NULL, 'k'}, {"smooth", required_argument, NULL, 'S'},
        {"colour-bits", required_argument, NULL, 'c'}, {"no-colour", no_argument, NULL, 'Z'},
        {"metadata", required_argument, NULL, 'X'}, {"thumbnail", required_argument, NULL, 'B'},
        {"no-thumbnail", no_argument, NULL, 'O'}, {"up", required_argument, NULL, 'u'},
        {"annotations", required_argument, NULL, 'W'}, {NULL, 0, NULL, 0},
    };
    memset(options, 0, sizeof *options);
    ms_bake_options_default(&options->bake);
    int c, status;
    int64_t value;
    while ((c = ms_cli_next("meshbake", argc, argv, "ho:", long_options)) != -1) {
        switch (c) {
        case 'i': options->mode = MODE_INFO; break;
        case 'l': options->mode = MODE_LIST; options->list_dir = optarg; break;
        case 'R': options->mode = MODE_REMOVE; options->remove_name = optarg; break;
        case 'B': case 'X': case 'O': case 'u': case 'W':
            if ((status = picture_option(c, optarg, options)) >= 0)
                return status;
            break;
        case 'j': options->json = true; break;
        case 'h': print_usage(stdout); return EXIT_SUCCESS;
        case 'o': options->bake.archive_dir = optarg; break;
        case 'N': options->bake.name = optarg; break;
        case 'T': options->bake.tmp_dir = optarg; break;
        case 'b': case 'n': case 'r': case 'm': case 't': case 'M':
            if (!option_int(long_options, c, optarg, 1, (int64_t)1 << 31, &value, &status))
                return status;
            if (c == 'b') options->bake.bits = (unsigned)value;
            else if (c == 'n') options->bake.n = (unsigned)value;
            else if (c == 'r') options->bake.root_bits = (unsigned)value;
            else if (c == 'm') options->bake.min_triangles = (uint32_t)value;
            else if (c == 't') options->bake.threads = (unsigned)value;
            else options->bake.mem_mb = (size_t)value;
            break;
        case 'Y':
            if (!option_int(long_options, c, optarg, 1, 8, &value, &status))
                return status;
            options->bake.subtree_levels = (unsigned)value;
            break;
        case 'K': case 'k':
            if (!option_int(long_options, c, optarg, 0, c == 'K' ? MS_CODEC_MAX_AHEAD : MS_CODEC_MAX_AHEAD_UNTIL,
                            &value, &status))
                return status;
            *(c == 'K' ? &options->bake.ahead : &options->bake.ahead_until) = (unsigned)value;
            break;
        case 'S':
            if (!option_int(long_options, c, optarg, 0, MS_CODEC_SMOOTH_ROUNDS_MAX, &value, &status))
                return status;
            options->bake.smooth_rounds = (unsigned)value;
            break;
        case 'c':
            if (!option_int(long_options, c, optarg, 1, 8, &value, &status))
                return status;
            options->bake.colour_bits = (unsigned)value;
            break;
        case 'Z': options->bake.no_colour = true; break;
        case 'A': options->bake.apo.enabled = true; break;
        case 'a': options->bake.apo.enabled = false; break;
        case 'V': options->bake.apo.verify = true; break;
        case 'C': options->bake.apo.accuracy = true; break;
        case 'P': case 'U':
            if (!option_int(long_options, c, optarg, 0, 20, &value, &status))
                return status;
            if (c == 'P') {
                options->bake.public_bits = (int)value;
            } else {
                options->set_public_bits = (unsigned)value;
                options->mode = MODE_SET_PUBLIC;
            }
            break;
        case 'L': case 'D': case 'I':
            if (!option_int(long_options, c, optarg, 0, 30, &value, &status))
                return status;
            if (c == 'L') options->bake.apo.lead = (uint32_t)value;
            else if (c == 'D') options->bake.apo.max_depth = (uint32_t)value;
            else options->bake.apo.init_depth = (uint32_t)value;
            break;
        case 'E': case 'G': case 'F':
            if (!apo_real_option(c, optarg, &options->bake.apo, &status))
                return status;
            break;
        default:
            return EXIT_USAGE; /* reported by ms_cli_next */
        }
    }
    return check_mode(argc, argv, options);
}

typedef struct progress_state {
    const char *path;
    struct timespec start;
    int last_percent;
    bool shown;
    /* --info: every triangle's vertex indices, for the edge counts */
    uint32_t *triangles;
    size_t triangle_count, triangle_cap;
    ms_colour_tally colours; /* --info: every vertex colour, for the distinct count */
} progress_state;

static ms_status keep_colours(void *context, const uint8_t *rgba, size_t count, ms_error *err)
{
    return ms_colour_tally_add(&((progress_state *)context)->colours, rgba, count, err);
}

static ms_status keep_triangles(void *context, const uint32_t *indices, size_t count, ms_error *err)
{
    progress_state *p = context;
    if (p->triangle_count + count > p->triangle_cap) {
        size_t cap = p->triangle_cap ? p->triangle_cap : 4096;
        while (cap < p->triangle_count + count)
            cap *= 2;
        uint32_t *grown = cap <= SIZE_MAX / 12 ? realloc(p->triangles, 3 * cap * sizeof *grown) : NULL;
        if (!grown)
            return ms_error_set(err, MS_ERR_NOMEM, "%s: no memory to count the edges of %zu triangles", p->path,
                                p->triangle_count + count);
        p->triangles = grown;
        p->triangle_cap = cap;
    }
    memcpy(&p->triangles[3 * p->triangle_count], indices, 3 * count * sizeof *indices);
    p->triangle_count += count;
    return MS_OK;
}

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

static void print_json(const char *path, const ms_mesh_read_report *r, const ms_mesh_edge_counts *e,
                       uint64_t colours, double seconds)
{
    ms_json_print(stdout,
                  json_pack("{s:o, s:s, s:b, s:I, s:I, s:I, s:[f, f, f], s:[f, f, f], s:I, s:I, s:I, s:o, "
                            "s:{s:I, s:I, s:I, s:I, s:I}, s:{s:b, s:b, s:I}}",
                            "file", ms_json_text(path), "format", ms_mesh_format_name(r->format), "gzip",
                            r->gzip, "vertices", (json_int_t)r->vertices, "triangles",
                            (json_int_t)r->triangles, "input_faces", (json_int_t)r->input_faces,
                            "bbox_min", r->bbox_min[0], r->bbox_min[1], r->bbox_min[2], "bbox_max",
                            r->bbox_max[0], r->bbox_max[1], r->bbox_max[2], "dropped_faces",
                            (json_int_t)r->dropped_faces, "isolated_vertices",
                            (json_int_t)r->isolated_vertices, "bytes", (json_int_t)r->input_bytes,
                            "seconds", ms_json_fixed(seconds, 9), "edges", "total", (json_int_t)e->edges,
                            "boundary", (json_int_t)e->boundary, "manifold", (json_int_t)e->manifold,
                            "inconsistently_oriented", (json_int_t)e->flipped, "non_manifold",
                            (json_int_t)e->non_manifold, "colour", "present", r->colour, "alpha",
                            r->colour_alpha, "distinct", (json_int_t)colours),
                  MS_JSON_SPACED | MS_JSON_EXACT); /* the bounding box as read */
}

static void print_text(const char *path, const ms_mesh_read_report *r, const ms_mesh_edge_counts *e,
                       uint64_t colours, double seconds)
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
    if (r->colour)
        printf("vertex colour:     %s, %" PRIu64 " distinct\n", r->colour_alpha ? "rgba" : "rgb",
               colours);
    else
        printf("vertex colour:     none\n");
    printf("edges:             %" PRIu64 " (%" PRIu64 " boundary, %" PRIu64 " manifold)\n", e->edges,
           e->boundary, e->manifold);
    printf("flipped edges:     %" PRIu64 " (used twice in the same direction: faces inconsistently oriented)\n",
           e->flipped);
    printf("non-manifold:      %" PRIu64 " edges (used by three or more faces)\n", e->non_manifold);
    printf("bytes parsed:      %" PRIu64 "\n", r->input_bytes);
    printf("parse time:        %.3f s (%.1f MB/s)\n", seconds,
           seconds > 0 ? (double)r->input_bytes / seconds / 1e6 : 0.0);
}

static int run_info(const bake_options *options)
{
    progress_state progress = {.path = options->input, .last_percent = -1, .shown = false};
    const ms_mesh_sink sink = {
        .context = &progress,
        .triangles = keep_triangles,
        .colours = keep_colours,
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
    ms_mesh_edge_counts edges;
    if (st == MS_OK)
        st = ms_mesh_count_edges(progress.triangles, progress.triangle_count, &edges, &err);
    free(progress.triangles);
    uint64_t colours = 0;
    if (st == MS_OK)
        st = ms_colour_tally_distinct(&progress.colours, &colours, &err);
    ms_colour_tally_free(&progress.colours);
    if (st != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    if (options->json)
        print_json(options->input, &report, &edges, colours, seconds);
    else
        print_text(options->input, &report, &edges, colours, seconds);
    return fflush(stdout) == 0 ? EXIT_SUCCESS : EXIT_INPUT;
}

/* apo.sampling: the APO builders' work, summed (docs/APO.md, "Per-cell chunks"). */
static json_t *apo_sampling_json(const ms_bake_report *r)
{
    return json_pack("{s:I, s:I, s:I, s:I, s:I, s:I, s:I}", "rays", (json_int_t)r->apo_rays, "point_queries",
                     (json_int_t)r->apo_point_queries, "smooth_leaves", (json_int_t)r->apo_smooth_leaves,
                     "triangle_visits", (json_int_t)r->apo_triangle_visits, "samples", (json_int_t)r->apo_samples,
                     "leaves", (json_int_t)r->apo_sampled_leaves, "agreed_leaves", (json_int_t)r->apo_agreed_leaves);
}

static void print_bake_json(const ms_bake_options *o, const ms_bake_report *r)
{
    json_t *seconds = json_pack("{s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f}", "read", r->seconds_read,
                                "quantise", r->seconds_quantise, "distribute",
                                r->seconds_distribute, "lone", r->seconds_lone,
                                "encode", r->seconds_encode, "apo",
                                r->seconds_apo, "write", r->seconds_write, "total",
                                r->seconds_total);
    json_t *per_level = json_array();
    for (uint32_t d = 0; per_level && d < r->apo_levels; ++d)
        json_array_append_new(per_level, json_integer((json_int_t)r->apo_level_texels[d]));
    json_t *apo = json_pack("{s:b, s:i, s:i, s:i, s:f, s:I, s:I, s:i, s:I, s:I, s:o, s:I, s:I}",
                            "enabled", o->apo.enabled, "lead", (int)o->apo.lead,
                            "max_depth",
                            (int)o->apo.max_depth, "init_depth", (int)o->apo.init_depth,
                            "tolerance", o->apo.tolerance, "bytes", (json_int_t)r->apo_bytes,
                            "raw_bytes", (json_int_t)r->apo_raw_bytes, "chunks",
                            (int)r->apo_chunks, "internal_nodes",
                            (json_int_t)r->apo_internal_nodes, "leaves",
                            (json_int_t)r->apo_leaves, "level_texels", per_level,
                            "sample_triangles", (json_int_t)r->apo_sample_triangles,
                            "sample_triangles_max", (json_int_t)r->apo_sample_triangles_max);
    if (apo) /* keep a texel only where it corrects the smooth normal by more (docs/APO.md) */
        json_object_set_new(apo, "correction", json_real(o->apo.correction));
    /* the byte budget (docs/APO.md): the stored ratio and what the budget dropped */
    const ms_bake_apo_budget_report *cut = &r->apo_budget;
    if (apo)
        json_object_set_new(apo, "budget",
                            json_pack("{s:f, s:I, s:I, s:f, s:I, s:I, s:i, s:i, s:i, s:I, s:I, s:I}", "ratio",
                                      r->geometry_bytes ? (double)r->apo_bytes / (double)r->geometry_bytes : 0.0,
                                      "geometry_bytes", (json_int_t)r->geometry_bytes, "limit_bytes",
                                      (json_int_t)cut->limit, "budget", o->apo.budget, "bytes_before",
                                      (json_int_t)cut->bytes_before, "bytes_dropped",
                                      (json_int_t)(cut->bytes_before - cut->bytes_after), "chunks_cut",
                                      (int)cut->chunks_cut, "chunks_removed", (int)cut->chunks_removed,
                                      "levels_dropped", (int)cut->levels_dropped, "texels_dropped",
                                      (json_int_t)cut->texels_dropped, "internal_nodes_dropped",
                                      (json_int_t)cut->internal_dropped, "leaves_dropped",
                                      (json_int_t)cut->leaves_dropped));
    /* the issue-31 target is stated as this share: the APO build against the whole bake */
    if (apo)
        json_object_set_new(apo, "share_of_bake",
                            json_real(r->seconds_total > 0 ? r->seconds_apo / r->seconds_total : 0.0));
    if (apo)
        json_object_set_new(apo, "sampling", apo_sampling_json(r));
    if (apo && o->apo.accuracy)
        json_object_set_new(apo, "accuracy",
                            json_pack("{s:I, s:f, s:f, s:f}", "points", (json_int_t)r->apo_accuracy_points,
                                      "mean_deg", r->apo_accuracy_mean, "median_deg",
                                      r->apo_accuracy_median, "p90_deg", r->apo_accuracy_p90));
    json_t *root = json_pack(
        "{s:o, s:o, s:o, s:I, s:I, s:I, s:I, s:i, s:i, s:i, s:i, s:f, s:I, s:I, s:I, s:f, s:o, "
        "s:f, s:i, s:f, s:f, s:I, s:o, s:{s:i, s:i, s:i, s:i, s:i, s:i, s:i, s:i, s:i}}",
        "name", ms_json_text(r->name), "archive", ms_json_text(r->archive_path), "source",
        ms_json_text(o->input),
        "input_vertices", (json_int_t)r->input_vertices,
        "input_triangles", (json_int_t)r->input_triangles,
        "vertices", (json_int_t)r->vertices, "triangles", (json_int_t)r->triangles,
        "cells", (int)r->cells, "leaves", (int)r->leaves, "empty_cells", (int)r->empty_cells,
        "depth", (int)r->depth, "duplicated_triangles", r->duplicated_percent,
        "leaf_triangles", (json_int_t)r->leaf_triangles,
        "archive_bytes", (json_int_t)r->archive_bytes,
        "geometry_bytes", (json_int_t)r->geometry_bytes,
        "bits_per_vertex", r->bits_per_vertex, "seconds", seconds,
        "triangles_per_second", r->seconds_total > 0 ? (double)r->input_triangles / r->seconds_total : 0.0,
        "threads", (int)r->threads, "peak_rss_mb", r->peak_rss_mb,
        "peak_rss_build_mb", r->peak_rss_build_mb,
        "spilled_blocks", (json_int_t)r->blocks_written, "apo", apo,
        "parameters", "bits", (int)o->bits, "n", (int)o->n, "root_bits", (int)o->root_bits,
        "min_tris", (int)r->min_triangles, "mem_mb", (int)o->mem_mb, "ahead", (int)o->ahead,
        "ahead_until", (int)o->ahead_until,
        "smooth_rounds", (int)r->smooth_rounds, "smooth_bits", (int)r->smooth_bits);
    const struct { const char *phase; const ms_nsp_io *io; } phases[] = {
        {"read", &r->io_read}, {"quantise", &r->io_quantise}, {"distribute", &r->io_distribute},
        {"lone", &r->io_lone}, {"encode", &r->io_encode}};
    json_t *io = json_object();
    for (size_t i = 0; io && i < sizeof phases / sizeof *phases; ++i)
        json_object_set_new(io, phases[i].phase,
                            json_pack("{s:I, s:I}", "spilled_bytes", (json_int_t)phases[i].io->spilled,
                                      "read_back_bytes", (json_int_t)phases[i].io->read_back));
    json_t *by_depth = json_array();
    for (unsigned d = 0; by_depth && d < MS_NSP_MAX_DEPTH; ++d)
        if (r->depth_leaves[d] > 0)
            json_array_append_new(by_depth, json_pack("{s:i, s:I, s:I, s:I}", "depth", (int)d, "leaves",
                                                      (json_int_t)r->depth_leaves[d], "triangles",
                                                      (json_int_t)r->depth_triangles[d], "duplicates",
                                                      (json_int_t)(r->depth_triangles[d] - r->depth_owned[d])));
    if (root && by_depth)
        json_object_set_new(root, "duplication_by_leaf_depth", by_depth);
    else
        json_decref(by_depth);
    if (root && io) {
        json_object_set_new(root, "temporary_io", io);
        json_object_set_new(root, "key_page_misses", json_integer((json_int_t)r->key_page_misses));
    } else {
        json_decref(io);
    }
    if (root) /* colour streams (docs/ARCHIVE.md): present, precision, bytes */
        json_object_set_new(root, "colour", json_pack("{s:b, s:b, s:i, s:I}", "present", r->colour,
                                                      "alpha", r->colour_alpha, "bits", (int)r->colour_bits,
                                                      "bytes", (json_int_t)r->colour_bytes));
    if (root && r->thumbnail_bytes)
        json_object_set_new(root, "thumbnail",
                            json_pack("{s:i, s:i, s:I, s:i, s:f}", "width", MS_THUMBNAIL_WIDTH,
                                      "height", MS_THUMBNAIL_HEIGHT, "bytes",
                                      (json_int_t)r->thumbnail_bytes, "bits",
                                      (int)r->thumbnail_bits, "seconds", r->seconds_thumbnail));
    if (root) {
        json_object_set_new(root, "duplicated_at_insertion",
                            json_real(r->duplicated_at_insertion_percent));
        json_object_set_new(root, "insertion_copies", json_integer((json_int_t)r->insertion_copies));
    }
    if (!root) {
        fputs("{}\n", stdout);
        return;
    }
    ms_json_print(stdout, root, MS_JSON_COMPACT);
}

static void print_bake_text(const ms_bake_report *r)
{
    printf("model:                %s -> %s\n", r->name, r->archive_path);
    printf("input:                %" PRIu64 " vertices, %" PRIu64 " triangles\n", r->input_vertices,
           r->input_triangles);
    printf("welded:               %" PRIu64 " vertices, %" PRIu64 " triangles\n", r->vertices,
           r->triangles);
    printf("cells:                %u (%u leaves, %u empty, depth %u)\n", r->cells, r->leaves,
           r->empty_cells, r->depth);
    printf("duplicated triangles: %.2f %% (%.2f %% counted at insertion, as the thesis)\n",
           r->duplicated_percent, r->duplicated_at_insertion_percent);
    printf("archive:              %" PRIu64 " bytes, %.2f bits per vertex\n", r->archive_bytes,
           r->bits_per_vertex);
    printf("geometry:             %" PRIu64 " bytes\n", r->geometry_bytes);
    if (r->smooth_rounds > 0)
        printf("smoothing:            %u rounds below %u bits (half the vertices alone in their kd-cell)\n",
               r->smooth_rounds, r->smooth_bits);
    if (r->colour)
        printf("colour:               %" PRIu64 " bytes, %u bits per channel, %s\n", r->colour_bytes,
               r->colour_bits, r->colour_alpha ? "rgba" : "rgb");
    if (r->apo_chunks > 0) {
        printf("APO:                  %u chunks, %" PRIu64 " bytes (%" PRIu64 " raw), %" PRIu64
               " internal nodes, %" PRIu64 " leaves (%" PRIu64 " more left to the smooth normal)\n",
               r->apo_chunks, r->apo_bytes, r->apo_raw_bytes, r->apo_internal_nodes, r->apo_leaves,
               r->apo_smooth_leaves);
        printf("APO sampling:         internal cells' M %" PRIu64 " triangles, largest %" PRIu64 "; %" PRIu64
               " rays, %" PRIu64 " closest-point queries, %" PRIu64 " triangle visits\n",
               r->apo_sample_triangles, r->apo_sample_triangles_max, r->apo_rays, r->apo_point_queries,
               r->apo_triangle_visits);
        if (r->apo_accuracy_points > 0)
            printf("APO accuracy:         %" PRIu64 " full-precision centroids of internal cells: "
                   "mean %.2f, median %.2f, p90 %.2f degrees\n",
                   r->apo_accuracy_points, r->apo_accuracy_mean, r->apo_accuracy_median, r->apo_accuracy_p90);
        printf("APO budget:           %.2f x the geometry (limit %" PRIu64 " bytes); dropped %" PRIu64
               " bytes, %u levels of %u chunks (%u removed), %" PRIu64 " texels\n",
               r->geometry_bytes ? (double)r->apo_bytes / (double)r->geometry_bytes : 0.0, r->apo_budget.limit, r->apo_budget.bytes_before - r->apo_budget.bytes_after,
               r->apo_budget.levels_dropped, r->apo_budget.chunks_cut, r->apo_budget.chunks_removed,
               r->apo_budget.texels_dropped);
        printf("APO texels per level:");
        for (uint32_t d = 0; d < r->apo_levels; ++d)
            printf(" %" PRIu64, r->apo_level_texels[d]);
        printf("\n");
    }
    printf("seconds:              read %.2f, quantise %.2f, distribute %.2f, lone %.2f, encode %.2f "
           "(APO %.2f, %.0f %% of the bake), write %.2f, total %.2f (%.0f triangles/s on %u threads)\n",
           r->seconds_read, r->seconds_quantise, r->seconds_distribute, r->seconds_lone, r->seconds_encode,
           r->seconds_apo, r->seconds_total > 0 ? 100.0 * r->seconds_apo / r->seconds_total : 0.0,
           r->seconds_write, r->seconds_total,
           r->seconds_total > 0 ? (double)r->input_triangles / r->seconds_total : 0.0, r->threads);
    printf("temporary files (MB): spilled / read back: read %.1f / %.1f, quantise %.1f / %.1f, "
           "distribute %.1f / %.1f, lone %.1f / %.1f, encode %.1f / %.1f\n",
           r->io_read.spilled / 1e6, r->io_read.read_back / 1e6, r->io_quantise.spilled / 1e6,
           r->io_quantise.read_back / 1e6, r->io_distribute.spilled / 1e6,
           r->io_distribute.read_back / 1e6, r->io_lone.spilled / 1e6, r->io_lone.read_back / 1e6,
           r->io_encode.spilled / 1e6, r->io_encode.read_back / 1e6);
    if (r->thumbnail_bytes)
        printf("thumbnail:            %ux%u, %" PRIu64 " bytes at %u bits, %.2f s\n",
               MS_THUMBNAIL_WIDTH, MS_THUMBNAIL_HEIGHT, r->thumbnail_bytes, r->thumbnail_bits,
               r->seconds_thumbnail);
    printf("peak memory:          %.1f MB (the process's peak resident set, from the OS)\n",
           r->peak_rss_mb);
}

static int run_bake(bake_options *options)
{
    options->bake.input = options->input;
    options->bake.progress = isatty(STDERR_FILENO) ? stderr : NULL;
    options->bake.notes = stderr;
    ms_bake_report report;
    ms_error err;
    ms_error_clear(&err);
    ms_metadata *metadata = NULL;
    if (options->metadata_path &&
        ms_metadata_load(options->metadata_path, &metadata, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return EXIT_INPUT;
    }
    options->bake.metadata = metadata;
    ms_status st = ms_bake(&options->bake, &report, &err);
    options->bake.metadata = NULL;
    ms_metadata_free(metadata);
    if (st != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return st == MS_ERR_ARG ? EXIT_USAGE : EXIT_INPUT;
    }
    if (options->json)
        print_bake_json(&options->bake, &report);
    else
        print_bake_text(&report);
    return fflush(stdout) == 0 ? EXIT_SUCCESS : EXIT_INPUT;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshbake");
    for (int i = 1; i < argc; ++i)
        if (strcmp(argv[i], "--apo-classic") == 0)
            return ms_apo_classic_cli(argc, argv);
    bake_options options;
    int status = parse_options(argc, argv, &options);
    if (status >= 0)
        return status;
    switch (options.mode) {
    case MODE_INFO: return run_info(&options);
    case MODE_BAKE: return run_bake(&options);
    case MODE_SET_PUBLIC:
        return ms_bake_cli_set_public(options.bake.archive_dir, options.bake.name,
                                      options.set_public_bits, options.bake.thumbnail_up,
                                      options.bake.threads);
    case MODE_LIST: return ms_bake_cli_list(options.list_dir, options.json);
    case MODE_ANNOTATIONS:
        return ms_bake_cli_annotations(options.bake.archive_dir, options.bake.name,
                                       options.annotations_path, options.json);
    case MODE_REMOVE: return ms_bake_cli_remove(options.bake.archive_dir, options.remove_name);
    case MODE_THUMBNAIL:
        return ms_bake_cli_thumbnail(options.bake.archive_dir, options.thumbnail_name,
                                     options.bake.thumbnail_up, options.bake.threads,
                                     options.json);
    case MODE_NONE: break;
    }
    return EXIT_USAGE;
}
