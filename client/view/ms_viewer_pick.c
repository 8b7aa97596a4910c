/* Picking a piece of a scene: see ms_viewer_pick.h. */
#include "ms_viewer_pick.h"

#include <math.h>
#include <string.h>

#include "ms_render.h"
#include "ms_viewer_readback.h"

/* The placement's uniform scale: the length of its first column. */
static double placement_scale(const double t[16])
{
    return sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
}

/* A world point in the model's coordinates: the linear part is scale times a
 * rotation, so its inverse is its transpose over scale^2. */
static void to_model(const double t[16], const double world[3], double model[3])
{
    double s2 = t[0] * t[0] + t[1] * t[1] + t[2] * t[2];
    double rel[3] = {world[0] - t[12], world[1] - t[13], world[2] - t[14]};
    for (int c = 0; c < 3; ++c)
        model[c] = (t[4 * c] * rel[0] + t[4 * c + 1] * rel[1] + t[4 * c + 2] * rel[2]) / s2;
}

static double box_diagonal(const ms_viewer_pick_box *box)
{
    double d2 = 0;
    for (int a = 0; a < 3; ++a)
        d2 += (box->hi[a] - box->lo[a]) * (box->hi[a] - box->lo[a]);
    return sqrt(d2);
}

long ms_viewer_pick_box_at(const ms_viewer_pick_box *boxes, size_t count, const double point[3],
                           double margin)
{
    long best = -1;
    double best_d2 = INFINITY;
    for (size_t i = 0; i < count; ++i) {
        const ms_viewer_pick_box *b = &boxes[i];
        if (!(placement_scale(b->placement) > 0))
            continue;
        double p[3], grow = margin * box_diagonal(b);
        to_model(b->placement, point, p);
        bool inside = true;
        for (int a = 0; a < 3; ++a)
            inside &= p[a] >= b->lo[a] - grow && p[a] <= b->hi[a] + grow;
        if (!inside)
            continue;
        double centre[3], radius, d2 = 0;
        ms_scene_placed_sphere(b->placement, b->lo, b->hi, centre, &radius);
        for (int a = 0; a < 3; ++a)
            d2 += (point[a] - centre[a]) * (point[a] - centre[a]);
        if (d2 < best_d2) {
            best_d2 = d2;
            best = (long)i;
        }
    }
    return best;
}

long ms_viewer_pick_cycle(long selected, size_t count, int delta)
{
    if (!count)
        return -1;
    long n = (long)count;
    if (selected < 0 || selected >= n)
        return delta >= 0 ? 0 : n - 1;
    long step = delta > 0 ? 1 : delta < 0 ? -1 : 0;
    return ((selected + step) % n + n) % n;
}

bool ms_viewer_pick_surface(const ms_camera *camera, double x, double y, double world[3])
{
    int w = (int)camera->width, h = (int)camera->height;
    if (!(x >= 0 && y >= 0 && x < w && y < h))
        return false;
    int px = (int)x, py = h - 1 - (int)y; /* OpenGL counts rows from the bottom */
    double depth;
    return ms_viewer_read_depth(px, py, w, h, &depth) &&
           ms_render_unproject(camera, px + 0.5, py + 0.5, depth, world);
}

bool ms_viewer_pick_scene_box(ms_viewer_scene *vs, long i, ms_viewer_pick_box *box)
{
    if (i < 0 || (size_t)i >= ms_viewer_scene_piece_count(vs))
        return false;
    ms_viewer_scene_piece piece;
    ms_viewer_scene_piece_info(vs, (size_t)i, &piece);
    memcpy(box->placement, piece.placement, sizeof box->placement);
    memcpy(box->lo, piece.lo, sizeof box->lo);
    memcpy(box->hi, piece.hi, sizeof box->hi);
    return true;
}

long ms_viewer_pick_scene_piece(ms_viewer_scene *vs, const double point[3])
{
    ms_viewer_pick_box boxes[MS_SCENE_MAX_MODELS];
    size_t n = 0;
    while (n < MS_SCENE_MAX_MODELS && ms_viewer_pick_scene_box(vs, (long)n, &boxes[n]))
        ++n;
    return ms_viewer_pick_box_at(boxes, n, point, MS_VIEWER_PICK_MARGIN);
}

bool ms_viewer_pick_frame_piece(ms_viewer_scene *vs, long i, ms_viewer_controls *c, double aspect)
{
    ms_viewer_pick_box box;
    if (!ms_viewer_pick_scene_box(vs, i, &box))
        return false;
    double centre[3], radius;
    ms_scene_placed_sphere(box.placement, box.lo, box.hi, centre, &radius);
    ms_viewer_controls_frame(c, centre, radius, aspect);
    return true;
}
