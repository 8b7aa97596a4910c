/* `meshbake IN --apo-classic ...`: whole-model APO for comparison with the
 * published results (see ms_apo_classic_cli.h). */
#include "ms_apo_classic_cli.h"
#include "ms_cli.h"

#include <errno.h>
#include <stdbool.h>
#include <getopt.h>
#include <sys/resource.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_blob.h"
#include "ms_apo_classic.h"
#include "ms_apo_render.h"
#include "ms_apo_traverse.h"
#include "ms_demo_model.h"
#include "ms_error.h"
#include "ms_json_out.h"
#include "ms_mesh.h"
#include "ms_mesh_io.h"
#include "ms_parse_number.h"
#include "ms_png.h"
#include "ms_progress.h"

void ms_apo_classic_cli_usage(FILE *out)
{
    fputs("       meshbake IN --apo-classic --simplify N [options]\n"
          "\n"
          "Classic mode: builds one APO (appearance-preserving octree) over a whole model,\n"
          "as in the published method, and reports its size and the time of every phase;\n"
          "no archive is written. IN is a mesh file or demo:T, the built-in relief\n"
          "sculpture with about T triangles.\n"
          "  --apo-classic          whole-model mode\n"
          "  --simplify N           simplify to N triangles (quadric decimation) [3000]\n"
          "  --apo-tol T            tolerance on the variation measure [0.05]\n"
          "  --apo-init-depth D     depth split unconditionally [5]\n"
          "  --apo-max-depth D      deepest level, at most 30 [13]\n"
          "  --apo-measure NAME     classic (published, sum of squared deviations) or\n"
          "                         spread (area-weighted angular spread, radians) [classic]\n"
          "  --apo-search S         fixed ray search half-length in cube units [automatic]\n"
          "  --simplified FILE      use FILE as the simplified mesh (no simplification)\n"
          "  --save-simplified FILE write the simplified mesh to FILE (binary PLY)\n"
          "  --png FILE             write a 1024x1024 picture of the APO seen along -z\n"
          "  --bench-lookups N      time N CPU reference lookups at random points\n"
          "  --bench-accuracy N     angle between the looked-up normal and M's face normal\n"
          "                         at N centroids of M, for both missing-child rules\n"
          "  --threads N            worker threads, 0 = all cores [0]\n"
          "  -o FILE                write the stored chunk (zlib + CRC) to FILE\n"
          "  --json                 print the report as one JSON object\n",
          out);
}

static int usage_error(const char *message, const char *detail)
{
    return ms_cli_usage_error("meshbake", message, detail);
}

/* An option value (ms_option_*): 0, or -1 after printing its one line. */
static int parse_double(const char *s, const char *what, double lo, double hi, double *out)
{
    ms_error e;
    if (ms_option_double(what, s, lo, hi, out, &e) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", e.text);
        return -1;
    }
    return 0;
}

static int parse_int(const char *s, const char *what, int64_t lo, int64_t hi, int64_t *out)
{
    ms_error e;
    if (ms_option_int(what, s, lo, hi, out, &e) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", e.text);
        return -1;
    }
    return 0;
}

static int load_input(const char *in, ms_mesh *mesh, ms_error *err)
{
    if (strncmp(in, "demo:", 5) == 0) {
        int64_t t;
        if (parse_int(in + 5, "demo:T", 8, 200000000, &t) != 0)
            return -1;
        ms_demo_model model = {.grid = ms_demo_grid_for_triangles((uint64_t)t), .seed = 0};
        return ms_demo_build(&model, mesh, err) == MS_OK ? 0 : -2;
    }
    return ms_mesh_load(in, mesh, NULL, err) == MS_OK ? 0 : -2;
}

static int write_file(const char *path, const uint8_t *data, size_t size)
{
    FILE *f = fopen(path, "wb");
    if (!f || fwrite(data, 1, size, f) != size || fclose(f) != 0) {
        fprintf(stderr, "meshbake: cannot write %s: %s\n", path, strerror(errno));
        if (f)
            fclose(f);
        return -1;
    }
    return 0;
}

