#include "ms_viewer_options.h"
#include "ms_cli.h"

#include <getopt.h>
#include <math.h>
#include <string.h>

#include "ms_catalog.h"
#include "ms_parse_number.h"
#include "ms_viewer_annotate.h"

void ms_viewer_options_usage(FILE *out)
{
    fputs("usage: meshview --server HOST:PORT [--model NAME] [--token T] [options]\n"
          "       meshview ARCHIVE_DIR [--model NAME] [options]\n"
          "       meshview ARCHIVE_DIR|--server HOST:PORT --scene FILE [options]\n\n"
          "Shows a model streamed from meshserve, or read from a local archive directory\n"
          "(the same client core, without a network), shaded with its APO normals. Without\n"
          "--model it opens on the catalogue (name, triangles, size) to pick from.\n"
          "  --server HOST:PORT     numeric address and binary port of meshserve\n"
          "  --model NAME           open this model directly\n"
          "  --token T              access token\n"
          "  --size WxH             window size in pixels (default 1280x720)\n"
          "  --tolerance PX         geometric screen tolerance (default 1, with APO or without)\n"
          "  --apo-levels L         most APO octree levels fetched; the core fetches down to\n"
          "                         the level whose texel covers about a pixel (default 16)\n"
          "  --apo-min-tolerance PX fetch APO only where the geometric tolerance is PX or\n"
          "                         coarser (default 2: at a finer one the chunks add bytes\n"
          "                         and no picture, docs/ACCURACY.md); 0: at any tolerance\n"
          "  --no-apo               fetch no APO; shade with geometry normals\n"
          "  --apo-filter F         linear (default: 8-texel interpolation, no deeper than\n"
          "                         the first level whose texels fit in a pixel) | nearest\n"
          "                         (the nearest texel, the same depth limit) | none (the\n"
          "                         nearest leaf)\n"
          "  --shading MODE         apo | geometry | normals | cells | albedo (default apo);\n"
          "                         geometry fetches no APO; albedo is the model's colour\n"
          "                         unlit (its vertex colours; grey without)\n"
          "  --upload-budget BYTES  GPU upload per frame at most (default 4000000)\n"
          "  --memory MB            client cache target (default none)\n"
          "  --bandwidth B          bytes per second read (default unlimited)\n"
          "  --whole-index          take the model's whole index at open, as from a server\n"
          "                         without subtrees (default: the index head, then subtrees\n"
          "                         as the view needs them)\n"
          "  --up x|y|z             the model's up axis (default z)\n"
          "  --flat                 flat shading (each triangle's normal) where no APO normal\n"
          "                         is used (the M key toggles it)\n"
          "  --crease-angle DEG     edges sharper than DEG degrees stay hard, 0 to 180 (default:\n"
          "                         the model's catalogue crease_angle, else 60; K cycles it)\n"
          "Scenes (docs/SCENES.md):\n"
          "  --scene FILE           a room of catalogue models; --path defaults to its camera path\n"
          "  --effects-off LIST     effects left out of the program (comma-separated: detail_normals,\n"
          "                         specular, two_sided, haze, impostors, displacement)\n"
          "  --effects-all          compile every effect in, whether the scene calls for it or not\n"
          "  --connection-per-model from a server, one connection per model (default: one\n"
          "                         connection for all the models, their requests merged by\n"
          "                         priority); for comparisons\n"
          "Looking closely (one model; docs/VIEWER.md):\n"
          "  --light AZ,EL          a directional light, degrees in the camera's frame (azimuth\n"
          "                         from the view axis, > 0 from the right; elevation, > 0 from\n"
          "                         above; default the head light)\n"
          "  --section PLANE        cut the model (up to 3 times): AXIS=VALUE (AXIS x, y, z,\n"
          "                         -x, -y, -z: x=V cuts away x > V) or PX,PY,PZ,NX,NY,NZ (a\n"
          "                         point, and the normal of the side cut away)\n"
          "  --view TEXT            start from a view printed by the V key (camera, light and\n"
          "                         measuring points: mv1:t=...)\n"
          "  --annotations FILE     the model's annotations from FILE (docs/ANNOTATIONS.md;\n"
          "                         default: the archive's DIR/NAME.annotations.json, or the\n"
          "                         server's); Ctrl+S saves to it\n"
          "  --annotation ID        select annotation ID at the start (its text in the HUD;\n"
          "                         in the window the camera moves to its view)\n"
          "  --measure X,Y:X,Y...   scripted: measure along the surface points seen at these\n"
          "                         pixels of the first keyframe (top-left origin), 2 to 16;\n"
          "                         the distance and its precision in the report\n"
          "Camera path:\n"
          "  --path FILE            a camera path (docs/CAMERA_PATHS.md): Space plays it in the\n"
          "                         window; scripted, the camera follows it (else the home view)\n"
          "Scripted, headless (on with --screenshot-dir):\n"
          "  --screenshot-dir DIR   one PNG per keyframe (keyframe-NN.png; catalogue.png\n"
          "                         without --model); also where the P key writes\n"
          "  --frames N             frames drawn between two keyframes (default 8)\n"
          "  --keyframe-timeout S   longest wait for a complete view (default 30)\n"
          "  --hud                  draw the HUD into the pictures too\n"
          "  --compare-apo          draw every frame with APO and with plain shading, each\n"
          "                         timed (the report's compare_apo)\n"
          "  --json                 one JSON report on stdout\n"
          "  -h, --help             this help\n"
          "      --version          the version\n"
          "Mouse: left drag orbits (fly mode: looks around), right or shift drag pans,\n"
          "scroll zooms, double-click re-centres on the surface under the cursor; in a\n"
          "scene a click selects the piece under the cursor.\n"
          "Keys:  O  APO normals on/off        G  geometry-normal shading on/off\n"
          "       N  normals as colours        C  cell colours\n"
          "       B  albedo: the model's colour, unlit (B again: lit)\n"
          "       X  wireframe overlay         H  HUD on/off\n"
          "       M  smooth / flat shading where no APO normal is used\n"
          "       K  crease angle: 30, 45, 60, 90, 180 degrees (hard edges)\n"
          "       P  screenshot (into --screenshot-dir, default .)\n"
          "       + / -  tolerance down / up (finer / coarser)\n"
          "       R  reset view                U  cycle the up axis (x, y, z)\n"
          "       ] / [  (or PgDn / PgUp)  next / previous model\n"
          "       F  fly mode: W A S D move, Q / E down / up, mouse looks around\n"
          "       Tab  back to the catalogue   Esc  quit\n"
          "       Space  play / pause the camera path (--path, or the scene's) from\n"
          "              where the camera is; a drag, the wheel or a move stops it\n"
          "       . / ,  next / previous keyframe of the path\n"
          "       T  measuring on/off: a click adds the surface point under the cursor;\n"
          "          Backspace removes the last point, Delete clears them\n"
          "       L  raking light from the left, top, right, bottom, then the head light\n"
          "       Ctrl + left drag  moves the light     V  print the view text (--view)\n"
          "       Y  add a section through the orbit centre, across the view (up to 3)\n"
          "       J  turn the last section over     9 / 0  move it back / forward\n"
          "       I  remove the last section\n"
          "       a click on an annotation's marker selects it: its title and text in the\n"
          "          HUD, the camera moves to its view; a click elsewhere deselects\n"
          "       Enter  add an annotation at the surface under the cursor (type its\n"
          "          title, Enter, its text, Enter; Esc cancels)\n"
          "       Shift+Delete  delete the selected annotation   Ctrl+S  save them\n"
          "Scene: ] / [  select the next / previous piece   Z  frame the selected piece\n"
          "Exit status: 0 on success, 1 on an error (no OpenGL 4.1, server gone, unknown\n"
          "model, window closed while a scripted run streams), 2 for a usage error.\n",
          out);
}

