/* The renderer's upload rule (ms_render.h, "Uploads"; docs/RENDERER.md):
 * the same frame twice queues nothing; refining one cell queues exactly the cells
 * whose drawn triangles or vertex normals changed (found here independently, by
 * comparing each cell's triangles as world positions with the packed normals
 * of their corners, split at the crease angle: corner_normals); each cell
 * uploads one vertex per distinct (mesh vertex, normal) of its corners; with a
 * small budget no call sends more
 * than the budget, every cell completes, and until a cell's new mesh is wholly
 * on the GPU the picture is exactly the old one; a cell leaving the frame stops
 * drawing at once; APO prefixes are queued only when their levels change. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_render.h"
#include "ms_test.h"
#include "ms_test_render.h"

#define WIDTH 160
#define HEIGHT 120

typedef struct fixture {
    char dir[512];
    ms_archive *archive;
    ms_view *view;
    ms_render *render;
    ms_camera camera;
    uint32_t cell_count;
} fixture;

static ms_test_gl gl;
static fixture fx;

/* One triangle as its three world corners, rotated so the smallest corner comes
 * first (orientation kept), then the corners' packed vertex normals in the same
 * order, for comparing cells independently of numbering. */
typedef struct tri_key {
    double p[12];
} tri_key;

/* The crease angle the renderer runs with here (its default; setup checks). */
#define CREASE_DEG 60.0

/* One use of an edge by a triangle with area: the edge's two vertices (lo < hi),
 * whether the triangle walks it from lo to hi, and the triangle. */
typedef struct edge_use {
    uint32_t lo, hi, triangle;
    uint8_t forward;
} edge_use;

static int edge_use_cmp(const void *x, const void *y)
{
    const edge_use *a = x, *b = y;
    if (a->lo != b->lo)
        return a->lo < b->lo ? -1 : 1;
    if (a->hi != b->hi)
        return a->hi < b->hi ? -1 : 1;
    return (a->triangle > b->triangle) - (a->triangle < b->triangle);
}

/* A smooth edge: triangles a and b meet there at most CREASE_DEG apart (b
 * turned over first when it walks the edge the way a does). */
typedef struct join {
    uint32_t lo, hi, a, b;
    uint8_t flipped;
} join;

static uint32_t pack_normal(const double n[3])
{
    double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    uint32_t word = 0;
    if (!(len > 0.0))
        return 0;
    for (int ax = 0; ax < 3; ++ax)
        word |= ((uint32_t)lround(n[ax] / len * 511.0) & 0x3FFu) << (10 * ax);
    return word;
}

/* The mesh's corner normals as the renderer uploads them (docs/RENDERER.md,
 * "Vertex normals"), found here another way: the whole mesh's edges sorted
 * once; an edge used by exactly two triangles with area whose normals (the
 * second turned over if they walk it the same way) are at most CREASE_DEG apart,
 * plus each triangle's slack (how far its normal may be off because its
 * corners are not at full precision), is smooth; around each vertex, a breadth-first walk over the smooth edges
 * at that vertex groups its triangles, each with its sign against the group's
 * first; a group's normal is the signed sum of its triangles' (b - a) x (c - a)
 * in triangle order, and a corner gets it times its own sign, packed to 10-bit
 * components over 511 (GL_INT_2_10_10_10_REV, x low); 0 when undefined.
 * *contradictions counts smooth edges whose signs disagree with their group's
 * (a fan whose flips do not close), where the rule depends on the join order. */
