/* One model on screen: the client core streaming it (ms_client_core.h) and the
 * renderer drawing it (ms_render.h), driven once per drawn frame from the
 * viewer's loop. Nothing but _open waits for the network or for decoding:
 * ms_viewer_stream_step sets the camera, takes the newest frame if there is one,
 * hands it to the renderer and uploads at most the per-frame byte budget.
 *
 * Tolerance. The core's tolerance is fixed when it starts; the viewer changes
 * it at run time by handing the core a camera whose viewport is scaled by
 * k = start tolerance / wanted tolerance (same frustum, k times the pixels per
 * unit), which selects exactly what the wanted tolerance would; figures the
 * core reports in its pixels are divided by k back into screen pixels.
 *
 * Requires the renderer's GL context current on the calling thread for _open,
 * _step, _draw and _close. Ownership: the stream owns its core, renderer and
 * last frame. Errors: ms_status with one line; a core that stopped (server gone,
 * model changed) is reported by ms_viewer_stream_step as MS_ERR_IO with the
 * core's reason. Thread-safety: the drawing thread only.
 */
#ifndef MS_VIEWER_STREAM_H
#define MS_VIEWER_STREAM_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_client_core.h"
#include "ms_render.h"
#include "ms_viewer_model.h"

typedef struct ms_viewer_stream ms_viewer_stream;

/* How meshview introduces itself to a server, and how long a server may be gone
 * before the viewer ends (exit 1). */
#define MS_VIEWER_AGENT "meshview/0.1"
#define MS_VIEWER_GIVE_UP_S 8.0

typedef struct ms_viewer_stream_settings {
    double tolerance_px;       /* geometric screen tolerance at start; 0: the core's
                                  default (4 px with APO, whose normals carry the
                                  finer detail, 1 px without) */
    unsigned apo_levels;       /* 0: no APO fetched */
    double apo_min_tolerance_px; /* ms_core_options.apo_min_tolerance_px */
    double memory_mb;          /* core memory target; 0 = none (ceiling 1.5x) */
    ms_core_budget *shared_budget; /* NULL, or a budget shared with other streams (the
                                  scene's; ms_client_core.h): then memory_mb must be 0 */
    double bandwidth;          /* bytes per second; 0 = unlimited */
    unsigned decode_threads;   /* 0 = the core's default */
    bool whole_index;          /* take the whole index at open (ms_core_options.whole_index),
                                  as from a server without subtrees */
    double crease_angle_deg;   /* hard edges (ms_render_set_crease_angle), degrees in [0, 180];
                                  negative: the model's catalogue value where it sets one,
                                  else MS_RENDER_CREASE_ANGLE_DEFAULT */
    ms_core_link *shared_link; /* from a server: NULL, the stream's own connection; else a
                                  link shared with other streams (the scene's), which holds
                                  the server, bandwidth and whole_index (those here are then
                                  not used) */
} ms_viewer_stream_settings;

/* Starts the core for a model opened with ms_viewer_model_open, compiles the
 * renderer's programs while the core connects and its index head is on the
 * way, then waits (at most the source's time-out) until the core opened the
 * model and decoded its root to root precision, and fills in model->header and
 * model->index from what it received (the index crosses the network once)
 * with the content bounds it took from the root (ms_core_wait_open;
 * ms_viewer_model_bounds); the renderer takes the header. So the core's first
 * frame that holds the root finds the renderer ready. The renderer learns the
 * records of the cells it draws from the core's frames. The model must
 * outlive the stream. */
ms_status ms_viewer_stream_open(const ms_viewer_source *source, ms_viewer_model *model,
                                const ms_viewer_stream_settings *settings,
                                ms_viewer_stream **stream, ms_error *err);
/* ms_viewer_stream_open in two halves, so that several streams (a scene's
 * pieces) ask for their models at once and wait for them together: start
 * starts the core and compiles the renderer (the core connects and asks for
 * the model meanwhile); wait_open waits for that opening as described above
 * and fills in the model. After a failed wait_open the stream can only be
 * closed. */
ms_status ms_viewer_stream_start(const ms_viewer_source *source, ms_viewer_model *model,
                                 const ms_viewer_stream_settings *settings,
                                 ms_viewer_stream **stream, ms_error *err);
ms_status ms_viewer_stream_wait_open(ms_viewer_stream *stream, ms_error *err);
void ms_viewer_stream_close(ms_viewer_stream *stream);

/* The tolerance asked of the core from now on (screen pixels, clamped to
 * [0.05, 256]), and the current one. */
void ms_viewer_stream_set_tolerance(ms_viewer_stream *stream, double tolerance_px);
double ms_viewer_stream_tolerance(const ms_viewer_stream *stream);

typedef struct ms_viewer_step {
    bool new_frame;                 /* a frame was taken and handed to the renderer */
    uint64_t generation;            /* of the frame being drawn (0: none yet) */
    ms_render_upload_stats upload;  /* this step's upload */
    uint64_t frame_triangles;       /* triangles of the newest frame */
    bool settled;                   /* as ms_viewer_stream_settled after this step */
} ms_viewer_step;

/* Sets the camera, takes a new frame if any, uploads within budget_bytes. */
ms_status ms_viewer_stream_step(ms_viewer_stream *stream, const ms_camera *camera,
                                uint64_t budget_bytes, ms_viewer_step *step, ms_error *err);

/* Draws what the renderer holds into the bound framebuffer. */
ms_status ms_viewer_stream_draw(ms_viewer_stream *stream, const ms_camera *camera,
                                const ms_render_options *options, ms_render_draw_stats *stats,
                                ms_error *err);

/* The core's figures with achieved_error_px and tolerance_px in screen pixels. */
void ms_viewer_stream_stats(ms_viewer_stream *stream, ms_core_stats *stats);

/* True when, at the latest step, the core's view was complete for that step's
 * camera, its complete frame was in the renderer and nothing was left queued
 * for upload: what is drawn now is the finished view. */
bool ms_viewer_stream_settled(const ms_viewer_stream *stream);

const ms_viewer_model *ms_viewer_stream_model(const ms_viewer_stream *stream);

/* The core frame the renderer was last given (owned by the stream, valid until
 * the next step or close), or NULL before the first: what measuring casts its
 * rays against (ms_viewer_measure.h). */
const ms_core_frame *ms_viewer_stream_frame(const ms_viewer_stream *stream);

/* The stream's renderer (owned by the stream), e.g. to capture an impostor. */
ms_render *ms_viewer_stream_render(ms_viewer_stream *stream);

/* Changes the crease angle (degrees, [0, 180]) and sets the frame in hand
 * again, so the picture takes it as the cells go up (ms_render_upload).
 * MS_ERR_ARG for an angle out of range. */
ms_status ms_viewer_stream_set_crease_angle(ms_viewer_stream *stream, double degrees, ms_error *err);

/* The crease angle in effect, degrees. */
double ms_viewer_stream_crease_angle(const ms_viewer_stream *stream);

/* The section planes the core culls with (ms_core_set_sections: the cells
 * wholly cut away are requested last); its errors. */
ms_status ms_viewer_stream_set_sections(ms_viewer_stream *stream, const double (*planes)[4], size_t count,
                                        ms_error *err);

#endif
