/* The content bounds a client core hands over with the opening
 * (ms_core_opening.content_lo / _hi, ms_client_core_content.c): taken from
 * the root at root precision before any camera is set, they hold every vertex
 * of the source and of the full-resolution mesh and lie within one root
 * quantum (box_side / 2^root_bits) of the source's box on every side, for a
 * model of many cells (the demo) and of one (the bunny, whose root is a leaf),
 * the same with the index by subtree (the default) and whole. Before the
 * caller's first camera the core fetches the root's geometry bytes up to root
 * precision and nothing else (no APO). Local archives, no network. */
#include <float.h>
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_client_core.h"
#include "ms_mesh_io.h"
#include "ms_nsp_check.h"
#include "ms_test.h"

#define WAIT_SECONDS 30.0 /* bounds each wait (not a measurement) */

typedef struct fixture {
    char dir[512], archives[600];
    char demo_source[700], bunny_source[4096];
} fixture;

static fixture fx;

static void expect(ms_status st, const ms_error *err)
{
    if (st != MS_OK)
        fail_msg("%s", err->text);
}

/* Opens model `name` of the archive folder in a core and takes its opening
 * (no camera set); *bytes: what the core had fetched then. */
static void open_model(const char *name, bool whole_index, ms_core_opening *op, uint64_t *bytes)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", fx.archives, name);
    /* APO on (the demo has chunks): the root's geometry is still all it fetches */
    ms_core_options o = {.archive_path = path, .export_frames = true, .whole_index = whole_index,
                         .apo_levels = MS_ARCHIVE_MAX_APO_LEVELS};
    ms_core *core;
    ms_error err;
    expect(ms_core_start(&o, &core, &err), &err);
    expect(ms_core_wait_open(core, WAIT_SECONDS, op, &err), &err);
    ms_core_stats stats;
    ms_core_get_stats(core, &stats);
    *bytes = stats.bytes_received;
    ms_core_stop(core);
}

/* Checks the bounds of model `name` (baked from `source`) against the source's
 * vertices and box, and the full-resolution mesh's vertices. */