static uint32_t *corner_normals(const ms_view_mesh *m, size_t *contradictions)
{
    const ms_archive_header *h = ms_archive_get_header(fx.archive);
    size_t nt = m->triangle_count, nv = m->vertex_count;
    double *fn = malloc((3 * nt + 1) * sizeof *fn), *slack = malloc((nt + 1) * sizeof *slack);
    assert_true(fn && slack && m->levels);
    edge_use *uses = malloc((3 * nt + 1) * sizeof *uses);
    join *joins = malloc((3 * nt + 1) * sizeof *joins);
    uint32_t *packed = calloc(3 * nt + 1, sizeof *packed);
    assert_true(fn && uses && joins && packed);
    size_t use_count = 0, join_count = 0;
    for (size_t t = 0; t < nt; ++t) {
        const uint32_t *tri = &m->triangles[3 * t];
        const double *a = &m->positions[3 * (size_t)tri[0]], *b = &m->positions[3 * (size_t)tri[1]],
                     *c = &m->positions[3 * (size_t)tri[2]];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double *n = &fn[3 * t];
        n[0] = u[1] * v[2] - u[2] * v[1];
        n[1] = u[2] * v[0] - u[0] * v[2];
        n[2] = u[0] * v[1] - u[1] * v[0];
        /* the slack: the largest distance of a corner from where it lies at
         * full precision (a vertex of kd-level l is its kd-cell's centre, the
         * cell 2^(bits - splits) grid units wide on each axis, splits =
         * (l + 2 - axis) / 3, the full-precision vertex a grid cell's centre
         * inside it), times the longest side, over twice the area: the
         * arctangent is how far the normal may be off */
        double worst = 0.0;
        for (int k = 0; k < 3; ++k) {
            unsigned level = m->levels[tri[k]];
            double d2 = 0.0;
            for (unsigned ax = 0; ax < 3; ++ax) {
                unsigned splits = (level + 2u - ax) / 3u;
                double spare = ldexp(1.0, (int)h->bits - (int)splits) - 1.0;
                d2 += spare * spare;
            }
            double off = 0.5 * (h->box_side / ldexp(1.0, h->bits)) * sqrt(d2);
            worst = off > worst ? off : worst;
        }
        double sides[3] = {u[0] * u[0] + u[1] * u[1] + u[2] * u[2], v[0] * v[0] + v[1] * v[1] + v[2] * v[2],
                           (c[0] - b[0]) * (c[0] - b[0]) + (c[1] - b[1]) * (c[1] - b[1]) + (c[2] - b[2]) * (c[2] - b[2])};
        double longest = sqrt(fmax(sides[0], fmax(sides[1], sides[2])));
        double twice_area = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        slack[t] = worst > 0.0 ? (twice_area > 0.0 ? atan2(worst * longest, twice_area) : M_PI / 2) : 0.0;
        if (n[0] == 0.0 && n[1] == 0.0 && n[2] == 0.0)
            continue; /* no area: on no smooth edge */
        for (int k = 0; k < 3; ++k) {
            uint32_t from = tri[k], to = tri[(k + 1) % 3];
            uses[use_count++] = (edge_use){from < to ? from : to, from < to ? to : from, (uint32_t)t, from < to};
        }
    }
    qsort(uses, use_count, sizeof *uses, edge_use_cmp);
    double floor_cos = CREASE_DEG >= 180.0 ? -2.0 : cos(CREASE_DEG * M_PI / 180.0);
    for (size_t i = 0; i < use_count;) {
        size_t j = i + 1;
        while (j < use_count && uses[j].lo == uses[i].lo && uses[j].hi == uses[i].hi)
            j++;
        if (j - i == 2) {
            const edge_use *x = &uses[i], *y = &uses[i + 1];
            const double *na = &fn[3 * (size_t)x->triangle], *nb = &fn[3 * (size_t)y->triangle];
            uint8_t flipped = x->forward == y->forward;
            double dot = na[0] * nb[0] + na[1] * nb[1] + na[2] * nb[2];
            double cosine = (flipped ? -dot : dot) / (sqrt(na[0] * na[0] + na[1] * na[1] + na[2] * na[2]) *
                                                     sqrt(nb[0] * nb[0] + nb[1] * nb[1] + nb[2] * nb[2]));
            /* the crease angle widened by both normals' slack */
            double widened = CREASE_DEG * M_PI / 180.0 + slack[x->triangle] + slack[y->triangle];
            bool smooth = cosine >= floor_cos || widened >= M_PI || cosine >= cos(widened);
            if (smooth)
                joins[join_count++] = (join){x->lo, x->hi, x->triangle, y->triangle, flipped};
        }
        i = j;
    }
    /* per vertex: its fan (corners, ascending) and its smooth edges */
    size_t *fan_start = calloc(nv + 2, sizeof *fan_start), *join_start = calloc(nv + 2, sizeof *join_start);
    uint32_t *fan = malloc((3 * nt + 1) * sizeof *fan), *at = malloc((2 * join_count + 1) * sizeof *at);
    assert_true(fan_start && join_start && fan && at);
    for (size_t c = 0; c < 3 * nt; ++c)
        fan_start[m->triangles[c] + 2]++;
    for (size_t k = 0; k < join_count; ++k)
        join_start[joins[k].lo + 2]++, join_start[joins[k].hi + 2]++;
    for (size_t v = 0; v < nv; ++v) {
        fan_start[v + 2] += fan_start[v + 1];
        join_start[v + 2] += join_start[v + 1];
    }
    for (size_t c = 0; c < 3 * nt; ++c)
        fan[fan_start[m->triangles[c] + 1]++] = (uint32_t)c;
    for (size_t k = 0; k < join_count; ++k) {
        at[join_start[joins[k].lo + 1]++] = (uint32_t)k;
        at[join_start[joins[k].hi + 1]++] = (uint32_t)k;
    }
    /* fan_start[v] .. fan_start[v + 1] now (likewise join_start) */
    uint32_t *stamp = calloc(nt + 1, sizeof *stamp), *group = malloc((nt + 1) * sizeof *group);
    int8_t *sign = malloc(nt + 1);
    uint32_t *queue = malloc((3 * nt + 1) * sizeof *queue);
    double *sum = malloc((3 * nt + 3) * sizeof *sum);
    assert_true(stamp && group && sign && queue && sum);
    *contradictions = 0;
    for (size_t v = 0; v < nv; ++v) {
        uint32_t groups = 0;
        for (size_t f = fan_start[v]; f < fan_start[v + 1]; ++f) {
            uint32_t t = fan[f] / 3;
            if (stamp[t] == v + 1)
                continue;
            stamp[t] = (uint32_t)v + 1, group[t] = groups, sign[t] = 1;
            size_t head = 0, tail = 0;
            queue[tail++] = t;
            while (head < tail) {
                uint32_t here = queue[head++];
                for (size_t k = join_start[v]; k < join_start[v + 1]; ++k) {
                    const join *e = &joins[at[k]];
                    if (e->a != here && e->b != here)
                        continue;
                    uint32_t there = e->a == here ? e->b : e->a;
                    int8_t want = (int8_t)(e->flipped ? -sign[here] : sign[here]);
                    if (stamp[there] == v + 1) {
                        *contradictions += sign[there] != want;
                        continue;
                    }
                    stamp[there] = (uint32_t)v + 1, group[there] = groups, sign[there] = want;
                    queue[tail++] = there;
                }
            }
            sum[3 * (size_t)groups] = sum[3 * (size_t)groups + 1] = sum[3 * (size_t)groups + 2] = 0.0;
            groups++;
        }
        for (size_t f = fan_start[v]; f < fan_start[v + 1]; ++f) {
            uint32_t t = fan[f] / 3;
            for (int ax = 0; ax < 3; ++ax)
                sum[3 * (size_t)group[t] + (size_t)ax] += sign[t] * fn[3 * (size_t)t + (size_t)ax];
        }
        for (size_t f = fan_start[v]; f < fan_start[v + 1]; ++f) {
            uint32_t t = fan[f] / 3;
            const double *g = &sum[3 * (size_t)group[t]];
            double n[3] = {sign[t] * g[0], sign[t] * g[1], sign[t] * g[2]};
            packed[fan[f]] = pack_normal(n);
        }
    }
    free(fn);
    free(slack);
    free(uses);
    free(joins);
    free(fan_start);
    free(join_start);
    free(fan);
    free(at);
    free(stamp);
    free(group);
    free(sign);
    free(queue);
    free(sum);
    return packed;
}

