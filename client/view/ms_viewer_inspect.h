/* Looking closely in meshview's window and scripted runs (docs/VIEWER.md,
 * "Measuring", "Light", "Sections", "Shareable views"): the glue between the window's
 * input, the stream's frames, the HUD and the report on one side, and the
 * measuring chain (ms_viewer_measure.h), the light (ms_viewer_light.h) and the
 * view text (ms_viewer_share.h) on the other.
 *
 * In the window: T toggles measuring (a click then adds the surface point
 * under the cursor to the chain), Backspace removes the last point, Delete
 * clears the chain; L steps through the raking presets; a Ctrl + left drag
 * moves the light; V prints the view text on stdout. One model only (not in
 * a scene, whose lights are its own).
 *
 * Requires the GL context current for ms_viewer_inspect_markers (the overlay's
 * batch). Thread-safety: the drawing thread.
 */
#ifndef MS_VIEWER_INSPECT_H
#define MS_VIEWER_INSPECT_H

#include <jansson.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

#include "ms_viewer_annotate.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_hud.h"
#include "ms_viewer_light.h"
#include "ms_viewer_measure.h"
#include "ms_viewer_options.h"
#include "ms_viewer_probe.h"
#include "ms_viewer_stream.h"
#include "ms_viewer_text.h"
#include "ms_viewer_unit.h"

#include "ms_viewer_section.h"

#define MS_VIEWER_INSPECT_LINES 4

typedef struct ms_viewer_inspect {
    ms_viewer_light light;
    ms_viewer_sections sections;
    ms_viewer_sections sections_sent; /* what the core culls with */
    bool sections_known;     /* sections_sent was sent to this stream */
    double box_side;         /* the model's, for the section keys' steps */
    ms_viewer_measure measure;
    bool measuring;          /* T: a click adds a point */
    bool lighting;           /* a Ctrl drag is moving the light */
    bool add_requested;      /* a click to add, at (add_x, add_y) framebuffer pixels */
    double add_x, add_y;
    uint64_t generation;     /* the frame the chain was last cast on */
    ms_camera camera;        /* the last frame's, for the markers */
    bool have_camera;
    const ms_viewer_source *source; /* for the probe */
    ms_viewer_probe *probe;  /* refining the points' cells (started when needed) */
    bool probe_failed;       /* it could not start: the view's precision stays */
    bool refining;           /* the probe has a point in hand */
    ms_viewer_annotate notes; /* the model's annotations (ms_viewer_annotate.h) */
    ms_viewer_unit unit;      /* the measurements' unit (ms_viewer_unit.h) */
    char lines[MS_VIEWER_INSPECT_LINES][MS_HUD_LINE_MAX];
} ms_viewer_inspect;

/* The options' light and, with --view, its chain (the controls are set by
 * ms_viewer_inspect_view); source (kept) is where the probe streams from. */
void ms_viewer_inspect_init(ms_viewer_inspect *in, const ms_viewer_options *o, const ms_viewer_source *source);

/* Stops the probe (the model closes); the chain and the light stay, the
 * annotations go (the next model loads its own). */
void ms_viewer_inspect_close(ms_viewer_inspect *in);

/* --view on freshly initialised controls (nothing without --view). */
void ms_viewer_inspect_view(const ms_viewer_options *o, ms_viewer_controls *c);

/* A key (GLFW_KEY_*) pressed: true when it is one of T, Backspace, Delete, L,
 * V (V prints the view text of the controls, light, sections and chain on
 * out), or a section key (Y J 9 0 I, ms_viewer_section.h). */
bool ms_viewer_inspect_key(ms_viewer_inspect *in, int key, const ms_viewer_controls *c, FILE *out);

/* Per frame, after the stream's step and before its draw: the light and the
 * sections into the options for camera, the sections to the core when they
 * changed; a pending click cast on the frame; the chain cast
 * again on a new frame once the view settled (or while a point is lost);
 * once settled, the probe refines the points' cells (polled, never waited
 * for). The model's annotations are loaded at its first frame; a pending
 * Enter or click on them is handled (ms_viewer_annotate_frame). While
 * measuring (T, or a chain), the measurements' unit is asked for and polled
 * (ms_viewer_unit.h). */
void ms_viewer_inspect_frame(ms_viewer_inspect *in, ms_viewer_stream *stream, const ms_camera *camera,
                             ms_render_options *render);

/* The HUD's lines (the light, the sections, the measurement, the
 * annotations): how many are set. */
size_t ms_viewer_inspect_hud(ms_viewer_inspect *in, const ms_viewer_stream *stream);

/* Marks the chain's points on the overlay (small squares where they are
 * seen from the last frame's camera), and the annotations' markers where the
 * frame just drawn does not hide them (the bound read framebuffer's depth),
 * with the selected one's title and text. */
void ms_viewer_inspect_markers(ms_viewer_inspect *in, ms_viewer_text *text);

/* The measurement as text in unit (NULL: MS_METADATA_NO_UNIT): "measure 2
 * points: 1.0000005 +- 0.0000010 model units (20 bits, full)", "measure 2
 * points: 12.5 +- 0.01 mm (20 bits, full)". */
void ms_viewer_inspect_describe(const ms_viewer_measure *m, unsigned model_bits, const char *unit, char *text,
                                size_t size);

/* Scripted: the report's "light", "sections" (an array of {point, normal},
 * empty without) and (with --view) "view", the view text as
 * parsed and printed again; and, at the first keyframe (camera, the view
 * settled), its "measure": in's chain (the --view points) cast on the
 * stream's frame, then the --measure pixels added to it (so that the HUD and
 * the markers show them), then refined by the probe (waiting at most
 * MS_VIEWER_PROBE_TIMEOUT_S a point): the figures before (view_*) and after,
 * and its "unit" (the model's, waited for at most the source's time-out:
 * ms_viewer_unit.h; "model units" without).
 * Added to report; false (nothing added) when there is nothing to measure. */
void ms_viewer_inspect_report_light(const ms_viewer_options *o, json_t *report);
/* Scripted: the report's "annotations" (ms_viewer_annotate_report), their
 * markers tested against the frame last drawn (the bound read framebuffer). */
void ms_viewer_inspect_report_annotations(ms_viewer_inspect *in, json_t *report);
bool ms_viewer_inspect_report_measure(const ms_viewer_options *o, ms_viewer_inspect *in, ms_viewer_stream *stream,
                                      const ms_camera *camera, json_t *report);

#endif
