/* meshrender: the CPU reference renderer as a program. Renders a mesh file, or
 * the cut an archive shows for each camera, at the keyframes of a camera path,
 * to PNG files (ms_study_render.h says how). */
#include <errno.h>
#include <getopt.h>
#include <jansson.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "ms_archive.h"
#include "ms_cli.h"
#include "ms_section.h"
#include "ms_camera_path.h"
#include "ms_json_out.h"
#include "ms_mesh_io.h"
#include "ms_parse_number.h"
#include "ms_progress.h"
#include "ms_study_apo.h"
#include "ms_study_cut.h"
#include "ms_study_render.h"
#include "ms_view_decoder.h"
#include "ms_version.h"

enum { EXIT_INPUT = 1, EXIT_USAGE = 2 };

static void usage(FILE *out)
{
    fputs("usage: meshrender INPUT -p CAMERA_PATH -o OUT_DIR [--width 640] [--height 480]\n"
          "                  [--near D] [--far D] [--tolerance 1] [--apo] [--apo-levels L]\n"
          "                  [--apo-filter linear|nearest|none] [--smooth] [--normals]\n"
          "                  [--albedo] [--section PLANE]... [--threads N] [--json]\n"
          "Ray casts INPUT on the CPU (Embree) at every keyframe of CAMERA_PATH and writes\n"
          "OUT_DIR/frame_K.png (K = keyframe number, 3 digits): head light at the camera,\n"
          "Lambert + Blinn-Phong, sRGB. INPUT is a mesh file (PLY, OBJ, OFF, optionally\n"
          "gzipped), rendered whole, or an archive (*.msa), rendered as the cut a client\n"
          "shows for each camera (every payload held, selection converged). A model with\n"
          "vertex colours is shaded with them as its albedo (interpolated across each\n"
          "triangle, as meshview does); without, grey.\n\n"
          "  -p, --path FILE     camera path (docs/CAMERA_PATHS.md)\n"
          "  -o, --output DIR    where to write (created)\n"
          "      --width N, --height N   viewport in pixels (1 to 65535)\n"
          "      --near D, --far D       clipping distances (default: from the bounds)\n"
          "      --tolerance PX  archive: screen tolerance of the cut (default 1)\n"
          "      --apo           archive: shade with the APO chunks (CPU traversal)\n"
          "      --apo-levels L  only the first L levels of each chunk, as a client that\n"
          "                      fetched that many (default 0: whole chunks)\n"
          "      --apo-filter F  the APO lookup, as meshview's: linear (default: depth\n"
          "                      limited by the pixel's footprint, 8-cell interpolation),\n"
          "                      nearest (footprint depth only), none (the nearest leaf)\n"
          "      --smooth        interpolated vertex normals instead of flat ones (where\n"
          "                      APO gives none)\n"
          "      --normals       also write OUT_DIR/normals_K.png, rgb = (N + 1) / 2\n"
          "      --albedo        the unlit picture: the vertex colours interpolated (the\n"
          "                      viewer's grey without colours), as meshview --shading albedo\n"
          "      --section PLANE cut the model (up to 3 times), as meshview --section:\n"
          "                      AXIS=VALUE (x=V cuts away x > V; -x, -y, -z the other\n"
          "                      side) or PX,PY,PZ,NX,NY,NZ; the inside seen through the\n"
          "                      cut (back faces) drawn flat in the section colour\n"
          "      --threads N     render threads (default: every core)\n"
          "      --json          print the summary as one JSON object\n"
          "  -h, --help          show this help\n"
          "      --version       show the version\n\n"
          "Exit status: 0 on success, 1 for an input or render error, 2 for a usage error.\n",
          out);
}

static bool parse_positive(const char *text, double *out)
{
    const char *end = ms_parse_double(text, out);
    return end && *end == '\0' && *out > 0 && *out < 1e300;
}

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcmp(s + n - m, suffix) == 0;
}

typedef struct options {
    const char *input, *path, *out_dir;
    double width, height, near_distance, far_distance, tolerance;
    unsigned threads, apo_levels;
    ms_study_apo_filter apo_filter;
    bool apo, smooth, normals, albedo, json;
    unsigned section_count;
    double sections[MS_SECTIONS_MAX][4];
} options;