/* Option values (ms_option_*): false after printing the one line to err
 * (when err is not NULL). */
static bool number(FILE *err, const char *name, const char *text, double lo, double hi,
                   double *out)
{
    ms_error e;
    if (ms_option_double(name, text, lo, hi, out, &e) == MS_OK)
        return true;
    if (err)
        fprintf(err, "meshview: %s\n", e.text);
    return false;
}

static bool integer(FILE *err, const char *name, const char *text, int64_t lo, int64_t hi,
                    int64_t *out)
{
    ms_error e;
    if (ms_option_int(name, text, lo, hi, out, &e) == MS_OK)
        return true;
    if (err)
        fprintf(err, "meshview: %s\n", e.text);
    return false;
}

/* "1280x720" */
static bool size_pair(const char *text, int *w, int *h)
{
    const char *x = strchr(text, 'x');
    char first[16];
    if (!x || x == text || (size_t)(x - text) >= sizeof first)
        return false;
    memcpy(first, text, (size_t)(x - text));
    first[x - text] = 0;
    int64_t a, b;
    if (!integer(NULL, "--size", first, 16, 16384, &a) ||
        !integer(NULL, "--size", x + 1, 16, 16384, &b))
        return false;
    *w = (int)a, *h = (int)b;
    return true;
}

