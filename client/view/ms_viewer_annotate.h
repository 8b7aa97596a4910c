/* Annotations in meshview (docs/VIEWER.md, "Annotations"; the file:
 * docs/ANNOTATIONS.md, ms_annotations.h): hotspots loaded for the open model,
 * drawn as markers that face the camera and are hidden where the drawn
 * surface is in front of them, selected by a click (the HUD shows the title
 * and the text, the camera moves to the view stored with it), added, deleted
 * and saved from the window.
 *
 * Where they come from, the first that applies: --annotations FILE; a local
 * archive's sidecar DIR/NAME.annotations.json (none when it does not exist);
 * from a server, the model's annotations document through the binary door
 * (GET_DOCUMENT on a fetcher thread of its own, ms_viewer_fetcher.h, bounded
 * by the source's time-out, so that the drawing thread never waits on the
 * network: the markers appear when it comes; NO_DOCUMENT: none; scripted
 * runs hold a keyframe until it came). Ctrl+S saves to FILE, or to the archive's
 * sidecar, or (from a server) to NAME.annotations.json in the working
 * directory. Every stored view must read as a view text
 * (ms_viewer_share_parse), or the whole file is refused with one line.
 *
 * Occlusion: a marker is hidden when the surface drawn at its pixel (the
 * depth buffer, unprojected) is nearer the eye than the point by more than
 * the annotation's radius or 1% of the point's distance, whichever is larger
 * (a point on the full-resolution surface may lie a grid step under a coarser
 * cut). Markers are squares of 2 * MS_VIEWER_ANNOTATE_MARKER_PX * scale
 * pixels centred on the point's pixel; a click within that square (the
 * nearest marker's) selects it.
 *
 * The camera's move: over MS_VIEWER_ANNOTATE_MOVE_S seconds (smoothstep),
 * the orbit centre, the distance (geometrically), yaw, pitch and field of view
 * go from where they are to the stored view's, which then also sets the light
 * (an annotation without a view: the orbit centre goes to its point). A drag,
 * the wheel or a key that moves the camera stops the move.
 *
 * Typing (Enter adds): the HUD asks for a title, then a text; printable
 * characters append, Backspace removes the last character, Enter goes on
 * (an empty title cancels), Esc cancels. While typing, keys do nothing else.
 *
 * GL: ms_viewer_annotate_markers reads the bound read framebuffer's depth
 * (the context current). Thread-safety: the drawing thread.
 */
#ifndef MS_VIEWER_ANNOTATE_H
#define MS_VIEWER_ANNOTATE_H

#include <jansson.h>
#include <stdbool.h>
#include <stdio.h>

#include "ms_annotations.h"
#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_fetcher.h"
#include "ms_viewer_hud.h"
#include "ms_viewer_light.h"
#include "ms_viewer_model.h"
#include "ms_viewer_share.h"
#include "ms_viewer_text.h"

#define MS_VIEWER_ANNOTATE_MARKER_PX 6
#define MS_VIEWER_ANNOTATE_MOVE_S 0.8

typedef enum ms_annotate_typing {
    MS_ANNOTATE_NOT_TYPING = 0,
    MS_ANNOTATE_TYPING_TITLE,
    MS_ANNOTATE_TYPING_TEXT
} ms_annotate_typing;