static int corner_cmp(const double *a, const double *b)
{
    for (int k = 0; k < 3; ++k)
        if (a[k] != b[k])
            return a[k] < b[k] ? -1 : 1;
    return 0;
}

static int tri_cmp(const void *x, const void *y)
{
    const tri_key *a = x, *b = y;
    for (int k = 0; k < 12; ++k)
        if (a->p[k] != b->p[k])
            return a->p[k] < b->p[k] ? -1 : 1;
    return 0;
}

/* Sorted triangle keys of every cell: keys[start[c] .. start[c + 1]). */
typedef struct cell_tris {
    tri_key *keys;
    size_t *start;
} cell_tris;

static void cell_tris_build(const ms_view_mesh *m, uint32_t cells, cell_tris *out)
{
    out->keys = malloc((m->triangle_count + 1) * sizeof *out->keys);
    out->start = calloc((size_t)cells + 1, sizeof *out->start);
    size_t *fill = calloc((size_t)cells + 1, sizeof *fill);
    assert_true(out->keys && out->start && fill);
    for (size_t t = 0; t < m->triangle_count; ++t)
        out->start[m->triangle_cell[t] + 1]++;
    for (uint32_t c = 0; c < cells; ++c)
        out->start[c + 1] += out->start[c];
    memcpy(fill, out->start, ((size_t)cells + 1) * sizeof *fill);
    size_t contradictions;
    uint32_t *normals = corner_normals(m, &contradictions);
    assert_int_equal(contradictions, 0); /* the rule is the same whatever the join order */
    for (size_t t = 0; t < m->triangle_count; ++t) {
        const double *corner[3];
        int first = 0;
        for (int k = 0; k < 3; ++k)
            corner[k] = &m->positions[3 * (size_t)m->triangles[3 * t + (size_t)k]];
        for (int k = 1; k < 3; ++k)
            if (corner_cmp(corner[k], corner[first]) < 0)
                first = k;
        tri_key *key = &out->keys[fill[m->triangle_cell[t]]++];
        for (int k = 0; k < 3; ++k) {
            memcpy(&key->p[3 * k], corner[(first + k) % 3], 3 * sizeof(double));
            key->p[9 + k] = normals[3 * t + (size_t)((first + k) % 3)];
        }
    }
    free(normals);
    free(fill);
    for (uint32_t c = 0; c < cells; ++c)
        qsort(&out->keys[out->start[c]], out->start[c + 1] - out->start[c], sizeof *out->keys, tri_cmp);
}