/* "haze,specular" to MS_EFFECT_* bits; false for an unknown or empty name. */
static bool effect_list(const char *text, unsigned *bits)
{
    *bits = 0;
    for (const char *p = text;;) {
        size_t n = strcspn(p, ",");
        bool known = false;
        for (unsigned bit = 1; bit <= MS_EFFECTS_ALL && !known; bit <<= 1)
            if (strlen(ms_effect_name(bit)) == n && strncmp(ms_effect_name(bit), p, n) == 0) {
                *bits |= bit;
                known = true;
            }
        if (!known)
            return false;
        if (!p[n])
            return true;
        p += n + 1;
    }
}

/* "X,Y:X,Y..." into o->measure_px: 2 to 16 points, each coordinate finite. */
static bool measure_pixels(const char *text, ms_viewer_options *o)
{
    o->measure_count = 0;
    for (const char *p = text;;) {
        size_t len = strcspn(p, ":");
        char pair[96];
        if (o->measure_count >= MS_VIEWER_MEASURE_MAX_POINTS || len >= sizeof pair)
            return false;
        memcpy(pair, p, len);
        pair[len] = 0;
        if (!ms_viewer_numbers(pair, ',', o->measure_px[o->measure_count], 2))
            return false;
        o->measure_count++;
        if (!p[len])
            return o->measure_count >= 2;
        p += len + 1;
    }
}

/* The checks across options and the settings derived from them, after the
 * command line was read; 0, or 2 after printing the one line. */
static int finish_options(ms_viewer_options *o, const char *shading, bool no_apo, FILE *err)
{
    if (!o->archive_dir == !o->port) {
        fprintf(err, "meshview: give either --server HOST:PORT or an ARCHIVE_DIR (see --help)\n");
        return 2;
    }
    if (o->model && !ms_model_name_valid(o->model)) {
        fprintf(err, "meshview: '%s' is not a model name\n", o->model);
        return 2;
    }
    if (shading) {
        if (!strcmp(shading, "apo"))
            o->shading = MS_SHADING_LIT;
        else if (!strcmp(shading, "geometry"))
            o->shading = MS_SHADING_LIT, o->apo_shading = false;
        else if (!strcmp(shading, "normals"))
            o->shading = MS_SHADING_NORMALS;
        else if (!strcmp(shading, "cells"))
            o->shading = MS_SHADING_CELLS;
        else if (!strcmp(shading, "albedo"))
            o->shading = MS_SHADING_ALBEDO;
        else {
            fprintf(err, "meshview: --shading wants apo, geometry, normals, cells or albedo\n");
            return 2;
        }
    }
    /* Geometry shading draws no APO normal: fetching the chunks would only
     * cost bytes (--compare-apo draws both, so it still fetches them). */
    if (no_apo || (!o->apo_shading && !o->compare_apo))
        o->apo_levels = 0, o->apo_shading = false;
    o->scripted = o->screenshot_dir != NULL;
    if (o->scene_file && o->model) {
        fprintf(err, "meshview: --scene and --model exclude each other\n");
        return 2;
    }
    if (o->path_file && !o->model && !o->scene_file) {
        fprintf(err, "meshview: --path needs --model or --scene\n");
        return 2;
    }
    if ((o->effects_off || o->effects_all || o->connection_per_model) && !o->scene_file) {
        fprintf(err, "meshview: --effects-off, --effects-all and --connection-per-model need "
                "--scene\n");
        return 2;
    }
    if ((o->has_view || o->measure_count || o->light.directional || o->sections.count || o->annotations_file ||
         o->annotation_id) && !o->model) {
        fprintf(err, "meshview: --view, --light, --section, --measure and --annotations need --model\n");
        return 2;
    }
    if (o->measure_count && !o->scripted) {
        fprintf(err, "meshview: --measure is for a scripted run (--screenshot-dir); in the window T measures\n");
        return 2;
    }
    for (size_t i = 0; i < o->measure_count; ++i)
        if (!(o->measure_px[i][0] >= 0 && o->measure_px[i][0] <= o->width && o->measure_px[i][1] >= 0 &&
              o->measure_px[i][1] <= o->height)) {
            fprintf(err, "meshview: --measure: pixel %zu is outside the %dx%d picture\n", i + 1, o->width,
                    o->height);
            return 2;
        }
    if (o->has_view && o->path_file && o->scripted) {
        fprintf(err, "meshview: --view and --path exclude each other in a scripted run\n");
        return 2;
    }
    if (o->has_view && !o->light.directional) /* --light wins over the view's */
        o->light = o->view.light;
    if (o->has_view && !o->sections.count) /* so does --section */
        o->sections = o->view.sections;
    if (o->json && !o->scripted) {
        fprintf(err, "meshview: --json reports a scripted run (--screenshot-dir)\n");
        return 2;
    }
    return 0;
}