/* Angles (degrees) between the APO normal and M's face normal at M's
 * centroids, which lie off m by up to the simplification error: a stress test of
 * the missing-child rules. Index 0: MS_APO_MISSING_STOP, 1: NEAREST. */
typedef struct accuracy {
    double mean, median, p90;
    size_t points, off_tree; /* lookups that met a missing child */
} accuracy;

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static ms_status measure_accuracy(const ms_apo_view *view, const ms_mesh *M, const ms_apo_classic_report *r,
                                  size_t wanted, accuracy acc[2], ms_error *err)
{
    size_t stride = M->triangle_count / wanted ? M->triangle_count / wanted : 1;
    size_t n = (M->triangle_count + stride - 1) / stride;
    double *angles = malloc((n + 1) * sizeof *angles);
    if (!angles)
        return ms_error_set(err, MS_ERR_NOMEM, "accuracy: no memory");
    for (int rule = 0; rule < 2; ++rule) {
        size_t k = 0, off = 0;
        double sum = 0;
        for (size_t t = 0; t < M->triangle_count; t += stride) {
            const uint32_t *v = &M->triangles[3 * t];
            const double *a = &M->positions[3 * v[0]], *b = &M->positions[3 * v[1]], *c = &M->positions[3 * v[2]];
            double e1[3], e2[3], nrm[3];
            float p[3];
            for (int i = 0; i < 3; ++i) {
                e1[i] = b[i] - a[i];
                e2[i] = c[i] - a[i];
                p[i] = (float)(((a[i] + b[i] + c[i]) / 3.0 - r->cube_origin[i]) / r->cube_size);
            }
            nrm[0] = e1[1] * e2[2] - e1[2] * e2[1];
            nrm[1] = e1[2] * e2[0] - e1[0] * e2[2];
            nrm[2] = e1[0] * e2[1] - e1[1] * e2[0];
            double len = sqrt(nrm[0] * nrm[0] + nrm[1] * nrm[1] + nrm[2] * nrm[2]);
            if (!(len > 0))
                continue;
            ms_apo_lookup_result res;
            ms_apo_lookup(view, p, MS_APO_MAX_DEPTH, rule ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP, &res);
            off += res.stop == MS_APO_STOP_MISSING || res.substitutions > 0;
            double dot = (res.normal[0] * nrm[0] + res.normal[1] * nrm[1] + res.normal[2] * nrm[2]) / len;
            angles[k] = acos(dot > 1 ? 1 : dot < -1 ? -1 : dot) * 180.0 / M_PI;
            sum += angles[k++];
        }
        qsort(angles, k, sizeof *angles, compare_double);
        acc[rule].points = k;
        acc[rule].off_tree = off;
        acc[rule].mean = k ? sum / (double)k : 0;
        acc[rule].median = k ? angles[k / 2] : 0;
        acc[rule].p90 = k ? angles[(size_t)(0.9 * (double)(k - 1))] : 0;
    }
    free(angles);
    return MS_OK;
}

/* CPU seconds (user + system, all threads) used by this process so far. */
static double cpu_seconds(void)
{
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0)
        return 0.0;
    return (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec +
           ru.ru_stime.tv_usec * 1e-6;
}

/* Lookups per second of the CPU reference traversal at pseudo-random points
 * (xorshift, fixed seed), one thread, both missing-child rules alternating. */
static double time_lookups(const ms_apo_view *view, uint64_t count)
{
    uint64_t state = 88172645463325252ull, sink = 0;
    double t0 = ms_now_seconds();
    for (uint64_t i = 0; i < count; ++i) {
        uint32_t u[3];
        for (int a = 0; a < 3; ++a) {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            u[a] = (uint32_t)(state >> 32);
        }
        ms_apo_lookup_result r;
        ms_apo_lookup_fixed(view, u, MS_APO_MAX_DEPTH, (i & 1) ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP, &r);
        sink += r.code;
    }
    double dt = ms_now_seconds() - t0;
    return sink == 1 ? 0.0 : (double)count / (dt > 0 ? dt : 1e-9);
}

