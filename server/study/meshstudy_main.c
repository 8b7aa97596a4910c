/* meshstudy: what accuracy costs, for one model. At chosen keyframes of a camera
 * path and a few screen tolerances, makes the cut a client shows (locally, from
 * the archive file), and reports the bytes it needs, its geometric error against
 * the full-resolution model and its image error against the model's reference
 * render, with geometric normals and with APO (docs/ACCURACY.md). */
#include <errno.h>
#include <getopt.h>
#include <jansson.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive.h"
#include "ms_cli.h"
#include "ms_camera_path.h"
#include "ms_json_out.h"
#include "ms_mesh_io.h"
#include "ms_parse_number.h"
#include "ms_progress.h"
#include "ms_study_apo.h"
#include "ms_study_cut.h"
#include "ms_study_measure.h"
#include "ms_study_render.h"
#include "ms_view_decoder.h"
#include "ms_version.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };
#define MAX_LIST 64

static void usage(FILE *out)
{
    fputs("usage: meshstudy MESH ARCHIVE -p CAMERA_PATH [--keys 0,4,8] [--tolerances 1,4,16]\n"
          "       meshstudy MESH --whole CANDIDATE -p CAMERA_PATH [--keys ...] [options]\n"
          "                 [--width 320] [--height 240] [--spacing S] [--reference flat|smooth]\n"
          "                 [--apo-levels L|footprint] [--apo-texel PX] [--apo-geometry-ratio K]\n"
          "                 [--apo-filter linear|nearest|none] [--threads N] [--json]\n"
          "For every chosen keyframe of CAMERA_PATH and every screen tolerance (pixels),\n"
          "makes the cut of ARCHIVE (baked from MESH) a client shows for that camera and\n"
          "measures it against MESH at full resolution: bytes (index, geometry, APO),\n"
          "triangles, symmetric Hausdorff and RMS distance (model units and projected\n"
          "pixels), and the image error of its CPU render against MESH's reference render\n"
          "(normal angle, PSNR, SSIM, silhouette), drawn flat (geometric normals), smooth\n"
          "(interpolated vertex normals, as the client draws without APO) and, when the\n"
          "archive has APO, with APO normals (smooth where a cell has no chunk, as the\n"
          "client draws it). Each cut is made from a fresh view, so its\n"
          "seconds.cut are a client's whole selection, decoding and stitching for it.\n"
          "With --whole, CANDIDATE is a mesh file (a decoded Draco or meshcodec stream,\n"
          "say) measured whole, one point per keyframe (tolerance_px 0, bytes 0).\n"
          "Definitions: docs/ACCURACY.md.\n\n"
          "  -p, --path FILE       camera path (docs/CAMERA_PATHS.md)\n"
          "      --keys LIST       keyframe numbers, comma-separated (default: every one)\n"
          "      --tolerances LIST screen tolerances in pixels (default 1,4,16)\n"
          "      --width N, --height N   viewport in pixels (default 320 x 240)\n"
          "      --spacing S       geometric sample spacing, model units (default:\n"
          "                        sqrt(area of MESH / 10^5))\n"
          "      --reference R     how MESH's reference render shades: flat (its geometric\n"
          "                        normals, the default) or smooth (its interpolated\n"
          "                        vertex normals: the surface APO samples)\n"
          "      --apo-levels L    APO as a client that fetches the first L levels of each\n"
          "                        visible cell's chunk (default 0: whole chunks), or\n"
          "                        'footprint': per cell, the client core's rule\n"
          "                        (ms_apo_footprint_levels): down to the level whose\n"
          "                        texel projects to at most --apo-texel PX pixels at the\n"
          "                        cell's nearest point (default: the point's tolerance,\n"
          "                        as the client does)\n"
          "      --apo-geometry-ratio K  the client core's APO mode (docs/CLIENT.md): cells\n"
          "                        that carry an APO chunk refine their geometry only to K\n"
          "                        times the tolerance (the client's apo_geometry_tolerance_px\n"
          "                        over tolerance_px), cells without one to the tolerance;\n"
          "                        default 1 (one cut for both renders)\n"
          "      --apo-filter F    the APO lookup, as meshview's: linear (default: depth\n"
          "                        limited by the pixel's footprint, 8-cell interpolation),\n"
          "                        nearest (footprint depth only), none (the nearest leaf)\n"
          "      --whole FILE      measure the mesh FILE drawn whole instead of an archive's cuts\n"
          "      --threads N       threads (default: every core)\n"
          "      --json            print the results as one JSON object\n"
          "  -h, --help            show this help\n"
          "      --version         show the version\n\n"
          "Exit status: 0 on success, 1 for an input or measuring error, 2 for a usage error.\n",
          out);
}

