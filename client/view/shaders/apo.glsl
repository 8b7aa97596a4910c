// The APO traversal (docs/APO.md, "Traversal"), step for step as the CPU oracle
// ms_apo_lookup (common/apo/ms_apo_traverse.c). Words of every cell's chunk prefix
// live in one GL_R32UI buffer texture; a cell's words start at apo_base.
// Included into the fragment shader (no #version here).

uniform usamplerBuffer apo_words;

// A node without a texel (a missing child, or a mean word holding this code):
// the fragment's smooth normal (docs/APO.md, "APO as a correction").
#define APO_SMOOTH 0xFFFFFFu

uvec3 apo_fixed(vec3 p)
{
    uvec3 u;
    for (int a = 0; a < 3; ++a)
        u[a] = p[a] >= 1.0 ? 0xFFFFFFFFu : (p[a] > 0.0 ? uint(p[a] * 4294967296.0) : 0u);
    return u;
}

// 24-bit octahedral code to a unit vector; s(t) = +1 for t >= 0 (not sign()).
vec3 apo_decode(uint code)
{
    float u = float(int(min(code & 0xFFFu, 4094u)) - 2047) / 2047.0;
    float v = float(int(min((code >> 12) & 0xFFFu, 4094u)) - 2047) / 2047.0;
    vec3 n = vec3(u, v, 1.0 - abs(u) - abs(v));
    if (n.z < 0.0)
        n.xy = vec2((1.0 - abs(v)) * (u >= 0.0 ? 1.0 : -1.0), (1.0 - abs(u)) * (v >= 0.0 ? 1.0 : -1.0));
    return normalize(n);
}

// The stored child nearest to the point (L-infinity distance to its cell; ties:
// fewer differing axes, then the lower octant), and the point moved into it.
uint apo_nearest(uint exist, uint oct, inout uvec3 u, uint depth)
{
    uint mid = 1u << (31u - depth);
    uint low = 2u * mid - 1u; // all ones at depth 0
    uvec3 r = u & uvec3(low);
    uvec3 dist; // mix() on unsigned vectors needs GLSL 4.50
    for (int a = 0; a < 3; ++a)
        dist[a] = r[a] >= mid ? r[a] - mid : mid - r[a];
    uint best = 8u, best_cost = 0u, best_axes = 0u;
    for (uint o = 0u; o < 8u; ++o) {
        if (((exist >> o) & 1u) == 0u)
            continue;
        uint diff = o ^ oct, cost = 0u;
        if ((diff & 4u) != 0u)
            cost = max(cost, dist.x);
        if ((diff & 2u) != 0u)
            cost = max(cost, dist.y);
        if ((diff & 1u) != 0u)
            cost = max(cost, dist.z);
        uint axes = uint(bitCount(diff));
        if (best == 8u || cost < best_cost || (cost == best_cost && axes < best_axes)) {
            best = o;
            best_cost = cost;
            best_axes = axes;
        }
    }
    uint diff = best ^ oct;
    for (int a = 0; a < 3; ++a)
        if (((diff >> uint(2 - a)) & 1u) != 0u)
            u[a] = (u[a] & ~low) | (r[a] >= mid ? mid - 1u : mid);
    return best;
}

// The walk from the root at a fixed-point point: the 24-bit normal code of the
// node where it stops (APO_SMOOTH: no texel), that node's depth and integer cell
// coordinates (at a missing child: the child's).
// stop_depth = min(depth cap, last complete level, footprint depth): an internal
// node there returns its mean normal (CAP / PREFIX); a level not wholly received
// is never read. Offsets were validated on the CPU (ms_apo_view_init) before
// upload.
uint apo_walk(uvec3 u, int base, bool root_internal, uint stop_depth, bool nearest, out uint depth, out uvec3 cell)
{
    int word = base;
    bool internal = root_internal;
    depth = 0u;
    cell = uvec3(0u);
    while (internal && depth < stop_depth) {
        uint header = texelFetch(apo_words, word).r;
        uint kind = texelFetch(apo_words, word + 1).r >> 24;
        uint exist = header & 0xFFu;
        uint bit = 31u - depth;
        uint oct = (((u.x >> bit) & 1u) << 2) | (((u.y >> bit) & 1u) << 1) | ((u.z >> bit) & 1u);
        if (((exist >> oct) & 1u) == 0u) {
            if (!nearest) {
                // MISSING: no texel, the smooth normal; the absent child's cell
                cell = 2u * cell + uvec3((oct >> 2) & 1u, (oct >> 1) & 1u, oct & 1u);
                ++depth;
                return APO_SMOOTH;
            }
            oct = apo_nearest(exist, oct, u, depth);
        }
        uint below = (1u << oct) - 1u;
        word += int((header >> 8) + uint(bitCount(exist & below) + bitCount(exist & kind & below)));
        internal = ((kind >> oct) & 1u) != 0u;
        cell = 2u * cell + uvec3((oct >> 2) & 1u, (oct >> 1) & 1u, oct & 1u);
        ++depth;
    }
    return texelFetch(apo_words, internal ? word + 1 : word).r & 0xFFFFFFu;
}