/* Parses argv; returns -1 to go on, else the exit status. */
static int parse_options(int argc, char **argv, options *o)
{
    static const struct option long_options[] = {
        {"path", required_argument, NULL, 'p'},     {"output", required_argument, NULL, 'o'},
        {"width", required_argument, NULL, 'W'},    {"height", required_argument, NULL, 'H'},
        {"near", required_argument, NULL, 'n'},     {"far", required_argument, NULL, 'f'},
        {"tolerance", required_argument, NULL, 't'}, {"threads", required_argument, NULL, 'T'},
        {"apo", no_argument, NULL, 'a'},            {"normals", no_argument, NULL, 'N'},
        {"smooth", no_argument, NULL, 'S'},         {"apo-levels", required_argument, NULL, 'L'},
        {"json", no_argument, NULL, 'j'},           {"help", no_argument, NULL, 'h'},
        {"apo-filter", required_argument, NULL, 'F'}, {"albedo", no_argument, NULL, 'A'},
        {"section", required_argument, NULL, 'X'},
        {NULL, 0, NULL, 0},
    };
    *o = (options){.width = 640, .height = 480, .tolerance = 1};
    int c;
    double v;
    while ((c = ms_cli_next("meshrender", argc, argv, "p:o:h", long_options)) != -1) {
        switch (c) {
        case 'p': o->path = optarg; break;
        case 'o': o->out_dir = optarg; break;
        case 'a': o->apo = true; break;
        case 'N': o->normals = true; break;
        case 'S': o->smooth = true; break;
        case 'A': o->albedo = true; break;
        case 'X': {
            double point[3], normal[3];
            ms_error e;
            if (o->section_count >= MS_SECTIONS_MAX) {
                fprintf(stderr, "meshrender: --section: at most %d section planes\n", MS_SECTIONS_MAX);
                return EXIT_USAGE;
            }
            if (ms_section_parse(optarg, point, normal, &e) != MS_OK) {
                fprintf(stderr, "meshrender: --section: %s\n", e.text);
                return EXIT_USAGE;
            }
            ms_section_plane(point, normal, o->sections[o->section_count++]);
            break;
        }
        case 'j': o->json = true; break;
        case 'h': usage(stdout); return 0;
        case 'F':
            if (!ms_study_apo_filter_parse(optarg, &o->apo_filter)) {
                fprintf(stderr, "meshrender: --apo-filter wants linear, nearest or none, not '%s'\n", optarg);
                return EXIT_USAGE;
            }
            break;
        case 'W':
        case 'H':
            if (!parse_positive(optarg, &v) || v != (double)(long)v || v > 65535) {
                fprintf(stderr, "meshrender: --%s must be a whole number from 1 to 65535\n",
                        c == 'W' ? "width" : "height");
                return EXIT_USAGE;
            }
            *(c == 'W' ? &o->width : &o->height) = v;
            break;
        case 'n':
        case 'f':
        case 't':
            if (!parse_positive(optarg, &v)) {
                fprintf(stderr, "meshrender: '%s' is not a positive number\n", optarg);
                return EXIT_USAGE;
            }
            *(c == 'n' ? &o->near_distance : c == 'f' ? &o->far_distance : &o->tolerance) = v;
            break;
        case 'T':
        case 'L':
            if (c == 'L' && strcmp(optarg, "0") == 0) { /* whole chunks */
                o->apo_levels = 0;
                break;
            }
            if (!parse_positive(optarg, &v) || v != (double)(long)v || v > 1024) {
                fprintf(stderr, "meshrender: --%s must be a whole number from 1 to 1024\n",
                        c == 'T' ? "threads" : "apo-levels");
                return EXIT_USAGE;
            }
            *(c == 'T' ? &o->threads : &o->apo_levels) = (unsigned)v;
            break;
        default: return MS_CLI_USAGE; /* reported by ms_cli_next */
        }
    }
    if (optind != argc - 1 || !o->path || !o->out_dir) {
        fprintf(stderr, "meshrender: expected INPUT -p CAMERA_PATH -o OUT_DIR (try 'meshrender --help')\n");
        return EXIT_USAGE;
    }
    if (o->near_distance > 0 && o->far_distance > 0 && o->far_distance <= o->near_distance) {
        fprintf(stderr, "meshrender: --far must exceed --near\n");
        return EXIT_USAGE;
    }
    o->input = argv[optind];
    if (o->apo && !ends_with(o->input, ".msa")) {
        fprintf(stderr, "meshrender: --apo needs an archive (*.msa) input\n");
        return EXIT_USAGE;
    }
    return -1;
}

