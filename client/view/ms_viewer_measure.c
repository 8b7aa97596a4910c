/* Measuring on the decoded cut: see ms_viewer_measure.h. */
#include "ms_viewer_measure.h"

#include <math.h>
#include <string.h>

#include "ms_ray.h"
#include "ms_section.h"

static double dot3(const double a[3], const double b[3]) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static bool unit3(const double v[3], double out[3])
{
    double len = sqrt(dot3(v, v));
    if (!(len > 0) || !isfinite(len))
        return false;
    for (int a = 0; a < 3; ++a)
        out[a] = v[a] / len;
    return true;
}

void ms_viewer_measure_pixel_ray(const ms_camera *c, double x, double y, double origin[3], double direction[3])
{
    double th = tan(0.5 * c->fovy), aspect = c->width / c->height;
    double sx = (2.0 * x / c->width - 1.0) * th * aspect, sy = (1.0 - 2.0 * y / c->height) * th;
    double d[3];
    for (int a = 0; a < 3; ++a) {
        origin[a] = c->position[a];
        d[a] = c->forward[a] + sx * c->right[a] + sy * c->up[a];
    }
    if (!unit3(d, direction))
        memcpy(direction, c->forward, sizeof d);
}

/* The hit of each of n rays (t >= t_min[i], t nearest t_near[i]) in one pass
 * over the triangles, so that the mesh is read once for every ray. */
static void cast_rays(const ms_core_frame *frame, double box_side, size_t n, const double (*origin)[3],
                      const double (*d)[3], const double *t_min, const double *t_near,
                      const double (*planes)[4], size_t plane_count, ms_viewer_measure_hit *hit, bool *found)
{
    const ms_view_mesh *m = &frame->mesh;
    double best[MS_VIEWER_MEASURE_MAX_POINTS];
    size_t best_tri[MS_VIEWER_MEASURE_MAX_POINTS] = {0};
    for (size_t r = 0; r < n; ++r)
        best[r] = INFINITY, found[r] = false;
    for (size_t i = 0; i < m->triangle_count; ++i) {
        const uint32_t *tri = &m->triangles[3 * i];
        if (tri[0] >= m->vertex_count || tri[1] >= m->vertex_count || tri[2] >= m->vertex_count)
            continue;
        const double *p0 = &m->positions[3 * tri[0]], *p1 = &m->positions[3 * tri[1]], *p2 = &m->positions[3 * tri[2]];
        for (size_t r = 0; r < n; ++r) {
            double t;
            if (ms_ray_triangle(origin[r], d[r], p0, p1, p2, &t) && t >= t_min[r] && fabs(t - t_near[r]) < best[r]) {
                double x[3] = {origin[r][0] + t * d[r][0], origin[r][1] + t * d[r][1], origin[r][2] + t * d[r][2]};
                if (ms_section_cuts_away(planes, plane_count, x))
                    continue; /* not drawn: behind it, the surface the picture shows */
                best[r] = fabs(t - t_near[r]);
                hit[r].t = t;
                best_tri[r] = i;
                found[r] = true;
            }
        }
    }
    for (size_t r = 0; r < n; ++r) {
        if (!found[r])
            continue;
        for (int a = 0; a < 3; ++a)
            hit[r].point[a] = origin[r][a] + hit[r].t * d[r][a];
        hit[r].cell = m->triangle_cell ? m->triangle_cell[best_tri[r]] : 0;
        uint8_t bits = ms_core_frame_cell_bits(frame, hit[r].cell);
        hit[r].bits = bits <= 64 ? bits : 0;
        hit[r].step = ldexp(box_side, -(int)hit[r].bits);
    }
}

bool ms_viewer_measure_cast(const ms_core_frame *frame, double box_side, const double origin[3],
                            const double direction[3], double t_min, double t_near,
                            ms_viewer_measure_hit *hit)
{
    double d[1][3];
    bool found;
    if (!frame || !unit3(direction, d[0]))
        return false;
    cast_rays(frame, box_side, 1, (const double(*)[3])origin, (const double(*)[3])d, &t_min, &t_near, NULL, 0,
              hit, &found);
    return found;
}

/* The one cast of add: its planes. */
static bool measure_cast(const ms_viewer_measure *m, const ms_core_frame *frame, double box_side,
                         const double origin[3], const double direction[3], ms_viewer_measure_hit *hit)
{
    double d[1][3], t_min = 0, t_near = 0;
    bool found;
    if (!frame || !unit3(direction, d[0]))
        return false;
    cast_rays(frame, box_side, 1, (const double(*)[3])origin, (const double(*)[3])d, &t_min, &t_near,
              (const double(*)[4])m->planes, m->plane_count, hit, &found);
    return found;
}

bool ms_viewer_measure_set_planes(ms_viewer_measure *m, const double (*planes)[4], size_t count)
{
    if (count > MS_VIEWER_MEASURE_MAX_PLANES)
        count = MS_VIEWER_MEASURE_MAX_PLANES;
    bool same = count == m->plane_count && (!count || !memcmp(m->planes, planes, count * sizeof *planes));
    if (count)
        memcpy(m->planes, planes, count * sizeof *planes);
    m->plane_count = count;
    return !same;
}

