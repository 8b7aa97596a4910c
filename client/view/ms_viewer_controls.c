#include "ms_viewer_controls.h"

#include <math.h>
#include <string.h>

#define PITCH_LIMIT (89.0 * M_PI / 180.0)

/* The world frame of an up axis: up, and two horizontal axes such that yaw 0
 * looks along -h0 (from +h0 towards the target). */
static void world_frame(int up_axis, double up[3], double h0[3], double h1[3])
{
    memset(up, 0, 3 * sizeof *up);
    memset(h0, 0, 3 * sizeof *h0);
    memset(h1, 0, 3 * sizeof *h1);
    up[up_axis] = 1;
    h0[(up_axis + 2) % 3] = 1;  /* y-up: z is "towards the viewer"; z-up: y */
    h1[(up_axis + 1) % 3] = 1;
}

void ms_viewer_controls_forward(const ms_viewer_controls *c, double forward[3])
{
    double up[3], h0[3], h1[3];
    world_frame(c->up_axis, up, h0, h1);
    double cp = cos(c->pitch), sp = sin(c->pitch), cy = cos(c->yaw), sy = sin(c->yaw);
    for (int k = 0; k < 3; ++k)
        forward[k] = -cp * (cy * h0[k] + sy * h1[k]) + sp * up[k];
}

void ms_viewer_controls_eye(const ms_viewer_controls *c, double eye[3])
{
    double f[3];
    ms_viewer_controls_forward(c, f);
    for (int k = 0; k < 3; ++k)
        eye[k] = c->target[k] - c->distance * f[k];
}

/* Sets yaw and pitch from a view direction (not necessarily unit). */
static void look_along(ms_viewer_controls *c, const double direction[3])
{
    double up[3], h0[3], h1[3];
    world_frame(c->up_axis, up, h0, h1);
    double a = 0, b = 0, u = 0;
    for (int k = 0; k < 3; ++k) {
        a -= direction[k] * h0[k];
        b -= direction[k] * h1[k];
        u += direction[k] * up[k];
    }
    double horizontal = hypot(a, b);
    c->pitch = atan2(u, horizontal);
    if (c->pitch > PITCH_LIMIT)
        c->pitch = PITCH_LIMIT;
    if (c->pitch < -PITCH_LIMIT)
        c->pitch = -PITCH_LIMIT;
    if (horizontal > 0)
        c->yaw = atan2(b, a);
}

void ms_viewer_controls_reset(ms_viewer_controls *c)
{
    memcpy(c->target, c->home_target, sizeof c->target);
    c->yaw = c->home_yaw;
    c->pitch = -0.3;
    c->fovy_degrees = 40;
    double diagonal = 0;
    for (int k = 0; k < 3; ++k)
        diagonal += (c->home_hi[k] - c->home_lo[k]) * (c->home_hi[k] - c->home_lo[k]);
    double radius = 0.5 * sqrt(diagonal);
    c->distance = 1.6 * c->model_size; /* kept by a degenerate box */
    ms_viewer_controls_frame(c, c->home_target, 1.05 * (radius > 0 ? radius : 0.5 * c->model_size),
                             c->aspect > 0 ? c->aspect : 1.0);
}

void ms_viewer_controls_init(ms_viewer_controls *c, const double lo[3], const double hi[3],
                             int up_axis, double aspect)
{
    memset(c, 0, sizeof *c);
    c->aspect = aspect > 0 && isfinite(aspect) ? aspect : 1.0;
    double side = 0;
    for (int k = 0; k < 3; ++k) {
        c->home_target[k] = (lo[k] + hi[k]) / 2;
        if (hi[k] - lo[k] > side)
            side = hi[k] - lo[k];
    }
    c->model_size = side > 0 ? side : 1;
    c->up_axis = up_axis >= 0 && up_axis <= 2 ? up_axis : 2;
    memcpy(c->home_lo, lo, sizeof c->home_lo);
    memcpy(c->home_hi, hi, sizeof c->home_hi);
    ms_viewer_controls_set_up(c, c->up_axis);
}

void ms_viewer_controls_set_up(ms_viewer_controls *c, int up_axis)
{
    c->up_axis = up_axis >= 0 && up_axis <= 2 ? up_axis : 2;
    /* Yaw 0 looks along -h0: when the box is longer along h0 than along h1,
     * turn a quarter to look across it. */
    double up[3], h0[3], h1[3], along0 = 0, along1 = 0;
    world_frame(c->up_axis, up, h0, h1);
    for (int k = 0; k < 3; ++k) {
        along0 += (c->home_hi[k] - c->home_lo[k]) * h0[k];
        along1 += (c->home_hi[k] - c->home_lo[k]) * h1[k];
    }
    c->home_yaw = (along0 > along1 ? M_PI / 2 : 0) + 0.35;
    ms_viewer_controls_reset(c);
}

void ms_viewer_controls_rotate(ms_viewer_controls *c, double dx, double dy, double height)
{
    if (!(height >= 1))
        return;
    double eye[3];
    ms_viewer_controls_eye(c, eye);
    double per_pixel = M_PI / height;
    /* The same signs serve both modes: orbiting, a drag to the right swings the
     * eye to the left round the model (the model turns with the hand) and a drag
     * down lifts the eye; flying, the view turns right and down with the hand. */
    c->yaw += dx * per_pixel;
    c->pitch -= dy * per_pixel;
    if (c->pitch > PITCH_LIMIT)
        c->pitch = PITCH_LIMIT;
    if (c->pitch < -PITCH_LIMIT)
        c->pitch = -PITCH_LIMIT;
    c->yaw = remainder(c->yaw, 2 * M_PI);
    if (c->fly) { /* keep the eye, move the target */
        double f[3];
        ms_viewer_controls_forward(c, f);
        for (int k = 0; k < 3; ++k)
            c->target[k] = eye[k] + c->distance * f[k];
    }
}

