/* A frame's stitched mesh split by drawing cell (ms_render_internal.h).
 *
 * Triangles are grouped by triangle_cell with one stable radix sort per frame
 * (ms_radix_sort_pairs; arrays sized by the frame's triangles and drawing cells, never by the
 * model's cell count, which may be millions); each
 * cell's vertices are numbered in the order its triangles first use them, so the
 * same cell content always gives the same arrays and the same hash, and a cell
 * whose drawn triangles did not change is not uploaded again.
 *
 * Corner normals are computed once per frame over the whole stitched mesh, so a
 * vertex on a cell border has the same normals in every cell that draws it; they
 * are part of a cell's hash, so a cell whose normals moved because a neighbour
 * refined (new triangles around a shared border vertex) is uploaded again.
 * Around each vertex the triangles fall into groups joined across smooth
 * manifold edges (a crease, an edge of three or more triangles or a boundary
 * separates them; an edge is a crease when its angle exceeds the crease angle
 * plus both triangles' slack, how far their normals may be off because their
 * corners sit at kd-cell centres, so a coarse level's roughness is not taken
 * for edges), with each face turned to its group's orientation where the
 * stored orientation flips across an edge (a scan's inconsistently wound
 * faces): a cube keeps its edges, and a flipped face neither cancels its
 * neighbours' normals nor darkens. A mesh vertex with several normals is
 * several cell vertices. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_radix_sort.h"
#include "ms_render_internal.h"

void ms_render_split_init(ms_render_split *s, const ms_archive_header *header)
{
    memset(s, 0, sizeof *s);
    s->header = header;
    s->cell_count = header->cell_count;
}

void ms_render_split_free(ms_render_split *s)
{
    free(s->order);
    free(s->sort_keys);
    free(s->present);
    free(s->present_start);
    free(s->local);
    free(s->stamp);
    free(s->face_normal);
    free(s->face_slack);
    free(s->face_rlen);
    free(s->corner_packed);
    free(s->fan);
    free(s->fan_start);
    free(s->fan_keys);
    free(s->fan_parent);
    free(s->fan_parity);
    free(s->fan_sum);
    free(s->vertices);
    free(s->normals);
    free(s->same_next);
    free(s->indices);
    memset(s, 0, sizeof *s);
}

/* Grows *array to hold at least need elements of size bytes (contents kept). */
static bool grow(void **array, size_t *cap, size_t need, size_t size)
{
    if (need <= *cap)
        return true;
    size_t cap2 = *cap ? *cap : 64;
    while (cap2 < need)
        cap2 *= 2;
    void *p = realloc(*array, cap2 * size);
    if (!p)
        return false;
    *array = p;
    *cap = cap2;
    return true;
}

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

/* The corner normals of the whole mesh into s->corner_packed. */
static ms_status corner_normals(ms_render_split *s, const ms_view_mesh *mesh, ms_error *err)
{
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
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
        if (rlen)
            s->face_rlen = rlen;
        uint32_t *fan = rlen ? realloc(s->fan, 3 * nt * sizeof *fan) : NULL;
        if (!fan)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu triangles' normals", nt);
        s->fan = fan;
        s->triangle_normal_cap = nt;
    }
    if (nv + 1 > s->fan_start_cap) {
        uint32_t *start = realloc(s->fan_start, (nv + 1) * sizeof *start);
        if (!start)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu vertices' normals", nv);
        s->fan_start = start;
        s->fan_start_cap = nv + 1;
    }
    if (nt == 0)
        return MS_OK;
    const double *p = mesh->positions;
    /* A vertex decoded at kd-level l sits at its kd-cell's centre, and the
     * vertex at full precision at the centre of one of the cell's grid cells:
     * at most half the diagonal of (width - 1) grid units away on each axis
     * (0 at full precision). */
    double level_error[64] = {0};
    unsigned bits = s->header->bits, full = 3 * bits;
    double unit = s->header->box_side / (double)(1u << bits);
    for (unsigned level = 0; level < full && level < 64; ++level) {
        double d2 = 0.0;
        for (unsigned a = 0; a < 3; ++a) {
            double w = (double)(1u << (bits - (level + 2u - a) / 3u)) - 1.0;
            d2 += w * w;
        }
        level_error[level] = 0.5 * unit * sqrt(d2);
    }
    memset(s->fan_start, 0, (nv + 1) * sizeof *s->fan_start);
    for (size_t t = 0; t < nt; ++t) {
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
        /* its corners' decode error, turned into an angle when an edge asks
         * (face_slack) */
        double e = 0.0;
        if (mesh->levels)
            for (int k = 0; k < 3; ++k) {
                unsigned level = mesh->levels[tri[k]];
                double ek = level < 64 ? level_error[level] : 0.0;
                e = ek > e ? ek : e;
            }
        s->face_slack[t] = -e;
        for (int k = 0; k < 3; ++k)
            s->fan_start[tri[k] + 1]++;
    }
    uint32_t widest = 0;
    for (size_t v = 0; v < nv; ++v) {
        uint32_t f = s->fan_start[v + 1];
        widest = f > widest ? f : widest;
        s->fan_start[v + 1] += s->fan_start[v];
    }
    /* fill: fan_start[v] walks up to the next vertex's start, then is restored */
    for (size_t corner = 0; corner < 3 * nt; ++corner)
        s->fan[s->fan_start[mesh->triangles[corner]]++] = (uint32_t)corner;
    for (size_t v = nv; v > 0; --v)
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
    for (size_t v = 0; v < nv; ++v) {
        uint32_t first = s->fan_start[v], f = s->fan_start[v + 1] - first;
        if (f)
            fan_normals(s, mesh, &s->fan[first], f);
    }
    return MS_OK;
}

