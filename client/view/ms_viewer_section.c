/* meshview's section planes: see ms_viewer_section.h. */
#include "ms_viewer_section.h"

#include <GLFW/glfw3.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ms_section.h"

bool ms_viewer_sections_add(ms_viewer_sections *s, const double point[3], const double normal[3])
{
    double len2 = normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2];
    if (s->count >= MS_SECTIONS_MAX || !(len2 > 0) || !isfinite(len2) || !isfinite(point[0]) ||
        !isfinite(point[1]) || !isfinite(point[2]))
        return false;
    /* the plane's offset must be finite too */
    double d = normal[0] * point[0] + normal[1] * point[1] + normal[2] * point[2];
    if (!isfinite(d))
        return false;
    memcpy(s->point[s->count], point, sizeof s->point[0]);
    memcpy(s->normal[s->count], normal, sizeof s->normal[0]);
    s->count++;
    return true;
}

ms_status ms_viewer_sections_add_text(ms_viewer_sections *s, const char *text, ms_error *err)
{
    if (s->count >= MS_SECTIONS_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "at most %d section planes", MS_SECTIONS_MAX);
    double point[3], normal[3];
    ms_status st = ms_section_parse(text, point, normal, err);
    if (st != MS_OK)
        return st;
    ms_viewer_sections_add(s, point, normal);
    return MS_OK;
}

size_t ms_viewer_sections_planes(const ms_viewer_sections *s, double planes[MS_SECTIONS_MAX][4])
{
    size_t n = s->count < MS_SECTIONS_MAX ? s->count : MS_SECTIONS_MAX;
    for (size_t k = 0; k < n; ++k) {
        ms_section_plane(s->point[k], s->normal[k], planes[k]);
    }
    return n;
}

void ms_viewer_sections_apply(const ms_viewer_sections *s, ms_render_options *o)
{
    o->section_count = (unsigned)ms_viewer_sections_planes(s, o->sections);
}

bool ms_viewer_sections_key(ms_viewer_sections *s, int key, const double forward[3], const double target[3],
                            double box_side)
{
    size_t last = s->count - 1;
    switch (key) {
    case GLFW_KEY_Y: {
        /* across the axis nearest the view direction, the half towards the eye cut away */
        int axis = 0;
        for (int a = 1; a < 3; ++a)
            if (fabs(forward[a]) > fabs(forward[axis]))
                axis = a;
        double normal[3] = {0, 0, 0};
        normal[axis] = forward[axis] > 0 ? -1 : 1;
        ms_viewer_sections_add(s, target, normal);
        return true;
    }
    case GLFW_KEY_J:
        for (int a = 0; a < 3 && s->count; ++a)
            s->normal[last][a] = -s->normal[last][a];
        return true;
    case GLFW_KEY_9:
    case GLFW_KEY_0: {
        if (!s->count || !(box_side > 0) || !isfinite(box_side))
            return true;
        const double *m = s->normal[last];
        double len = sqrt(m[0] * m[0] + m[1] * m[1] + m[2] * m[2]), step = (key == GLFW_KEY_0 ? 1 : -1) * box_side / 50;
        for (int a = 0; a < 3; ++a)
            s->point[last][a] += step * m[a] / len;
        return true;
    }
    case GLFW_KEY_I:
        if (s->count)
            s->count--;
        return true;
    default: return false;
    }
}

void ms_viewer_sections_describe(const ms_viewer_sections *s, char *text, size_t size)
{
    size_t used = 0;
    text[0] = 0;
    for (size_t k = 0; k < s->count && used < size; ++k) {
        const double *p = s->point[k], *m = s->normal[k];
        int axis = -1;
        for (int a = 0; a < 3; ++a)
            if (m[a] != 0 && m[(a + 1) % 3] == 0 && m[(a + 2) % 3] == 0)
                axis = a;
        int n;
        const char *lead = k ? "  " : s->count > 1 ? "sections " : "section ";
        if (axis >= 0)
            n = snprintf(text + used, size - used, "%s%s%c=%.4g", lead, m[axis] < 0 ? "-" : "", 'x' + axis,
                         p[axis]);
        else
            n = snprintf(text + used, size - used, "%sat %.4g,%.4g,%.4g normal %.3g,%.3g,%.3g", lead, p[0], p[1],
                         p[2], m[0], m[1], m[2]);
        used += n > 0 ? (size_t)n : 0;
    }
}