static void cell_tris_free(cell_tris *t)
{
    free(t->keys);
    free(t->start);
}

/* A corner as the cell vertex it becomes: its cell, mesh vertex and packed
 * normal. */
typedef struct corner_key {
    uint32_t cell, vertex, normal;
} corner_key;

static int corner_key_cmp(const void *x, const void *y)
{
    const corner_key *a = x, *b = y;
    if (a->cell != b->cell)
        return a->cell < b->cell ? -1 : 1;
    if (a->vertex != b->vertex)
        return a->vertex < b->vertex ? -1 : 1;
    return (a->normal > b->normal) - (a->normal < b->normal);
}

/* The vertices each cell uploads: its corners' distinct (mesh vertex, packed
 * normal) pairs (a vertex with several normals is several cell vertices). */
static void vertices_per_cell(const ms_view_mesh *m, uint32_t cells, size_t *count)
{
    memset(count, 0, cells * sizeof *count);
    size_t contradictions, n = 3 * m->triangle_count;
    uint32_t *normals = corner_normals(m, &contradictions);
    assert_int_equal(contradictions, 0);
    corner_key *keys = malloc((n + 1) * sizeof *keys);
    assert_non_null(keys);
    for (size_t c = 0; c < n; ++c)
        keys[c] = (corner_key){m->triangle_cell[c / 3], m->triangles[c], normals[c]};
    qsort(keys, n, sizeof *keys, corner_key_cmp);
    for (size_t i = 0; i < n; ++i)
        if (i == 0 || corner_key_cmp(&keys[i - 1], &keys[i]) != 0)
            count[keys[i].cell]++;
    free(keys);
    free(normals);
}

/* Distinct mesh vertices of all cells' triangles, counted once per cell (what
 * one normal per vertex would upload), for the report. */