/* The defaults a command line starts from. */
static void default_options(ms_viewer_options *o)
{
    memset(o, 0, sizeof *o);
    o->width = 1280, o->height = 720;
    o->frames = 8;
    o->shading = MS_SHADING_LIT;
    o->apo_shading = true;
    o->tolerance_px = 0; /* the stream's default */
    o->apo_levels = 16;
    o->apo_min_tolerance_px = MS_CORE_APO_MIN_TOLERANCE_DEFAULT;
    o->apo_filter = true, o->apo_footprint = true;
    o->upload_budget = 4000000;
    o->keyframe_timeout = 30;
    o->up_axis = 2;
    o->crease_angle_deg = -1; /* the catalogue's, else the renderer's default */
}

/* "HOST:PORT" into o->host and o->port; false when it is not one. */
static bool server_address(const char *text, ms_viewer_options *o)
{
    int64_t i;
    const char *colon = strrchr(text, ':');
    if (!colon || colon == text || (size_t)(colon - text) >= sizeof o->host ||
        !integer(NULL, "port", colon + 1, 1, 65535, &i))
        return false;
    memcpy(o->host, text, (size_t)(colon - text));
    o->host[colon - text] = 0;
    o->port = (uint16_t)i;
    return true;
}

/* What an option leaves for finish_options. */
typedef struct {
    bool no_apo;
    const char *shading;
} option_leftovers;

enum { OPTION_UNKNOWN = -1 };

/* The options of looking closely (--light, --view, --section, --measure), as
 * apply_option. */
static int inspect_option(int ch, const char *arg, ms_viewer_options *o, FILE *err)
{
    switch (ch) {
    case 'L':
        if (!ms_viewer_light_parse(arg, &o->light)) {
            fprintf(err, "meshview: --light wants AZ,EL in degrees, AZ in [-180, 180] and EL in [-90, 90], "
                    "not '%.64s'\n", arg);
            return 2;
        }
        break;
    case 'V': {
        ms_error e;
        if (ms_viewer_share_parse(arg, &o->view, &e) != MS_OK) {
            fprintf(err, "meshview: --view: %s\n", e.text);
            return 2;
        }
        o->has_view = true;
        break;
    }
    case 'X': {
        ms_error e;
        if (ms_viewer_sections_add_text(&o->sections, arg, &e) != MS_OK) {
            fprintf(err, "meshview: --section: %s\n", e.text);
            return 2;
        }
        break;
    }
    case 'Q': {
        ms_annotations *set;
        ms_error e;
        if (ms_viewer_annotate_read(arg, &set, &e) != MS_OK) {
            fprintf(err, "meshview: --annotations: %s\n", e.text);
            return 2;
        }
        ms_annotations_free(set);
        o->annotations_file = arg;
        break;
    }
    case 'q': o->annotation_id = arg; break;
    case 'G':
        if (!measure_pixels(arg, o)) {
            fprintf(err, "meshview: --measure wants 2 to 16 pixels X,Y separated by ':', not '%.64s'\n", arg);
            return 2;
        }
        break;
    default: return OPTION_UNKNOWN;
    }
    return 0;
}

