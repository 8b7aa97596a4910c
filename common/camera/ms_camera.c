/* Camera maths: see ms_camera.h. */
#include "ms_camera.h"
#include "ms_vec3.h"

#include <math.h>

static bool finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

ms_status ms_camera_look_at(const double position[3], const double target[3],
                            const double up[3], double fovy_degrees, double width,
                            double height, double near_distance, double far_distance,
                            ms_camera *c, ms_error *err)
{
    if (!finite3(position) || !finite3(target) || !finite3(up))
        return ms_error_set(err, MS_ERR_ARG, "camera: position, target and up must be finite");
    if (!(fovy_degrees > 0.0 && fovy_degrees < 180.0))
        return ms_error_set(err, MS_ERR_ARG, "camera: field of view %g is not in (0, 180) degrees",
                            fovy_degrees);
    if (!(width >= 1.0 && height >= 1.0 && width <= 1e6 && height <= 1e6))
        return ms_error_set(err, MS_ERR_ARG, "camera: viewport %gx%g is not in [1, 1e6] pixels",
                            width, height);
    if (!(near_distance > 0.0 && far_distance > near_distance && isfinite(far_distance)))
        return ms_error_set(err, MS_ERR_ARG, "camera: need 0 < near < far, finite");
    double f[3] = {target[0] - position[0], target[1] - position[1], target[2] - position[2]};
    if (!ms_vec3_normalise(f))
        return ms_error_set(err, MS_ERR_ARG, "camera: position and target coincide");
    double r[3];
    ms_vec3_cross(f, up, r);
    double up_len = sqrt(ms_vec3_dot(up, up));
    if (!(sqrt(ms_vec3_dot(r, r)) > 1e-9 * up_len) || !ms_vec3_normalise(r))
        return ms_error_set(err, MS_ERR_ARG, "camera: up is parallel to the view direction");
    double u[3];
    ms_vec3_cross(r, f, u);
    ms_vec3_normalise(u);
    for (int i = 0; i < 3; ++i) {
        c->position[i] = position[i];
        c->forward[i] = f[i];
        c->up[i] = u[i];
        c->right[i] = r[i];
    }
    c->fovy = fovy_degrees * (M_PI / 180.0);
    c->width = width;
    c->height = height;
    c->near_distance = near_distance;
    c->far_distance = far_distance;
    return MS_OK;
}

double ms_camera_pixels_per_unit(const ms_camera *c)
{
    return c->height / (2.0 * tan(c->fovy / 2.0));
}

/* Stores plane k through point p with inward normal n. */
static void set_plane(ms_frustum *fr, int k, const double n[3], const double p[3])
{
    double m[3] = {n[0], n[1], n[2]};
    ms_vec3_normalise(m);
    for (int i = 0; i < 3; ++i)
        fr->normal[k][i] = m[i];
    fr->offset[k] = -ms_vec3_dot(m, p);
}

void ms_camera_frustum(const ms_camera *c, ms_frustum *fr)
{
    double ty = tan(c->fovy / 2.0), tx = ty * c->width / c->height;
    const double *f = c->forward, *u = c->up, *r = c->right, *p = c->position;
    double near_point[3], far_point[3], back[3];
    for (int i = 0; i < 3; ++i) {
        near_point[i] = p[i] + f[i] * c->near_distance;
        far_point[i] = p[i] + f[i] * c->far_distance;
        back[i] = -f[i];
    }
    set_plane(fr, 0, f, near_point);
    set_plane(fr, 1, back, far_point);
    /* Side planes contain the eye; their inward normals lean towards forward. */
    double n[3];
    for (int i = 0; i < 3; ++i)
        n[i] = r[i] + f[i] * tx; /* left plane */
    set_plane(fr, 2, n, p);
    for (int i = 0; i < 3; ++i)
        n[i] = -r[i] + f[i] * tx; /* right plane */
    set_plane(fr, 3, n, p);
    for (int i = 0; i < 3; ++i)
        n[i] = u[i] + f[i] * ty; /* bottom plane */
    set_plane(fr, 4, n, p);
    for (int i = 0; i < 3; ++i)
        n[i] = -u[i] + f[i] * ty; /* top plane */
    set_plane(fr, 5, n, p);
}

bool ms_frustum_keeps_box(const ms_frustum *fr, const double lo[3], const double hi[3],
                          double margin)
{
    for (int k = 0; k < 6; ++k) {
        /* The box corner furthest along the inward normal. */
        double best[3];
        for (int i = 0; i < 3; ++i)
            best[i] = fr->normal[k][i] >= 0.0 ? hi[i] : lo[i];
        if (ms_vec3_dot(fr->normal[k], best) + fr->offset[k] < -margin)
            return false;
    }
    return true;
}

double ms_camera_box_distance(const ms_camera *c, const double lo[3], const double hi[3])
{
    double sum = 0.0;
    for (int i = 0; i < 3; ++i) {
        double d = 0.0;
        if (c->position[i] < lo[i])
            d = lo[i] - c->position[i];
        else if (c->position[i] > hi[i])
            d = c->position[i] - hi[i];
        sum += d * d;
    }
    return sqrt(sum);
}

