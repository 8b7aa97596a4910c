/* The renderer's work per frame (ms_render.h, ms_render_frame_stats;
 * ms_render_cells.c): a frame derives the meshes of the cells whose triangles
 * changed (the stitched mesh's run versions, ms_view_decoder.h) and of the
 * cells sharing a vertex with what they drew or draw, exactly those, and makes
 * again the meshes of the changed cells and of the neighbours whose corner
 * normals moved, exactly those (two renderers deriving every cell, one per
 * frame, say which moved); an unchanged frame derives, makes and walks
 * nothing; and the meshes it keeps or derives are,
 * byte for byte, those a renderer deriving every cell of the frame makes (the
 * buffers it would upload), so the picture is the same. */
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
#include "ms_render_internal.h"
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

static ms_render_frame_stats set_frame(ms_render *r, const ms_view_mesh *mesh)
{
    ms_error err;
    if (ms_render_set_frame(r, mesh, NULL, 0, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_render_frame_stats st;
    ms_render_frame_stats_get(r, &st);
    return st;
}

/* Cells drawing a triangle in m. */
static uint32_t present_cells(const ms_view_mesh *m)
{
    bool *seen = calloc(fx.cell_count, 1);
    assert_non_null(seen);
    uint32_t n = 0;
    for (size_t t = 0; t < m->triangle_count; ++t)
        if (!seen[m->triangle_cell[t]])
            seen[m->triangle_cell[t]] = true, n++;
    free(seen);
    return n;
}

/* The run version of cell in m, false when it draws nothing there. */
static bool version_of(const ms_view_mesh *m, uint32_t cell, uint64_t *version)
{
    for (size_t k = 0; k < m->run_count; ++k)
        if (m->run_cell[k] == cell && m->run_first[k + 1] > m->run_first[k]) {
            *version = m->run_version[k];
            return true;
        }
    return false;
}

/* Per cell: whether one of its triangles in m has a corner at a position of
 * mark (positions of the vertices of the cells flagged in from). */
typedef struct pos_set {
    double *p;
    size_t n, cap;
} pos_set;

static void pos_add_cells(pos_set *s, const ms_view_mesh *m, const bool *cells)
{
    for (size_t t = 0; t < m->triangle_count; ++t) {
        if (!cells[m->triangle_cell[t]])
            continue;
        for (int k = 0; k < 3; ++k) {
            if (s->n == s->cap) {
                s->cap = s->cap ? 2 * s->cap : 1024;
                s->p = realloc(s->p, 3 * s->cap * sizeof *s->p);
                assert_non_null(s->p);
            }
            memcpy(&s->p[3 * s->n++], &m->positions[3 * (size_t)m->triangles[3 * t + (size_t)k]], 3 * sizeof(double));
        }
    }
}

static int cmp_pos(const void *a, const void *b)
{
    return memcmp(a, b, 3 * sizeof(double));
}

static bool pos_has(const pos_set *s, const double *p)
{
    return bsearch(p, s->p, s->n, 3 * sizeof(double), cmp_pos) != NULL;
}

/* The cells a frame after `before` must derive, found by brute force: those
 * new or with another version, and every cell of after with a corner at a
 * vertex position that such a cell, or a cell that left, used in before or
 * uses in after. *changed gets the first count. */
static uint32_t expected_derived(const ms_view_mesh *before, const ms_view_mesh *after, uint32_t *changed)
{
    bool *dirty_before = calloc(fx.cell_count, 1), *dirty_after = calloc(fx.cell_count, 1);
    bool *derived = calloc(fx.cell_count, 1);
    assert_true(dirty_before && dirty_after && derived);
    *changed = 0;
    for (size_t k = 0; k < after->run_count; ++k) {
        uint32_t cell = after->run_cell[k];
        uint64_t v;
        if (after->run_first[k + 1] == after->run_first[k])
            continue;
        if (!version_of(before, cell, &v) || v != after->run_version[k]) {
            dirty_before[cell] = dirty_after[cell] = derived[cell] = true;
            (*changed)++;
        }
    }
    for (size_t k = 0; k < before->run_count; ++k) {
        uint64_t v;
        if (before->run_first[k + 1] > before->run_first[k] && !version_of(after, before->run_cell[k], &v))
            dirty_before[before->run_cell[k]] = true; /* left */
    }
    pos_set s = {0};
    pos_add_cells(&s, before, dirty_before);
    pos_add_cells(&s, after, dirty_after);
    qsort(s.p, s.n, 3 * sizeof(double), cmp_pos);
    for (size_t t = 0; t < after->triangle_count; ++t)
        for (int k = 0; k < 3 && !derived[after->triangle_cell[t]]; ++k)
            if (pos_has(&s, &after->positions[3 * (size_t)after->triangles[3 * t + (size_t)k]]))
                derived[after->triangle_cell[t]] = true;
    uint32_t n = 0;
    for (uint32_t c = 0; c < fx.cell_count; ++c)
        n += derived[c];
    free(s.p);
    free(dirty_before);
    free(dirty_after);
    free(derived);
    return n;
}

/* The cells present in both frames with the same version whose corner normals
 * differ, found by two renderers that derive every cell (one per frame): the
 * neighbours whose meshes must be made again, and *tris their triangles. */
static uint32_t expected_moved(const ms_view_mesh *before, const ms_view_mesh *after, double crease, uint64_t *tris)
{
    ms_render *a, *b;
    ms_error err;
    const ms_archive_header *h = ms_archive_get_header(fx.archive);
    assert_int_equal(ms_render_new(h, ms_archive_get_cell(fx.archive, 0), &a, &err), MS_OK);
    assert_int_equal(ms_render_new(h, ms_archive_get_cell(fx.archive, 0), &b, &err), MS_OK);
    assert_int_equal(ms_render_set_crease_angle(a, crease, &err), MS_OK);
    assert_int_equal(ms_render_set_crease_angle(b, crease, &err), MS_OK);
    set_frame(a, before);
    set_frame(b, after);
    uint32_t moved = 0;
    *tris = 0;
    for (size_t k = 0; k < after->run_count; ++k) {
        uint32_t cell = after->run_cell[k];
        uint64_t v;
        if (after->run_first[k + 1] == after->run_first[k] || !version_of(before, cell, &v) ||
            v != after->run_version[k])
            continue;
        const render_cell *x = ms_render_cell_at(a, cell), *y = ms_render_cell_at(b, cell);
        assert_true(x && y && x->corner_count == y->corner_count && x->corners && y->corners);
        if (memcmp(x->corners, y->corners, x->corner_count * sizeof *x->corners)) {
            moved++;
            *tris += y->corner_count / 3;
        }
    }
    ms_render_free(a);
    ms_render_free(b);
    return moved;
}

/* The mesh cell wants to draw: its pending one (nothing is uploaded here). */
static const pending_mesh *wanted(const ms_render *r, uint32_t cell)
{
    const render_cell *c = ms_render_cell_at(r, cell);
    assert_non_null(c);
    assert_true(c->next_mesh.active);
    return &c->next_mesh;
}

/* Every cell drawing in mesh wants, in a and b, the same mesh, byte for byte. */
static void assert_same_meshes(const ms_render *a, const ms_render *b, const ms_view_mesh *mesh)
{
    uint32_t cells = 0;
    for (uint32_t k = 0; k < b->split.present_count; ++k) {
        uint32_t cell = b->split.present[k];
        const pending_mesh *x = wanted(a, cell), *y = wanted(b, cell);
        assert_int_equal(x->gpu.vertex_count, y->gpu.vertex_count);
        assert_int_equal(x->gpu.triangle_count, y->gpu.triangle_count);
        assert_true(x->gpu.hash == y->gpu.hash);
        assert_memory_equal(x->vertices, y->vertices, 3 * (size_t)x->gpu.vertex_count * sizeof(float));
        assert_memory_equal(x->normals, y->normals, (size_t)x->gpu.vertex_count * sizeof(uint32_t));
        assert_memory_equal(x->indices, y->indices, 3 * (size_t)x->gpu.triangle_count * sizeof(uint32_t));
        cells++;
    }
    assert_int_equal(a->frame_cell_count, cells);
    assert_int_equal(cells, present_cells(mesh));
}

/* The same frame's meshes from a renderer that derives every cell. */
static void check_against_fresh(const ms_view_mesh *mesh, double crease)
{
    ms_render *fresh;
    ms_error err;
    assert_int_equal(ms_render_new(ms_archive_get_header(fx.archive), ms_archive_get_cell(fx.archive, 0), &fresh, &err),
                     MS_OK);
    assert_int_equal(ms_render_set_crease_angle(fresh, crease, &err), MS_OK);
    ms_render_frame_stats st = set_frame(fresh, mesh);
    assert_int_equal(st.cells_derived, present_cells(mesh));
    assert_same_meshes(fx.render, fresh, mesh);
    ms_render_free(fresh);
}

/* A shown cell that can refine and draws triangles, not in except[0..n). */
static uint32_t refinable_cell(const ms_view_mesh *mesh, const uint32_t *except, size_t n)
{
    uint32_t best = UINT32_MAX;
    size_t best_tris = 0;
    size_t *tris = calloc(fx.cell_count, sizeof *tris);
    for (size_t t = 0; t < mesh->triangle_count; ++t)
        tris[mesh->triangle_cell[t]]++;
    for (uint32_t c = 0; c < fx.cell_count; ++c) {
        bool skip = false;
        for (size_t i = 0; i < n; ++i)
            skip |= except[i] == c;
        if (!skip && ms_view_state(fx.view, c) == MS_VIEW_SHOWN &&
            ms_view_bits(fx.view, c) < ms_view_cell(fx.view, c)->bits_max && tris[c] > best_tris)
            best = c, best_tris = tris[c];
    }
    free(tris);
    assert_true(best != UINT32_MAX);
    return best;
}

/* The first frame derives every cell; the same frame again, or a new stitch of
 * the same view, derives none and makes no normal. */
static void test_unchanged_frame_derives_nothing(void **state)
{
    (void)state;
    ms_view_mesh mesh = {0}, again = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &mesh);
    uint32_t present = present_cells(&mesh);
    assert_true(present > 4);
    ms_render_frame_stats st = set_frame(fx.render, &mesh);
    assert_int_equal(st.cells_present, present);
    assert_int_equal(st.cells_changed, present);
    assert_int_equal(st.cells_derived, present);
    assert_int_equal(st.cells_left, 0);
    assert_int_equal(st.face_normals, mesh.triangle_count);
    assert_true(st.vertex_fans > 0 && st.vertex_fans <= mesh.vertex_count);
    assert_int_equal(st.cells_rebuilt, present);
    assert_int_equal(st.cells_queued, present);
    assert_int_equal(st.neighbours_moved, 0);
    assert_int_equal(st.triangles_rebuilt, mesh.triangle_count);
    assert_int_equal(st.triangles_walked, 0);
    check_against_fresh(&mesh, MS_RENDER_CREASE_ANGLE_DEFAULT);
    ms_error err;
    for (int round = 0; round < 2; ++round) {
        if (round == 1)
            assert_int_equal(ms_view_stitch(fx.view, NULL, &again, &err), MS_OK);
        st = set_frame(fx.render, round ? &again : &mesh);
        assert_int_equal(st.cells_present, present);
        assert_int_equal(st.cells_changed, 0);
        assert_int_equal(st.cells_left, 0);
        assert_int_equal(st.cells_derived, 0);
        assert_int_equal(st.vertex_fans, 0);
        assert_int_equal(st.face_normals, 0);
        assert_int_equal(st.cells_rebuilt, 0);
        assert_int_equal(st.cells_queued, 0);
        assert_int_equal(st.triangles_rebuilt, 0);
        assert_int_equal(st.triangles_walked, 0);
    }
    /* another crease angle derives every cell again, as a fresh renderer would */
    assert_int_equal(ms_render_set_crease_angle(fx.render, 25.0, &err), MS_OK);
    st = set_frame(fx.render, &again);
    assert_int_equal(st.cells_changed, present);
    assert_int_equal(st.cells_derived, present);
    check_against_fresh(&again, 25.0);
    ms_view_mesh_free(&again);
    ms_view_mesh_free(&mesh);
}

/* Refining k cells: the versions change for exactly the cells whose triangles
 * may have (every cell whose triangles did is among them), the frame derives
 * exactly those plus their neighbours (by brute force over positions), and
 * every mesh is the one a fresh renderer makes. */
static void test_refining_k_cells(void **state)
{
    (void)state;
    ms_view_mesh before = {0}, after = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &before);
    set_frame(fx.render, &before);
    ms_error err;
    uint32_t picked[3];
    for (size_t k = 1; k <= 3; ++k) {
        for (size_t i = 0; i < k; ++i) {
            picked[i] = refinable_cell(&before, picked, i);
            assert_int_equal(ms_view_set_bits(fx.view, picked[i], ms_view_bits(fx.view, picked[i]) + 1, &err), MS_OK);
        }
        assert_int_equal(ms_view_stitch(fx.view, NULL, &after, &err), MS_OK);
        uint32_t changed;
        uint32_t derived = expected_derived(&before, &after, &changed);
        for (size_t i = 0; i < k; ++i) {
            uint64_t v0, v1;
            assert_true(version_of(&before, picked[i], &v0) && version_of(&after, picked[i], &v1));
            assert_true(v0 != v1);
        }
        /* a cell whose triangles changed has another version (and how many
         * of those with another version did change) */
        uint32_t moved = 0;
        for (size_t r = 0; r < after.run_count; ++r) {
            uint64_t v0;
            uint32_t cell = after.run_cell[r], n1 = after.run_first[r + 1] - after.run_first[r];
            if (!n1)
                continue;
            size_t b = 0;
            while (b < before.run_count && before.run_cell[b] != cell)
                b++;
            bool same = b < before.run_count && before.run_first[b + 1] - before.run_first[b] == n1;
            for (uint32_t i = 0; same && i < 3 * n1; ++i)
                same = !memcmp(&before.positions[3 * (size_t)before.triangles[3 * (size_t)before.run_first[b] + i]],
                               &after.positions[3 * (size_t)after.triangles[3 * (size_t)after.run_first[r] + i]],
                               3 * sizeof(double));
            moved += !same;
            if (version_of(&before, cell, &v0) && v0 == after.run_version[r])
                assert_true(same);
        }
        uint64_t moved_tris, changed_tris = 0;
        uint32_t normals_moved = expected_moved(&before, &after, MS_RENDER_CREASE_ANGLE_DEFAULT, &moved_tris);
        for (size_t r = 0; r < after.run_count; ++r) {
            uint64_t v0;
            if (!version_of(&before, after.run_cell[r], &v0) || v0 != after.run_version[r])
                changed_tris += after.run_first[r + 1] - after.run_first[r];
        }
        ms_render_frame_stats st = set_frame(fx.render, &after);
        print_message("refining %zu cells: %u of %u cells changed (%u with other triangles), %u derived, %u rebuilt "
                      "(%u neighbours whose normals moved), %u queued; %llu vertex fans of %zu vertices, %llu face "
                      "normals, %llu triangles rebuilt, %llu walked of %zu\n",
                      k, st.cells_changed, st.cells_present, moved, st.cells_derived, st.cells_rebuilt,
                      st.neighbours_moved, st.cells_queued, (unsigned long long)st.vertex_fans, after.vertex_count,
                      (unsigned long long)st.face_normals, (unsigned long long)st.triangles_rebuilt,
                      (unsigned long long)st.triangles_walked, after.triangle_count);
        assert_true(changed >= k);
        assert_int_equal(st.cells_changed, changed);
        assert_int_equal(st.cells_derived, derived);
        /* only the changed cells and the neighbours whose normals moved are
         * made again; the other neighbours are walked, not rebuilt */
        assert_int_equal(st.neighbours_moved, normals_moved);
        assert_int_equal(st.cells_rebuilt, changed + normals_moved);
        assert_int_equal(st.triangles_rebuilt, changed_tris + moved_tris);
        assert_true(st.cells_queued <= st.cells_rebuilt && st.cells_queued >= moved);
        assert_true(st.triangles_walked + st.triangles_rebuilt <= after.triangle_count + moved_tris);
        if (k == 1) {
            assert_true(st.cells_derived < st.cells_present);
            assert_true(st.vertex_fans < after.vertex_count);
        }
        check_against_fresh(&after, MS_RENDER_CREASE_ANGLE_DEFAULT);
        /* nothing more changed: nothing derived */
        st = set_frame(fx.render, &after);
        assert_int_equal(st.cells_changed, 0);
        assert_int_equal(st.cells_derived, 0);
        assert_int_equal(st.cells_rebuilt, 0);
        assert_int_equal(st.vertex_fans, 0);
        assert_int_equal(st.triangles_walked, 0);
        ms_view_mesh tmp = before;
        before = after;
        after = tmp;
    }
    ms_view_mesh_free(&before);
    ms_view_mesh_free(&after);
}

