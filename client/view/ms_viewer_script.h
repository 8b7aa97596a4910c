/* meshview's scripted, headless run: the camera follows a path (or stays at
 * the home view), the viewer draws frames into an offscreen framebuffer exactly
 * as the interactive loop does (step the stream within the upload budget, draw),
 * and at every keyframe the clock holds until the view is settled (complete for
 * that camera and wholly uploaded) or --keyframe-timeout passes; then one PNG.
 * Between two keyframes it draws --frames frames along the path.
 *
 * The report (JSON through jansson) has per keyframe the PNG, the seconds to
 * view complete, triangles drawn, bytes received (geometry, APO), achieved
 * error and tolerance; overall the frame time p50/p95/max (milliseconds: the
 * step, the draw and glFinish, not the idle waits between frames) and the
 * upload bytes per frame (max, mean) against the budget; the first frame
 * that drew a triangle (first-frame.png), to show the coarse start; and the
 * memory: the core's, the GL storage the viewer holds (ms_render.h, "GL
 * memory") and the process's resident memory at the run's stages
 * (docs/VIEWER.md, "Memory").
 *
 * Requires the hidden window's GL context current. Errors: ms_status with one
 * line (the stream's: server gone, unknown model; MS_ERR_IO "window closed").
 * A keyframe that does not settle in time is not an error: the report says
 * complete: false and the caller exits 1. Thread-safety: main thread.
 */
#ifndef MS_VIEWER_SCRIPT_H
#define MS_VIEWER_SCRIPT_H

#include <jansson.h>
#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_viewer_model.h"
#include "ms_viewer_options.h"

typedef struct GLFWwindow GLFWwindow;

/* The process's resident memory (VmRSS, bytes; 0: unknown) the caller read
 * before it made the GL context and after, for the report's rss_stages. */
typedef struct ms_viewer_rss {
    uint64_t start, context;
} ms_viewer_rss;

/* Runs the script; *report (owned by the caller, json_decref) is set on MS_OK,
 * and *complete says whether every keyframe settled. Without options->model it
 * pictures the catalogue screen (catalogue.png). */
ms_status ms_viewer_script_run(const ms_viewer_options *options, const ms_viewer_source *source,
                               GLFWwindow *window, const ms_viewer_rss *rss, json_t **report, bool *complete,
                               ms_error *err);

/* Prints a run's report on stdout: the JSON document with json, else a line
 * per keyframe (or the catalogue picture's name). */
void ms_viewer_script_print(const json_t *report, bool json);

/* The q-quantile (0..1) of n values by the nearest-rank rule (sorts them);
 * 0 for n = 0. */
double ms_viewer_quantile(double *values, size_t n, double q);

#endif