/* What is rendered: a fixed scene (mesh input) or a view over an archive. */
typedef struct source {
    ms_study_scene *mesh_scene;
    ms_archive *archive;
    ms_view *view;
    ms_study_apo *apo;
    uint32_t *apo_levels; /* per cell, with --apo-levels */
    uint8_t *colours;     /* the mesh input's vertex colours, NULL without */
    double lo[3], hi[3];
} source;

static ms_status open_source(const options *o, source *s, ms_error *err)
{
    memset(s, 0, sizeof *s);
    ms_status st;
    if (!ends_with(o->input, ".msa")) {
        ms_mesh mesh = {0};
        if ((st = ms_mesh_load(o->input, &mesh, NULL, err)) != MS_OK)
            return st;
        st = ms_study_scene_new(mesh.positions, mesh.vertex_count, mesh.triangles, mesh.triangle_count,
                                &s->mesh_scene, err);
        if (st == MS_OK && mesh.colours) { /* the scene keeps the vertices' numbers */
            s->colours = mesh.colours;
            mesh.colours = NULL;
        }
        ms_mesh_free(&mesh);
        if (st == MS_OK)
            ms_study_scene_bounds(s->mesh_scene, s->lo, s->hi);
        return st;
    }
    if ((st = ms_archive_open(o->input, &s->archive, err)) != MS_OK)
        return st;
    const ms_archive_header *h = ms_archive_get_header(s->archive);
    for (int k = 0; k < 3; ++k) {
        s->lo[k] = h->box_origin[k];
        s->hi[k] = h->box_origin[k] + h->box_side;
    }
    if ((st = ms_view_create_from_archive(s->archive, &s->view, err)) != MS_OK)
        return st;
    if (o->apo_levels) {
        if (!(s->apo_levels = malloc(h->cell_count * sizeof *s->apo_levels + 1)))
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
        for (uint32_t c = 0; c < h->cell_count; ++c)
            s->apo_levels[c] = o->apo_levels;
    }
    if (o->apo) {
        if (!h->has_apo)
            return ms_error_set(err, MS_ERR_ARG, "%s: the archive has no APO chunks (baked with --no-apo)", o->input);
        if ((st = ms_study_apo_from_archive(s->archive, o->apo_levels, UINT32_MAX, MS_APO_MISSING_STOP, &s->apo,
                                            err)) != MS_OK)
            return st;
        ms_study_apo_set_filter(s->apo, o->apo_filter);
    }
    return MS_OK;
}