/* What the command line asks for. */
typedef struct cli_args {
    ms_apo_classic_options o;
    const char *in, *out_path, *simplified_path, *save_path, *png_path;
    int json;
    uint64_t lookups;
    size_t accuracy_points;
} cli_args;

/* What a run measured, for the report. */
typedef struct cli_results {
    ms_apo_classic_report r;
    accuracy acc[2];
    double load_seconds, run_cpu, lookup_rate;
} cli_results;

/* Returns -1 to go on, or the exit status to end with. */
static int parse_cli(int argc, char **argv, cli_args *a)
{
    enum { OPT_CLASSIC = 256, OPT_SIMPLIFY, OPT_TOL, OPT_INIT, OPT_MAX, OPT_MEASURE, OPT_SEARCH, OPT_THREADS, OPT_JSON, OPT_HELP, OPT_SIMPLIFIED, OPT_SAVE, OPT_LOOKUPS, OPT_ACCURACY, OPT_PNG };
    static const struct option longs[] = {
        {"apo-classic", no_argument, NULL, OPT_CLASSIC},     {"simplify", required_argument, NULL, OPT_SIMPLIFY},
        {"apo-tol", required_argument, NULL, OPT_TOL},       {"apo-init-depth", required_argument, NULL, OPT_INIT},
        {"apo-max-depth", required_argument, NULL, OPT_MAX}, {"apo-measure", required_argument, NULL, OPT_MEASURE},
        {"apo-search", required_argument, NULL, OPT_SEARCH}, {"threads", required_argument, NULL, OPT_THREADS},
        {"json", no_argument, NULL, OPT_JSON},               {"help", no_argument, NULL, OPT_HELP},
        {"output", required_argument, NULL, 'o'},
        {"simplified", required_argument, NULL, OPT_SIMPLIFIED}, {"save-simplified", required_argument, NULL, OPT_SAVE},
        {"bench-lookups", required_argument, NULL, OPT_LOOKUPS},
        {"bench-accuracy", required_argument, NULL, OPT_ACCURACY},
        {"png", required_argument, NULL, OPT_PNG},
        {NULL, 0, NULL, 0}};
    memset(a, 0, sizeof *a);
    ms_apo_classic_options_default(&a->o);
    ms_apo_classic_options *o = &a->o;
    int c;
    int64_t v;
    optind = 1;
    while ((c = ms_cli_next("meshbake", argc, argv, "ho:", longs)) != -1) {
        switch (c) {
        case OPT_CLASSIC: break;
        case OPT_SIMPLIFY:
            if (parse_int(optarg, "--simplify", 4, 1000000000, &v) != 0)
                return 2;
            o->simplify_triangles = (size_t)v;
            break;
        case OPT_TOL:
            if (parse_double(optarg, "--apo-tol", 0, 1e12, &o->tolerance) != 0)
                return 2;
            break;
        case OPT_INIT:
            if (parse_int(optarg, "--apo-init-depth", 0, 30, &v) != 0)
                return 2;
            o->init_depth = (uint32_t)v;
            break;
        case OPT_MAX:
            if (parse_int(optarg, "--apo-max-depth", 0, 30, &v) != 0)
                return 2;
            o->max_depth = (uint32_t)v;
            break;
        case OPT_MEASURE:
            if (strcmp(optarg, "classic") == 0)
                o->measure = MS_APO_MEASURE_CLASSIC;
            else if (strcmp(optarg, "spread") == 0)
                o->measure = MS_APO_MEASURE_SPREAD;
            else {
                return usage_error("--apo-measure is classic or spread", optarg);
            }
            break;
        case OPT_SEARCH:
            if (parse_double(optarg, "--apo-search", 0, 1, &o->search_distance) != 0)
                return 2;
            break;
        case OPT_THREADS:
            if (parse_int(optarg, "--threads", 0, 1024, &v) != 0)
                return 2;
            o->threads = (unsigned)v;
            break;
        case 'o': a->out_path = optarg; break;
        case OPT_SIMPLIFIED: a->simplified_path = optarg; break;
        case OPT_SAVE: a->save_path = optarg; break;
        case OPT_LOOKUPS:
            if (parse_int(optarg, "--bench-lookups", 0, 1000000000, &v) != 0)
                return 2;
            a->lookups = (uint64_t)v;
            break;
        case OPT_PNG: a->png_path = optarg; break;
        case OPT_ACCURACY:
            if (parse_int(optarg, "--bench-accuracy", 0, 1000000000, &v) != 0)
                return 2;
            a->accuracy_points = (size_t)v;
            break;
        case OPT_JSON: a->json = 1; break;
        case 'h':
        case OPT_HELP: ms_apo_classic_cli_usage(stdout); return 0;
        default: return 2; /* reported by ms_cli_next */
        }
    }
    if (optind != argc - 1)
        return usage_error(optind < argc ? "expected one input, got more" : "missing input file", NULL);
    a->in = argv[optind];
    return -1;
}

