/* Procedural demo sculpture: see ms_demo_model.h. */
#include "ms_demo_model.h"

#include <math.h>
#include <stdlib.h>

#define PI 3.14159265358979323846

uint32_t ms_demo_grid_for_triangles(uint64_t triangles)
{
    double n = sqrt((double)triangles / 12.0);
    if (!(n >= MS_DEMO_MIN_GRID))
        return MS_DEMO_MIN_GRID;
    if (n >= MS_DEMO_MAX_GRID)
        return MS_DEMO_MAX_GRID;
    return (uint32_t)llround(n);
}

uint64_t ms_demo_vertex_count(const ms_demo_model *model)
{
    uint64_t n = model->grid;
    return 6 * n * n + 2;
}

uint64_t ms_demo_triangle_count(const ms_demo_model *model)
{
    uint64_t n = model->grid;
    return 12 * n * n;
}

/* --- Lattice of the cube surface -------------------------------------------
 * Points of [0,n]^3 with at least one coordinate at 0 or n, numbered layer by
 * layer along z: the full bottom grid, then the perimeter ring of each inner
 * layer, then the full top grid. */

static void ring_to_xy(uint64_t n, uint64_t r, uint64_t *x, uint64_t *y)
{
    if (r < n) {
        *x = r, *y = 0;
    } else if (r < 2 * n) {
        *x = n, *y = r - n;
    } else if (r < 3 * n) {
        *x = n - (r - 2 * n), *y = n;
    } else {
        *x = 0, *y = n - (r - 3 * n);
    }
}

static uint64_t xy_to_ring(uint64_t n, uint64_t x, uint64_t y)
{
    if (y == 0 && x < n)
        return x;
    if (x == n && y < n)
        return n + y;
    if (y == n && x > 0)
        return 2 * n + (n - x);
    return 3 * n + (n - y);
}

static uint64_t lattice_index(uint64_t n, const uint64_t q[3])
{
    uint64_t full = (n + 1) * (n + 1);
    if (q[2] == 0)
        return q[1] * (n + 1) + q[0];
    if (q[2] == n)
        return full + (n - 1) * 4 * n + q[1] * (n + 1) + q[0];
    return full + (q[2] - 1) * 4 * n + xy_to_ring(n, q[0], q[1]);
}

static void lattice_point(uint64_t n, uint64_t index, uint64_t q[3])
{
    uint64_t full = (n + 1) * (n + 1);
    if (index < full) {
        q[0] = index % (n + 1), q[1] = index / (n + 1), q[2] = 0;
        return;
    }
    index -= full;
    if (index < (n - 1) * 4 * n) {
        q[2] = 1 + index / (4 * n);
        ring_to_xy(n, index % (4 * n), &q[0], &q[1]);
        return;
    }
    index -= (n - 1) * 4 * n;
    q[0] = index % (n + 1), q[1] = index / (n + 1), q[2] = n;
}

/* --- Relief ---------------------------------------------------------------- */

static uint64_t mix64(uint64_t x)
{
    x ^= x >> 30;
    x *= 0xbf58476d1ce4e5b9ull;
    x ^= x >> 27;
    x *= 0x94d049bb133111ebull;
    x ^= x >> 31;
    return x;
}

/* Uniform in [-1, 1) from a lattice corner and the seed. */
static double lattice_value(int64_t x, int64_t y, int64_t z, uint64_t seed)
{
    uint64_t h = mix64((uint64_t)x * 0x9e3779b97f4a7c15ull ^ mix64((uint64_t)y + seed) ^
                       mix64((uint64_t)z * 0xc2b2ae3d27d4eb4full));
    return (double)(h >> 11) * (2.0 / 9007199254740992.0) - 1.0;
}

static double smooth(double t) { return t * t * (3.0 - 2.0 * t); }

/* Trilinear value noise with smoothstep weights: continuous, in [-1, 1]. */
static double value_noise(const double p[3], uint64_t seed)
{
    double fl[3], t[3];
    int64_t c[3];
    for (int a = 0; a < 3; ++a) {
        fl[a] = floor(p[a]);
        c[a] = (int64_t)fl[a];
        t[a] = smooth(p[a] - fl[a]);
    }
    double acc = 0.0;
    for (int k = 0; k < 8; ++k) {
        int dx = k & 1, dy = (k >> 1) & 1, dz = (k >> 2) & 1;
        double w = (dx ? t[0] : 1 - t[0]) * (dy ? t[1] : 1 - t[1]) * (dz ? t[2] : 1 - t[2]);
        acc += w * lattice_value(c[0] + dx, c[1] + dy, c[2] + dz, seed);
    }
    return acc;
}

