/* The corner normals of a frame's cells (ms_render_split_normals,
 * ms_render_internal.h), made only for the cells asked about.
 *
 * Around each vertex the triangles fall into groups joined across smooth
 * manifold edges (a crease, an edge of three or more triangles or a boundary
 * separates them; an edge is a crease when its angle exceeds the crease angle
 * plus both triangles' slack, how far their normals may be off because their
 * corners sit at kd-cell centres, so a coarse level's roughness is not taken
 * for edges), with each face turned to its group's orientation where the
 * stored orientation flips across an edge (a scan's inconsistently wound
 * faces): a cube keeps its edges, and a flipped face neither cancels its
 * neighbours' normals nor darkens. A vertex's fan is made of the triangles of
 * the cells around, in ascending corner order, so a vertex gets the same
 * normals as over the whole stitched mesh, whichever cells are asked about. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_render_internal.h"

uint32_t ms_render_pack_normal(const double n[3])
{
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !isfinite(len))
        return 0;
    uint32_t word = 0;
    for (int a = 0; a < 3; ++a) {
        long q = lround(n[a] / len * 511.0);
        q = q < -511 ? -511 : (q > 511 ? 511 : q);
        word |= ((uint32_t)q & 0x3FFu) << (10 * a);
    }
    return word;
}

/* Sorts a fan's keys (a handful, a few dozen at a pole: insertion sort;
 * qsort beyond). */
static int compare_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

static void sort_keys(uint64_t *keys, size_t n)
{
    if (n > 48) {
        qsort(keys, n, sizeof *keys, compare_u64);
        return;
    }
    for (size_t i = 1; i < n; ++i) {
        uint64_t k = keys[i];
        size_t j = i;
        for (; j > 0 && keys[j - 1] > k; --j)
            keys[j] = keys[j - 1];
        keys[j] = k;
    }
}

/* Union-find with parity over one fan: the root of i, and in *flip whether i's
 * face is turned over against the root's. */
static uint32_t fan_find(ms_render_split *s, uint32_t i, uint8_t *flip)
{
    uint8_t parity = 0;
    uint32_t root = i;
    while (s->fan_parent[root] != root) {
        parity ^= s->fan_parity[root];
        root = s->fan_parent[root];
    }
    /* compress: point every node on the way straight at the root */
    uint8_t left = parity;
    while (s->fan_parent[i] != root && i != root) {
        uint32_t up = s->fan_parent[i];
        uint8_t step = s->fan_parity[i];
        s->fan_parent[i] = root;
        s->fan_parity[i] = left;
        left ^= step;
        i = up;
    }
    *flip = parity;
    return root;
}

/* How far triangle t's normal may be off (radians): a corner moved by e
 * tilts the plane by up to about atan(e / h), h the smallest height (twice
 * the area over the longest side). Computed when first asked for: most
 * edges pass the plain crease test and never ask. */
static double face_slack(ms_render_split *s, const ms_view_mesh *mesh, uint32_t t)
{
    double slack = s->face_slack[t];
    if (slack >= 0.0)
        return slack;
    double e = -slack;
    const uint32_t *tri = &mesh->triangles[3 * (size_t)t];
    const double *p = mesh->positions;
    const double *a = &p[3 * (size_t)tri[0]], *b = &p[3 * (size_t)tri[1]], *c = &p[3 * (size_t)tri[2]];
    double l = 0.0;
    for (int k = 0; k < 3; ++k) {
        const double *u = k == 0 ? a : k == 1 ? b : c, *w = k == 0 ? b : k == 1 ? c : a;
        double d2 = (w[0] - u[0]) * (w[0] - u[0]) + (w[1] - u[1]) * (w[1] - u[1]) +
                    (w[2] - u[2]) * (w[2] - u[2]);
        l = d2 > l ? d2 : l;
    }
    double twice_area = s->face_rlen[t] > 0.0 ? 1.0 / s->face_rlen[t] : 0.0;
    slack = twice_area > 0.0 ? atan2(e * sqrt(l), twice_area) : M_PI / 2;
    s->face_slack[t] = slack;
    return slack;
}