static size_t plain_vertices(const ms_view_mesh *m)
{
    size_t n = 3 * m->triangle_count, count = 0;
    corner_key *keys = malloc((n + 1) * sizeof *keys);
    assert_non_null(keys);
    for (size_t c = 0; c < n; ++c)
        keys[c] = (corner_key){m->triangle_cell[c / 3], m->triangles[c], 0};
    qsort(keys, n, sizeof *keys, corner_key_cmp);
    for (size_t i = 0; i < n; ++i)
        count += i == 0 || corner_key_cmp(&keys[i - 1], &keys[i]) != 0;
    free(keys);
    return count;
}

static bool same_cell(const cell_tris *a, const cell_tris *b, uint32_t c)
{
    size_t na = a->start[c + 1] - a->start[c], nb = b->start[c + 1] - b->start[c];
    return na == nb && memcmp(&a->keys[a->start[c]], &b->keys[b->start[c]], na * sizeof(tri_key)) == 0;
}

/* The same triangles, whatever their corners' normals (keys sort by position
 * first, and no two triangles of a cell share all three corners). */
static bool same_cell_triangles(const cell_tris *a, const cell_tris *b, uint32_t c)
{
    size_t na = a->start[c + 1] - a->start[c], nb = b->start[c + 1] - b->start[c];
    if (na != nb)
        return false;
    for (size_t i = 0; i < na; ++i)
        if (memcmp(a->keys[a->start[c] + i].p, b->keys[b->start[c] + i].p, 9 * sizeof(double)) != 0)
            return false;
    return true;
}

static void set_frame(const ms_view_mesh *mesh, const ms_core_apo_chunk *apo, size_t count)
{
    ms_error err;
    if (ms_render_set_frame(fx.render, mesh, apo, count, &err) != MS_OK)
        fail_msg("%s", err.text);
}

