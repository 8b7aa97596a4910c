/* A frame's stitched mesh split by drawing cell (ms_render_internal.h).
 *
 * A mesh with runs (ms_view_stitch's) already holds each cell's triangles in
 * one run, with a version; without, the triangles are grouped by
 * triangle_cell with one stable radix sort per frame (ms_radix_sort_pairs;
 * arrays sized by the frame's triangles and drawing cells, never by the
 * model's cell count, which may be millions) and each cell's version is a hash
 * of its corners. Each cell's vertices are numbered in the order its triangles
 * first use them, so the same cell content always gives the same arrays and
 * the same hash, and a cell whose drawn triangles did not change is not
 * uploaded again.
 *
 * Corner normals (ms_render_normals.c) are those of the whole stitched mesh,
 * so a vertex on a cell border has the same normals in every cell that draws
 * it; they are part of a cell's hash, so a cell whose normals moved because a
 * neighbour refined (new triangles around a shared border vertex) is uploaded
 * again. A mesh vertex with several normals is several cell vertices. A mesh
 * with colours gives each cell vertex its mesh vertex's colour, hashed too. */
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
    /* A vertex decoded at kd-level l sits at its kd-cell's centre, and the
     * vertex at full precision at the centre of one of the cell's grid cells:
     * at most half the diagonal of (width - 1) grid units away on each axis
     * (0 at full precision). */
    unsigned bits = header->bits, full = 3 * bits;
    double unit = bits < 32 ? header->box_side / (double)(1u << bits) : 0.0;
    for (unsigned level = 0; level < full && level < 64 && bits < 32; ++level) {
        double d2 = 0.0;
        for (unsigned a = 0; a < 3; ++a) {
            double w = (double)(1u << (bits - (level + 2u - a) / 3u)) - 1.0;
            d2 += w * w;
        }
        s->level_error[level] = 0.5 * unit * sqrt(d2);
    }
}

void ms_render_split_free(ms_render_split *s)
{
    free(s->order);
    free(s->sort_keys);
    free(s->present);
    free(s->present_start);
    free(s->present_version);
    free(s->local);
    free(s->stamp);
    free(s->face_normal);
    free(s->face_slack);
    free(s->face_rlen);
    free(s->corner_packed);
    free(s->fan);
    free(s->fan_start);
    free(s->fan_vstamp);
    free(s->fan_vlocal);
    free(s->fan_keys);
    free(s->fan_parent);
    free(s->fan_parity);
    free(s->fan_sum);
    free(s->vertices);
    free(s->normals);
    free(s->same_next);
    free(s->indices);
    free(s->colours);
    memset(s, 0, sizeof *s);
}

bool ms_render_grow(void **array, size_t *cap, size_t need, size_t size)
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

static uint64_t hash_bytes(uint64_t h, const void *data, size_t size);

/* One more present cell (its first entry of order, or triangle with runs). */
static ms_status add_present(ms_render_split *s, uint32_t cell, uint32_t first, uint64_t version, ms_error *err)
{
    size_t cap = s->present_cap, cap2 = cap, cap3 = cap;
    if (!ms_render_grow((void **)&s->present, &cap, (size_t)s->present_count + 2, sizeof *s->present) ||
        (cap != s->present_cap &&
         (!ms_render_grow((void **)&s->present_version, &cap2, cap, sizeof *s->present_version) ||
          !ms_render_grow((void **)&s->present_start, &cap3, cap, sizeof *s->present_start))))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the frame's cells");
    s->present_cap = cap;
    s->present_start[s->present_count] = first;
    s->present_version[s->present_count] = version;
    s->present[s->present_count++] = cell;
    return MS_OK;
}

/* What a run's version is turned by when the mesh has colours: a cell's
 * version changes when the mesh gains or loses them. */
#define COLOURED_VERSION 0xC0105C0105C01051ull

/* The cells of a mesh with runs: the runs checked, the empty ones left out. */
static ms_status split_runs(ms_render_split *s, const ms_view_mesh *mesh, ms_error *err)
{
    size_t nt = mesh->triangle_count;
    if (!mesh->run_cell || !mesh->run_first || !mesh->run_version || mesh->run_first[0] != 0 ||
        mesh->run_first[mesh->run_count] != nt)
        return ms_error_set(err, MS_ERR_ARG, "render: the mesh's runs do not cover its %zu triangles", nt);
    for (size_t k = 0; k < mesh->run_count; ++k) {
        uint32_t cell = mesh->run_cell[k], first = mesh->run_first[k], end = mesh->run_first[k + 1];
        if (cell >= s->cell_count || (k > 0 && cell <= mesh->run_cell[k - 1]) || end < first)
            return ms_error_set(err, MS_ERR_ARG, "render: run %zu (cell %u of %u) out of order", k, cell,
                                s->cell_count);
        if (end == first)
            continue;
        uint64_t version = mesh->run_version[k] ^ (mesh->colours ? COLOURED_VERSION : 0);
        ms_status st = add_present(s, cell, first, version, err);
        if (st != MS_OK)
            return st;
    }
    if (s->present_count)
        s->present_start[s->present_count] = (uint32_t)nt;
    return MS_OK;
}