/* The corner normals of one vertex's fan (ms_render_internal.h says the rule). */
static void fan_normals(ms_render_split *s, const ms_view_mesh *mesh, const uint32_t *corners, uint32_t f)
{
    size_t keys = 0;
    for (uint32_t i = 0; i < f; ++i) {
        s->fan_parent[i] = i;
        s->fan_parity[i] = 0;
        uint32_t t = corners[i] / 3, k = corners[i] % 3;
        const double *n = &s->face_normal[3 * (size_t)t];
        if (n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0)
            continue; /* no area, no direction: joins nothing */
        const uint32_t *tri = &mesh->triangles[3 * (size_t)t];
        /* the edge to the next corner leaves the vertex (direction 0), the one
         * from the previous corner arrives (1) */
        s->fan_keys[keys++] = (uint64_t)tri[(k + 1) % 3] << 32 | (uint64_t)i << 1;
        s->fan_keys[keys++] = (uint64_t)tri[(k + 2) % 3] << 32 | (uint64_t)i << 1 | 1u;
    }
    sort_keys(s->fan_keys, keys);
    for (size_t a = 0; a < keys;) {
        size_t b = a + 1;
        while (b < keys && s->fan_keys[b] >> 32 == s->fan_keys[a] >> 32)
            b++;
        if (b - a == 2) { /* a manifold edge; one used by more faces is a crease */
            uint32_t i = (uint32_t)(s->fan_keys[a] & 0xFFFFFFFFu) >> 1;
            uint32_t j = (uint32_t)(s->fan_keys[a + 1] & 0xFFFFFFFFu) >> 1;
            /* used in the same direction: one of the two faces is flipped */
            uint8_t flipped = (s->fan_keys[a] & 1u) == (s->fan_keys[a + 1] & 1u);
            uint32_t ti = corners[i] / 3, tj = corners[j] / 3;
            const double *ni = &s->face_normal[3 * (size_t)ti];
            const double *nj = &s->face_normal[3 * (size_t)tj];
            double dot = ni[0] * nj[0] + ni[1] * nj[1] + ni[2] * nj[2];
            double cosine = (flipped ? -dot : dot) * s->face_rlen[ti] * s->face_rlen[tj];
            bool smooth = cosine >= s->crease_cos;
            if (!smooth && (s->face_slack[ti] != 0.0 || s->face_slack[tj] != 0.0)) {
                /* the crease angle widened by how far each normal may be off
                 * (a coarse level's vertices sit at their kd-cells' centres) */
                double slack = face_slack(s, mesh, ti) + face_slack(s, mesh, tj);
                smooth = s->crease_rad + slack >= M_PI || cosine >= cos(s->crease_rad + slack);
            }
            if (i != j && smooth) {
                uint8_t fi, fj;
                uint32_t ri = fan_find(s, i, &fi), rj = fan_find(s, j, &fj);
                /* already joined: a loop of flips that does not close (a
                 * Moebius-like fan) keeps the first joins */
                if (ri != rj) {
                    s->fan_parent[rj] = ri;
                    s->fan_parity[rj] = fi ^ fj ^ flipped;
                }
            }
        }
        a = b;
    }
    for (uint32_t i = 0; i < f; ++i)
        s->fan_sum[3 * (size_t)i] = s->fan_sum[3 * (size_t)i + 1] = s->fan_sum[3 * (size_t)i + 2] = 0.0;
    for (uint32_t i = 0; i < f; ++i) {
        uint8_t flip;
        uint32_t root = fan_find(s, i, &flip);
        const double *n = &s->face_normal[3 * (size_t)(corners[i] / 3)];
        double sign = flip ? -1.0 : 1.0;
        for (int a = 0; a < 3; ++a)
            s->fan_sum[3 * (size_t)root + (size_t)a] += sign * n[a];
    }
    /* packed once per group and side (the keys are free again: a group's
     * packed word for either side, UINT64_MAX until made) */
    for (uint32_t i = 0; i < f; ++i)
        s->fan_keys[2 * (size_t)i] = s->fan_keys[2 * (size_t)i + 1] = UINT64_MAX;
    for (uint32_t i = 0; i < f; ++i) {
        uint8_t flip;
        uint32_t root = fan_find(s, i, &flip);
        uint64_t *packed = &s->fan_keys[2 * (size_t)root + flip];
        if (*packed == UINT64_MAX) {
            const double *sum = &s->fan_sum[3 * (size_t)root];
            double sign = flip ? -1.0 : 1.0, n[3] = {sign * sum[0], sign * sum[1], sign * sum[2]};
            *packed = ms_render_pack_normal(n);
        }
        s->corner_packed[corners[i]] = (uint32_t)*packed;
    }
}