static ms_render_upload_stats upload(uint64_t budget)
{
    ms_render_upload_stats s;
    ms_error err;
    if (ms_render_upload(fx.render, budget, &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_true(s.bytes <= budget);
    return s;
}

static ms_render_draw_stats draw(float *ids)
{
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    ms_render_options o;
    ms_render_options_default(&o);
    o.shading = MS_SHADING_CELL_ID;
    ms_render_draw_stats s;
    ms_error err;
    if (ms_render_draw(fx.render, &fx.camera, &o, &s, &err) != MS_OK)
        fail_msg("%s", err.text);
    if (ids)
        ms_test_fbo_read(&fbo, ids, NULL);
    ms_test_fbo_free(&fbo);
    return s;
}

static uint64_t mesh_bytes(const ms_view_mesh *m, uint32_t cells, const bool *which)
{
    size_t *verts = malloc(cells * sizeof *verts);
    size_t *tris = calloc(cells, sizeof *tris);
    assert_true(verts && tris);
    vertices_per_cell(m, cells, verts);
    for (size_t t = 0; t < m->triangle_count; ++t)
        tris[m->triangle_cell[t]]++;
    uint64_t bytes = 0;
    for (uint32_t c = 0; c < cells; ++c)
        if (!which || which[c])
            bytes += 16ull * verts[c] + 12ull * tris[c]; /* position + packed normal; indices */
    free(verts);
    free(tris);
    return bytes;
}

static uint32_t drawing_cells(const ms_view_mesh *m, uint32_t cells)
{
    bool *seen = calloc(cells, 1);
    uint32_t n = 0;
    for (size_t t = 0; t < m->triangle_count; ++t)
        if (!seen[m->triangle_cell[t]])
            seen[m->triangle_cell[t]] = true, n++;
    free(seen);
    return n;
}

/* The first frame, in pieces of 4 KiB: never more per call, every cell completes,
 * exactly the frame's bytes; then the same frame again queues nothing. */
static void test_budget_and_same_frame(void **state)
{
    (void)state;
    ms_view_mesh mesh = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &mesh);
    uint32_t cells = drawing_cells(&mesh, fx.cell_count);
    set_frame(&mesh, NULL, 0);
    uint64_t total = 0, calls = 0, completed = 0;
    for (;;) {
        ms_render_upload_stats s = upload(4096);
        total += s.bytes;
        completed += s.cells_completed;
        calls++;
        if (s.cells_pending == 0)
            break;
        assert_int_equal(s.bytes, 4096); /* a pending cell never leaves budget unused */
        assert_true(calls < 100000);
    }
    uint64_t want = mesh_bytes(&mesh, fx.cell_count, NULL);
    print_message("first frame: %u cells, %llu bytes in %llu calls of at most 4096 (%zu triangles, %llu cell "
                  "vertices, %zu with one normal per mesh vertex)\n",
                  cells, (unsigned long long)total, (unsigned long long)calls, mesh.triangle_count,
                  (unsigned long long)((want - 12ull * mesh.triangle_count) / 16), plain_vertices(&mesh));
    assert_int_equal(total, want);
    assert_int_equal(completed, cells);
    ms_render_draw_stats d = draw(NULL);
    assert_int_equal(d.cells_drawn, cells);
    assert_int_equal(d.triangles_drawn, mesh.triangle_count);
    /* the same frame again, and a copy of it (other arrays, same content) */
    set_frame(&mesh, NULL, 0);
    ms_render_upload_stats s = upload(1);
    assert_int_equal(s.bytes, 0);
    assert_int_equal(s.cells_pending, 0);
    assert_int_equal(s.cells_completed, 0);
    ms_view_mesh again = {0};
    ms_error err;
    assert_int_equal(ms_view_stitch(fx.view, NULL, &again, &err), MS_OK);
    set_frame(&again, NULL, 0);
    s = upload(UINT64_MAX);
    assert_int_equal(s.bytes, 0);
    assert_int_equal(s.cells_pending, 0);
    ms_view_mesh_free(&again);
    ms_view_mesh_free(&mesh);
}

/* A shown cell that can refine and draws triangles. */
static uint32_t refinable_cell(const ms_view_mesh *mesh, uint32_t except)
{
    uint32_t best = UINT32_MAX;
    size_t best_tris = 0;
    size_t *tris = calloc(fx.cell_count, sizeof *tris);
    for (size_t t = 0; t < mesh->triangle_count; ++t)
        tris[mesh->triangle_cell[t]]++;
    for (uint32_t c = 0; c < fx.cell_count; ++c)
        if (c != except && ms_view_state(fx.view, c) == MS_VIEW_SHOWN &&
            ms_view_bits(fx.view, c) < ms_view_cell(fx.view, c)->bits_max && tris[c] > best_tris)
            best = c, best_tris = tris[c];
    free(tris);
    assert_true(best != UINT32_MAX);
    return best;
}

/* Refining one cell queues exactly the cells whose triangles or vertex normals
 * changed, and until each is complete the old picture stays. */
static void test_refinement_queues_changed_cells(void **state)
{
    (void)state;
    ms_view_mesh before = {0}, after = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &before);
    set_frame(&before, NULL, 0);
    upload(UINT64_MAX);
    size_t np = (size_t)WIDTH * HEIGHT;
    float *old_ids = malloc(np * 4 * sizeof(float)), *ids = malloc(np * 4 * sizeof(float));
    assert_true(old_ids && ids);
    ms_render_draw_stats d0 = draw(old_ids);
    assert_int_equal(d0.triangles_drawn, before.triangle_count);

    uint32_t cell = refinable_cell(&before, UINT32_MAX);
    ms_error err;
    assert_int_equal(ms_view_set_bits(fx.view, cell, ms_view_bits(fx.view, cell) + 1, &err), MS_OK);
    assert_int_equal(ms_view_stitch(fx.view, NULL, &after, &err), MS_OK);
    cell_tris a, b;
    cell_tris_build(&before, fx.cell_count, &a);
    cell_tris_build(&after, fx.cell_count, &b);
    bool *changed = calloc(fx.cell_count, 1);
    uint32_t changed_count = 0, triangles_changed = 0;
    for (uint32_t c = 0; c < fx.cell_count; ++c) {
        if (!same_cell(&a, &b, c))
            changed[c] = true, changed_count++;
        triangles_changed += !same_cell_triangles(&a, &b, c);
    }
    assert_true(triangles_changed <= changed_count);
    assert_true(changed[cell]);
    assert_true(changed_count < drawing_cells(&after, fx.cell_count));
    uint64_t want = mesh_bytes(&after, fx.cell_count, changed);
    set_frame(&after, NULL, 0);
    /* nothing current changed yet: the same picture, the same triangles */
    ms_render_draw_stats d1 = draw(ids);
    assert_int_equal(d1.triangles_drawn, before.triangle_count);
    assert_memory_equal(ids, old_ids, np * 4 * sizeof(float));
    /* a few bytes at a time, smaller than any cell: still the old picture */
    ms_render_upload_stats s = upload(64);
    assert_int_equal(s.bytes, 64);
    assert_int_equal(s.cells_completed, 0);
    assert_int_equal(s.cells_pending, changed_count);
    d1 = draw(ids);
    assert_memory_equal(ids, old_ids, np * 4 * sizeof(float));
    uint64_t total = s.bytes, completed = 0;
    do {
        s = upload(256);
        total += s.bytes;
        completed += s.cells_completed;
    } while (s.cells_pending > 0);
    print_message("refining cell %u: %u cells changed (%u by their triangles, of %u drawing), %llu bytes, expected %llu\n",
                  cell, changed_count, triangles_changed, drawing_cells(&after, fx.cell_count), (unsigned long long)total,
                  (unsigned long long)want);
    assert_int_equal(completed, changed_count);
    assert_int_equal(total, want);
    ms_render_draw_stats d2 = draw(NULL);
    assert_int_equal(d2.triangles_drawn, after.triangle_count);
    free(changed);
    cell_tris_free(&a);
    cell_tris_free(&b);
    free(old_ids);
    free(ids);
    ms_view_mesh_free(&before);
    ms_view_mesh_free(&after);
}