ms_status ms_render_split_frame(ms_render_split *s, const ms_view_mesh *mesh, double crease_angle_deg,
                                ms_error *err)
{
    s->mesh = NULL;
    s->present_count = 0;
    if (!mesh)
        return ms_error_set(err, MS_ERR_ARG, "render: no mesh");
    if (!(crease_angle_deg >= 0.0 && crease_angle_deg <= 180.0))
        return ms_error_set(err, MS_ERR_ARG, "render: crease angle %g degrees (0 to 180)", crease_angle_deg);
    /* 180 joins every manifold edge: the cosine's floor, whatever the rounding */
    s->crease_cos = crease_angle_deg >= 180.0 ? -2.0 : cos(crease_angle_deg * M_PI / 180.0);
    s->crease_rad = crease_angle_deg * M_PI / 180.0;
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
    if (nv >= UINT32_MAX || nt >= UINT32_MAX / 3)
        return ms_error_set(err, MS_ERR_ARG, "render: mesh of %zu vertices, %zu triangles too large", nv, nt);
    if ((nv && !mesh->positions) || (nt && (!mesh->triangles || !mesh->triangle_cell)))
        return ms_error_set(err, MS_ERR_ARG, "render: mesh arrays missing");
    for (size_t i = 0; i < 3 * nv; ++i)
        if (!isfinite(mesh->positions[i]))
            return ms_error_set(err, MS_ERR_ARG, "render: vertex %zu is not finite", i / 3);
    for (size_t t = 0; t < nt; ++t) {
        if (mesh->triangle_cell[t] >= s->cell_count)
            return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu drawn by cell %u of %u", t,
                                mesh->triangle_cell[t], s->cell_count);
        for (int k = 0; k < 3; ++k)
            if (mesh->triangles[3 * t + (size_t)k] >= nv)
                return ms_error_set(err, MS_ERR_ARG, "render: triangle %zu uses vertex %u of %zu", t,
                                    mesh->triangles[3 * t + (size_t)k], nv);
    }
    size_t local_cap = s->vertex_cap, order_cap = s->order_cap;
    if (!grow((void **)&s->order, &order_cap, nt ? nt : 1, sizeof *s->order) ||
        (order_cap != s->order_cap &&
         !grow((void **)&s->sort_keys, &s->order_cap, order_cap, sizeof *s->sort_keys)) ||
        !grow((void **)&s->local, &local_cap, nv ? nv : 1, sizeof *s->local))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu triangles", nt);
    if (local_cap != s->vertex_cap) {
        uint32_t *stamp = realloc(s->stamp, local_cap * sizeof *stamp);
        if (!stamp)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu vertices", nv);
        memset(stamp + s->vertex_cap, 0, (local_cap - s->vertex_cap) * sizeof *stamp);
        s->stamp = stamp;
        s->vertex_cap = local_cap;
    }
    /* the triangles by cell, in their order within a cell (a stable radix sort on
     * as many bits as the model's largest cell id needs) */
    uint32_t *order = s->order;
    for (size_t t = 0; t < nt; ++t) {
        order[t] = (uint32_t)t;
        s->sort_keys[t] = mesh->triangle_cell[t];
    }
    unsigned key_bits = 1;
    while (key_bits < 32 && (s->cell_count - 1) >> key_bits)
        key_bits++;
    ms_status sorted = ms_radix_sort_pairs(s->sort_keys, order, nt, key_bits, err);
    if (sorted != MS_OK)
        return sorted;
    /* the runs of equal cells */
    for (size_t i = 0; i < nt; ++i) {
        uint32_t cell = mesh->triangle_cell[order[i]];
        if (i > 0 && cell == s->present[s->present_count - 1])
            continue;
        size_t cap = s->present_cap;
        if (!grow((void **)&s->present, &cap, (size_t)s->present_count + 2, sizeof *s->present) ||
            (cap != s->present_cap &&
             !grow((void **)&s->present_start, &s->present_cap, cap, sizeof *s->present_start)))
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the frame's cells");
        s->present_start[s->present_count] = (uint32_t)i;
        s->present[s->present_count++] = cell;
    }
    if (s->present_count)
        s->present_start[s->present_count] = (uint32_t)nt;
    ms_status st = corner_normals(s, mesh, err);
    if (st != MS_OK)
        return st;
    s->mesh = mesh;
    return MS_OK;
}