/* Face normal, its inverse length and its corners' decode error (turned into
 * an angle when an edge asks: face_slack) of triangle t. */
static void make_face(ms_render_split *s, const ms_view_mesh *mesh, size_t t)
{
    const double *p = mesh->positions;
    const uint32_t *tri = &mesh->triangles[3 * t];
    const double *a = &p[3 * (size_t)tri[0]], *b = &p[3 * (size_t)tri[1]], *c = &p[3 * (size_t)tri[2]];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
    double e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    /* twice the area times the unit normal: the weighting by area */
    double *n = &s->face_normal[3 * t];
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
    double twice_area = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    s->face_rlen[t] = twice_area > 0.0 ? 1.0 / twice_area : 0.0;
    double e = 0.0;
    if (mesh->levels)
        for (int k = 0; k < 3; ++k) {
            unsigned level = mesh->levels[tri[k]];
            double ek = level < 64 ? s->level_error[level] : 0.0;
            e = ek > e ? ek : e;
        }
    s->face_slack[t] = -e;
}

/* Checks triangle t of a mesh with runs as drawn by cell (its indices, its
 * drawing cell, its corners' positions). */
static ms_status check_triangle(const ms_view_mesh *mesh, size_t t, uint32_t cell, ms_error *err)
{
    if (mesh->triangle_cell[t] != cell)
        return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu drawn by cell %u in the run of cell %u", t,
                            mesh->triangle_cell[t], cell);
    for (int k = 0; k < 3; ++k) {
        uint32_t v = mesh->triangles[3 * t + (size_t)k];
        if (v >= mesh->vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu uses vertex %u of %zu", t, v,
                                mesh->vertex_count);
        const double *p = &mesh->positions[3 * (size_t)v];
        if (!isfinite(p[0]) || !isfinite(p[1]) || !isfinite(p[2]))
            return ms_error_set(err, MS_ERR_ARG, "render: vertex %u is not finite", v);
    }
    return MS_OK;
}

/* The per-triangle arrays for nt triangles, the per-vertex ones for nv. */
static ms_status normals_room(ms_render_split *s, size_t nv, size_t nt, ms_error *err)
{
    if (nt > s->triangle_normal_cap) {
        double *fn = realloc(s->face_normal, 3 * nt * sizeof *fn);
        if (fn)
            s->face_normal = fn;
        uint32_t *cp = fn ? realloc(s->corner_packed, 3 * nt * sizeof *cp) : NULL;
        if (cp)
            s->corner_packed = cp;
        double *slack = cp ? realloc(s->face_slack, nt * sizeof *slack) : NULL;
        if (slack)
            s->face_slack = slack;
        double *rlen = slack ? realloc(s->face_rlen, nt * sizeof *rlen) : NULL;
        if (!rlen)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu triangles' normals", nt);
        s->face_rlen = rlen;
        s->triangle_normal_cap = nt;
    }
    if (nv > s->fan_vertex_cap) {
        uint32_t *vstamp = realloc(s->fan_vstamp, nv * sizeof *vstamp);
        if (vstamp) {
            memset(vstamp + s->fan_vertex_cap, 0, (nv - s->fan_vertex_cap) * sizeof *vstamp);
            s->fan_vstamp = vstamp;
        }
        uint32_t *vlocal = vstamp ? realloc(s->fan_vlocal, nv * sizeof *vlocal) : NULL;
        if (!vlocal)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu vertices' normals", nv);
        s->fan_vlocal = vlocal;
        s->fan_vertex_cap = nv;
    }
    return MS_OK;
}

/* The normals of every fan vertex, from its fan. */
static void make_fans(ms_render_split *s, uint32_t fan_vertices)
{
    for (uint32_t v = 0; v < fan_vertices; ++v) {
        uint32_t first = s->fan_start[v], f = s->fan_start[v + 1] - first;
        uint32_t *fan = &s->fan[first];
        for (uint32_t a = 1; a < f; ++a) { /* ascending already with runs */
            uint32_t x = fan[a], b = a;
            for (; b > 0 && fan[b - 1] > x; --b)
                fan[b] = fan[b - 1];
            fan[b] = x;
        }
        fan_normals(s, s->mesh, fan, f);
        s->fans_made++;
    }
}

