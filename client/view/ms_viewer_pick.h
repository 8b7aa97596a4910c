/* Picking a piece of a scene in meshview's window (docs/VIEWER.md, "Scenes
 * in the window"): the surface point under the cursor, from the depth read
 * back and unprojected (ms_viewer_read_depth, ms_render_unproject, as
 * double-click re-centring does), is taken into each piece's own coordinates
 * through its placement (ms_scene_model_transform) and tested against the
 * bounds the piece was placed by. The room (floor, walls, plinths) is not a
 * piece: a point on it picks nothing. Also the maths of cycling and framing
 * the selected piece.
 *
 * Bounds are grown by MS_VIEWER_PICK_MARGIN of their diagonal on every side:
 * the depth buffer's precision puts an unprojected surface point a little off
 * the surface, and a point on a piece's outermost face must still pick it.
 * When a point lies in several grown bounds, the piece whose bounds' centre
 * (ms_scene_placed_sphere) is nearest wins (the lower index on equal
 * distances).
 *
 * Units: world (the scene's metres); pixels are framebuffer pixels with the
 * origin at the top left, as the cursor's. A placement is column-major, a
 * uniform scale times a rotation plus a translation (what
 * ms_scene_model_transform makes). Thread-safety: the pure functions are;
 * ms_viewer_pick_surface needs the GL context current (the drawing thread),
 * and the functions taking a scene are the drawing thread's.
 */
#ifndef MS_VIEWER_PICK_H
#define MS_VIEWER_PICK_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_camera.h"
#include "ms_viewer_controls.h"
#include "ms_viewer_scene.h"

#define MS_VIEWER_PICK_MARGIN 0.01 /* of a piece's bounds' diagonal */

typedef struct ms_viewer_pick_box {
    double placement[16];    /* model to world */
    double lo[3], hi[3];     /* bounds in the model's coordinates */
} ms_viewer_pick_box;

/* The index of the box whose bounds, grown by margin times their diagonal,
 * hold the world point; of several, the nearest centre's (lower index on a
 * tie); -1 when none does. */
long ms_viewer_pick_box_at(const ms_viewer_pick_box *boxes, size_t count, const double point[3],
                           double margin);

/* The next (delta > 0) or previous (delta < 0) of count pieces after selected,
 * wrapping round; from none (-1) the first or the last; -1 when count is 0. */
long ms_viewer_pick_cycle(long selected, size_t count, int delta);

/* The surface point drawn at framebuffer pixel (x, y) (top-left origin) into
 * the bound read framebuffer of camera->width x camera->height pixels with
 * camera; false on the background or outside the framebuffer. */
bool ms_viewer_pick_surface(const ms_camera *camera, double x, double y, double world[3]);

/* The box of piece i of the scene (ms_viewer_scene_piece_info); false when
 * there is no piece i. */
bool ms_viewer_pick_scene_box(ms_viewer_scene *vs, long i, ms_viewer_pick_box *box);

/* The scene's piece holding the world point (ms_viewer_pick_box_at with
 * MS_VIEWER_PICK_MARGIN), or -1. */
long ms_viewer_pick_scene_piece(ms_viewer_scene *vs, const double point[3]);

/* Frames piece i (ms_viewer_controls_frame on ms_scene_placed_sphere) for a
 * framebuffer of the given aspect (width / height); false, changing nothing,
 * when there is no piece i. */
bool ms_viewer_pick_frame_piece(ms_viewer_scene *vs, long i, ms_viewer_controls *c, double aspect);

#endif
