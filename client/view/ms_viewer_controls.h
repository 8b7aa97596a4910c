/* meshview's camera controller: the maths behind mouse orbit, pan, zoom,
 * double-click re-centring and fly mode, kept apart from GLFW so that it can be
 * tested and used by scripted runs.
 *
 * State: an orbit centre `target`, the eye's `distance` from it and the view
 * direction as yaw and pitch (radians) about the world up axis. The eye is
 * target - distance * forward. Orbit turns the direction about the target; fly
 * mode turns it about the eye (looking around) and moves eye and target
 * together (WASD). Pitch stays within +-89 degrees so up never lines up with
 * the view. Lengths are in model units; pixel arguments are framebuffer pixels
 * (HiDPI: never window coordinates), so a drag across the whole framebuffer
 * height turns the view by half a turn whatever the pixel density.
 *
 * Pure functions on a caller-owned value; thread-safe.
 */
#ifndef MS_VIEWER_CONTROLS_H
#define MS_VIEWER_CONTROLS_H

#include <stdbool.h>

#include "ms_camera.h"
#include "ms_error.h"
#include "ms_render.h"

typedef struct ms_viewer_controls {
    double home_target[3];  /* the model's centre */
    double home_yaw;
    double home_lo[3], home_hi[3]; /* the model's bounds */
    double model_size;      /* the model's largest side: sets the home distance and speeds */
    int up_axis;            /* 0 = x, 1 = y, 2 = z: world up */
    double fovy_degrees;
    double aspect;          /* the framebuffer's width / height, for the home view */
    double target[3];
    double distance;        /* > 0 */
    double yaw, pitch;      /* radians */
    bool fly;
} ms_viewer_controls;

/* A home view of the box [lo, hi] (the model's bounds) on a framebuffer of
 * width / height = aspect (1 when not > 0): looking at its centre a little
 * from above and to the side, across the box's longer horizontal side (a
 * model is seen along its length, not end-on), fovy 40 degrees, from as far
 * as frames the box's circumscribed sphere with 5 % to spare in the narrower
 * field (ms_viewer_controls_frame): the whole model in view whatever its
 * shape, orientation or the window's. */
void ms_viewer_controls_init(ms_viewer_controls *c, const double lo[3], const double hi[3],
                             int up_axis, double aspect);
/* Back to the home view (keeps up_axis, fly and aspect; set c->aspect when the
 * framebuffer changes shape). */
void ms_viewer_controls_reset(ms_viewer_controls *c);
/* Changes the up axis (0..2) and goes home. */
void ms_viewer_controls_set_up(ms_viewer_controls *c, int up_axis);

/* The unit view direction and the eye position. */
void ms_viewer_controls_forward(const ms_viewer_controls *c, double forward[3]);
void ms_viewer_controls_eye(const ms_viewer_controls *c, double eye[3]);

/* A mouse drag of (dx, dy) framebuffer pixels (y down) on a framebuffer
 * `height` pixels tall: orbits about the target, or looks around in fly mode. */
void ms_viewer_controls_rotate(ms_viewer_controls *c, double dx, double dy, double height);
/* Moves eye and target in the view plane so the point under the cursor follows it. */
void ms_viewer_controls_pan(ms_viewer_controls *c, double dx, double dy, double height);
/* Scroll: each step brings the eye 15 % closer (steps > 0) or farther. In fly
 * mode it moves eye and target along the view instead. */
void ms_viewer_controls_zoom(ms_viewer_controls *c, double steps);
/* Makes point the orbit centre, keeping the eye where it is (the view turns to
 * it). A point at the eye is ignored. */
void ms_viewer_controls_recentre(ms_viewer_controls *c, const double point[3]);
/* Puts the eye at eye, the orbit centre at target and the field of view at
 * fovy_degrees (in (0, 180), else kept): a path's camera handed to the
 * controls (ms_viewer_playback.h), so that a drag goes on from it. Roll is not
 * kept (the view's up is the world up); a pitch past the limit is clamped with
 * the eye kept. Eye and target (nearly) equal: nothing changes. */
void ms_viewer_controls_look(ms_viewer_controls *c, const double eye[3], const double target[3],
                             double fovy_degrees);
/* Frames a sphere: the orbit centre goes to centre and the eye, along the
 * present view direction, to radius / sin(h) from it, h being half the
 * vertical field of view, or half the horizontal one when the framebuffer is
 * narrower than tall (aspect = width / height < 1): the sphere just fits. A
 * radius or aspect not > 0, or a non-finite value, changes nothing. */
void ms_viewer_controls_frame(ms_viewer_controls *c, const double centre[3], double radius,
                              double aspect);
/* Fly mode: moves eye and target by (forward, right, up) times the speed for
 * `seconds` (speed: a quarter of the distance to the target per second, at
 * least model_size / 1000). */
void ms_viewer_controls_fly(ms_viewer_controls *c, double forward, double right, double up,
                            double seconds);

/* Near and far that frame the model's bounds (home_lo, home_hi) from the
 * present eye (ms_camera_depth_range): the model stays between the planes at
 * any distance, and the depth buffer's precision follows it. */
void ms_viewer_controls_depth_range(const ms_viewer_controls *c, double *near_distance,
                                    double *far_distance);
/* The camera for a framebuffer of width x height pixels; near and far from
 * ms_viewer_controls_depth_range.
 * MS_ERR_ARG only for an empty framebuffer or a degenerate state. */
ms_status ms_viewer_controls_camera(const ms_viewer_controls *c, double width, double height,
                                    ms_camera *camera, ms_error *err);

/* The N, C and B keys: shading `mode` (normals, cells, albedo), or lit again
 * when it is the current one. */
ms_shading ms_viewer_toggle_shading(ms_shading current, ms_shading mode);

/* The K key: the crease angle after `degrees` in the cycle 30, 45, 60, 90, 180
 * (the first step above it; 30 again after 180 or anything above). */
double ms_viewer_next_crease_angle(double degrees);

#endif