typedef struct ms_viewer_annotate {
    const char *file;          /* --annotations (NULL: none) */
    const char *select_id;     /* --annotation ID: selected once loaded */
    ms_annotations *set;       /* owned; NULL: none loaded */
    ms_viewer_fetcher *fetcher; /* a server's document in flight (owned), else NULL */
    char model[128];           /* the model they were loaded for ("" none yet) */
    char from[16];             /* "file", "archive", "server" or "none" */
    char save_path[4200];
    char message[MS_HUD_LINE_MAX]; /* the last load or save result, or a refusal */
    long selected;             /* -1: none */
    /* the markers of the last frame drawn: pixel and whether seen */
    size_t marked;
    double pixel[MS_ANNOTATIONS_MAX][2];
    bool seen[MS_ANNOTATIONS_MAX];
    /* input from the window */
    bool click_requested;      /* a click (no drag) at click_x, click_y (framebuffer pixels) */
    double click_x, click_y;
    bool add_requested;        /* Enter: a new annotation at the surface under the cursor */
    double cursor_x, cursor_y; /* framebuffer pixels, kept by the window */
    char add_view[MS_VIEWER_SHARE_MAX]; /* the view when Enter was pressed */
    double add_point[3];
    ms_annotate_typing typing;
    char title[MS_ANNOTATION_TITLE_MAX + 1];
    char text[MS_ANNOTATION_TEXT_MAX + 1];
    /* the camera's move */
    bool go;                   /* a selection asks for it; the next frame starts it */
    bool moving;
    double move_t;
    ms_viewer_controls move_from, handed;
    ms_viewer_share move_to;
    bool move_has_view;
} ms_viewer_annotate;

/* Empty, nothing selected; file and select_id kept (may be NULL). */
void ms_viewer_annotate_init(ms_viewer_annotate *a, const char *file, const char *select_id);
void ms_viewer_annotate_free(ms_viewer_annotate *a);

/* Loads the annotations of model (from source, or file) unless they are the
 * ones held or asked for; a failure leaves none, with the one line in
 * a->message and on log (may be NULL). From a server it only asks: the
 * answer is taken by a later call (every frame calls it), never waited for. */
void ms_viewer_annotate_load(ms_viewer_annotate *a, const ms_viewer_source *source, const char *model,
                             FILE *log);

/* Whether a server's annotations are still on their way. */
bool ms_viewer_annotate_pending(const ms_viewer_annotate *a);

/* Reads a file and checks every view it stores (ms_viewer_share_parse). */
ms_status ms_viewer_annotate_read(const char *path, ms_annotations **out, ms_error *err);

/* A key (GLFW_KEY_*, GLFW_MOD_*): true when taken. While typing: Enter,
 * Backspace, Esc, and every other key (ignored). Else: Enter (a new
 * annotation at the cursor, the view of c and light stored with it),
 * Shift+Delete (delete the selected one), Ctrl+S (save). */
bool ms_viewer_annotate_key(ms_viewer_annotate *a, int key, int mods, const ms_viewer_controls *c,
                            const ms_viewer_light *light, FILE *log);
/* A character typed (a Unicode code point). */
void ms_viewer_annotate_char(ms_viewer_annotate *a, unsigned codepoint);

/* Per frame: a pending Enter cast on the frame (box_side the model's), a
 * pending click selecting the marker under it. */
void ms_viewer_annotate_frame(ms_viewer_annotate *a, const ms_core_frame *frame, double box_side,
                              const ms_camera *camera);

/* Selects annotation i (-1: none); selecting asks for the camera's move. */
void ms_viewer_annotate_select(ms_viewer_annotate *a, long i);

/* Moves the controls toward the selected annotation's view, seconds after
 * the last call (and sets the light at the end). */
void ms_viewer_annotate_animate(ms_viewer_annotate *a, ms_viewer_controls *c, ms_viewer_light *light,
                                double seconds);

/* Where each marker is seen from camera, tested against the depth of the
 * bound read framebuffer (the frame just drawn with camera); then, when text
 * is not NULL, the markers and the selected annotation's title and text (or
 * the prompt while typing) added to its batch. */
void ms_viewer_annotate_markers(ms_viewer_annotate *a, const ms_camera *camera, ms_viewer_text *text);

/* The report's "annotations": {from, count, message, selected, markers:
 * [{id, pixel, seen}]} (the markers of the last frame), added to report. */
void ms_viewer_annotate_report(const ms_viewer_annotate *a, json_t *report);

#endif