static void close_source(source *s)
{
    ms_study_scene_free(s->mesh_scene);
    ms_study_apo_free(s->apo);
    free(s->apo_levels);
    free(s->colours);
    ms_view_destroy(s->view);
    ms_archive_close(s->archive);
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshrender");
    options o;
    int rc = parse_options(argc, argv, &o);
    if (rc >= 0)
        return rc;
    if (mkdir(o.out_dir, 0755) != 0 && errno != EEXIST) {
        fprintf(stderr, "meshrender: cannot create %s: %s\n", o.out_dir, strerror(errno));
        return EXIT_INPUT;
    }
    double start = ms_now_seconds();
    ms_error err;
    ms_camera_path path = {0};
    source src;
    ms_status st = ms_camera_path_load(o.path, &path, &err);
    if (st == MS_OK)
        st = open_source(&o, &src, &err);
    else
        memset(&src, 0, sizeof src);
    json_t *frames = json_array();
    ms_study_image image = {0};
    ms_view_mesh cut = {0};
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = o.tolerance;
    uint64_t pixels_covered = 0;
    for (size_t key = 0; st == MS_OK && key < path.count; ++key) {
        ms_camera camera;
        if ((st = ms_study_key_camera(&path, key, o.width, o.height, o.near_distance, o.far_distance, src.lo, src.hi,
                                      &camera, &err)) != MS_OK)
            break;
        double frame_start = ms_now_seconds();
        ms_study_scene *scene = src.mesh_scene, *cut_scene = NULL;
        ms_study_cut_report report = {0};
        if (!scene) {
            if ((st = ms_study_cut(src.archive, src.view, &camera, &params, src.apo_levels, &cut, &report, &err)) != MS_OK ||
                (st = ms_study_scene_new(cut.positions, cut.vertex_count, cut.triangles, cut.triangle_count,
                                         &cut_scene, &err)) != MS_OK)
                break;
            scene = cut_scene;
        }
        /* the colours: the mesh's, or the cut's where the archive carries them */
        ms_study_render_options ro = {.threads = o.threads, .apo = src.apo, .triangle_cell = cut.triangle_cell,
                                      .smooth = o.smooth, .colours = src.mesh_scene ? src.colours : cut.colours,
                                      .albedo = o.albedo, .section_count = o.section_count};
        memcpy(ro.sections, o.sections, sizeof ro.sections);
        bool coloured = ro.colours != NULL;
        st = ms_study_render(scene, &camera, &ro, &image, &err);
        size_t triangles = ms_study_scene_triangle_count(scene);
        ms_study_scene_free(cut_scene);
        char file[4200];
        snprintf(file, sizeof file, "%s/frame_%03zu.png", o.out_dir, key);
        if (st == MS_OK)
            st = ms_study_image_write_png(&image, file, &err);
        if (st == MS_OK && o.normals) {
            char normals[4200];
            snprintf(normals, sizeof normals, "%s/normals_%03zu.png", o.out_dir, key);
            st = ms_study_image_write_normals_png(&image, normals, &err);
        }
        if (st != MS_OK)
            break;
        uint64_t covered = 0;
        for (size_t p = 0; p < (size_t)image.width * image.height; ++p)
            covered += ms_study_image_covered(&image, p) != 0;
        pixels_covered += covered;
        json_t *frame = json_pack("{s:I, s:f, s:o, s:I, s:I, s:b, s:f}", "key", (json_int_t)key, "time",
                                  path.keys[key].time, "png", ms_json_text(file), "pixels_covered", (json_int_t)covered,
                                  "triangles", (json_int_t)triangles, "coloured", coloured,
                                  "seconds", ms_now_seconds() - frame_start);
        if (frame && !src.mesh_scene)
            json_object_set_new(frame, "cut",
                                json_pack("{s:I, s:I, s:I, s:I, s:I}", "shown_cells", (json_int_t)report.shown_cells,
                                          "index_bytes", (json_int_t)report.index_bytes, "geometry_bytes",
                                          (json_int_t)report.geometry_bytes, "apo_bytes",
                                          (json_int_t)report.apo_bytes, "triangles", (json_int_t)report.triangles));
        json_array_append_new(frames, frame);
        if (!o.json)
            printf("meshrender: %s: %llu pixels covered\n", file, (unsigned long long)covered);
    }
    ms_study_image_free(&image);
    ms_view_mesh_free(&cut);
    close_source(&src);
    ms_camera_path_free(&path);
    if (st != MS_OK) {
        fprintf(stderr, "meshrender: %s\n", err.text);
        json_decref(frames);
        return EXIT_INPUT;
    }
    json_t *root = json_pack("{s:o, s:o, s:o, s:o, s:I, s:f}", "input", ms_json_text(o.input), "path",
                             ms_json_text(o.path), "output", ms_json_text(o.out_dir), "frames", frames, "pixels_covered", (json_int_t)pixels_covered, "seconds",
                             ms_now_seconds() - start);
    if (o.json)
        ms_json_print(stdout, root ? root : json_object(), MS_JSON_COMPACT);
    else
        json_decref(root);
    return fflush(stdout) == 0 ? 0 : EXIT_INPUT;
}
