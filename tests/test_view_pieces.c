/* The stitch that keeps each shown cell's piece (ms_view_stitch,
 * ms_view_mesh.cells_stitched; docs/CLIENT.md "Frames"): on the built-in demo
 * model (about 30,000 triangles), refined one selection round at a time
 * along the demo close-up and back out, every stitch is, byte for byte
 * (vertices, keys, levels, triangles, their cells, runs and versions,
 * figures), the stitch of a twin view whose pieces are all forgotten first;
 * it works out again exactly the cells whose run is new or has another
 * version (k cells changed: k stitched, the rest kept), and a stitch with
 * nothing changed works out none. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_camera_path.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_test_render.h"
#include "ms_view_decoder.h"
#include "ms_view_decoder_internal.h"

#define PATH_FILE "scripts/paths/demo-closeup.cam"

static void assert_meshes_equal(const ms_view_mesh *a, const ms_view_mesh *b)
{
    assert_int_equal(a->vertex_count, b->vertex_count);
    assert_int_equal(a->triangle_count, b->triangle_count);
    assert_int_equal(a->run_count, b->run_count);
    assert_int_equal(a->dropped_finer, b->dropped_finer);
    assert_int_equal(a->dropped_snapped, b->dropped_snapped);
    assert_int_equal(a->unresolved, b->unresolved);
    assert_int_equal(a->snapped_frozen, b->snapped_frozen);
    assert_true((a->colours == NULL) == (b->colours == NULL));
    size_t nv = a->vertex_count, nt = a->triangle_count, nr = a->run_count;
    if (nv) {
        assert_memory_equal(a->positions, b->positions, 3 * nv * sizeof *a->positions);
        assert_memory_equal(a->keys, b->keys, nv * sizeof *a->keys);
        assert_memory_equal(a->levels, b->levels, nv);
        if (a->colours)
            assert_memory_equal(a->colours, b->colours, 4 * nv);
    }
    if (nt) {
        assert_memory_equal(a->triangles, b->triangles, 3 * nt * sizeof *a->triangles);
        assert_memory_equal(a->triangle_cell, b->triangle_cell, nt * sizeof *a->triangle_cell);
    }
    if (nr) {
        assert_memory_equal(a->run_cell, b->run_cell, nr * sizeof *a->run_cell);
        assert_memory_equal(a->run_first, b->run_first, (nr + 1) * sizeof *a->run_first);
        assert_memory_equal(a->run_version, b->run_version, nr * sizeof *a->run_version);
    }
}

/* Runs of now that are new against before or carry another version. */
static size_t runs_changed(const ms_view_mesh *before, const ms_view_mesh *now)
{
    size_t changed = 0, j = 0;
    for (size_t k = 0; k < now->run_count; ++k) {
        while (j < before->run_count && before->run_cell[j] < now->run_cell[k])
            j++;
        changed += j == before->run_count || before->run_cell[j] != now->run_cell[k] ||
                   before->run_version[j] != now->run_version[k];
    }
    return changed;
}

static void test_pieces_kept(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_archive *archive = ms_test_render_bake_demo(50, dir, 16, 1500, 4);
    ms_camera_path path;
    ms_error err;
    if (ms_camera_path_load(PATH_FILE, &path, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_view *kept, *fresh;
    assert_int_equal(ms_view_create_from_archive(archive, &kept, &err), MS_OK);
    assert_int_equal(ms_view_create_from_archive(archive, &fresh, &err), MS_OK);
    ms_view_mesh a = {0}, b = {0}, before = {0};
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = 1.0;
    size_t stitches = 0, partial = 0, stitched = 0, runs = 0;
    /* in along the path, then back out to its first key */
    for (size_t step = 0; step < 2 * path.count - 1; ++step) {
        size_t k = step < path.count ? step : 2 * path.count - 2 - step;
        ms_camera cam = ms_test_core_key_camera(&path, k);
        for (int round = 0; round < 64; ++round) {
            ms_view_select(kept, &cam, &params, NULL);
            ms_view_select(fresh, &cam, &params, NULL);
            ms_view_apply_report ra, rb;
            assert_int_equal(ms_view_apply(kept, &ra, &err), MS_OK);
            assert_int_equal(ms_view_apply(fresh, &rb, &err), MS_OK);
            assert_memory_equal(&ra, &rb, sizeof ra);
            if (round > 0 && ra.splits + ra.merges + ra.refined + ra.coarsened == 0)
                break;
            assert_int_equal(ms_view_stitch(kept, NULL, &a, &err), MS_OK);
            ms_view_pieces_forget(fresh);
            assert_int_equal(ms_view_stitch(fresh, NULL, &b, &err), MS_OK);
            assert_meshes_equal(&a, &b);
            assert_int_equal(b.cells_stitched, b.run_count);
            /* exactly the cells whose triangles may have changed */
            assert_int_equal(a.cells_stitched, runs_changed(&before, &a));
            stitches++;
            partial += a.cells_stitched < a.run_count;
            stitched += a.cells_stitched;
            runs += a.run_count;
            /* nothing changed: nothing worked out, the same mesh */
            assert_int_equal(ms_view_stitch(kept, NULL, &before, &err), MS_OK);
            assert_int_equal(before.cells_stitched, 0);
            assert_int_equal(before.triangles_stitched, 0);
            assert_meshes_equal(&a, &before);
        }
    }
    printf("%zu stitches (%zu keeping some pieces): %zu cells worked out of %zu drawn\n", stitches, partial,
           stitched, runs);
    assert_true(stitches >= 10);
    assert_true(partial >= 5);
    assert_true(stitched < runs / 2);
    ms_view_mesh_free(&a);
    ms_view_mesh_free(&b);
    ms_view_mesh_free(&before);
    ms_view_destroy(kept);
    ms_view_destroy(fresh);
    ms_camera_path_free(&path);
    ms_archive_close(archive);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_pieces_kept),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