/* Unit right and camera-up vectors of the current view. */
static void view_axes(const ms_viewer_controls *c, double right[3], double cam_up[3])
{
    double f[3], up[3], h0[3], h1[3];
    ms_viewer_controls_forward(c, f);
    world_frame(c->up_axis, up, h0, h1);
    right[0] = f[1] * up[2] - f[2] * up[1];
    right[1] = f[2] * up[0] - f[0] * up[2];
    right[2] = f[0] * up[1] - f[1] * up[0];
    double n = sqrt(right[0] * right[0] + right[1] * right[1] + right[2] * right[2]);
    for (int k = 0; k < 3; ++k)
        right[k] /= n;
    cam_up[0] = right[1] * f[2] - right[2] * f[1];
    cam_up[1] = right[2] * f[0] - right[0] * f[2];
    cam_up[2] = right[0] * f[1] - right[1] * f[0];
}

void ms_viewer_controls_pan(ms_viewer_controls *c, double dx, double dy, double height)
{
    if (!(height >= 1))
        return;
    double right[3], cam_up[3];
    view_axes(c, right, cam_up);
    /* World units per pixel at the target's depth. */
    double per_pixel = 2 * c->distance * tan(c->fovy_degrees * M_PI / 360) / height;
    for (int k = 0; k < 3; ++k)
        c->target[k] += (-dx * right[k] + dy * cam_up[k]) * per_pixel;
}

void ms_viewer_controls_zoom(ms_viewer_controls *c, double steps)
{
    if (c->fly) {
        ms_viewer_controls_fly(c, steps * 0.5, 0, 0, 1);
        return;
    }
    double d = c->distance * pow(0.85, steps);
    double lo = c->model_size * 1e-6, hi = c->model_size * 100;
    c->distance = d < lo ? lo : d > hi ? hi : d;
}

/* Puts the eye at eye looking at point (the orbit centre); false, changing
 * nothing, when the two (nearly) coincide. */
static bool aim(ms_viewer_controls *c, const double eye[3], const double point[3])
{
    double d[3];
    for (int k = 0; k < 3; ++k)
        d[k] = point[k] - eye[k];
    double n = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(n > c->model_size * 1e-9) || !isfinite(n))
        return false;
    look_along(c, d);
    c->distance = n;
    /* The clamped pitch may not point exactly at the point: keep the eye. */
    double f[3];
    ms_viewer_controls_forward(c, f);
    for (int k = 0; k < 3; ++k)
        c->target[k] = eye[k] + n * f[k];
    return true;
}

void ms_viewer_controls_recentre(ms_viewer_controls *c, const double point[3])
{
    double eye[3];
    ms_viewer_controls_eye(c, eye);
    aim(c, eye, point);
}

void ms_viewer_controls_look(ms_viewer_controls *c, const double eye[3], const double target[3],
                             double fovy_degrees)
{
    if (aim(c, eye, target) && fovy_degrees > 0 && fovy_degrees < 180)
        c->fovy_degrees = fovy_degrees;
}

void ms_viewer_controls_frame(ms_viewer_controls *c, const double centre[3], double radius,
                              double aspect)
{
    if (!(radius > 0) || !isfinite(radius) || !(aspect > 0) || !isfinite(aspect) ||
        !isfinite(centre[0] + centre[1] + centre[2]))
        return;
    double half = c->fovy_degrees * M_PI / 360;
    if (aspect < 1) /* the narrower, horizontal field must hold it */
        half = atan(tan(half) * aspect);
    memcpy(c->target, centre, sizeof c->target);
    c->distance = radius / sin(half);
}

void ms_viewer_controls_fly(ms_viewer_controls *c, double forward, double right, double up,
                            double seconds)
{
    double speed = c->distance / 4;
    if (speed < c->model_size / 1000)
        speed = c->model_size / 1000;
    double f[3], r[3], u[3];
    ms_viewer_controls_forward(c, f);
    view_axes(c, r, u);
    for (int k = 0; k < 3; ++k)
        c->target[k] += (forward * f[k] + right * r[k] + up * u[k]) * speed * seconds;
}

void ms_viewer_controls_depth_range(const ms_viewer_controls *c, double *near_distance,
                                    double *far_distance)
{
    double eye[3];
    ms_viewer_controls_eye(c, eye);
    ms_camera_depth_range(eye, c->home_lo, c->home_hi, near_distance, far_distance);
}

ms_status ms_viewer_controls_camera(const ms_viewer_controls *c, double width, double height,
                                    ms_camera *camera, ms_error *err)
{
    double eye[3], up[3], h0[3], h1[3], near_d, far_d;
    ms_viewer_controls_eye(c, eye);
    world_frame(c->up_axis, up, h0, h1);
    ms_viewer_controls_depth_range(c, &near_d, &far_d);
    return ms_camera_look_at(eye, c->target, up, c->fovy_degrees, width, height, near_d, far_d,
                             camera, err);
}

ms_shading ms_viewer_toggle_shading(ms_shading current, ms_shading mode)
{
    return current == mode ? MS_SHADING_LIT : mode;
}

double ms_viewer_next_crease_angle(double degrees)
{
    static const double steps[] = {30, 45, 60, 90, 180};
    for (size_t i = 0; i < sizeof steps / sizeof *steps; ++i)
        if (steps[i] > degrees + 1e-9)
            return steps[i];
    return steps[0];
}