/* The top view of the chunk's tree as a 1024 x 1024 grey PNG. */
static ms_status write_top_view(const ms_apo_chunk *chunk, const char *path, ms_error *err)
{
    enum { PNG_SIZE = 1024 };
    ms_apo_view view;
    uint8_t *grey = malloc((size_t)PNG_SIZE * PNG_SIZE);
    ms_status st = grey ? ms_apo_view_of_chunk(&view, chunk, err)
                        : ms_error_set(err, MS_ERR_NOMEM, "no memory for the picture");
    if (st == MS_OK) {
        ms_apo_render_top_view(&view, MS_APO_MAX_DEPTH, PNG_SIZE, PNG_SIZE, grey);
        st = ms_png_write(path, grey, PNG_SIZE, PNG_SIZE, 1, err);
    }
    free(grey);
    return st;
}

/* Loads the input (and a given simplified mesh), builds the chunk (kept in
 * *chunk when *keep_chunk), measures its accuracy and saves the simplified
 * mesh as asked. Returns 0, or the exit status after printing the error. */
static int build_chunk(cli_args *a, cli_results *res, ms_apo_chunk *chunk, bool *keep_chunk)
{
    ms_error err;
    ms_error_clear(&err);
    ms_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    double t0 = ms_now_seconds();
    int lr = load_input(a->in, &mesh, &err);
    if (lr == -1)
        return 2;
    if (lr != 0) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return 1;
    }
    ms_mesh given, kept;
    memset(&given, 0, sizeof given);
    memset(&kept, 0, sizeof kept);
    if (a->simplified_path) {
        if (ms_mesh_load(a->simplified_path, &given, NULL, &err) != MS_OK) {
            fprintf(stderr, "meshbake: %s\n", err.text);
            ms_mesh_free(&mesh);
            return 1;
        }
        a->o.simplified = &given;
    }
    if (a->save_path)
        a->o.keep_simplified = &kept;
    res->load_seconds = ms_now_seconds() - t0;
    *keep_chunk = a->out_path || a->lookups || a->accuracy_points || a->png_path;
    ms_status st = ms_apo_classic_run(&mesh, &a->o, *keep_chunk ? chunk : NULL, &res->r, &err);
    res->run_cpu = cpu_seconds(); /* reading + the whole run, before any extra measurement */
    if (st == MS_OK && a->accuracy_points) {
        ms_apo_view view;
        st = ms_apo_view_of_chunk(&view, chunk, &err);
        if (st == MS_OK)
            st = measure_accuracy(&view, &mesh, &res->r, a->accuracy_points, res->acc, &err);
    }
    ms_mesh_free(&mesh);
    ms_mesh_free(&given);
    a->o.simplified = NULL;
    a->o.keep_simplified = NULL;
    if (st == MS_OK && a->save_path && kept.triangle_count)
        st = ms_ply_write(a->save_path, &kept, true, true, &err);
    ms_mesh_free(&kept);
    if (st != MS_OK) {
        if (*keep_chunk)
            ms_apo_chunk_free(chunk);
        fprintf(stderr, "meshbake: %s\n", err.text);
        return 1;
    }
    return 0;
}

/* The picture, the lookup rate and the blob file the command line asks for;
 * 0, or 1 after printing the error. The chunk stays the caller's. */