/* Applies the option getopt_long returned as ch with its value arg: 0, 2
 * after printing the one line to err, or OPTION_UNKNOWN for a ch it does not
 * know. */
static int apply_option(int ch, const char *arg, ms_viewer_options *o, option_leftovers *left,
                        FILE *err)
{
    int64_t i;
    switch (ch) {
    case 's':
        if (!server_address(arg, o)) {
            fprintf(err, "meshview: --server wants HOST:PORT, not '%s'\n", arg);
            return 2;
        }
        break;
    case 'm': o->model = arg; break;
    case 'T': o->token = arg; break;
    case 'z':
        if (!size_pair(arg, &o->width, &o->height)) {
            fprintf(err, "meshview: --size wants WxH, each in [16, 16384], not '%s'\n", arg);
            return 2;
        }
        break;
    case 't':
        if (!number(err, "--tolerance", arg, 0.05, 256, &o->tolerance_px))
            return 2;
        break;
    case 'a':
        if (!integer(err, "--apo-levels", arg, 0, 32, &i))
            return 2;
        o->apo_levels = (unsigned)i;
        break;
    case 'N':
        if (!number(err, "--apo-min-tolerance", arg, 0, 256, &o->apo_min_tolerance_px))
            return 2;
        break;
    case 'n': left->no_apo = true; break;
    case 'F':
        if (!strcmp(arg, "linear"))
            o->apo_filter = true, o->apo_footprint = true;
        else if (!strcmp(arg, "nearest"))
            o->apo_filter = false, o->apo_footprint = true;
        else if (!strcmp(arg, "none"))
            o->apo_filter = false, o->apo_footprint = false;
        else {
            fprintf(err, "meshview: --apo-filter wants linear, nearest or none, not '%s'\n", arg);
            return 2;
        }
        break;
    case 'S': left->shading = arg; break;
    case 'u':
        if (!integer(err, "--upload-budget", arg, 4096, INT64_C(1) << 40, &i))
            return 2;
        o->upload_budget = (uint64_t)i;
        break;
    case 'M':
        if (!number(err, "--memory", arg, 1, 1e7, &o->memory_mb))
            return 2;
        break;
    case 'b':
        if (!number(err, "--bandwidth", arg, 1000, 1e12, &o->bandwidth))
            return 2;
        break;
    case 'W': o->whole_index = true; break;
    case 'U':
        if (strlen(arg) != 1 || arg[0] < 'x' || arg[0] > 'z') {
            fprintf(err, "meshview: --up wants x, y or z\n");
            return 2;
        }
        o->up_axis = arg[0] - 'x';
        break;
    case 'p': o->path_file = arg; break;
    case 'd': o->screenshot_dir = arg; break;
    case 'f':
        if (!integer(err, "--frames", arg, 1, 100000, &i))
            return 2;
        o->frames = (unsigned)i;
        break;
    case 'k':
        if (!number(err, "--keyframe-timeout", arg, 0.1, 86400, &o->keyframe_timeout))
            return 2;
        break;
    case 'j': o->json = true; break;
    case 'l': o->flat = true; break;
    case 'K':
        if (!number(err, "--crease-angle", arg, 0, 180, &o->crease_angle_deg))
            return 2;
        break;
    case 'H': o->hud = true; break;
    case 'A': o->compare_apo = true; break;
    case 'c': o->scene_file = arg; break;
    case 'E': o->effects_all = true; break;
    case 'C': o->connection_per_model = true; break;
    case 'e':
        if (!effect_list(arg, &o->effects_off)) {
            fprintf(err, "meshview: --effects-off wants effect names separated by commas, not '%s'\n",
                    arg);
            return 2;
        }
        break;
    default: return inspect_option(ch, arg, o, err);
    }
    return 0;
}

