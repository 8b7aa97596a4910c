/* meshview's light: see ms_viewer_light.h. */
#include "ms_viewer_light.h"

#include <math.h>
#include <stdio.h>

#include "ms_viewer_share.h"

#define DEG (M_PI / 180.0)

bool ms_viewer_light_parse(const char *text, ms_viewer_light *light)
{
    double v[2];
    if (!text || !ms_viewer_numbers(text, ',', v, 2) || !(v[0] >= -180 && v[0] <= 180) ||
        !(v[1] >= -90 && v[1] <= 90))
        return false;
    *light = (ms_viewer_light){.directional = true, .azimuth_deg = v[0], .elevation_deg = v[1]};
    return true;
}

void ms_viewer_light_eye(const ms_viewer_light *l, double eye[3])
{
    double az = l->directional ? l->azimuth_deg * DEG : 0, el = l->directional ? l->elevation_deg * DEG : 0;
    eye[0] = cos(el) * sin(az);
    eye[1] = sin(el);
    eye[2] = cos(el) * cos(az);
}

void ms_viewer_light_world(const ms_viewer_light *l, const ms_camera *c, double world[3])
{
    double e[3];
    ms_viewer_light_eye(l, e);
    for (int a = 0; a < 3; ++a)
        world[a] = e[0] * c->right[a] + e[1] * c->up[a] - e[2] * c->forward[a];
}

void ms_viewer_light_apply(const ms_viewer_light *l, const ms_camera *c, ms_render_options *o)
{
    ms_render_light light = {.kind = MS_RENDER_LIGHT_HEAD, .colour = {1, 1, 1}};
    if (l->directional) {
        light.kind = MS_RENDER_LIGHT_DIRECTIONAL;
        ms_viewer_light_world(l, c, light.vector);
    }
    o->lights[0] = light;
    o->light_count = 1;
}

void ms_viewer_light_drag(ms_viewer_light *l, double dx, double dy, double height)
{
    if (!(height > 0) || !isfinite(dx) || !isfinite(dy))
        return;
    if (!l->directional)
        *l = (ms_viewer_light){.directional = true};
    double az = l->azimuth_deg + 180.0 * dx / height, el = l->elevation_deg - 180.0 * dy / height;
    az = fmod(az, 360.0);
    if (az > 180)
        az -= 360;
    else if (az <= -180)
        az += 360;
    l->azimuth_deg = az;
    l->elevation_deg = el > 90 ? 90 : el < -90 ? -90 : el;
}

void ms_viewer_light_next_preset(ms_viewer_light *l)
{
    static const double presets[4][2] = {{-80, 0}, {0, 80}, {80, 0}, {0, -80}};
    int next = 0;
    if (l->directional) {
        next = 4; /* a light of no preset, or the last: the head light */
        for (int i = 0; i < 4; ++i)
            if (l->azimuth_deg == presets[i][0] && l->elevation_deg == presets[i][1])
                next = i + 1;
    }
    if (next == 4)
        *l = (ms_viewer_light){.directional = false};
    else
        *l = (ms_viewer_light){.directional = true, .azimuth_deg = presets[next][0],
                               .elevation_deg = presets[next][1]};
}

void ms_viewer_light_describe(const ms_viewer_light *l, char *text, size_t size)
{
    if (l->directional)
        snprintf(text, size, "light az %.1f el %.1f deg", l->azimuth_deg, l->elevation_deg);
    else
        snprintf(text, size, "head light");
}