bool ms_viewer_measure_add(ms_viewer_measure *m, const ms_core_frame *frame, double box_side,
                           const double origin[3], const double direction[3])
{
    ms_viewer_measure_hit hit;
    if (m->count >= MS_VIEWER_MEASURE_MAX_POINTS ||
        !measure_cast(m, frame, box_side, origin, direction, &hit))
        return false;
    size_t i = m->count++;
    unit3(direction, m->direction[i]);
    memcpy(m->anchor[i], hit.point, sizeof hit.point);
    m->hit[i] = hit;
    m->found[i] = true;
    m->refined[i] = false;
    m->id[i] = ++m->next_id;
    return true;
}

bool ms_viewer_measure_add_anchor(ms_viewer_measure *m, const double anchor[3], const double direction[3])
{
    double d[3]; /* kept as given: a shared view's text comes back exactly */
    if (m->count >= MS_VIEWER_MEASURE_MAX_POINTS || !unit3(direction, d) || !isfinite(dot3(anchor, anchor)))
        return false;
    memcpy(d, direction, sizeof d);
    size_t i = m->count++;
    memcpy(m->direction[i], d, sizeof d);
    memcpy(m->anchor[i], anchor, sizeof d);
    memset(&m->hit[i], 0, sizeof m->hit[i]);
    memcpy(m->hit[i].point, anchor, sizeof d);
    m->found[i] = false;
    m->refined[i] = false;
    m->id[i] = ++m->next_id;
    return true;
}

void ms_viewer_measure_update(ms_viewer_measure *m, const ms_core_frame *frame, double box_side)
{
    double d[MS_VIEWER_MEASURE_MAX_POINTS][3], t_min[MS_VIEWER_MEASURE_MAX_POINTS],
        t_near[MS_VIEWER_MEASURE_MAX_POINTS];
    ms_viewer_measure_hit hit[MS_VIEWER_MEASURE_MAX_POINTS];
    bool found[MS_VIEWER_MEASURE_MAX_POINTS];
    for (size_t i = 0; i < m->count; ++i) {
        unit3(m->direction[i], d[i]); /* never zero: checked when added */
        t_min[i] = -INFINITY, t_near[i] = 0;
    }
    if (frame)
        cast_rays(frame, box_side, m->count, (const double(*)[3])m->anchor, (const double(*)[3])d, t_min, t_near,
                  (const double(*)[4])m->planes, m->plane_count, hit, found);
    for (size_t i = 0; i < m->count; ++i) {
        if (m->refined[i] && m->found[i])
            continue; /* at the probe's precision: the view's frame is no finer */
        m->found[i] = frame && found[i];
        if (m->found[i]) {
            m->hit[i] = hit[i];
            memcpy(m->anchor[i], hit[i].point, sizeof hit[i].point);
        }
    }
}

void ms_viewer_measure_pop(ms_viewer_measure *m)
{
    if (m->count)
        m->count--;
}

void ms_viewer_measure_clear(ms_viewer_measure *m) { m->count = 0; }

bool ms_viewer_measure_result_of(const ms_viewer_measure *m, unsigned model_bits, ms_viewer_measure_result *r)
{
    memset(r, 0, sizeof *r);
    r->points = m->count;
    if (m->count < 2)
        return false;
    r->full = r->refined = true;
    r->bits_min = 255;
    for (size_t i = 0; i < m->count; ++i) {
        if (!m->found[i])
            return false;
        r->refined &= m->refined[i];
        r->full &= m->hit[i].bits >= model_bits;
        if (m->hit[i].bits < r->bits_min)
            r->bits_min = m->hit[i].bits;
    }
    for (size_t i = 1; i < m->count; ++i) {
        const ms_viewer_measure_hit *a = &m->hit[i - 1], *b = &m->hit[i];
        double d[3] = {b->point[0] - a->point[0], b->point[1] - a->point[1], b->point[2] - a->point[2]};
        r->last_length = sqrt(dot3(d, d));
        r->last_precision = a->step > b->step ? a->step : b->step;
        r->length += r->last_length;
        r->precision += r->last_precision;
    }
    return true;
}

/* Where camera c shows world point p (framebuffer pixels, top-left origin);
 * false behind the eye. */
bool ms_viewer_measure_project(const ms_camera *c, const double p[3], double *sx, double *sy)
{
    double th = tan(0.5 * c->fovy), aspect = c->width / c->height;
    double rel[3] = {p[0] - c->position[0], p[1] - c->position[1], p[2] - c->position[2]};
    double z = rel[0] * c->forward[0] + rel[1] * c->forward[1] + rel[2] * c->forward[2];
    if (!(z > 0))
        return false;
    double x = rel[0] * c->right[0] + rel[1] * c->right[1] + rel[2] * c->right[2];
    double y = rel[0] * c->up[0] + rel[1] * c->up[1] + rel[2] * c->up[2];
    *sx = 0.5 * c->width * (1 + x / (z * th * aspect));
    *sy = 0.5 * c->height * (1 - y / (z * th));
    return isfinite(*sx) && isfinite(*sy);
}
