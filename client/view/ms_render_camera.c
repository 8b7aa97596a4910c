/* The renderer's camera conventions (ms_render.h, "Camera"), in doubles.
 *
 * Eye space: x = camera right, y = camera up, z = -forward (right-handed, since
 * right = forward x up). The projection is OpenGL's symmetric perspective: clip
 * depth -1 at the near plane and +1 at the far one, window depth (clip + 1) / 2.
 */
#include <math.h>
#include <string.h>

#include "ms_render_internal.h"

static bool finite3(const double v[3])
{
    return isfinite(v[0]) && isfinite(v[1]) && isfinite(v[2]);
}

static bool unit3(const double v[3])
{
    double l = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
    return fabs(l - 1.0) < 1e-6;
}

ms_status ms_render_camera_check(const ms_camera *c, ms_error *err)
{
    if (!c)
        return ms_error_set(err, MS_ERR_ARG, "render: no camera");
    if (!finite3(c->position) || !finite3(c->forward) || !finite3(c->up) || !finite3(c->right) ||
        !unit3(c->forward) || !unit3(c->up) || !unit3(c->right))
        return ms_error_set(err, MS_ERR_ARG, "render: camera position or axes not finite unit vectors");
    if (!(c->width >= 1.0 && c->width <= 16384.0 && c->height >= 1.0 && c->height <= 16384.0))
        return ms_error_set(err, MS_ERR_ARG, "render: viewport %gx%g outside 1..16384", c->width,
                            c->height);
    if (!(c->fovy > 0.0 && c->fovy < M_PI))
        return ms_error_set(err, MS_ERR_ARG, "render: field of view %g rad outside (0, pi)", c->fovy);
    if (!(c->near_distance > 0.0 && c->far_distance > c->near_distance && isfinite(c->far_distance)))
        return ms_error_set(err, MS_ERR_ARG, "render: near %g and far %g distances invalid",
                            c->near_distance, c->far_distance);
    return MS_OK;
}

void ms_render_camera_matrices(const ms_camera *c, double view[16], double projection[16])
{
    /* view: rows right, up, -forward; translation -R * position */
    const double *r = c->right, *u = c->up, *f = c->forward, *p = c->position;
    double rows[3][3] = {{r[0], r[1], r[2]}, {u[0], u[1], u[2]}, {-f[0], -f[1], -f[2]}};
    memset(view, 0, 16 * sizeof *view);
    for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j)
            view[4 * j + i] = rows[i][j];
        view[12 + i] = -(rows[i][0] * p[0] + rows[i][1] * p[1] + rows[i][2] * p[2]);
    }
    view[15] = 1.0;
    double t = 1.0 / tan(0.5 * c->fovy), aspect = c->width / c->height;
    double n = c->near_distance, fa = c->far_distance;
    memset(projection, 0, 16 * sizeof *projection);
    projection[0] = t / aspect;
    projection[5] = t;
    projection[10] = (fa + n) / (n - fa);
    projection[11] = -1.0;
    projection[14] = 2.0 * fa * n / (n - fa);
}

float ms_render_apo_footprint_scale(const ms_camera *c, double cube_side)
{
    return (float)(2.0 * tan(0.5 * c->fovy) / (c->height * cube_side));
}

bool ms_render_unproject(const ms_camera *c, double x, double y, double depth, double world[3])
{
    if (!c || !(depth >= 0.0 && depth < 1.0) || !isfinite(x) || !isfinite(y))
        return false;
    double view[16], proj[16];
    ms_render_camera_matrices(c, view, proj);
    double nx = 2.0 * x / c->width - 1.0, ny = 2.0 * y / c->height - 1.0, nz = 2.0 * depth - 1.0;
    /* nz = (A z + B) / -z  =>  z = -B / (A + nz) (eye z, negative in front) */
    double ze = -proj[14] / (proj[10] + nz);
    double xe = nx * -ze / proj[0], ye = ny * -ze / proj[5];
    for (int a = 0; a < 3; ++a)
        world[a] = c->position[a] + xe * c->right[a] + ye * c->up[a] - ze * c->forward[a];
    return finite3(world);
}

void ms_render_cell_cube(const ms_archive_header *h, const ms_archive_cell *cell, double origin[3],
                         double *side)
{
    double s = h->box_side;
    for (unsigned l = 0; l < cell->level; ++l)
        s /= (double)h->n;
    for (int a = 0; a < 3; ++a)
        origin[a] = h->box_origin[a] + (double)cell->position[a] * s;
    *side = s;
}

void ms_render_cell_modelview(const double view[16], const double origin[3], double side, float out[16])
{
    /* view * [side*I | origin] : the 3x3 part scales, the translation is
     * view applied to origin (done in doubles, small near the camera). */
    for (int col = 0; col < 3; ++col)
        for (int row = 0; row < 4; ++row)
            out[4 * col + row] = (float)(view[4 * col + row] * side);
    for (int row = 0; row < 4; ++row)
        out[12 + row] = (float)(view[row] * origin[0] + view[4 + row] * origin[1] + view[8 + row] * origin[2] +
                                view[12 + row]);
}