static int use_chunk(const cli_args *a, cli_results *res, const ms_apo_chunk *chunk)
{
    ms_error err;
    if (a->png_path && write_top_view(chunk, a->png_path, &err) != MS_OK) {
        fprintf(stderr, "meshbake: %s\n", err.text);
        return 1;
    }
    res->lookup_rate = 0.0;
    if (a->lookups) {
        ms_apo_view view;
        if (ms_apo_view_of_chunk(&view, chunk, &err) != MS_OK) {
            fprintf(stderr, "meshbake: %s\n", err.text);
            return 1;
        }
        res->lookup_rate = time_lookups(&view, a->lookups);
    }
    if (a->out_path) {
        uint8_t *blob = NULL;
        size_t size = 0;
        ms_status st = ms_apo_blob_write(chunk, a->o.zlib_level, &blob, &size, &err);
        int wr = st == MS_OK ? write_file(a->out_path, blob, size) : -1;
        free(blob);
        if (st != MS_OK)
            fprintf(stderr, "meshbake: %s\n", err.text);
        if (st != MS_OK || wr != 0)
            return 1;
    }
    return 0;
}

static void report_json(const cli_args *a, const cli_results *res)
{
    const ms_apo_classic_options o = a->o;
    const ms_apo_classic_report r = res->r;
    const accuracy *acc = res->acc;
    const char *in = a->in, *measure = o.measure == MS_APO_MEASURE_CLASSIC ? "classic" : "spread";
    double run_cpu = res->run_cpu, load_seconds = res->load_seconds, lookup_rate = res->lookup_rate;
    uint64_t lookups = a->lookups;
    size_t accuracy_points = a->accuracy_points;
        json_t *level_texels = json_array();
    for (uint32_t d = 0; d < r.levels; ++d)
        json_array_append_new(level_texels, json_integer(r.level_texels[d]));
    json_t *root = json_pack(
        "{s:o, s:I, s:I, s:I, s:f, s:s, s:i, s:i, s:I, s:I, s:I, s:I, s:I, s:I, s:i, s:[i, i], s:o, "
        "s:I, s:I, s:I, s:I, s:o, s:o, s:o, s:o}",
        "input", ms_json_text(in), "input_triangles", (json_int_t)r.input_triangles,
        "simplified_triangles", (json_int_t)r.simplified_triangles, "refused_faces",
        (json_int_t)r.refused_faces, "tolerance", o.tolerance, "measure", measure, "init_depth",
        (int)o.init_depth, "max_depth", (int)o.max_depth, "internal_nodes", (json_int_t)r.internal_nodes,
        "leaves", (json_int_t)r.leaves, "cells", (json_int_t)(r.internal_nodes + r.leaves), "texels",
        (json_int_t)r.texels, "bytes", (json_int_t)r.bytes, "stored_bytes", (json_int_t)r.stored_bytes,
        "levels", (int)r.levels, "texture", (int)r.texture_width, (int)r.texture_height, "level_texels",
        level_texels, "samples", (json_int_t)r.build.samples, "ray_hits", (json_int_t)r.build.ray_hits,
        "closest_points", (json_int_t)r.build.closest_points, "unsampled", (json_int_t)r.build.unsampled,
        "m_to_M_distance", ms_json_number(r.build.m_to_M_distance), "cpu_seconds", ms_json_fixed(run_cpu, 3),
        "seconds", ms_json_fixed(r.seconds_total, 3), "seconds_apo", ms_json_fixed(r.seconds_apo, 3));
    if (root) {
        json_object_set_new(root, "phases",
                            json_pack("{s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o, s:o}", "load",
                                      ms_json_fixed(load_seconds, 3), "simplify",
                                      ms_json_fixed(r.seconds_simplify, 3), "prepare",
                                      ms_json_fixed(r.seconds_prepare, 3), "embree_scene",
                                      ms_json_fixed(r.build.seconds_scene, 3), "distance",
                                      ms_json_fixed(r.build.seconds_distance, 3), "octree",
                                      ms_json_fixed(r.seconds_octree, 3), "sample",
                                      ms_json_fixed(r.seconds_sample, 3), "encode",
                                      ms_json_fixed(r.seconds_encode, 3), "store",
                                      ms_json_fixed(r.seconds_store, 3)));
        if (lookups)
            json_object_set_new(root, "lookups_per_second", json_integer((json_int_t)llround(lookup_rate)));
        if (accuracy_points) {
            json_t *accuracy_report = json_pack("{s:I}", "points", (json_int_t)acc[0].points);
            for (int rule = 0; rule < 2; ++rule)
                json_object_set_new(accuracy_report, rule ? "nearest" : "stop",
                                    json_pack("{s:I, s:o, s:o, s:o}", "off_tree", (json_int_t)acc[rule].off_tree,
                                              "mean_deg", ms_json_fixed(acc[rule].mean, 3), "median_deg",
                                              ms_json_fixed(acc[rule].median, 3), "p90_deg",
                                              ms_json_fixed(acc[rule].p90, 3)));
            json_object_set_new(root, "accuracy", accuracy_report);
        }
        json_object_set_new(root, "peak_rss_mb", ms_json_fixed(ms_peak_rss_mb(), 1));
    }
    ms_json_print(stdout, root, MS_JSON_COMPACT);
}

