/* meshview's heads-up display: what the viewer is doing, as text in the
 * overlay pass (ms_viewer_text.h), top-left, on a translucent panel, and a
 * thin progress bar along the top edge while the view refines.
 *
 * The lines are composed by ms_viewer_hud_lines (pure, so tests check the
 * words) and drawn by ms_viewer_hud_draw. Below the view's figures: the
 * camera path's clock while it drives the camera (ms_viewer_playback.h), and
 * the selected piece of a scene (ms_viewer_pick.h): its name, whether it is
 * drawn as geometry or impostor, its material, its triangles, cells, bytes
 * and achieved error. Memory shows as "core X MB + GL Y MB": the
 * client core's measure (ms_core_stats.memory) and the GL storage the viewer
 * asked for; the driver's own share is in neither (docs/VIEWER.md, "Memory").
 * Units: milliseconds, pixels, MB (10^6 bytes). Thread-safety: none shared.
 */
#ifndef MS_VIEWER_HUD_H
#define MS_VIEWER_HUD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_client_core.h"
#include "ms_render.h"
#include "ms_viewer_playback.h"
#include "ms_viewer_scene.h"
#include "ms_viewer_text.h"

#define MS_HUD_MAX_LINES 16
#define MS_HUD_LINE_MAX 96

typedef struct ms_viewer_hud_info {
    const char *model;           /* model name */
    const char *mode;            /* e.g. "APO lit", "geometry normals" */
    uint64_t gl_bytes;           /* GL storage the viewer holds (ms_render.h, "GL memory") */
    double frame_ms, fps;        /* smoothed */
    uint64_t triangles_drawn;
    uint32_t cells_drawn;
    const ms_core_stats *core;   /* errors and tolerance in screen pixels */
    bool settled;                /* view complete and uploaded */
    bool fly;
    bool show_effects;           /* a scene: list the effects that ran this frame */
    unsigned effects_ran;        /* MS_EFFECT_* (ms_render.h) */
    const ms_viewer_playback *playback; /* a line while the path drives the camera; may be NULL */
    const ms_viewer_scene_piece *piece; /* the selected piece: three lines; NULL: none */
    size_t piece_index, piece_count;    /* its index (from 0) and the scene's pieces */
    const char (*extra)[MS_HUD_LINE_MAX]; /* lines added at the end (the light, a
                                           measurement, the annotations: ms_viewer_inspect.h) */
    size_t extra_count;                 /* at most MS_VIEWER_INSPECT_LINES (4) */
} ms_viewer_hud_info;

/* The shading line of the HUD for render's options: the shading, then flat,
 * or the crease angle (crease_deg < 0: not said), written into text. */
const char *ms_viewer_hud_mode(const ms_render_options *render, double crease_deg, char *text, size_t size);

/* Writes the HUD's lines; returns how many (at most MS_HUD_MAX_LINES). */
size_t ms_viewer_hud_lines(const ms_viewer_hud_info *info,
                           char lines[MS_HUD_MAX_LINES][MS_HUD_LINE_MAX]);

/* Refinement progress in [0, 1]: tolerance / achieved error (1 when settled). */
double ms_viewer_hud_progress(const ms_viewer_hud_info *info);

/* Adds the panel, its lines and (unless settled) the progress bar to the batch
 * (the caller began it for a framebuffer of width x height and draws it). */
void ms_viewer_hud_draw(ms_viewer_text *text, const ms_viewer_hud_info *info, int width,
                        int height, bool show_text);

#endif
