/* Camera path playback: see ms_viewer_playback.h. */
#include "ms_viewer_playback.h"

#include <string.h>

void ms_viewer_playback_init(ms_viewer_playback *p, ms_camera_path *path)
{
    memset(p, 0, sizeof *p);
    if (path) {
        p->path = *path;
        memset(path, 0, sizeof *path);
    }
}

ms_status ms_viewer_playback_load(ms_viewer_playback *p, const char *file, ms_error *err)
{
    if (!file || p->path.count)
        return MS_OK;
    ms_camera_path path;
    ms_status st = ms_camera_path_load(file, &path, err);
    if (st == MS_OK)
        ms_viewer_playback_init(p, &path);
    return st;
}

void ms_viewer_playback_free(ms_viewer_playback *p)
{
    ms_camera_path_free(&p->path);
    memset(p, 0, sizeof *p);
}

bool ms_viewer_playback_on(const ms_viewer_playback *p)
{
    return p->state != MS_PLAYBACK_OFF;
}

/* The clock the path takes over with: where the camera is. */
static double start_time(const ms_viewer_playback *p, const ms_viewer_controls *c)
{
    if (ms_viewer_playback_on(p))
        return p->time;
    double eye[3];
    ms_viewer_controls_eye(c, eye);
    return ms_camera_path_nearest_time(&p->path, eye);
}

void ms_viewer_playback_toggle(ms_viewer_playback *p, const ms_viewer_controls *c)
{
    if (!p->path.count)
        return;
    if (p->state == MS_PLAYBACK_PLAYING) {
        p->state = MS_PLAYBACK_PAUSED;
        return;
    }
    double t = start_time(p, c);
    p->time = t >= ms_camera_path_duration(&p->path) ? p->path.keys[0].time : t;
    p->handed = p->handed && p->state != MS_PLAYBACK_OFF;
    p->state = MS_PLAYBACK_PLAYING;
}

void ms_viewer_playback_step(ms_viewer_playback *p, int direction, const ms_viewer_controls *c)
{
    const ms_camera_path *path = &p->path;
    if (!path->count || !direction)
        return;
    double t = start_time(p, c);
    size_t k;
    if (direction > 0) /* the first keyframe after t, else the last */
        for (k = 0; k + 1 < path->count && !(path->keys[k].time > t); ++k)
            ;
    else /* the last keyframe before t, else the first */
        for (k = path->count - 1; k > 0 && !(path->keys[k].time < t); --k)
            ;
    p->time = path->keys[k].time;
    p->handed = p->handed && p->state != MS_PLAYBACK_OFF;
    p->state = MS_PLAYBACK_PAUSED;
}

void ms_viewer_playback_advance(ms_viewer_playback *p, double seconds)
{
    if (p->state != MS_PLAYBACK_PLAYING || !(seconds > 0))
        return;
    double end = ms_camera_path_duration(&p->path);
    p->time += seconds;
    if (p->time >= end) {
        p->time = end;
        p->state = MS_PLAYBACK_PAUSED;
    }
}

void ms_viewer_playback_stop(ms_viewer_playback *p)
{
    p->state = MS_PLAYBACK_OFF;
    p->handed = false;
}

ms_status ms_viewer_playback_camera(ms_viewer_playback *p, ms_viewer_controls *c, double width,
                                    double height, ms_camera *camera, ms_error *err)
{
    if (!p->path.count)
        return ms_error_set(err, MS_ERR_EMPTY, "no camera path to play");
    ms_camera_key key;
    ms_camera_path_key_at(&p->path, p->time, &key);
    ms_viewer_controls_look(c, key.position, key.target, key.fovy_degrees);
    p->view = *c;
    p->handed = true;
    return ms_camera_path_sample_framing(&p->path, p->time, width, height, c->home_lo,
                                         c->home_hi, camera, err);
}

/* Whether the controls were moved since the path handed them its view (fly
 * mode toggled alone moves nothing). */
static bool moved(const ms_viewer_playback *p, const ms_viewer_controls *c)
{
    const ms_viewer_controls *h = &p->view;
    return p->handed && (memcmp(h->target, c->target, sizeof c->target) != 0 ||
                         h->distance != c->distance || h->yaw != c->yaw || h->pitch != c->pitch ||
                         h->fovy_degrees != c->fovy_degrees || h->up_axis != c->up_axis);
}

ms_status ms_viewer_playback_frame_camera(ms_viewer_playback *p, ms_viewer_controls *c,
                                          double width, double height, double seconds,
                                          ms_camera *camera, ms_error *err)
{
    if (moved(p, c))
        ms_viewer_playback_stop(p);
    ms_viewer_playback_advance(p, seconds);
    if (ms_viewer_playback_on(p) &&
        ms_viewer_playback_camera(p, c, width, height, camera, err) == MS_OK)
        return MS_OK;
    ms_viewer_playback_stop(p);
    return ms_viewer_controls_camera(c, width, height, camera, err);
}