ms_status ms_render_split_normals(ms_render_split *s, const uint32_t *vertices, uint32_t vertex_count,
                                  const uint32_t *around, uint32_t around_count, ms_error *err)
{
    const ms_view_mesh *mesh = s->mesh;
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    s->fans_made = s->faces_made = 0;
    ms_status st = normals_room(s, nv, nt, err);
    if (st != MS_OK)
        return st;
    if (++s->fan_pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->fan_vstamp, 0, s->fan_vertex_cap * sizeof *s->fan_vstamp);
        s->fan_pass = 1;
    }
    /* the vertices asked about, numbered: only their fans are made */
    uint32_t fan_vertices = vertex_count;
    if (!ms_render_grow((void **)&s->fan_start, &s->fan_start_cap, (size_t)fan_vertices + 2, sizeof *s->fan_start))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the normals' fans");
    for (uint32_t i = 0; i < fan_vertices; ++i) {
        uint32_t v = vertices[i];
        s->fan_vstamp[v] = s->fan_pass;
        s->fan_vlocal[v] = i;
        s->fan_start[i + 1] = 0;
    }
    /* the corners of the cells around at those vertices, counted; the faces
     * of their triangles (no other triangle is in a fan made) */
    size_t corners = 0;
    for (uint32_t j = 0; j < around_count; ++j) {
        uint32_t k = around[j], count = s->present_start[k + 1] - s->present_start[k];
        for (uint32_t i = 0; i < count; ++i) {
            size_t t = ms_render_split_triangle(s, k, i);
            if (s->runs && (st = check_triangle(mesh, t, s->present[k], err)) != MS_OK)
                return st;
            size_t hits = 0;
            for (int c = 0; c < 3; ++c) {
                uint32_t v = mesh->triangles[3 * t + (size_t)c];
                if (s->fan_vstamp[v] == s->fan_pass) {
                    s->fan_start[s->fan_vlocal[v] + 1]++;
                    hits++;
                }
            }
            if (hits) {
                make_face(s, mesh, t);
                s->faces_made++;
                corners += hits;
            }
        }
    }
    if (!ms_render_grow((void **)&s->fan, &s->fan_corner_cap, corners ? corners : 1, sizeof *s->fan))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the normals' fans");
    s->fan_start[0] = 0;
    uint32_t widest = 0;
    for (uint32_t v = 0; v < fan_vertices; ++v) {
        uint32_t f = s->fan_start[v + 1];
        widest = f > widest ? f : widest;
        s->fan_start[v + 1] += s->fan_start[v];
    }
    /* fill in ascending corner order (around is ascending, so are its cells'
     * triangles with runs; without, each fan is sorted below): fan_start[v]
     * walks up to the next vertex's start, then is restored */
    for (uint32_t j = 0; j < around_count; ++j) {
        uint32_t k = around[j], count = s->present_start[k + 1] - s->present_start[k];
        for (uint32_t i = 0; i < count; ++i) {
            size_t t = ms_render_split_triangle(s, k, i);
            for (size_t c = 3 * t; c < 3 * t + 3; ++c) {
                uint32_t v = mesh->triangles[c];
                if (s->fan_vstamp[v] == s->fan_pass)
                    s->fan[s->fan_start[s->fan_vlocal[v]]++] = (uint32_t)c;
            }
        }
    }
    for (uint32_t v = fan_vertices; v > 0; --v)
        s->fan_start[v] = s->fan_start[v - 1];
    s->fan_start[0] = 0;
    if (widest > s->fan_cap) {
        uint64_t *keys = realloc(s->fan_keys, 2 * (size_t)widest * sizeof *keys);
        if (keys)
            s->fan_keys = keys;
        uint32_t *parent = keys ? realloc(s->fan_parent, widest * sizeof *parent) : NULL;
        if (parent)
            s->fan_parent = parent;
        uint8_t *parity = parent ? realloc(s->fan_parity, widest * sizeof *parity) : NULL;
        if (parity)
            s->fan_parity = parity;
        double *sum = parity ? realloc(s->fan_sum, 3 * (size_t)widest * sizeof *sum) : NULL;
        if (!sum)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for a fan of %u triangles", widest);
        s->fan_sum = sum;
        s->fan_cap = widest;
    }
    make_fans(s, fan_vertices);
    return MS_OK;
}