/* Cells leave and come (other views, splits, merges): every frame's meshes are
 * a fresh renderer's, with the runs and without them (versions hashed). */
static void test_views_match_fresh(void **state)
{
    (void)state;
    const double dirs[4][3] = {{0.3, 0.2, 1.0}, {-1.0, 0.1, 0.2}, {0.2, 1.0, -0.3}, {0.3, 0.2, 1.0}};
    const double tolerance[4] = {2.0, 1.0, 0.5, 1.5};
    ms_view_mesh prev = {0}, mesh = {0};
    ms_camera cam;
    for (int runs = 1; runs >= 0; --runs)
        for (int i = 0; i < 4; ++i) {
            ms_test_render_look(fx.archive, fx.view, dirs[i], WIDTH, HEIGHT, tolerance[i], &cam, &mesh);
            ms_view_mesh plain = mesh;
            if (!runs)
                plain.run_count = 0;
            uint32_t changed = 0, derived = runs && i ? expected_derived(&prev, &mesh, &changed) : 0;
            ms_render_frame_stats st = set_frame(fx.render, &plain);
            print_message("view %d (%s runs): %u of %u cells changed, %u left, %u derived\n", i, runs ? "with" : "without",
                          st.cells_changed, st.cells_present, st.cells_left, st.cells_derived);
            if (runs && i) {
                assert_int_equal(st.cells_changed, changed);
                assert_int_equal(st.cells_derived, derived);
            }
            check_against_fresh(&plain, MS_RENDER_CREASE_ANGLE_DEFAULT);
            ms_view_mesh tmp = prev;
            prev = mesh;
            mesh = tmp;
        }
    ms_view_mesh_free(&prev);
    ms_view_mesh_free(&mesh);
}

