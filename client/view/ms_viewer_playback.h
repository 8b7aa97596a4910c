/* Camera path playback in meshview's window (docs/VIEWER.md, "Camera path
 * playback"): the path of --path, or the scene's camera_path, played in path
 * time at real speed, paused, or stepped keyframe by keyframe, until the user
 * takes the camera back.
 *
 * States: OFF (the controls drive the camera), PLAYING (the path does, its
 * clock advancing with the frames' seconds) and PAUSED (the path does, its
 * clock held). Starting from OFF, the clock starts where the camera is: at the
 * path time whose position is nearest the controls' eye
 * (ms_camera_path_nearest_time), or at the start when that is the path's end.
 * Playing reaches the end and pauses there; playing again from the end starts
 * at the start. A
 * step goes to the next (previous) keyframe strictly after (before) the clock,
 * the last (first) one at most, and pauses there.
 *
 * Taking the camera back. Each frame on the path hands its view to the
 * controls (ms_viewer_controls_look) and remembers what it handed; when the
 * controls differ from that at the next frame, something moved them (a drag,
 * the wheel, a movement key, R, U, a re-centring double click, framing a
 * piece) and playback stops (OFF): the controls go on from the path's last
 * view. Toggling fly mode moves nothing and does not stop it.
 *
 * The path's maths is ms_camera_path.h's: the camera at a time is
 * ms_camera_path_sample's, near and far from the controls'
 * ms_viewer_controls_depth_range; the controls take the view of
 * ms_camera_path_key_at. Times are path seconds.
 *
 * No GL and no clock of its own: the caller gives each frame's seconds.
 * Ownership: the playback owns its path. Errors: ms_status with one line.
 * Thread-safety: none shared.
 */
#ifndef MS_VIEWER_PLAYBACK_H
#define MS_VIEWER_PLAYBACK_H

#include <stdbool.h>

#include "ms_camera_path.h"
#include "ms_error.h"
#include "ms_viewer_controls.h"

typedef enum ms_playback_state {
    MS_PLAYBACK_OFF = 0,
    MS_PLAYBACK_PLAYING = 1,
    MS_PLAYBACK_PAUSED = 2
} ms_playback_state;

typedef struct ms_viewer_playback {
    ms_camera_path path;      /* owned; no keyframes: every call leaves it OFF */
    ms_playback_state state;
    double time;              /* the clock, path seconds within the path's keyframe times */
    bool handed;              /* `view` holds what the controls were last handed */
    ms_viewer_controls view;
} ms_viewer_playback;

/* Takes the path over (*path is left empty; NULL: no path), OFF. */
void ms_viewer_playback_init(ms_viewer_playback *p, ms_camera_path *path);
/* Loads file (ms_camera_path_load) as the path, OFF; nothing when file is NULL
 * or a path is held already (the first path given wins: --path before the
 * scene's). The path's errors. */
ms_status ms_viewer_playback_load(ms_viewer_playback *p, const char *file, ms_error *err);
void ms_viewer_playback_free(ms_viewer_playback *p);

/* True while the path drives the camera (PLAYING or PAUSED). */
bool ms_viewer_playback_on(const ms_viewer_playback *p);

/* Play / pause: OFF starts playing from the controls' eye's nearest path time
 * (from the start instead of the end), PLAYING pauses, PAUSED plays on (from
 * the start at the end). */
void ms_viewer_playback_toggle(ms_viewer_playback *p, const ms_viewer_controls *c);

/* direction > 0: the next keyframe, < 0: the previous one, from the clock (or,
 * when OFF, from the controls' eye's nearest path time); PAUSED there. */
void ms_viewer_playback_step(ms_viewer_playback *p, int direction, const ms_viewer_controls *c);

/* A frame of `seconds` went by: the clock advances while PLAYING, and stops at
 * the path's end, PAUSED. */
void ms_viewer_playback_advance(ms_viewer_playback *p, double seconds);

/* OFF (the clock stays). */
void ms_viewer_playback_stop(ms_viewer_playback *p);

/* The path's camera at the clock for a width x height framebuffer; hands the
 * view to the controls first, whose depth range then gives near and far.
 * MS_ERR_EMPTY without a path; ms_camera_look_at's errors. */
ms_status ms_viewer_playback_camera(ms_viewer_playback *p, ms_viewer_controls *c, double width,
                                    double height, ms_camera *camera, ms_error *err);

/* One frame's camera, the loop's one call: stops playback when the controls
 * were moved since the path last handed them its view, advances the clock by
 * `seconds`, and gives the path's camera while it is on, else (and when the
 * path's camera fails) the controls' (ms_viewer_controls_camera). */
ms_status ms_viewer_playback_frame_camera(ms_viewer_playback *p, ms_viewer_controls *c,
                                          double width, double height, double seconds,
                                          ms_camera *camera, ms_error *err);

#endif