// The nearest node's normal (ms_apo_lookup); smooth_n where it has no texel
// (texel false).
vec3 apo_lookup(vec3 p, int base, bool root_internal, uint stop_depth, bool nearest, vec3 smooth_n, out bool texel)
{
    uint depth;
    uvec3 cell;
    uint code = apo_walk(apo_fixed(p), base, root_internal, stop_depth, nearest, depth, cell);
    texel = code != APO_SMOOTH;
    return texel ? apo_decode(code) : smooth_n;
}

// The first depth whose cells are no wider than the pixel footprint f
// (ms_apo_footprint_depth): 2^-depth <= f. With f = m * 2^e, m in [0.5, 1)
// (frexp's split, read from the float's bits: exact): 1 - e. A subnormal f
// gives 127: no limit within 30 levels.
uint apo_footprint_depth(float f)
{
    if (!(f > 0.0))
        return 0xFFFFFFFFu;
    if (f >= 1.0)
        return 0u;
    int e = int((floatBitsToUint(f) >> 23) & 0xFFu) - 126;
    return uint(1 - e);
}

// 8-cell interpolation (ms_apo_lookup_filtered, docs/APO.md "Filtering"): the
// centre node, and the 7 neighbours on the sides of its nearer faces, each
// looked up one fixed-point unit past the face with the STOP rule (a neighbour
// without a texel gives smooth_n, the fragment's smooth normal); an axis whose
// neighbour would leave the cube stays (clamp to edge). texel: some corner gave
// a texel (else the result is smooth_n itself).
vec3 apo_lookup_filtered(vec3 p, int base, bool root_internal, uint stop_depth, bool nearest, vec3 smooth_n,
                         out bool texel)
{
    uvec3 u = apo_fixed(p);
    uint depth;
    uvec3 cell;
    uint code0 = apo_walk(u, base, root_internal, stop_depth, nearest, depth, cell);
    texel = code0 != APO_SMOOTH;
    vec3 n0 = texel ? apo_decode(code0) : smooth_n;
    if (depth == 0u)
        return n0;
    uint shift = 32u - depth;
    uint width = 1u << shift;
    uint half_width = width >> 1;
    uvec3 at, across;
    bvec3 moves;
    vec3 t;
    for (int a = 0; a < 3; ++a) {
        uint lower = cell[a] << shift;
        uint v = clamp(u[a], lower, lower + (width - 1u));
        uint r = v - lower;
        bool upper = r >= half_width;
        uint dist = upper ? r - half_width : half_width - 1u - r;
        t[a] = (float(dist) + 0.5) / float(width);
        at[a] = v;
        moves[a] = upper ? cell[a] + 1u < (1u << depth) : cell[a] > 0u;
        across[a] = upper ? lower + width : lower - 1u;
    }
    vec3 sum = vec3(0.0);
    for (uint k = 0u; k < 8u; ++k) {
        float w = 1.0;
        uvec3 q;
        bool moved = false;
        for (int a = 0; a < 3; ++a) {
            bool bit = ((k >> uint(2 - a)) & 1u) != 0u;
            w *= bit ? t[a] : 1.0 - t[a];
            q[a] = (bit && moves[a]) ? across[a] : at[a];
            moved = moved || (bit && moves[a]);
        }
        vec3 n = n0;
        if (moved) {
            uint d;
            uvec3 c;
            uint code = apo_walk(q, base, root_internal, stop_depth, false, d, c);
            texel = texel || code != APO_SMOOTH;
            n = code != APO_SMOOTH ? apo_decode(code) : smooth_n;
        }
        sum += (dot(n, n0) < 0.0 ? -w : w) * n; // a neighbour facing away: turned over
    }
    if (!texel)
        return smooth_n; // no texel around: the smooth normal as given
    float len = length(sum);
    return len >= 1e-6 ? sum / len : n0;
}