static bool parse_positive(const char *text, double *out)
{
    const char *end = ms_parse_double(text, out);
    return end && *end == '\0' && *out > 0 && *out < 1e300;
}

/* A comma-separated list of numbers (>= 0 when whole, > 0 otherwise). */
static bool parse_list(const char *text, bool whole, double *values, size_t *count)
{
    char buf[1024];
    if (strlen(text) >= sizeof buf)
        return false;
    strcpy(buf, text);
    *count = 0;
    for (char *save = NULL, *tok = strtok_r(buf, ",", &save); tok; tok = strtok_r(NULL, ",", &save)) {
        double v;
        const char *end = ms_parse_double(tok, &v);
        if (!end || *end || *count == MAX_LIST || !(whole ? v >= 0 && v == floor(v) && v < 1e9 : v > 0 && v < 1e9))
            return false;
        values[(*count)++] = v;
    }
    return *count > 0;
}

typedef struct options {
    const char *mesh, *archive, *path, *whole;
    double keys[MAX_LIST], tolerances[MAX_LIST];
    size_t key_count, tolerance_count;
    double width, height, spacing;
    unsigned threads, apo_levels;
    double apo_texel_px, apo_geometry_ratio;
    ms_study_apo_filter apo_filter;
    bool apo_footprint, smooth_reference, json;
} options;