/* 64-bit hash of a byte array whose size is a multiple of 4: two independent
 * multiply-xorshift lanes over 8-byte words (fast, well mixed; not
 * cryptographic: a collision only keeps a cell's previous mesh). */
#define HASH_MULTIPLIER 0x9E3779B97F4A7C15ull

static uint64_t hash_bytes(uint64_t h, const void *data, size_t size)
{
    const unsigned char *p = data;
    uint64_t a = h, b = h ^ 0x6A09E667F3BCC909ull;
    size_t i = 0;
    for (; i + 16 <= size; i += 16) {
        uint64_t x, y;
        memcpy(&x, p + i, 8);
        memcpy(&y, p + i + 8, 8);
        a = (a ^ x) * HASH_MULTIPLIER;
        a ^= a >> 29;
        b = (b ^ y) * HASH_MULTIPLIER;
        b ^= b >> 29;
    }
    for (; i + 4 <= size; i += 4) {
        uint32_t w;
        memcpy(&w, p + i, 4);
        a = (a ^ w) * HASH_MULTIPLIER;
        a ^= a >> 29;
    }
    a ^= (b << 31 | b >> 33) * HASH_MULTIPLIER;
    return a ^ a >> 32;
}

ms_status ms_render_split_cell(ms_render_split *s, uint32_t k, const ms_archive_cell *record,
                               ms_render_cell_mesh *out, ms_error *err)
{
    const ms_view_mesh *m = s->mesh;
    uint32_t cell = s->present[k];
    uint32_t first = s->present_start[k], end = s->present_start[k + 1];
    uint32_t tris = end - first;
    if (!grow((void **)&s->indices, &s->cell_triangle_cap, 3 * (size_t)tris, sizeof *s->indices))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
    if (++s->pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->stamp, 0, s->vertex_cap * sizeof *s->stamp);
        s->pass = 1;
    }
    double origin[3], side;
    ms_render_cell_cube(s->header, record, origin, &side);
    uint32_t verts = 0;
    for (uint32_t i = first; i < end; ++i) {
        size_t t = s->order[i];
        const uint32_t *tri = &m->triangles[3 * t];
        for (int c = 0; c < 3; ++c) {
            uint32_t v = tri[c], packed = s->corner_packed[3 * t + (size_t)c];
            /* the cell vertex of this mesh vertex with this normal, if any (a
             * chain of one in smooth parts, a few at creases) */
            uint32_t found = UINT32_MAX;
            if (s->stamp[v] == s->pass)
                for (uint32_t at = s->local[v]; at != UINT32_MAX; at = s->same_next[at])
                    if (s->normals[at] == packed) {
                        found = at;
                        break;
                    }
            if (found == UINT32_MAX) {
                size_t cap = s->cell_normal_cap;
                if (!grow((void **)&s->vertices, &s->cell_vertex_cap, 3 * ((size_t)verts + 1),
                          sizeof *s->vertices) ||
                    !grow((void **)&s->normals, &cap, (size_t)verts + 1, sizeof *s->normals) ||
                    (cap != s->cell_normal_cap &&
                     !grow((void **)&s->same_next, &s->cell_normal_cap, cap, sizeof *s->same_next)))
                    return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
                /* a new head of v's chain: the first-use order is kept in the arrays */
                s->same_next[verts] = s->stamp[v] == s->pass ? s->local[v] : UINT32_MAX;
                s->stamp[v] = s->pass;
                s->local[v] = verts;
                for (int a = 0; a < 3; ++a)
                    s->vertices[3 * (size_t)verts + (size_t)a] =
                        (float)((m->positions[3 * (size_t)v + (size_t)a] - origin[a]) / side);
                s->normals[verts] = packed;
                found = verts++;
            }
            s->indices[3 * (size_t)(i - first) + (size_t)c] = found;
        }
    }
    uint32_t counts[2] = {verts, tris};
    uint64_t h = hash_bytes(0xCBF29CE484222325ull, counts, sizeof counts);
    h = hash_bytes(h, s->vertices, 3 * (size_t)verts * sizeof *s->vertices);
    h = hash_bytes(h, s->normals, (size_t)verts * sizeof *s->normals);
    h = hash_bytes(h, s->indices, 3 * (size_t)tris * sizeof *s->indices);
    out->cell = cell;
    out->vertex_count = verts;
    out->triangle_count = tris;
    out->vertices = s->vertices;
    out->normals = s->normals;
    out->indices = s->indices;
    out->hash = h;
    return MS_OK;
}
