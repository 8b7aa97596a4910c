/* Orthographic octree march of an APO chunk (see ms_apo_render.h). */
#include "ms_apo_render.h"

#include <math.h>

#include "ms_apo_traverse.h"

uint64_t ms_apo_render_top_view(const ms_apo_view *view, uint32_t depth_cap, uint32_t width, uint32_t height,
                                uint8_t *grey)
{
    const double light[3] = {0.3 / 1.1180339887, 0.4 / 1.1180339887, 1.0 / 1.1180339887};
    uint64_t hits = 0;
    for (uint32_t j = 0; j < height; ++j)
        for (uint32_t i = 0; i < width; ++i) {
            float p[3] = {(float)((i + 0.5) / width), (float)(1.0 - (j + 0.5) / height), 1.0f};
            uint32_t u[3];
            ms_apo_position_to_fixed(p, u);
            uint8_t value = 0;
            for (;;) {
                ms_apo_lookup_result r;
                ms_apo_stop stop = ms_apo_lookup_fixed(view, u, depth_cap, MS_APO_MISSING_STOP, &r);
                if (stop == MS_APO_STOP_EMPTY)
                    break;
                if (stop != MS_APO_STOP_MISSING) {
                    double lambert = r.normal[0] * light[0] + r.normal[1] * light[1] + r.normal[2] * light[2];
                    value = (uint8_t)(lambert > 0.0 ? 30.5 + 225.0 * lambert : 30.5);
                    ++hits;
                    break;
                }
                /* The missing child (r.depth >= 1 is its depth) spans
                 * 2^(32 - depth) fixed-point units in z: continue just below
                 * its lower face. */
                uint32_t lower = u[2] & ~((1u << (32u - r.depth)) - 1u);
                if (lower == 0)
                    break;
                u[2] = lower - 1u;
            }
            grey[(uint64_t)j * width + i] = value;
        }
    return hits;
}