/* A split: the parent leaves the frame and stops drawing at once, before any of
 * its children is uploaded; the children (holes) go up before a refinement of
 * another cell queued with them. */
static void test_leaving_cell_stops_at_once(void **state)
{
    (void)state;
    ms_view_mesh before = {0}, after = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &before);
    set_frame(&before, NULL, 0);
    upload(UINT64_MAX);
    uint32_t parent = UINT32_MAX;
    size_t parent_tris = 0;
    for (uint32_t c = 0; c < fx.cell_count && parent == UINT32_MAX; ++c)
        if (ms_view_state(fx.view, c) == MS_VIEW_SHOWN && ms_view_cell(fx.view, c)->first_child != MS_ARCHIVE_NONE) {
            for (size_t t = 0; t < before.triangle_count; ++t)
                parent_tris += before.triangle_cell[t] == c;
            if (parent_tris)
                parent = c;
        }
    assert_true(parent != UINT32_MAX);
    ms_error err;
    if (ms_view_bits(fx.view, parent) < ms_view_cell(fx.view, parent)->bits_max)
        assert_int_equal(ms_view_set_bits(fx.view, parent, ms_view_cell(fx.view, parent)->bits_max, &err), MS_OK);
    uint32_t other = refinable_cell(&before, parent);
    assert_int_equal(ms_view_set_bits(fx.view, other, ms_view_bits(fx.view, other) + 1, &err), MS_OK);
    assert_int_equal(ms_view_split(fx.view, parent, &err), MS_OK);
    assert_int_equal(ms_view_stitch(fx.view, NULL, &after, &err), MS_OK);
    set_frame(&after, NULL, 0);
    ms_render_draw_stats d = draw(NULL);
    /* the other cells draw what they drew (changed ones their old mesh) */
    size_t others = 0;
    for (size_t t = 0; t < before.triangle_count; ++t)
        others += before.triangle_cell[t] != parent;
    assert_int_equal(d.triangles_drawn, others);
    uint32_t final_cells = drawing_cells(&after, fx.cell_count), drawn = d.cells_drawn, holes = final_cells - drawn;
    assert_true(holes > 0);
    ms_render_upload_stats s;
    do {
        s = upload(8192);
        d = draw(NULL);
        /* while holes remain, whatever completes is a hole */
        if (d.cells_drawn < final_cells)
            assert_int_equal(d.cells_drawn, drawn + s.cells_completed);
        drawn = d.cells_drawn;
    } while (s.cells_pending > 0);
    print_message("split of cell %u: %u new cells uploaded before the refinement of cell %u\n", parent, holes,
                  other);
    assert_int_equal(d.cells_drawn, final_cells);
    assert_int_equal(d.triangles_drawn, after.triangle_count);
    ms_view_mesh_free(&before);
    ms_view_mesh_free(&after);
}

