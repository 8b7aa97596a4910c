/* Filtered APO lookup (rules in ms_apo_filter.h). */
#include "ms_apo_filter.h"

#include <math.h>
#include <stdbool.h>
#include <string.h>

uint32_t ms_apo_footprint_depth(float footprint)
{
    if (!(footprint > 0.0f))
        return UINT32_MAX;
    if (footprint >= 1.0f)
        return 0;
    int e;
    frexpf(footprint, &e); /* footprint = m * 2^e, m in [0.5, 1), e <= 0 */
    return (uint32_t)(1 - e);
}

ms_apo_stop ms_apo_lookup_filtered_fixed(const ms_apo_view *view, const uint32_t fixed[3], uint32_t depth_cap,
                                         ms_apo_missing_rule rule, const float smooth[3], ms_apo_filter_result *res)
{
    static const float zero[3] = {0.0f, 0.0f, 0.0f};
    if (!smooth)
        smooth = zero;
    memset(res, 0, sizeof *res);
    ms_apo_stop stop = ms_apo_lookup_fixed(view, fixed, depth_cap, rule, &res->centre);
    const float *n0 = res->centre.smooth ? smooth : res->centre.normal;
    memcpy(res->normal, n0, sizeof res->normal);
    res->lookups = 1;
    uint32_t d = res->centre.depth;
    res->texels = !res->centre.smooth;
    if (stop == MS_APO_STOP_EMPTY || d == 0)
        return stop;
    uint32_t shift = 32u - d, width = 1u << shift, half = width >> 1;
    uint32_t at[3], across[3];
    bool moves[3];
    for (int a = 0; a < 3; ++a) {
        uint32_t lower = res->centre.cell[a] << shift, top = lower + (width - 1u);
        uint32_t u = fixed[a] < lower ? lower : (fixed[a] > top ? top : fixed[a]);
        uint32_t r = u - lower;
        bool upper = r >= half;
        uint32_t dist = upper ? r - half : half - 1u - r;
        res->weight[a] = ((float)dist + 0.5f) / (float)width;
        at[a] = u;
        moves[a] = upper ? res->centre.cell[a] + 1u < (1u << d) : res->centre.cell[a] > 0u;
        across[a] = upper ? lower + width : lower - 1u;
    }
    float sum[3] = {0.0f, 0.0f, 0.0f};
    for (uint32_t k = 0; k < 8; ++k) {
        float w = 1.0f;
        uint32_t q[3];
        bool moved = false;
        for (int a = 0; a < 3; ++a) {
            bool bit = k >> (2 - a) & 1u;
            w *= bit ? res->weight[a] : 1.0f - res->weight[a];
            q[a] = bit && moves[a] ? across[a] : at[a];
            moved = moved || (bit && moves[a]);
        }
        const float *n = n0;
        ms_apo_lookup_result nb;
        if (moved) {
            ms_apo_lookup_fixed(view, q, depth_cap, MS_APO_MISSING_STOP, &nb);
            res->lookups++;
            res->missing += nb.stop == MS_APO_STOP_MISSING;
            res->smooth += nb.smooth;
            res->texels += !nb.smooth;
            res->neighbour_depth[k] = nb.depth;
            n = nb.smooth ? smooth : nb.normal;
        } else {
            res->neighbour_depth[k] = d;
            res->texels += !res->centre.smooth && k > 0;
        }
        /* a neighbour facing away from the centre is taken turned over */
        float side = n[0] * n0[0] + n[1] * n0[1] + n[2] * n0[2] < 0.0f ? -w : w;
        for (int a = 0; a < 3; ++a)
            sum[a] += side * n[a];
    }
    float len = sqrtf(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    if (res->texels == 0)
        return stop; /* no texel around: the smooth normal as given */
    if (len >= 1e-6f)
        for (int a = 0; a < 3; ++a)
            res->normal[a] = sum[a] / len;
    return stop;
}

ms_apo_stop ms_apo_lookup_filtered_smooth(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                                          ms_apo_missing_rule rule, const float smooth[3],
                                          ms_apo_filter_result *result)
{
    uint32_t fixed[3];
    ms_apo_position_to_fixed(position, fixed);
    return ms_apo_lookup_filtered_fixed(view, fixed, depth_cap, rule, smooth, result);
}

ms_apo_stop ms_apo_lookup_filtered(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                                   ms_apo_missing_rule rule, ms_apo_filter_result *result)
{
    return ms_apo_lookup_filtered_smooth(view, position, depth_cap, rule, NULL, result);
}