/* A bad triangle in a derived cell of a mesh with runs is MS_ERR_ARG; the next
 * good frame derives every cell again, as a fresh renderer. */
static void test_bad_run_then_good(void **state)
{
    (void)state;
    ms_view_mesh mesh = {0};
    ms_test_render_view(fx.view, &fx.camera, 2.0, &mesh);
    ms_error err;
    uint32_t keep = mesh.triangles[4];
    mesh.triangles[4] = (uint32_t)mesh.vertex_count;
    assert_int_equal(ms_render_set_frame(fx.render, &mesh, NULL, 0, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "render: triangle 1 uses vertex"));
    mesh.triangles[4] = keep;
    uint32_t last = mesh.run_first[mesh.run_count];
    mesh.run_first[mesh.run_count] = last - 1;
    assert_int_equal(ms_render_set_frame(fx.render, &mesh, NULL, 0, &err), MS_ERR_ARG);
    mesh.run_first[mesh.run_count] = last;
    ms_render_frame_stats st = set_frame(fx.render, &mesh);
    assert_int_equal(st.cells_derived, present_cells(&mesh));
    check_against_fresh(&mesh, MS_RENDER_CREASE_ANGLE_DEFAULT);
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

static int per_test_setup(void **state)
{
    (void)state;
    ms_test_render_open(fx.archive, &fx.render, &fx.view);
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
        cmocka_unit_test_setup_teardown(test_unchanged_frame_derives_nothing, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_refining_k_cells, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_views_match_fresh, per_test_setup, per_test_teardown),
        cmocka_unit_test_setup_teardown(test_bad_run_then_good, per_test_setup, per_test_teardown),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