/* APO prefixes: queued when their level count changes, not otherwise; dropping
 * a cell's chunk costs no upload. */
static void test_apo_changes(void **state)
{
    (void)state;
    ms_view_mesh mesh = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &mesh);
    set_frame(&mesh, NULL, 0);
    upload(UINT64_MAX);
    ms_core_apo_chunk *two, *all;
    size_t n_two, n_all;
    ms_test_render_apo(fx.archive, &mesh, 2, false, &two, &n_two);
    ms_test_render_apo(fx.archive, &mesh, 0, false, &all, &n_all);
    assert_true(n_two > 0 && n_two == n_all);
    uint64_t words_two = 0, words_all = 0;
    for (size_t i = 0; i < n_two; ++i) {
        uint32_t t;
        ms_archive_apo_prefix(fx.archive, two[i].cell, 1, &t);
        words_two += t;
        ms_archive_apo_prefix(fx.archive, all[i].cell, all[i].levels - 1, &t);
        words_all += t;
    }
    set_frame(&mesh, two, n_two);
    ms_render_upload_stats s = upload(UINT64_MAX);
    assert_int_equal(s.bytes, 4 * words_two);
    assert_int_equal(s.cells_completed, n_two);
    set_frame(&mesh, two, n_two); /* same levels: nothing */
    s = upload(UINT64_MAX);
    assert_int_equal(s.bytes, 0);
    /* half of the next level in transit: still two levels, nothing to send */
    ms_core_apo_chunk *mid;
    size_t n_mid;
    ms_test_render_apo(fx.archive, &mesh, 2, true, &mid, &n_mid);
    set_frame(&mesh, mid, n_mid);
    s = upload(UINT64_MAX);
    assert_int_equal(s.bytes, 0);
    set_frame(&mesh, all, n_all);
    s = upload(1000);
    assert_true(s.bytes == 1000 || s.cells_pending == 0);
    uint64_t total = s.bytes;
    while (s.cells_pending > 0) {
        s = upload(1000);
        total += s.bytes;
    }
    assert_int_equal(total, 4 * words_all);
    set_frame(&mesh, NULL, 0); /* chunks gone: geometric normals, nothing sent */
    s = upload(UINT64_MAX);
    assert_int_equal(s.bytes, 0);
    free(two);
    free(all);
    free(mid);
    ms_view_mesh_free(&mesh);
}

static int setup(void **state)
{
    (void)state;
    ms_test_gl_start(&gl);
    memset(&fx, 0, sizeof fx);
    char model[4096];
    ms_test_tmpdir(fx.dir, sizeof fx.dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    fx.archive = ms_test_render_bake(model, fx.dir, "dragon", 16, 1500, 4);
    fx.cell_count = ms_archive_get_header(fx.archive)->cell_count;
    const double dir[3] = {0.3, 0.2, 1.0};
    ms_test_render_camera(ms_archive_get_header(fx.archive), dir, 1.1, 40.0, WIDTH, HEIGHT, &fx.camera);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    ms_archive_close(fx.archive);
    ms_test_rmdir(fx.dir);
    ms_test_gl_stop(&gl);
    return 0;
}

/* Each test starts from a fresh view and renderer. */
static int per_test_setup(void **state)
{
    (void)state;
    ms_test_render_open(fx.archive, &fx.render, &fx.view);
    assert_true(ms_render_crease_angle(fx.render) == CREASE_DEG);
    return 0;
}

static int per_test_teardown(void **state)
{
    (void)state;
    ms_render_free(fx.render);
    ms_view_destroy(fx.view);
    fx.render = NULL;
    fx.view = NULL;
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_budget_and_same_frame, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_refinement_queues_changed_cells, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_leaving_cell_stops_at_once, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_apo_changes, per_test_setup, per_test_teardown),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