/* The cells of a mesh without runs: checked whole, sorted, versions hashed. */
static ms_status split_sorted(ms_render_split *s, const ms_view_mesh *mesh, ms_error *err)
{
    size_t nv = mesh->vertex_count, nt = mesh->triangle_count;
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
    size_t order_cap = s->order_cap;
    if (!ms_render_grow((void **)&s->order, &order_cap, nt ? nt : 1, sizeof *s->order) ||
        (order_cap != s->order_cap &&
         !ms_render_grow((void **)&s->sort_keys, &s->order_cap, order_cap, sizeof *s->sort_keys)))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu triangles", nt);
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
    /* the runs of equal cells, each hashed: its corners' positions, levels and colours */
    uint64_t h = 0;
    for (size_t i = 0; i < nt; ++i) {
        uint32_t cell = mesh->triangle_cell[order[i]];
        if (i == 0 || cell != s->present[s->present_count - 1]) {
            if (i > 0)
                s->present_version[s->present_count - 1] = h;
            ms_status st = add_present(s, cell, (uint32_t)i, 0, err);
            if (st != MS_OK)
                return st;
            h = 0x84222325CBF29CE4ull;
        }
        for (int k = 0; k < 3; ++k) {
            uint32_t v = mesh->triangles[3 * (size_t)order[i] + (size_t)k];
            h = hash_bytes(h, &mesh->positions[3 * (size_t)v], 3 * sizeof *mesh->positions);
            uint32_t level = mesh->levels ? mesh->levels[v] : 0;
            h = hash_bytes(h, &level, sizeof level);
            if (mesh->colours)
                h = hash_bytes(h, &mesh->colours[4 * (size_t)v], 4);
        }
    }
    if (s->present_count) {
        s->present_version[s->present_count - 1] = h;
        s->present_start[s->present_count] = (uint32_t)nt;
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
    size_t local_cap = s->vertex_cap;
    if (!ms_render_grow((void **)&s->local, &local_cap, nv ? nv : 1, sizeof *s->local))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu vertices", nv);
    if (local_cap != s->vertex_cap) {
        uint32_t *stamp = realloc(s->stamp, local_cap * sizeof *stamp);
        if (!stamp)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory to split %zu vertices", nv);
        memset(stamp + s->vertex_cap, 0, (local_cap - s->vertex_cap) * sizeof *stamp);
        s->stamp = stamp;
        s->vertex_cap = local_cap;
    }
    s->runs = mesh->run_count > 0;
    ms_status st = s->runs ? split_runs(s, mesh, err) : split_sorted(s, mesh, err);
    if (st != MS_OK) {
        s->present_count = 0;
        return st;
    }
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
    if (!ms_render_grow((void **)&s->indices, &s->cell_triangle_cap, 3 * (size_t)tris, sizeof *s->indices))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
    if (++s->pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->stamp, 0, s->vertex_cap * sizeof *s->stamp);
        s->pass = 1;
    }
    double origin[3], side;
    ms_render_cell_cube(s->header, record, origin, &side);
    uint32_t verts = 0;
    for (uint32_t i = first; i < end; ++i) {
        size_t t = ms_render_split_triangle(s, k, i - first);
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
                if (!ms_render_grow((void **)&s->vertices, &s->cell_vertex_cap, 3 * ((size_t)verts + 1),
                          sizeof *s->vertices) ||
                    !ms_render_grow((void **)&s->normals, &cap, (size_t)verts + 1, sizeof *s->normals) ||
                    (cap != s->cell_normal_cap &&
                     !ms_render_grow((void **)&s->same_next, &s->cell_normal_cap, cap, sizeof *s->same_next)))
                    return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
                /* a new head of v's chain: the first-use order is kept in the arrays */
                s->same_next[verts] = s->stamp[v] == s->pass ? s->local[v] : UINT32_MAX;
                s->stamp[v] = s->pass;
                s->local[v] = verts;
                for (int a = 0; a < 3; ++a)
                    s->vertices[3 * (size_t)verts + (size_t)a] =
                        (float)((m->positions[3 * (size_t)v + (size_t)a] - origin[a]) / side);
                s->normals[verts] = packed;
                if (m->colours) {
                    if (!ms_render_grow((void **)&s->colours, &s->cell_colour_cap, (size_t)verts + 1,
                                        sizeof *s->colours))
                        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", cell);
                    memcpy(&s->colours[verts], &m->colours[4 * (size_t)v], 4);
                }
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
    if (m->colours)
        h = hash_bytes(h, s->colours, (size_t)verts * sizeof *s->colours);
    out->cell = cell;
    out->vertex_count = verts;
    out->triangle_count = tris;
    out->vertices = s->vertices;
    out->normals = s->normals;
    out->indices = s->indices;
    out->colours = m->colours ? s->colours : NULL;
    out->hash = h;
    return MS_OK;
}