static void check_model(const char *name, const char *source)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", fx.archives, name);
    ms_archive *archive;
    ms_error err;
    expect(ms_archive_open(path, &archive, &err), &err);
    const ms_archive_header h = *ms_archive_get_header(archive);
    const ms_archive_cell *root = ms_archive_get_cell(archive, 0);
    unsigned root_precision = root->bits_max < h.root_bits ? root->bits_max : h.root_bits;
    uint32_t root_bytes = ms_archive_geometry_prefix(archive, 0, root_precision);
    ms_archive_close(archive);
    double quantum = h.box_side / (double)(1u << h.root_bits);

    ms_core_opening by_subtree, whole;
    uint64_t bytes;
    open_model(name, false, &by_subtree, &bytes);
    assert_true(by_subtree.by_subtree);
    assert_true(by_subtree.content_known);
    /* before a camera: the root up to root precision, nothing more */
    assert_int_equal(bytes, root_bytes);
    open_model(name, true, &whole, &bytes);
    assert_false(whole.by_subtree);
    assert_true(whole.content_known);
    /* one rule whatever the index holds */
    assert_memory_equal(whole.content_lo, by_subtree.content_lo, sizeof whole.content_lo);
    assert_memory_equal(whole.content_hi, by_subtree.content_hi, sizeof whole.content_hi);
    const double *lo = by_subtree.content_lo, *hi = by_subtree.content_hi;

    /* the source: every vertex inside, its box within one root quantum */
    ms_mesh mesh = {0};
    expect(ms_mesh_load(source, &mesh, NULL, &err), &err);
    assert_true(mesh.vertex_count > 0);
    double true_lo[3], true_hi[3];
    for (int a = 0; a < 3; ++a)
        true_lo[a] = true_hi[a] = mesh.positions[a];
    for (size_t v = 0; v < mesh.vertex_count; ++v)
        for (int a = 0; a < 3; ++a) {
            double x = mesh.positions[3 * v + (size_t)a];
            true_lo[a] = x < true_lo[a] ? x : true_lo[a];
            true_hi[a] = x > true_hi[a] ? x : true_hi[a];
        }
    ms_mesh_free(&mesh);
    double widest = 0;
    for (int a = 0; a < 3; ++a) {
        widest = true_lo[a] - lo[a] > widest ? true_lo[a] - lo[a] : widest;
        widest = hi[a] - true_hi[a] > widest ? hi[a] - true_hi[a] : widest;
    }
    print_message("%s: %u cells, root to %u bits: %u bytes before a camera; bounds at most "
                  "%.3f root quanta off the source's box\n",
                  name, h.cell_count, root_precision, root_bytes, widest / quantum);
    /* the archive's cube itself ends at origin + side rounded, which can be
     * an ulp short of the source's largest coordinate (ms_quant_fit_box) */
    for (int a = 0; a < 3; ++a) {
        double slack = 4 * DBL_EPSILON * (fabs(h.box_origin[a]) + h.box_side);
        assert_true(lo[a] <= true_lo[a] + slack && true_hi[a] <= hi[a] + slack);
        assert_true(true_lo[a] - lo[a] <= quantum);
        assert_true(hi[a] - true_hi[a] <= quantum);
    }

    /* the full-resolution mesh (the archive's box, p bits): every vertex inside */
    ms_qmesh q = {0};
    ms_nsp_test_reference(source, h.bits, &q);
    assert_memory_equal(q.box.origin, h.box_origin, sizeof h.box_origin);
    assert_true(q.box.size == h.box_side);
    for (size_t v = 0; v < q.vertex_count; ++v)
        for (int a = 0; a < 3; ++a) {
            double x = ms_dequantise(&q.box, q.bits, a, q.coords[3 * v + (size_t)a]);
            assert_true(lo[a] <= x && x <= hi[a]);
        }
    ms_qmesh_free(&q);
    ms_core_opening_free(&by_subtree);
    ms_core_opening_free(&whole);
}

/* The demo: a tree of cells (N_min 1500 on 4000 triangles). */
static void test_demo_bounds(void **state)
{
    (void)state;
    check_model("demo", fx.demo_source);
}

/* The bunny in one cell: its root is a leaf whose window runs to p; the
 * bounds come at root precision all the same. */
static void test_bunny_one_cell_bounds(void **state)
{
    (void)state;
    check_model("bunny", fx.bunny_source);
}

/* The bunny as a tree (N_min 300). */
static void test_bunny_tree_bounds(void **state)
{
    (void)state;
    check_model("bunnytree", fx.bunny_source);
}

static int setup(void **state)
{
    (void)state;
    if (ms_nsp_test_demo_archive(fx.dir, sizeof fx.dir, fx.archives, sizeof fx.archives) != 0)
        return -1;
    snprintf(fx.demo_source, sizeof fx.demo_source, "%s/demo.ply", fx.dir);
    ms_test_model_path(fx.bunny_source, sizeof fx.bunny_source, "stanford_bunny_res3.ply.gz");
    ms_bake_report report;
    ms_nsp_test_bake(fx.bunny_source, fx.archives, "bunny", 16, 0, &report);
    if (report.cells != 1) {
        fprintf(stderr, "the bunny baked into %u cells, not one\n", (unsigned)report.cells);
        return -1;
    }
    ms_nsp_test_bake(fx.bunny_source, fx.archives, "bunnytree", 16, 300, &report);
    if (report.cells < 2) {
        fprintf(stderr, "the bunny tree baked into one cell\n");
        return -1;
    }
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    ms_test_rmdir(fx.dir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_demo_bounds),
        cmocka_unit_test(test_bunny_one_cell_bounds),
        cmocka_unit_test(test_bunny_tree_bounds),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