static int parse_options(int argc, char **argv, options *o)
{
    static const struct option long_options[] = {
        {"path", required_argument, NULL, 'p'},   {"keys", required_argument, NULL, 'k'},
        {"tolerances", required_argument, NULL, 't'}, {"width", required_argument, NULL, 'W'},
        {"height", required_argument, NULL, 'H'}, {"spacing", required_argument, NULL, 's'},
        {"threads", required_argument, NULL, 'T'}, {"json", no_argument, NULL, 'j'},
        {"reference", required_argument, NULL, 'r'}, {"apo-levels", required_argument, NULL, 'L'},
        {"apo-texel", required_argument, NULL, 'X'},  {"whole", required_argument, NULL, 'w'},
        {"apo-geometry-ratio", required_argument, NULL, 'G'}, {"apo-filter", required_argument, NULL, 'F'},
        {"help", no_argument, NULL, 'h'},         {NULL, 0, NULL, 0},
    };
    *o = (options){.width = 320, .height = 240, .tolerances = {1, 4, 16}, .tolerance_count = 3, .apo_geometry_ratio = 1};
    int c;
    double v;
    while ((c = ms_cli_next("meshstudy", argc, argv, "p:h", long_options)) != -1) {
        switch (c) {
        case 'p': o->path = optarg; break;
        case 'w': o->whole = optarg; break;
        case 'j': o->json = true; break;
        case 'r':
            if (strcmp(optarg, "flat") && strcmp(optarg, "smooth")) {
                fprintf(stderr, "meshstudy: --reference must be flat or smooth\n");
                return EXIT_USAGE;
            }
            o->smooth_reference = !strcmp(optarg, "smooth");
            break;
        case 'h': usage(stdout); return 0;
        case 'F':
            if (!ms_study_apo_filter_parse(optarg, &o->apo_filter)) {
                fprintf(stderr, "meshstudy: --apo-filter wants linear, nearest or none, not '%s'\n", optarg);
                return EXIT_USAGE;
            }
            break;
        case 'k':
        case 't':
            if (!parse_list(optarg, c == 'k', c == 'k' ? o->keys : o->tolerances,
                            c == 'k' ? &o->key_count : &o->tolerance_count)) {
                fprintf(stderr, "meshstudy: bad --%s list '%s'\n", c == 'k' ? "keys" : "tolerances", optarg);
                return EXIT_USAGE;
            }
            break;
        case 'W':
        case 'H':
        case 'T':
        case 'L':
            if (c == 'L' && strcmp(optarg, "0") == 0) { /* whole chunks */
                o->apo_levels = 0;
                break;
            }
            if (c == 'L' && strcmp(optarg, "footprint") == 0) {
                o->apo_footprint = true;
                break;
            }
            if (!parse_positive(optarg, &v) || v != floor(v) || v > (c == 'W' || c == 'H' ? 65535 : 1024)) {
                fprintf(stderr, "meshstudy: '%s' is not a valid count\n", optarg);
                return EXIT_USAGE;
            }
            if (c == 'T' || c == 'L')
                *(c == 'T' ? &o->threads : &o->apo_levels) = (unsigned)v;
            else
                *(c == 'W' ? &o->width : &o->height) = v;
            break;
        case 'X':
            if (!parse_positive(optarg, &o->apo_texel_px)) {
                fprintf(stderr, "meshstudy: '%s' is not a positive texel size\n", optarg);
                return EXIT_USAGE;
            }
            break;
        case 'G':
            if (!parse_positive(optarg, &o->apo_geometry_ratio) || o->apo_geometry_ratio < 1) {
                fprintf(stderr, "meshstudy: --apo-geometry-ratio must be a number >= 1, not '%s'\n", optarg);
                return EXIT_USAGE;
            }
            break;
        case 's':
            if (!parse_positive(optarg, &o->spacing)) {
                fprintf(stderr, "meshstudy: '%s' is not a positive spacing\n", optarg);
                return EXIT_USAGE;
            }
            break;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
    }
    if (optind != argc - (o->whole ? 1 : 2) || !o->path) {
        fprintf(stderr, "meshstudy: expected MESH ARCHIVE -p CAMERA_PATH or MESH --whole CANDIDATE -p CAMERA_PATH "
                        "(try 'meshstudy --help')\n");
        return EXIT_USAGE;
    }
    o->mesh = argv[optind];
    o->archive = o->whole ? NULL : argv[optind + 1];
    if (o->whole) {
        o->tolerances[0] = 0;
        o->tolerance_count = 1;
    }
    return -1;
}

/* PSNR as JSON: null for identical images (infinite). */
static json_t *json_psnr(double psnr)
{
    return isinf(psnr) ? json_null() : json_real(psnr);
}

static json_t *image_json(const ms_study_image_error *e)
{
    return json_pack("{s:f, s:f, s:f, s:o, s:f, s:I, s:I}", "normal_mean_deg", e->normal_mean_deg, "normal_p95_deg",
                     e->normal_p95_deg, "normal_max_deg", e->normal_max_deg, "psnr_db", json_psnr(e->psnr_db), "ssim",
                     e->ssim, "silhouette_px", (json_int_t)e->silhouette_mismatch, "compared_px",
                     (json_int_t)e->both_covered);
}

typedef struct study {
    const options *o;
    ms_study_scene *full;
    ms_study_scene *whole; /* --whole: the candidate mesh, measured instead of cuts */
    ms_archive *archive;
    ms_view *view;
    ms_study_apo *apo;
    uint32_t *apo_levels; /* per cell, for the current camera */
    float *tolerance_scale; /* per cell, --apo-geometry-ratio (NULL: none) */
    ms_camera_path path;
    double spacing;
} study;

/* The APO levels every cell is read to for this camera (uniform, or by
 * footprint), set on the APO set and kept for the cut's bytes. */
static ms_status choose_apo_levels(study *s, const ms_camera *camera, double tolerance_px, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(s->archive);
    for (uint32_t c = 0; c < h->cell_count; ++c) {
        const ms_archive_cell *rec = ms_archive_get_cell(s->archive, c);
        uint32_t levels = s->o->apo_levels;
        if (s->o->apo_footprint) {
            double lo[3], side;
            ms_study_cell_cube(h, rec, lo, &side);
            levels = ms_apo_footprint_levels(camera, lo, side, s->o->apo_texel_px > 0 ? s->o->apo_texel_px
                                                                                      : tolerance_px,
                                             rec->apo_levels);
        }
        s->apo_levels[c] = levels;
        ms_status st = ms_study_apo_set_levels(s->apo, c, levels, err);
        if (st != MS_OK)
            return st;
    }
    return MS_OK;
}

/* One keyframe: the reference render, then every tolerance. */
static ms_status study_key(study *s, size_t key, json_t *points, ms_error *err)
{
    const options *o = s->o;
    double lo[3], hi[3];
    ms_study_scene_bounds(s->full, lo, hi);
    ms_camera camera;
    ms_status st = ms_study_key_camera(&s->path, key, o->width, o->height, 0, 0, lo, hi, &camera, err);
    if (st != MS_OK)
        return st;
    ms_study_render_options plain = {.threads = o->threads}, smooth = {.threads = o->threads, .smooth = true};
    ms_study_render_options truth = {.threads = o->threads, .smooth = o->smooth_reference};
    ms_study_image reference = {0}, image = {0};
    ms_view_mesh cut = {0};
    if ((st = ms_study_render(s->full, &camera, &truth, &reference, err)) != MS_OK)
        return st;
    for (size_t t = 0; st == MS_OK && t < o->tolerance_count; ++t) {
        ms_view_select_params params;
        ms_view_select_params_default(&params);
        params.tolerance_px = o->tolerances[t];
        params.hysteresis = 0; /* the cut depends on the camera and tolerance only */
        params.culled_bits_less = 6; /* the client core's default (docs/CLIENT.md) */
        params.tolerance_scale = s->tolerance_scale;
        ms_study_cut_report cr = {0};
        ms_study_scene *cut_scene = NULL;
        if (s->whole) {
            cut_scene = s->whole;
            cr.triangles = ms_study_scene_triangle_count(s->whole);
        } else {
            if (s->apo && (st = choose_apo_levels(s, &camera, o->tolerances[t], err)) != MS_OK)
                break;
            /* A fresh view for every point: the cut's seconds are then what a
             * client spends selecting, decoding and stitching it from nothing. */
            ms_view_destroy(s->view);
            s->view = NULL;
            if ((st = ms_view_create_from_archive(s->archive, &s->view, err)) != MS_OK ||
                (st = ms_study_cut(s->archive, s->view, &camera, &params, s->apo_levels, &cut, &cr, err)) != MS_OK)
                break;
            if (!cut.triangle_count) {
                st = ms_error_set(err, MS_ERR_EMPTY, "key %zu, %g px: the cut has no triangle", key,
                                  o->tolerances[t]);
                break;
            }
            if ((st = ms_study_scene_new(cut.positions, cut.vertex_count, cut.triangles, cut.triangle_count,
                                         &cut_scene, err)) != MS_OK)
                break;
        }
        double t0 = ms_now_seconds();
        ms_study_distance dist;
        ms_study_distance_params dp = {.spacing = s->spacing, .threads = o->threads, .camera = &camera};
        st = ms_study_distance_measure(cut_scene, s->full, &dp, &dist, err);
        double t1 = ms_now_seconds();
        ms_study_image_error plain_error = {0}, smooth_error = {0}, apo_error = {0};
        if (st == MS_OK && (st = ms_study_render(cut_scene, &camera, &plain, &image, err)) == MS_OK)
            st = ms_study_image_compare(&image, &reference, &plain_error, err);
        if (st == MS_OK && (st = ms_study_render(cut_scene, &camera, &smooth, &image, err)) == MS_OK)
            st = ms_study_image_compare(&image, &reference, &smooth_error, err);
        if (st == MS_OK && s->apo) {
            /* cells without a chunk drawn smooth, as the client draws them */
            ms_study_render_options with_apo = {
                .threads = o->threads, .apo = s->apo, .triangle_cell = cut.triangle_cell, .smooth = true};
            if ((st = ms_study_render(cut_scene, &camera, &with_apo, &image, err)) == MS_OK)
                st = ms_study_image_compare(&image, &reference, &apo_error, err);
        }
        double t2 = ms_now_seconds();
        if (cut_scene != s->whole)
            ms_study_scene_free(cut_scene);
        if (st != MS_OK)
            break;
        json_t *point = json_pack(
            "{s:I, s:f, s:f, s:I, s:I, s:{s:I, s:I, s:I}, s:{s:f, s:f, s:f, s:f, s:I, s:I}, s:o, s:{s:f, s:f, s:f}}",
            "key", (json_int_t)key, "time", s->path.keys[key].time, "tolerance_px", o->tolerances[t], "triangles",
            (json_int_t)cr.triangles, "shown_cells", (json_int_t)cr.shown_cells, "bytes", "index",
            (json_int_t)cr.index_bytes, "geometry", (json_int_t)cr.geometry_bytes, "apo", (json_int_t)cr.apo_bytes,
            "geometric", "hausdorff", dist.hausdorff, "rms", dist.rms, "hausdorff_px", dist.hausdorff_px, "rms_px",
            dist.rms_px, "samples", (json_int_t)(dist.samples_a + dist.samples_b), "samples_in_view",
            (json_int_t)dist.samples_px, "image", image_json(&plain_error), "seconds", "cut", cr.seconds,
            "distance", t1 - t0, "render", t2 - t1);
        if (point)
            json_object_set_new(point, "image_smooth", image_json(&smooth_error));
        if (point && s->apo)
            json_object_set_new(point, "image_apo", image_json(&apo_error));
        json_array_append_new(points, point);
        if (!o->json)
            printf("key %zu, %5g px: %8llu tris, %9llu B geometry, %9llu B APO, Hausdorff %.3g (%.3g px), RMS %.3g "
                   "(%.3g px); normals %.2f / %.2f deg (APO %.2f / %.2f), PSNR %.2f (smooth %.2f, APO %.2f), SSIM "
                   "%.4f (smooth %.4f, APO %.4f), silhouette %llu px\n",
                   key, o->tolerances[t], (unsigned long long)cr.triangles, (unsigned long long)cr.geometry_bytes,
                   (unsigned long long)cr.apo_bytes, dist.hausdorff, dist.hausdorff_px, dist.rms, dist.rms_px,
                   plain_error.normal_mean_deg, plain_error.normal_p95_deg, apo_error.normal_mean_deg,
                   apo_error.normal_p95_deg, plain_error.psnr_db, smooth_error.psnr_db, apo_error.psnr_db,
                   plain_error.ssim, smooth_error.ssim, apo_error.ssim,
                   (unsigned long long)plain_error.silhouette_mismatch);
    }
    ms_view_mesh_free(&cut);
    ms_study_image_free(&reference);
    ms_study_image_free(&image);
    return st;
}

static ms_status open_study(const options *o, study *s, ms_error *err)
{
    ms_status st;
    if ((st = ms_camera_path_load(o->path, &s->path, err)) != MS_OK)
        return st;
    for (size_t k = 0; k < o->key_count; ++k)
        if (o->keys[k] >= (double)s->path.count)
            return ms_error_set(err, MS_ERR_RANGE, "%s: keyframe %.0f of %zu", o->path, o->keys[k], s->path.count);
    ms_mesh mesh = {0};
    if ((st = ms_mesh_load(o->mesh, &mesh, NULL, err)) != MS_OK)
        return st;
    st = ms_study_scene_new(mesh.positions, mesh.vertex_count, mesh.triangles, mesh.triangle_count, &s->full, err);
    ms_mesh_free(&mesh);
    if (st != MS_OK)
        return st;
    if (!ms_study_scene_triangle_count(s->full))
        return ms_error_set(err, MS_ERR_EMPTY, "%s: no triangle", o->mesh);
    /* About 10^5 sub-triangles of side s on MESH (each triangle has at least one
     * sample and its vertices besides). */
    double area = ms_study_scene_area(s->full);
    s->spacing = o->spacing > 0 ? o->spacing : area > 0 ? sqrt(area / 1e5) : 1;
    if (o->whole) {
        ms_mesh candidate = {0};
        if ((st = ms_mesh_load(o->whole, &candidate, NULL, err)) != MS_OK)
            return st;
        st = ms_study_scene_new(candidate.positions, candidate.vertex_count, candidate.triangles,
                                candidate.triangle_count, &s->whole, err);
        ms_mesh_free(&candidate);
        if (st == MS_OK && !ms_study_scene_triangle_count(s->whole))
            st = ms_error_set(err, MS_ERR_EMPTY, "%s: no triangle", o->whole);
        return st;
    }
    if ((st = ms_archive_open(o->archive, &s->archive, err)) != MS_OK ||
        (st = ms_view_create_from_archive(s->archive, &s->view, err)) != MS_OK)
        return st;
    const ms_archive_header *h = ms_archive_get_header(s->archive);
    if (!h->has_apo)
        return MS_OK;
    if (!(s->apo_levels = calloc(h->cell_count + 1, sizeof *s->apo_levels)))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
    if (o->apo_geometry_ratio > 1) { /* as the client core's dec_take_index */
        if (!(s->tolerance_scale = malloc((h->cell_count + 1) * sizeof *s->tolerance_scale)))
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
        for (uint32_t c = 0; c < h->cell_count; ++c)
            s->tolerance_scale[c] = ms_archive_get_cell(s->archive, c)->apo_levels ? (float)o->apo_geometry_ratio : 1;
    }
    if ((st = ms_study_apo_from_archive(s->archive, 0, UINT32_MAX, MS_APO_MISSING_STOP, &s->apo, err)) != MS_OK)
        return st;
    ms_study_apo_set_filter(s->apo, o->apo_filter);
    return MS_OK;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshstudy");
    options o;
    int rc = parse_options(argc, argv, &o);
    if (rc >= 0)
        return rc;
    double start = ms_now_seconds();
    study s = {.o = &o};
    ms_error err;
    json_t *points = json_array();
    ms_status st = open_study(&o, &s, &err);
    size_t keys = o.key_count ? o.key_count : s.path.count;
    for (size_t k = 0; st == MS_OK && k < keys; ++k)
        st = study_key(&s, o.key_count ? (size_t)o.keys[k] : k, points, &err);
    json_t *root = NULL;
    if (st == MS_OK)
        root = json_pack("{s:o, s:o, s:o, s:s, s:o, s:s, s:I, s:I, s:I, s:f, s:b, s:f, s:o, s:f}", "mesh", ms_json_text(o.mesh),
                         "archive", ms_json_text(o.whole ? o.whole : o.archive), "path", ms_json_text(o.path), "reference", o.smooth_reference ? "smooth" : "flat", "apo_levels",
                         o.apo_footprint ? json_string("footprint") : json_integer((json_int_t)o.apo_levels),
                         "apo_filter", (const char *[]){"linear", "nearest", "none"}[o.apo_filter], "width", (json_int_t)o.width, "height", (json_int_t)o.height,
                         "mesh_triangles", (json_int_t)ms_study_scene_triangle_count(s.full), "spacing", s.spacing,
                         "apo", s.apo != NULL, "apo_geometry_ratio", o.apo_geometry_ratio, "points", points, "seconds", ms_now_seconds() - start);
    else
        json_decref(points);
    ms_study_scene_free(s.full);
    ms_study_scene_free(s.whole);
    ms_study_apo_free(s.apo);
    free(s.apo_levels);
    free(s.tolerance_scale);
    ms_view_destroy(s.view);
    ms_archive_close(s.archive);
    ms_camera_path_free(&s.path);
    if (st != MS_OK) {
        fprintf(stderr, "meshstudy: %s\n", err.text);
        return EXIT_INPUT;
    }
    if (o.json)
        ms_json_print(stdout, root ? root : json_object(), MS_JSON_COMPACT);
    else
        json_decref(root);
    return fflush(stdout) == 0 ? 0 : EXIT_INPUT;
}