static void report_text(const cli_args *a, const cli_results *res)
{
    const ms_apo_classic_options *o = &a->o;
    const ms_apo_classic_report *r = &res->r;
    const accuracy *acc = res->acc;
    const char *measure = o->measure == MS_APO_MEASURE_CLASSIC ? "classic" : "spread";
    printf("input            %s: %zu triangles, simplified to %zu (%zu refused)\n", a->in, r->input_triangles,
           r->simplified_triangles, r->refused_faces);
    printf("settings         measure %s, tolerance %g, depths %u..%u\n", measure, o->tolerance, o->init_depth,
           o->max_depth);
    printf("octree           %zu internal nodes, %zu leaves, %zu cells, %u levels\n", r->internal_nodes,
           r->leaves, r->internal_nodes + r->leaves, r->levels);
    printf("texels           %zu (%zu bytes, stored %zu bytes; 2D layout %ux%u)\n", r->texels, r->bytes,
           r->stored_bytes, r->texture_width, r->texture_height);
    printf("samples          %llu: %llu ray hits, %llu closest points, %llu unsampled; m-to-M %.3g\n",
           (unsigned long long)r->build.samples, (unsigned long long)r->build.ray_hits,
           (unsigned long long)r->build.closest_points, (unsigned long long)r->build.unsampled,
           r->build.m_to_M_distance);
    printf("seconds          load %.2f, simplify %.2f, prepare %.2f, octree %.2f, sample %.2f, encode %.2f, "
           "store %.2f; APO %.2f, total %.2f (without load)\n",
           res->load_seconds, r->seconds_simplify, r->seconds_prepare, r->seconds_octree, r->seconds_sample,
           r->seconds_encode, r->seconds_store, r->seconds_apo, r->seconds_total);
    printf("cpu seconds      %.2f (all threads, reading included)\n", res->run_cpu);
    for (int rule = 0; rule < 2 && a->accuracy_points; ++rule)
        printf("accuracy %-7s  %zu centroids of M, %zu off the tree: angle to M mean %.2f, median %.2f, "
               "p90 %.2f degrees\n",
               rule ? "nearest" : "stop", acc[rule].points, acc[rule].off_tree, acc[rule].mean,
               acc[rule].median, acc[rule].p90);
    if (a->lookups)
        printf("lookups          %.3g per second (CPU reference, one thread, random points)\n", res->lookup_rate);
}

int ms_apo_classic_cli(int argc, char **argv)
{
    cli_args a;
    int status = parse_cli(argc, argv, &a);
    if (status >= 0)
        return status;
    cli_results res;
    memset(&res, 0, sizeof res);
    ms_apo_chunk chunk;
    bool keep_chunk = false;
    if ((status = build_chunk(&a, &res, &chunk, &keep_chunk)) != 0)
        return status;
    status = use_chunk(&a, &res, &chunk);
    if (keep_chunk)
        ms_apo_chunk_free(&chunk);
    if (status != 0)
        return status;
    if (a.json)
        report_json(&a, &res);
    else
        report_text(&a, &res);
    return 0;
}
