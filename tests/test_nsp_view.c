/* nSP archives end to end: bake, decode every cell to full precision and stitch
 * (exactly the welded quantised input), random cameras at mixed precisions (the
 * stitched mesh is the exact image of the mixed clustering, no crack), reversible
 * refinement and split/merge, byte prefixes, thread-count independence. */
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

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_view_decoder.h"

static ms_view *open_view(const char *path, ms_archive **archive)
{
    ms_error err;
    if (ms_archive_open(path, archive, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_view *v;
    if (ms_view_create_from_archive(*archive, &v, &err) != MS_OK)
        fail_msg("%s", err.text);
    return v;
}

static void check_full_with(const char *model, const char *dir, const char *name,
                            uint32_t min_tris, unsigned bits, unsigned n, unsigned root_bits)
{
    ms_bake_report rep;
    ms_bake_options o;
    ms_nsp_test_bake_options(model, dir, name, &o);
    o.bits = bits;
    o.n = n;
    o.root_bits = root_bits;
    o.min_triangles = min_tris;
    ms_error err;
    if (ms_bake(&o, &rep, &err) != MS_OK)
        fail_msg("bake: %s", err.text);
    ms_qmesh q = {0};
    ms_nsp_test_reference(model, bits, &q);
    assert_int_equal(rep.vertices, q.vertex_count);
    assert_int_equal(rep.triangles, q.tri_count);
    ms_archive *a;
    ms_view *v = open_view(rep.archive_path, &a);
    ms_nsp_test_decode_all(v); /* every child's start state is checked by its decoder */
    ms_nsp_view_check r;
    ms_nsp_test_check_view(v, &q, true, &r);
    print_message("%-36s %7zu tris, %5u cells (%u shown), dup %.2f %%, %.2f bpv, %zu frozen "
                  "corners\n", name, r.triangles, rep.cells, r.shown_cells,
                  rep.duplicated_percent, rep.bits_per_vertex, r.snapped_frozen);
    /* leaves stop refining their foreign vertices (ms_codec_region), and the
     * stitch still gives every triangle exactly */
    if (rep.cells > 1)
        assert_true(r.snapped_frozen > 0);
    assert_int_equal(r.missing, 0);
    assert_int_equal(r.extra, 0);
    assert_int_equal(r.duplicates, 0);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_qmesh_free(&q);
}

static void check_full(const char *model, const char *dir, const char *name, uint32_t min_tris)
{
    check_full_with(model, dir, name, min_tris, 16, 4, 7);
}

/* Other tree shapes and precisions, down to cells of a few triangles. */
static void test_full_precision_parameters(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    check_full_with(model, dir, "p12n2", 200, 12, 2, 3);
    check_full_with(model, dir, "p10n8", 300, 10, 8, 3);
    check_full_with(model, dir, "p20n4", 400, 20, 4, 7);
    check_full_with(model, dir, "p8n4", 100, 8, 4, 2);
    check_full_with(model, dir, "p16min4", 4, 16, 4, 7);
    ms_test_rmdir(dir);
}

/* Every test model (tests/data/README.md; the full-size dragon only with
 * MESHSTREAM_BIG=1: it is run by scripts/bench-bake on the release build). */
static void test_full_precision_all_models(void **state)
{
    (void)state;
    static const char *const files[] = {
        "stanford_bunny_res3.ply.gz",       "stanford_dragon_vrip_res4.ply.gz",
        "stanford_dragon_vrip_res3.ply.gz", "stanford_dragon_vrip_res2.ply.gz",
        "glmark2_bunny.obj.gz",             "cgal_armadillo.off.gz",
        "torus_tristrips.ply.gz",           "trefoil_color.ply.gz",
        "snowden_bust_hi.ply.gz",           "stanford_dragon_vrip.ply.gz",
    };
    char dir[512], path[4096];
    ms_test_tmpdir(dir, sizeof dir);
    bool big = getenv("MESHSTREAM_BIG") != NULL;
    for (size_t i = 0; i < sizeof files / sizeof files[0]; ++i) {
        if (!big && strcmp(files[i], "stanford_dragon_vrip.ply.gz") == 0)
            continue;
        ms_test_model_path(path, sizeof path, files[i]);
        char name[65];
        ms_bake_default_name(files[i], name, sizeof name);
        /* a small threshold gives every model a tree of several levels */
        check_full(path, dir, name, 2000);
    }
    ms_test_rmdir(dir);
}

static void random_camera(const ms_archive_header *h, uint64_t *rng, ms_camera *cam)
{
    double centre[3], pos[3], target[3];
    for (int a = 0; a < 3; ++a)
        centre[a] = h->box_origin[a] + 0.5 * h->box_side;
    *rng = *rng * 6364136223846793005ull + 1442695040888963407ull;
    double u = (double)(*rng >> 11) / 9007199254740992.0;
    *rng = *rng * 6364136223846793005ull + 1442695040888963407ull;
    double w = (double)(*rng >> 11) / 9007199254740992.0;
    *rng = *rng * 6364136223846793005ull + 1442695040888963407ull;
    double r = 0.15 + 1.6 * (double)(*rng >> 11) / 9007199254740992.0;
    double theta = 2 * M_PI * u, phi = acos(2 * w - 1);
    double dir[3] = {sin(phi) * cos(theta), sin(phi) * sin(theta), cos(phi)};
    for (int a = 0; a < 3; ++a) {
        pos[a] = centre[a] + r * h->box_side * dir[a];
        /* look near the centre, off by a little */
        target[a] = centre[a] + 0.2 * h->box_side * (u - 0.5) * (a == 1 ? -1 : 1);
    }
    double up[3] = {0, 0, 1};
    if (fabs(dir[2]) > 0.95)
        up[0] = 1, up[2] = 0;
    ms_error err;
    assert_int_equal(ms_camera_look_at(pos, target, up, 50.0, 640, 480, 1e-3 * h->box_side,
                                       100 * h->box_side, cam, &err),
                     MS_OK);
}

static void check_cameras(const char *model, const char *dir, const char *name, uint32_t min_tris,
                          unsigned cameras, double tolerance, double culled_less)
{
    ms_bake_report rep;
    ms_nsp_test_bake(model, dir, name, 16, min_tris, &rep);
    ms_qmesh q = {0};
    ms_nsp_test_reference(model, 16, &q);
    ms_archive *a;
    ms_view *v = open_view(rep.archive_path, &a);
    const ms_archive_header *h = ms_view_header(v);
    uint64_t rng = 12345;
    if (getenv("MS_NSP_CAMERAS"))
        cameras = (unsigned)atoi(getenv("MS_NSP_CAMERAS"));
    size_t mixed = 0, max_levels = 0, folds = 0;
    for (unsigned i = 0; i < cameras; ++i) {
        ms_camera cam;
        random_camera(h, &rng, &cam);
        ms_view_select_params sp = {.tolerance_px = tolerance, .margin = 0.01 * h->box_side,
                                    .hysteresis = 0.5, .culled_bits_less = culled_less};
        ms_view_select(v, &cam, &sp, NULL);
        ms_view_apply_report ar;
        ms_error err;
        if (ms_view_apply(v, &ar, &err) != MS_OK)
            fail_msg("apply: %s", err.text);
        assert_int_equal(ar.waiting, 0);
        ms_nsp_view_check r;
        ms_nsp_test_check_view(v, &q, false, &r);
        mixed += r.levels > 1;
        folds += r.folds;
        if (r.levels > max_levels)
            max_levels = r.levels;
        if (r.missing || r.extra || r.duplicates || r.cracks)
            fail_msg("%s camera %u: %zu tris, %u shown cells at %u precisions: %zu missing, %zu "
                     "extra, %zu duplicated, %zu cracks (of %zu boundary edges)",
                     name, i, r.triangles, r.shown_cells, r.levels, r.missing, r.extra,
                     r.duplicates, r.cracks, r.boundary_edges);
    }
    print_message("%s: %u cameras, %zu with mixed precisions (up to %zu), no crack (%zu fold "
                  "edges)\n", name, cameras, mixed, max_levels, folds);
    assert_true(mixed > cameras / 2);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_qmesh_free(&q);
}

static void test_no_crack_demo(void **state)
{
    (void)state;
    char dir[512], ply[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(ply, sizeof ply, "%s/demo.ply", dir);
    ms_nsp_test_demo_ply(ply, 60000);
    check_cameras(ply, dir, "demo", 1500, 10, 1.0, 2.0);
    ms_test_rmdir(dir);
}

static void test_no_crack_dragon(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model,
                       getenv("MESHSTREAM_BIG") ? "stanford_dragon_vrip.ply.gz"
                                                : "stanford_dragon_vrip_res3.ply.gz");
    check_cameras(model, dir, "dragon", getenv("MESHSTREAM_BIG") ? 8000 : 1500, 10, 1.0, 2.0);
    ms_test_rmdir(dir);
}

static bool states_equal(ms_view *v, uint32_t cell, const ms_codec_state *s)
{
    ms_codec_state now;
    ms_error err;
    assert_int_equal(ms_view_cell_state_copy(v, cell, &now, &err), MS_OK);
    bool eq = ms_codec_state_equal(&now, s, true) && now.level == s->level;
    ms_codec_state_free(&now);
    return eq;
}

/* A per-cell tolerance scale (ms_view_select_params.tolerance_scale): a uniform
 * scale s at tolerance t selects exactly what tolerance s*t does, and scaling
 * the leaves alone changes only the targets of leaves (the split decisions of
 * internal cells, taken at their own tolerance, stay those of the unscaled
 * selection). This is how a client with APO on refines the cells baked without
 * a chunk to the full tolerance. */
/* Selects for cam and copies every cell's target into target (cell_count). */
static void select_targets(ms_view *v, const ms_camera *cam, const ms_view_select_params *sp,
                           uint8_t *target)
{
    ms_view_select(v, cam, sp, NULL);
    for (uint32_t i = 0; i < ms_view_cell_count(v); ++i)
        target[i] = ms_view_target(v, i);
}

/* A public preview of 10 bits (permitted_steps 11, issue 32): no target above
 * 10 bits, no split of a cell whose window reaches 10 (its children could
 * not be read), no subtree prefetch for such a cell, every target below 10
 * as without the cap; returns the cells the cap lowered. */
static size_t check_preview_cap(ms_view *v, const ms_camera *cam, const uint8_t *fine,
                                uint8_t *capped)
{
    ms_view_select_params sp;
    ms_view_select_params_default(&sp);
    sp.permitted_steps = 11;
    ms_view_select_report report = {0};
    ms_view_select(v, cam, &sp, &report);
    for (uint32_t i = 0; i < ms_view_cell_count(v); ++i) {
        capped[i] = ms_view_target(v, i);
        const ms_archive_cell *c = ms_view_cell(v, i);
        if (capped[i] == MS_VIEW_TARGET_SPLIT)
            assert_true(c->bits_max < 10);
        else if (capped[i] != MS_VIEW_TARGET_HIDDEN)
            assert_true(capped[i] <= 10);
        if (fine[i] < 10)
            assert_int_equal(capped[i], fine[i]);
    }
    for (size_t k = 0; k < report.near_count; ++k)
        assert_true(ms_view_cell(v, report.near[k])->bits_max < 10);
    assert_int_equal(report.blocked_count, 0); /* a whole index */
    size_t lowered = report.capped_count;
    ms_view_select_report_free(&report);
    return lowered;
}

static void test_tolerance_scale(void **state)
{
    (void)state;
    char dir[512], ply[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(ply, sizeof ply, "%s/demo.ply", dir);
    ms_nsp_test_demo_ply(ply, 60000);
    ms_bake_report rep;
    ms_nsp_test_bake(ply, dir, "demo", 16, 1500, &rep);
    ms_archive *a;
    ms_view *v = open_view(rep.archive_path, &a);
    const ms_archive_header *h = ms_view_header(v);
    uint32_t n = h->cell_count;
    uint8_t *coarse = malloc(n), *fine = malloc(n), *scaled = malloc(n), *mixed = malloc(n);
    uint8_t *capped = malloc(n);
    size_t lowered = 0, above = 0;
    float *uniform = malloc(n * sizeof *uniform), *leaves = malloc(n * sizeof *leaves);
    assert_true(coarse && fine && scaled && mixed && uniform && leaves);
    for (uint32_t i = 0; i < n; ++i) {
        uniform[i] = 0.25f;
        leaves[i] = ms_view_cell(v, i)->first_child == MS_ARCHIVE_NONE ? 0.25f : 1.0f;
    }
    uint64_t rng = 777;
    size_t leaf_changes = 0;
    for (unsigned k = 0; k < 8; ++k) {
        ms_camera cam;
        random_camera(h, &rng, &cam);
        ms_view_select_params sp;
        ms_view_select_params_default(&sp);
        sp.tolerance_px = 4.0;
        select_targets(v, &cam, &sp, coarse);
        sp.tolerance_px = 1.0;
        select_targets(v, &cam, &sp, fine);
        lowered += check_preview_cap(v, &cam, fine, capped);
        for (uint32_t i = 0; i < n; ++i)
            above += fine[i] != MS_VIEW_TARGET_HIDDEN && fine[i] != MS_VIEW_TARGET_SPLIT && fine[i] > 10;
        sp.tolerance_px = 4.0;
        sp.tolerance_scale = uniform;
        select_targets(v, &cam, &sp, scaled);
        assert_memory_equal(scaled, fine, n);
        sp.tolerance_scale = leaves;
        select_targets(v, &cam, &sp, mixed);
        for (uint32_t i = 0; i < n; ++i) {
            bool leaf = ms_view_cell(v, i)->first_child == MS_ARCHIVE_NONE;
            if (!leaf)
                assert_int_equal(mixed[i], coarse[i]);
            else if (coarse[i] == MS_VIEW_TARGET_HIDDEN)
                assert_int_equal(mixed[i], MS_VIEW_TARGET_HIDDEN);
            else {
                assert_int_equal(mixed[i], fine[i]); /* shown leaf: the fine need */
                leaf_changes += mixed[i] != coarse[i];
            }
        }
    }
    assert_true(leaf_changes > 0); /* the cameras do reach leaves that refine */
    assert_true(above > 0 && lowered > 0); /* the cameras want more than the preview */
    free(coarse), free(fine), free(scaled), free(mixed), free(uniform), free(leaves), free(capped);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

static void test_reversible(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_report rep;
    ms_nsp_test_bake(model, dir, "rev", 16, 1500, &rep);
    ms_archive *a;
    ms_view *v = open_view(rep.archive_path, &a);
    ms_error err;
    const ms_archive_cell *root = ms_view_cell(v, 0);
    assert_true(root->first_child != MS_ARCHIVE_NONE);
    /* Refine the root bit by bit, coarsen back: identical states at every bit. */
    ms_codec_state before[32];
    for (unsigned b = root->bits_min; b <= root->bits_max; ++b) {
        assert_int_equal(ms_view_set_bits(v, 0, b, &err), MS_OK);
        assert_int_equal(ms_view_cell_state_copy(v, 0, &before[b], &err), MS_OK);
    }
    for (unsigned b = root->bits_max + 1; b-- > root->bits_min;) {
        assert_int_equal(ms_view_set_bits(v, 0, b, &err), MS_OK);
        assert_true(states_equal(v, 0, &before[b]));
    }
    assert_int_equal(ms_view_set_bits(v, 0, root->bits_max, &err), MS_OK);
    /* Split, refine a child fully, split it if it can, merge everything back. */
    ms_view_mesh m0 = {0}, m1 = {0};
    assert_int_equal(ms_view_stitch(v, NULL, &m0, &err), MS_OK);
    assert_int_equal(ms_view_split(v, 0, &err), MS_OK);
    uint32_t child = MS_ARCHIVE_NONE;
    for (uint32_t k = 0; k < 64; ++k) {
        const ms_archive_cell *c = ms_view_cell(v, root->first_child + k);
        if (c->geometry_length > 0 && (child == MS_ARCHIVE_NONE || c->first_child != MS_ARCHIVE_NONE))
            child = root->first_child + k;
    }
    assert_true(child != MS_ARCHIVE_NONE);
    const ms_archive_cell *cc = ms_view_cell(v, child);
    ms_codec_state child_start;
    assert_int_equal(ms_view_cell_state_copy(v, child, &child_start, &err), MS_OK);
    assert_int_equal(ms_view_set_bits(v, child, cc->bits_max, &err), MS_OK);
    ms_codec_state child_max;
    assert_int_equal(ms_view_cell_state_copy(v, child, &child_max, &err), MS_OK);
    if (cc->first_child != MS_ARCHIVE_NONE) {
        assert_int_equal(ms_view_split(v, child, &err), MS_OK);
        assert_int_equal(ms_view_merge(v, child, &err), MS_OK);
        assert_true(states_equal(v, child, &child_max));
    }
    assert_int_equal(ms_view_set_bits(v, child, cc->bits_min, &err), MS_OK);
    assert_true(states_equal(v, child, &child_start));
    assert_int_equal(ms_view_set_bits(v, child, cc->bits_max, &err), MS_OK);
    assert_true(states_equal(v, child, &child_max));
    assert_int_equal(ms_view_merge(v, 0, &err), MS_OK);
    assert_int_equal(ms_view_state(v, child), MS_VIEW_HIDDEN);
    assert_true(states_equal(v, 0, &before[root->bits_max]));
    assert_int_equal(ms_view_stitch(v, NULL, &m1, &err), MS_OK);
    assert_int_equal(m0.triangle_count, m1.triangle_count);
    assert_int_equal(m0.vertex_count, m1.vertex_count);
    assert_memory_equal(m0.triangles, m1.triangles, 12 * m0.triangle_count);
    assert_memory_equal(m0.positions, m1.positions, 24 * m0.vertex_count);
    /* Wrong requests are refused, not obeyed. */
    assert_int_equal(ms_view_set_bits(v, 0, root->bits_max + 1, &err), MS_ERR_RANGE);
    assert_int_equal(ms_view_set_bits(v, child, cc->bits_max, &err), MS_ERR_RANGE);
    assert_int_equal(ms_view_merge(v, 0, &err), MS_ERR_RANGE);
    assert_int_equal(ms_view_set_bits(v, 0, root->bits_min, &err), MS_OK);
    assert_int_equal(ms_view_split(v, 0, &err), MS_ERR_RANGE);
    for (unsigned b = root->bits_min; b <= root->bits_max; ++b)
        ms_codec_state_free(&before[b]);
    ms_codec_state_free(&child_start);
    ms_codec_state_free(&child_max);
    ms_view_mesh_free(&m0);
    ms_view_mesh_free(&m1);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* Byte prefixes: a cell decodes exactly as far as the prefix table says. */
static void test_prefixes(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    ms_bake_report rep;
    ms_nsp_test_bake(model, dir, "prefix", 12, 1000, &rep);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(rep.archive_path, &a, &err), MS_OK);
    /* What a client has: the index blob alone. */
    size_t index_size;
    const uint8_t *index = ms_archive_index_bytes(a, &index_size);
    ms_archive *ia;
    assert_int_equal(ms_archive_open_index(index, index_size, "prefix", &ia, &err), MS_OK);
    ms_view *v;
    assert_int_equal(ms_view_create_from_archive(ia, &v, &err), MS_OK);
    ms_archive_close(ia);
    size_t len;
    const uint8_t *g = ms_archive_geometry(a, 0, &len);
    const ms_archive_cell *root = ms_archive_get_cell(a, 0);
    assert_int_equal(ms_view_set_bits(v, 0, 1, &err), MS_ERR_FORMAT); /* nothing yet */
    for (unsigned b = root->bits_min; b <= root->bits_max; ++b) {
        uint32_t n = ms_archive_geometry_prefix(a, 0, b);
        assert_int_equal(ms_view_set_bytes(v, 0, g, n ? n - 1 : 0, &err), MS_OK);
        if (b > root->bits_min)
            assert_int_equal(ms_view_available_bits(v, 0), b - 1);
        assert_int_equal(ms_view_set_bytes(v, 0, g, n, &err), MS_OK);
        assert_int_equal(ms_view_available_bits(v, 0), b);
        assert_int_equal(ms_view_set_bits(v, 0, b, &err), MS_OK);
        if (b < root->bits_max)
            assert_int_equal(ms_view_set_bits(v, 0, b + 1, &err), MS_ERR_FORMAT);
    }
    assert_int_equal(ms_view_set_bytes(v, 0, g, len + 1, &err), MS_ERR_RANGE);
    /* Children show at their bits_min before any of their bytes arrive. */
    assert_int_equal(ms_view_split(v, 0, &err), MS_OK);
    ms_view_mesh m = {0};
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    assert_true(m.triangle_count > 0);
    assert_int_equal(m.unresolved, 0);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* Same archive bytes whatever the thread count. */
static void test_threads_identical(void **state)
{
    (void)state;
    char dir[512], model[4096], cmd[16384], out[256];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_options o;
    ms_nsp_test_bake_options(model, dir, NULL, &o);
    o.min_triangles = 1000;
    ms_bake_report r;
    ms_error err;
    const unsigned threads[3] = {1, 2, 5};
    for (int i = 0; i < 3; ++i) {
        char name[16];
        snprintf(name, sizeof name, "t%u", threads[i]);
        o.name = name;
        o.threads = threads[i];
        assert_int_equal(ms_bake(&o, &r, &err), MS_OK);
    }
    snprintf(cmd, sizeof cmd, "cmp '%s/t1.msa' '%s/t2.msa' && cmp '%s/t1.msa' '%s/t5.msa'", dir,
             dir, dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_tolerance_scale),
        cmocka_unit_test(test_prefixes),
        cmocka_unit_test(test_reversible),
        cmocka_unit_test(test_threads_identical),
        cmocka_unit_test(test_no_crack_demo),
        cmocka_unit_test(test_no_crack_dragon),
        cmocka_unit_test(test_full_precision_parameters),
        cmocka_unit_test(test_full_precision_all_models),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