/* Radius of the sculpture in unit direction d. */
static double relief_radius(const double d[3], uint64_t seed)
{
    /* Silhouette: an upright ellipsoid... */
    const double axes[3] = {0.62, 0.5, 1.0};
    double s = 0.0;
    for (int a = 0; a < 3; ++a)
        s += (d[a] / axes[a]) * (d[a] / axes[a]);
    double r = 1.0 / sqrt(s);
    /* ...with broad lumps (head, shoulders, drapery folds). */
    uint64_t state = seed ^ 0x5eedull;
    for (int i = 0; i < 7; ++i) {
        double c[3], len = 0.0;
        for (int a = 0; a < 3; ++a) {
            state = mix64(state + 0x9e3779b97f4a7c15ull);
            c[a] = (double)(state >> 11) / 9007199254740992.0 * 2.0 - 1.0;
            len += c[a] * c[a];
        }
        len = sqrt(len) + 1e-9;
        double cosang = (d[0] * c[0] + d[1] * c[1] + d[2] * c[2]) / len;
        double amp = (i & 1) ? -0.08 : 0.14;
        r += amp * exp(-(1.0 - cosang) / 0.06);
    }
    /* Fine relief: octaves of noise, and carved grooves that follow it. */
    double detail = 0.0, amp = 0.025, freq = 6.0;
    for (int o = 0; o < 6; ++o) {
        double p[3] = {d[0] * freq, d[1] * freq, d[2] * freq};
        detail += amp * value_noise(p, seed + (uint64_t)o);
        amp *= 0.5;
        freq *= 2.0;
    }
    double q[3] = {d[0] * 3.0, d[1] * 3.0, d[2] * 3.0};
    double warp = value_noise(q, seed + 101);
    double groove = 1.0 - fabs(sin(40.0 * d[2] + 6.0 * warp));
    detail -= 0.012 * groove * groove * groove * groove;
    return r * (1.0 + detail);
}

void ms_demo_vertex(const ms_demo_model *model, uint64_t index, double out[3])
{
    uint64_t n = model->grid, q[3];
    lattice_point(n, index, q);
    double c[3], len = 0.0;
    for (int a = 0; a < 3; ++a) {
        /* The tangent warp spreads the cube-face grid evenly over the sphere. */
        c[a] = tan((2.0 * (double)q[a] / (double)n - 1.0) * (PI / 4.0));
        len += c[a] * c[a];
    }
    len = sqrt(len);
    double d[3] = {c[0] / len, c[1] / len, c[2] / len};
    double r = relief_radius(d, model->seed);
    for (int a = 0; a < 3; ++a)
        out[a] = r * d[a];
}

/* Cube face f: fixed axis, whether it sits at n, and in-plane axes (u, v) with
 * u x v pointing outward, so (u, v)-counter-clockwise quads face outward. */
static const struct {
    int fixed, at_max, u, v;
} cube_faces[6] = {
    {0, 1, 1, 2}, {0, 0, 2, 1}, {1, 1, 2, 0}, {1, 0, 0, 2}, {2, 1, 0, 1}, {2, 0, 1, 0},
};

void ms_demo_triangle(const ms_demo_model *model, uint64_t index, uint32_t out[3])
{
    uint64_t n = model->grid;
    uint64_t per_face = 2 * n * n;
    int f = (int)(index / per_face);
    uint64_t rest = index % per_face;
    uint64_t cell = rest / 2, half = rest % 2;
    uint64_t i = cell % n, j = cell / n;
    /* Corners 0..3 of quad (i, j) counter-clockwise in (u, v). */
    const uint64_t du[4] = {0, 1, 1, 0}, dv[4] = {0, 0, 1, 1};
    uint64_t idx[4];
    for (int k = 0; k < 4; ++k) {
        uint64_t q[3];
        q[cube_faces[f].fixed] = cube_faces[f].at_max ? n : 0;
        q[cube_faces[f].u] = i + du[k];
        q[cube_faces[f].v] = j + dv[k];
        idx[k] = lattice_index(n, q);
    }
    /* Alternate the diagonal so the tessellation has no preferred direction. */
    static const int split_a[2][3] = {{0, 1, 2}, {0, 2, 3}};
    static const int split_b[2][3] = {{0, 1, 3}, {1, 2, 3}};
    const int(*split)[3] = ((i + j) & 1) ? split_b : split_a;
    for (int k = 0; k < 3; ++k)
        out[k] = (uint32_t)idx[split[half][k]];
}

ms_status ms_demo_build(const ms_demo_model *model, ms_mesh *mesh, ms_error *err)
{
    if (model->grid < MS_DEMO_MIN_GRID || model->grid > MS_DEMO_MAX_GRID)
        return ms_error_set(err, MS_ERR_ARG, "demo model grid %u outside [%u, %u]", model->grid,
                            MS_DEMO_MIN_GRID, MS_DEMO_MAX_GRID);
    uint64_t nv = ms_demo_vertex_count(model), nt = ms_demo_triangle_count(model);
    ms_status st = ms_mesh_reserve(mesh, (size_t)nv, (size_t)nt, err);
    if (st != MS_OK)
        return st;
    for (uint64_t v = 0; v < nv; ++v)
        ms_demo_vertex(model, v, mesh->positions + 3 * v);
    for (uint64_t t = 0; t < nt; ++t)
        ms_demo_triangle(model, t, mesh->triangles + 3 * t);
    mesh->vertex_count = (size_t)nv;
    mesh->triangle_count = (size_t)nt;
    return MS_OK;
}