int ms_viewer_options_parse(int argc, char **argv, ms_viewer_options *o, FILE *err)
{
    static const struct option opts[] = {
        {"server", required_argument, NULL, 's'},     {"model", required_argument, NULL, 'm'},
        {"token", required_argument, NULL, 'T'},      {"size", required_argument, NULL, 'z'},
        {"tolerance", required_argument, NULL, 't'},  {"apo-levels", required_argument, NULL, 'a'},
        {"no-apo", no_argument, NULL, 'n'},           {"shading", required_argument, NULL, 'S'},
        {"apo-min-tolerance", required_argument, NULL, 'N'},
        {"apo-filter", required_argument, NULL, 'F'},
        {"upload-budget", required_argument, NULL, 'u'},
        {"memory", required_argument, NULL, 'M'},     {"bandwidth", required_argument, NULL, 'b'},
        {"up", required_argument, NULL, 'U'},         {"path", required_argument, NULL, 'p'},
        {"screenshot-dir", required_argument, NULL, 'd'},
        {"frames", required_argument, NULL, 'f'},
        {"keyframe-timeout", required_argument, NULL, 'k'},
        {"json", no_argument, NULL, 'j'},             {"help", no_argument, NULL, 'h'},
        {"hud", no_argument, NULL, 'H'},
        {"compare-apo", no_argument, NULL, 'A'},
        {"scene", required_argument, NULL, 'c'},
        {"effects-off", required_argument, NULL, 'e'},
        {"effects-all", no_argument, NULL, 'E'},
        {"connection-per-model", no_argument, NULL, 'C'},
        {"whole-index", no_argument, NULL, 'W'},
        {"flat", no_argument, NULL, 'l'},
        {"crease-angle", required_argument, NULL, 'K'},
        {"light", required_argument, NULL, 'L'},
        {"view", required_argument, NULL, 'V'},
        {"measure", required_argument, NULL, 'G'},
        {"section", required_argument, NULL, 'X'},
        {"annotations", required_argument, NULL, 'Q'},
        {"annotation", required_argument, NULL, 'q'},
        {NULL, 0, NULL, 0}};
    default_options(o);
    option_leftovers left = {false, NULL};
    int ch;
    optind = 1;
    while ((ch = ms_cli_next("meshview", argc, argv, "h", opts)) != -1) {
        if (ch == 'h') {
            o->help = true;
            return 0;
        }
        if (ch == MS_CLI_ERROR)
            return MS_CLI_USAGE; /* reported by ms_cli_next */
        int status = apply_option(ch, optarg, o, &left, err);
        if (status == OPTION_UNKNOWN) {
            return ms_cli_usage_error("meshview", "unknown option", argv[optind - 1]);
        }
        if (status != 0)
            return status;
    }
    if (optind < argc)
        o->archive_dir = argv[optind++];
    if (optind < argc) {
        fprintf(err, "meshview: one archive directory at most, not also '%s'\n", argv[optind]);
        return 2;
    }
    return finish_options(o, left.shading, left.no_apo, err);
}

ms_viewer_stream_settings ms_viewer_options_stream_settings(const ms_viewer_options *o)
{
    ms_viewer_stream_settings s = {.tolerance_px = o->tolerance_px,
                                   .apo_levels = o->apo_levels,
                                   .apo_min_tolerance_px = o->apo_min_tolerance_px,
                                   .memory_mb = o->memory_mb,
                                   .bandwidth = o->bandwidth,
                                   .whole_index = o->whole_index,
                                   .crease_angle_deg = o->crease_angle_deg};
    return s;
}

ms_viewer_scene_settings ms_viewer_options_scene_settings(const ms_viewer_options *o)
{
    ms_viewer_scene_settings s = {.stream = ms_viewer_options_stream_settings(o),
                                  .effects_off = o->effects_off,
                                  .force_all = o->effects_all,
                                  .connection_per_model = o->connection_per_model};
    return s;
}
