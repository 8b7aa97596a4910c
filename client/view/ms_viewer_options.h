/* meshview's command line (README "Programs": --help, exit 2 for a usage error
 * with one line on stderr). Numbers go through ms_parse_number.h.
 *
 *   meshview --server HOST:PORT [--model NAME] [--token T] [options]
 *   meshview ARCHIVE_DIR [--model NAME] [options]
 *   meshview ARCHIVE_DIR|--server HOST:PORT --scene FILE [options]
 *
 * Scripted (headless) mode is on when --screenshot-dir is given:
 * no visible window, the camera follows the path (or stays at the home view),
 * one PNG per keyframe, a JSON report with --json. Without --model a scripted
 * run pictures the catalogue screen. In the window, --path (or a scene's
 * camera_path) is the path that Space plays (ms_viewer_playback.h).
 *
 * Ownership: string fields point into argv. Thread-safety: getopt's (main
 * thread, once).
 */
#ifndef MS_VIEWER_OPTIONS_H
#define MS_VIEWER_OPTIONS_H

#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "ms_render.h"
#include "ms_viewer_scene.h"
#include "ms_viewer_share.h"

typedef struct ms_viewer_options {
    const char *archive_dir;   /* positional: a local archive directory */
    char host[64];
    uint16_t port;             /* with host: the server (0: none) */
    const char *model, *token;
    const char *path_file, *screenshot_dir;
    int width, height;         /* window (scripted: framebuffer) size */
    unsigned frames;           /* scripted: frames drawn between two keyframes */
    ms_shading shading;
    bool apo_shading;          /* shade with APO normals (false: geometry normals) */
    double tolerance_px;       /* geometric; 0: the default (ms_viewer_stream.h) */
    unsigned apo_levels;       /* fetched; 0: none */
    double apo_min_tolerance_px; /* --apo-min-tolerance: APO only at this geometric tolerance or coarser */
    bool apo_filter;           /* --apo-filter: interpolate between texels (linear) */
    bool apo_footprint;        /* --apo-filter: depth limited by the pixel's footprint (linear, nearest) */
    uint64_t upload_budget;    /* bytes per frame */
    double memory_mb, bandwidth, keyframe_timeout;
    bool whole_index;          /* the whole index at open (ms_core_options.whole_index) */
    int up_axis;               /* 0..2 */
    bool json, scripted, help;
    bool hud;                  /* scripted: draw the HUD into the pictures */
    bool compare_apo;          /* scripted: time APO and plain shading of every frame */
    const char *scene_file;    /* --scene: a scene (docs/SCENES.md) instead of one model */
    unsigned effects_off;      /* --effects-off: MS_EFFECT_* bits left out of the scene's program */
    bool effects_all;          /* --effects-all: every effect compiled in, called for or not */
    bool connection_per_model; /* --connection-per-model: a scene from a server opens one
                                  connection per model instead of one for all */
    bool flat;                 /* --flat: each triangle's own normal where no APO normal is used */
    double crease_angle_deg;   /* --crease-angle; negative: the catalogue's, else the default */
    ms_viewer_light light;     /* --light AZ,EL (directional); else the head light */
    ms_viewer_sections sections; /* --section (repeatable); else --view's */
    bool has_view;             /* --view TEXT: the camera, light and chain to start from */
    ms_viewer_share view;
    size_t measure_count;      /* --measure X,Y:X,Y...: scripted, framebuffer pixels of the
                                  first keyframe (top-left origin) */
    double measure_px[MS_VIEWER_MEASURE_MAX_POINTS][2];
    const char *annotations_file; /* --annotations FILE (checked when parsed); NULL: the model's */
    const char *annotation_id;    /* --annotation ID: selected at the start */
} ms_viewer_options;

/* 0: parsed (o->help for --help); 2: a usage error, one line written to err. */
int ms_viewer_options_parse(int argc, char **argv, ms_viewer_options *o, FILE *err);

/* The usage text with the key list. */
void ms_viewer_options_usage(FILE *out);

/* What the options ask of one model's stream (tolerance, APO levels, memory,
 * bandwidth), and of a scene's (the same, and which effects to compile). */
ms_viewer_stream_settings ms_viewer_options_stream_settings(const ms_viewer_options *o);
ms_viewer_scene_settings ms_viewer_options_scene_settings(const ms_viewer_options *o);

#endif
