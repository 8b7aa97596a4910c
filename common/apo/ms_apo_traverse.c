/* CPU reference traversal of an APO chunk (rules in ms_apo_traverse.h). */
#include "ms_apo_traverse.h"

#include <string.h>

void ms_apo_position_to_fixed(const float position[3], uint32_t fixed[3])
{
    for (int a = 0; a < 3; ++a) {
        float p = position[a];
        if (p >= 1.0f)
            fixed[a] = UINT32_MAX;
        else if (p > 0.0f)
            fixed[a] = (uint32_t)(p * 4294967296.0f); /* p < 1 so p*2^32 <= 2^32 - 2^8 */
        else
            fixed[a] = 0; /* also NaN */
    }
}

/* Octant of the fixed-point point inside the node at `depth`. */
static uint32_t octant_at(const uint32_t u[3], uint32_t depth)
{
    uint32_t bit = 31u - depth;
    return (u[0] >> bit & 1u) << 2 | (u[1] >> bit & 1u) << 1 | (u[2] >> bit & 1u);
}

/* The existing child nearest to the point (L-infinity distance to its cell), then
 * the point moved onto that child's cell. */
static uint32_t nearest_existing_child(uint32_t exist, uint32_t octant, uint32_t u[3], uint32_t depth)
{
    uint32_t mid = 1u << (31u - depth);
    uint32_t low_mask = 2u * mid - 1u; /* wraps to all ones at depth 0 */
    uint32_t dist[3];
    for (int a = 0; a < 3; ++a) {
        uint32_t r = u[a] & low_mask;
        dist[a] = r >= mid ? r - mid : mid - r;
    }
    uint32_t best = 8, best_cost = 0, best_axes = 0;
    for (uint32_t o = 0; o < 8; ++o) {
        if (!(exist >> o & 1u))
            continue;
        uint32_t diff = o ^ octant, cost = 0;
        for (int a = 0; a < 3; ++a)
            if (diff >> (2 - a) & 1u && dist[a] > cost)
                cost = dist[a];
        uint32_t axes = ms_apo_popcount8(diff);
        if (best == 8 || cost < best_cost || (cost == best_cost && axes < best_axes)) {
            best = o;
            best_cost = cost;
            best_axes = axes;
        }
    }
    uint32_t diff = best ^ octant;
    for (int a = 0; a < 3; ++a) {
        if (!(diff >> (2 - a) & 1u))
            continue;
        bool was_upper = (u[a] & low_mask) >= mid;
        u[a] = (u[a] & ~low_mask) | (was_upper ? mid - 1u : mid);
    }
    return best;
}

static void finish(const ms_apo_view *view, uint32_t word, bool internal, uint32_t depth, const uint32_t cell[3],
                   ms_apo_stop stop, ms_apo_lookup_result *r)
{
    r->code = stop == MS_APO_STOP_MISSING ? MS_APO_NORMAL_SMOOTH
                                          : ms_apo_word_normal(view->texels[internal ? word + 1 : word]);
    r->smooth = r->code == MS_APO_NORMAL_SMOOTH;
    if (!r->smooth)
        ms_apo_normal_decode(r->code, r->normal);
    r->word = word;
    r->depth = depth;
    memcpy(r->cell, cell, sizeof r->cell);
    r->stop = stop;
}

ms_apo_stop ms_apo_lookup_fixed(const ms_apo_view *view, const uint32_t fixed[3], uint32_t depth_cap,
                                ms_apo_missing_rule rule, ms_apo_lookup_result *r)
{
    memset(r, 0, sizeof *r);
    if (view->complete_levels == 0) {
        r->stop = MS_APO_STOP_EMPTY;
        r->code = MS_APO_NORMAL_SMOOTH;
        r->smooth = true;
        return r->stop;
    }
    uint32_t u[3] = {fixed[0], fixed[1], fixed[2]};
    uint32_t last = view->complete_levels - 1; /* deepest level we may read */
    uint32_t word = 0, depth = 0, cell[3] = {0, 0, 0};
    bool internal = view->root_words == 2;
    for (;;) {
        if (!internal) {
            finish(view, word, false, depth, cell, MS_APO_STOP_LEAF, r);
            break;
        }
        if (depth >= depth_cap) {
            finish(view, word, true, depth, cell, MS_APO_STOP_CAP, r);
            break;
        }
        if (depth >= last) {
            finish(view, word, true, depth, cell, MS_APO_STOP_PREFIX, r);
            break;
        }
        uint32_t header = view->texels[word];
        uint32_t exist = ms_apo_header_exist(header);
        uint32_t kind = ms_apo_mean_kind(view->texels[word + 1]);
        uint32_t octant = octant_at(u, depth);
        if (!(exist >> octant & 1u)) {
            if (rule == MS_APO_MISSING_STOP) {
                /* no texel: the absent child's cell, for the filter */
                uint32_t child[3] = {2 * cell[0] + (octant >> 2 & 1u), 2 * cell[1] + (octant >> 1 & 1u),
                                     2 * cell[2] + (octant & 1u)};
                finish(view, word, true, depth + 1, child, MS_APO_STOP_MISSING, r);
                break;
            }
            octant = nearest_existing_child(exist, octant, u, depth);
            r->substitutions++;
        }
        word += ms_apo_header_offset(header) + ms_apo_sibling_words_below(exist, kind, octant);
        internal = kind >> octant & 1u;
        cell[0] = 2 * cell[0] + (octant >> 2 & 1u);
        cell[1] = 2 * cell[1] + (octant >> 1 & 1u);
        cell[2] = 2 * cell[2] + (octant & 1u);
        ++depth;
    }
    return r->stop;
}

ms_apo_stop ms_apo_lookup(const ms_apo_view *view, const float position[3], uint32_t depth_cap,
                          ms_apo_missing_rule rule, ms_apo_lookup_result *result)
{
    uint32_t fixed[3];
    ms_apo_position_to_fixed(position, fixed);
    return ms_apo_lookup_fixed(view, fixed, depth_cap, rule, result);
}
