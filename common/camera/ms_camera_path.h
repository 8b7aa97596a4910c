/* Camera path files: scripted camera motion for meshload and the viewer.
 *
 * Text, versioned. The first line is exactly `meshstream-camera-path 1`; then
 * one keyframe per line, `#` starts a comment, blank lines are ignored:
 *
 *     # time  position(x y z)  target(x y z)  up(x y z)  fovy_degrees
 *     0.0     0 0 3            0 0 0          0 1 0      45
 *
 * Times are seconds, >= 0 and strictly increasing; positions in model units;
 * the field of view in (0, 180) degrees; each keyframe must make a valid camera
 * (position != target, up not along the view). Between keyframes the position,
 * target, up and field of view are interpolated linearly (up renormalised);
 * before the first and after the last keyframe the path holds still. At most
 * MS_CAMERA_PATH_MAX_KEYS keyframes. Errors name the file and line.
 *
 * Ownership: the path owns its keyframes (ms_camera_path_free). Thread-safety:
 * read-only after loading.
 */
#ifndef MS_CAMERA_PATH_H
#define MS_CAMERA_PATH_H

#include <stddef.h>

#include "ms_camera.h"
#include "ms_error.h"

#define MS_CAMERA_PATH_MAX_KEYS 100000
#define MS_CAMERA_PATH_MAGIC "meshstream-camera-path 1"

typedef struct ms_camera_key {
    double time;
    double position[3], target[3], up[3];
    double fovy_degrees;
} ms_camera_key;

typedef struct ms_camera_path {
    ms_camera_key *keys;
    size_t count;
} ms_camera_path;

/* Parses text (not NUL-terminated; size bytes); name is used in errors. */
ms_status ms_camera_path_parse(const char *text, size_t size, const char *name,
                               ms_camera_path *path, ms_error *err);
ms_status ms_camera_path_load(const char *file, ms_camera_path *path, ms_error *err);
void ms_camera_path_free(ms_camera_path *path);

/* Time of the last keyframe. */
double ms_camera_path_duration(const ms_camera_path *path);

/* The keyframe at time t: position, target, up and fovy interpolated as
 * described above (up not yet renormalised: ms_camera_look_at does that), time
 * t clamped to the path. Every caller that moves a camera along a path goes
 * through this one interpolation. A path without keyframes gives zeros. */
void ms_camera_path_key_at(const ms_camera_path *path, double t, ms_camera_key *key);

/* The time at which the path's position comes nearest to point (positions move
 * linearly between keyframes, so this is exact); the earliest such time on a
 * tie, 0 for a path without keyframes. */
double ms_camera_path_nearest_time(const ms_camera_path *path, const double point[3]);

/* The camera at time t for a viewport: ms_camera_path_key_at, then
 * ms_camera_look_at (MS_ERR_EMPTY for a path without keyframes). */
ms_status ms_camera_path_sample(const ms_camera_path *path, double t, double width,
                                double height, double near_distance, double far_distance,
                                ms_camera *camera, ms_error *err);

/* ms_camera_path_sample with the clipping distances framing the box [lo, hi]
 * (the model's or the scene's bounds) from the sampled eye
 * (ms_camera_depth_range). */
ms_status ms_camera_path_sample_framing(const ms_camera_path *path, double t, double width,
                                        double height, const double lo[3], const double hi[3],
                                        ms_camera *camera, ms_error *err);

#endif