void ms_camera_depth_range(const double position[3], const double lo[3], const double hi[3],
                           double *near_distance, double *far_distance)
{
    double nearest = 0.0, farthest = 0.0;
    for (int i = 0; i < 3; ++i) {
        if (!isfinite(lo[i]) || !isfinite(hi[i]) || !isfinite(position[i]) || lo[i] > hi[i]) {
            *near_distance = 1e-4, *far_distance = 1e4;
            return;
        }
        double below = lo[i] - position[i], above = position[i] - hi[i];
        double out = below > 0 ? below : above > 0 ? above : 0.0;
        double across = fmax(fabs(position[i] - lo[i]), fabs(position[i] - hi[i]));
        nearest += out * out;
        farthest += across * across;
    }
    /* 1 % past the farthest corner, so the depth test's rounding never clips it */
    double far_d = 1.01 * sqrt(farthest), near_d = 0.5 * sqrt(nearest);
    if (!(far_d > 0)) /* an empty box at the eye */
        far_d = 1.0;
    if (near_d < far_d * 5e-5)
        near_d = far_d * 5e-5;
    *near_distance = near_d;
    *far_distance = far_d;
}

double ms_screen_bits_needed(const ms_camera *c, double cube_side, double distance,
                             double tolerance_px)
{
    if (!(distance > 0.0))
        return INFINITY;
    return log2(0.5 * sqrt(3.0) * cube_side * ms_camera_pixels_per_unit(c) /
                (distance * tolerance_px));
}

double ms_screen_error_px(const ms_camera *c, double cube_side, unsigned bits, double distance)
{
    if (!(distance > 0.0))
        return INFINITY;
    return 0.5 * sqrt(3.0) * ldexp(cube_side, -(int)bits) * ms_camera_pixels_per_unit(c) / distance;
}

unsigned ms_apo_footprint_levels(const ms_camera *c, const double cube_lo[3], double cube_side,
                                 double tolerance_px, unsigned max_levels)
{
    if (max_levels == 0)
        return 0;
    double hi[3] = {cube_lo[0] + cube_side, cube_lo[1] + cube_side, cube_lo[2] + cube_side};
    double distance = ms_camera_box_distance(c, cube_lo, hi);
    if (!(distance >= c->near_distance))
        distance = c->near_distance;
    double depth = log2(cube_side * ms_camera_pixels_per_unit(c) / (distance * tolerance_px));
    if (!(depth < (double)max_levels)) /* NaN too: the cap */
        return max_levels;
    double d = ceil(depth - 1e-9);
    unsigned levels = d > 0 ? (unsigned)d + 1 : 1;
    return levels < max_levels ? levels : max_levels;
}

unsigned ms_select_bits(double need, unsigned current, unsigned min_bits, unsigned max_bits,
                        double hysteresis)
{
    double up = isnan(need) ? (double)max_bits : ceil(need);
    unsigned chosen = current;
    if (up > (double)current) {
        chosen = up >= (double)max_bits ? max_bits : (unsigned)up;
    } else {
        double down = ceil(need + hysteresis);
        if (down < (double)current)
            chosen = down <= (double)min_bits ? min_bits : (unsigned)down;
    }
    if (chosen < min_bits)
        chosen = min_bits;
    if (chosen > max_bits)
        chosen = max_bits;
    return chosen;
}

ms_status ms_camera_home(const double lo[3], const double hi[3], int up_axis, double width,
                         double height, ms_camera *camera, ms_error *err)
{
    if (!finite3(lo) || !finite3(hi) || !(width >= 1) || !(height >= 1) || !isfinite(width) ||
        !isfinite(height))
        return ms_error_set(err, MS_ERR_ARG, "home view: a non-finite box or an empty viewport");
    int a = up_axis >= 0 && up_axis <= 2 ? up_axis : 2;
    double up[3] = {0, 0, 0}, h0[3] = {0, 0, 0}, h1[3] = {0, 0, 0}, target[3];
    up[a] = 1;
    h0[(a + 2) % 3] = 1;
    h1[(a + 1) % 3] = 1;
    double side = 0, diagonal = 0, along0 = 0, along1 = 0;
    for (int k = 0; k < 3; ++k) {
        double extent = hi[k] - lo[k];
        target[k] = (lo[k] + hi[k]) / 2;
        side = extent > side ? extent : side;
        diagonal += extent * extent;
        along0 += extent * h0[k];
        along1 += extent * h1[k];
    }
    double model_size = side > 0 ? side : 1, radius = 0.5 * sqrt(diagonal);
    radius = 1.05 * (radius > 0 ? radius : 0.5 * model_size);
    double yaw = (along0 > along1 ? M_PI / 2 : 0) + 0.35, pitch = -0.3, fovy = 40;
    double half = fovy * M_PI / 360, aspect = width / height;
    if (aspect < 1) /* the narrower, horizontal field must hold it */
        half = atan(tan(half) * aspect);
    double distance = radius / sin(half), eye[3], near_d, far_d;
    for (int k = 0; k < 3; ++k) {
        double forward = -cos(pitch) * (cos(yaw) * h0[k] + sin(yaw) * h1[k]) + sin(pitch) * up[k];
        eye[k] = target[k] - distance * forward;
    }
    ms_camera_depth_range(eye, lo, hi, &near_d, &far_d);
    return ms_camera_look_at(eye, target, up, fovy, width, height, near_d, far_d, camera, err);
}
