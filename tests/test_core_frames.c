/* The client core's frames counted cell by cell (ms_client_core.h,
 * ms_core_frame_work; docs/CLIENT.md "Frames") and what the renderer does
 * with them (ms_render_frame_stats). On the built-in demo model (about 30,000
 * triangles, APO in every cell) read from a local archive, along the demo
 * close-up with the bytes throttled so that each keyframe refines over many
 * passes, for every frame taken that directly follows the one taken before it
 * (generation + 1, so that the core's counts are against that frame):
 *   - each APO chunk whose prefix did not change is the previous frame's
 *     bytes, the same memory (shared, not copied); apo_bytes_copied is exactly
 *     the bytes of the chunks new or grown, and the chunks copied and shared
 *     add up to the frame's chunks;
 *   - cells_changed and cells_removed are exactly the drawing cells new or with
 *     another run version and the cells gone, counted here from both meshes;
 *     cells_stitched and triangles_stitched are exactly the runs (drawing or
 *     not) new or with another version and their triangles: the stitch worked
 *     out those cells again and kept the others' pieces;
 *   - the renderer given the frame finds the same cells changed and gone, and
 *     derives no mesh when none changed and none left;
 *   - for every frame the renderer makes again exactly the changed cells'
 *     meshes and those of the neighbours whose normals moved (counted apart,
 *     at most the neighbours looked at), queues only meshes it made, and its
 *     upload sends the meshes queued plus cells whose APO prefix alone changed;
 *   - every cell's mesh is the one a renderer deriving the whole frame makes
 *     (counts and content hash);
 *   - the same frame given again derives, makes, walks and uploads nothing.
 * A camera set again unchanged publishes no frame. Every wait is bounded. */
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
#include "ms_client_core.h"
#include "ms_progress.h"
#include "ms_render.h"
#include "ms_render_internal.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_test_render.h"

#define PATH_FILE "scripts/paths/demo-closeup.cam"
#define WAIT_SECONDS 60.0

static ms_test_gl gl;

typedef struct totals {
    unsigned exact_frames;   /* frames checked against their direct predecessor */
    unsigned refining;       /* of them, frames that changed some cells */
    uint64_t chunks_shared, chunks_copied, bytes_copied, bytes_shown;
    uint64_t cells_stitched, cells_drawn;
    uint64_t rebuilt, neighbours_moved, neighbours_kept; /* the renderer's, every frame */
} totals;

/* Whether cell's run in m has triangles, and its version. */
static bool drawn(const ms_view_mesh *m, uint32_t cell, uint64_t *version)
{
    size_t lo = 0, hi = m->run_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (m->run_cell[mid] < cell)
            lo = mid + 1;
        else
            hi = mid;
    }
    if (lo == m->run_count || m->run_cell[lo] != cell || m->run_first[lo + 1] == m->run_first[lo])
        return false;
    *version = m->run_version[lo];
    return true;
}

static const ms_core_apo_chunk *chunk_of(const ms_core_frame *f, uint32_t cell)
{
    for (size_t i = 0; i < f->apo_count; ++i)
        if (f->apo[i].cell == cell)
            return &f->apo[i];
    return NULL;
}

/* The counts of frame b, which directly follows a, recounted from both. */
static void check_against_previous(const ms_core_frame *a, const ms_core_frame *b, totals *t)
{
    uint32_t shared = 0, copied = 0, changed = 0, removed = 0, present = 0;
    uint64_t bytes = 0;
    for (size_t i = 0; i < b->apo_count; ++i) {
        const ms_core_apo_chunk *now = &b->apo[i], *before = chunk_of(a, now->cell);
        assert_non_null(now->shared);
        if (before && before->length == now->length) {
            /* the very bytes of the previous frame */
            assert_ptr_equal(before->data, now->data);
            shared++;
        } else {
            assert_true(!before || before->data != now->data);
            copied++;
            bytes += now->length;
        }
        t->bytes_shown += now->length;
    }
    assert_int_equal(b->work.apo_chunks_shared, shared);
    assert_int_equal(b->work.apo_chunks_copied, copied);
    assert_int_equal(b->work.apo_bytes_copied, bytes);
    for (size_t k = 0; k < b->mesh.run_count; ++k) {
        uint64_t vb, va;
        if (!drawn(&b->mesh, b->mesh.run_cell[k], &vb))
            continue;
        present++;
        changed += !drawn(&a->mesh, b->mesh.run_cell[k], &va) || va != vb;
    }
    for (size_t k = 0; k < a->mesh.run_count; ++k) {
        uint64_t va, vb;
        removed += drawn(&a->mesh, a->mesh.run_cell[k], &va) && !drawn(&b->mesh, a->mesh.run_cell[k], &vb);
    }
    assert_int_equal(b->work.cells_changed, changed);
    assert_int_equal(b->work.cells_removed, removed);
    /* the stitch worked out exactly the runs new or with another version
     * (empty ones included), and kept the others */
    uint32_t restitched = 0;
    uint64_t tris = 0;
    for (size_t k = 0; k < b->mesh.run_count; ++k) {
        size_t lo = 0, hi = a->mesh.run_count;
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (a->mesh.run_cell[mid] < b->mesh.run_cell[k])
                lo = mid + 1;
            else
                hi = mid;
        }
        if (lo == a->mesh.run_count || a->mesh.run_cell[lo] != b->mesh.run_cell[k] ||
            a->mesh.run_version[lo] != b->mesh.run_version[k]) {
            restitched++;
            tris += b->mesh.run_first[k + 1] - b->mesh.run_first[k];
        }
    }
    assert_int_equal(b->work.cells_stitched, restitched);
    assert_int_equal(b->work.triangles_stitched, tris);
    t->cells_stitched += restitched;
    t->cells_drawn += present;
    t->exact_frames++;
    t->refining += changed > 0;
    t->chunks_shared += shared;
    t->chunks_copied += copied;
    t->bytes_copied += bytes;
}

/* Every cell of frame f wants in r (its pending mesh, else its current one)
 * the mesh a renderer that derives the whole frame makes: same counts and the
 * same content hash (over the vertices, normals and indices). */
static void check_against_fresh(const ms_render *r, const ms_core_frame *f, const ms_archive_header *header)
{
    ms_render *fresh;
    ms_error err;
    if (ms_render_new(NULL, NULL, &fresh, &err) != MS_OK || ms_render_set_model(fresh, header, &err) != MS_OK ||
        ms_render_learn(fresh, f->record_ids, f->records, f->record_count, &err) != MS_OK ||
        ms_render_set_frame(fresh, &f->mesh, f->apo, f->apo_count, &err) != MS_OK)
        fail_msg("%s", err.text);
    for (uint32_t k = 0; k < fresh->split.present_count; ++k) {
        uint32_t cell = fresh->split.present[k];
        const render_cell *a = ms_render_cell_at(r, cell), *b = ms_render_cell_at(fresh, cell);
        assert_true(a && b && b->next_mesh.active);
        const gpu_mesh *x = a->next_mesh.active ? &a->next_mesh.gpu : &a->mesh, *y = &b->next_mesh.gpu;
        if (x->hash != y->hash || x->vertex_count != y->vertex_count || x->triangle_count != y->triangle_count)
            fail_msg("cell %u: the incremental mesh is not the fresh one", cell);
    }
    ms_render_free(fresh);
}

/* The frame to the renderer; its figures, and with `again` the same frame
 * once more: nothing derived, nothing uploaded. */
static void render_frame(ms_render *r, const ms_core_frame *f, const ms_core_frame *previous,
                         const ms_archive_header *header, totals *t)
{
    ms_error err;
    if (ms_render_learn(r, f->record_ids, f->records, f->record_count, &err) != MS_OK ||
        ms_render_set_frame(r, &f->mesh, f->apo, f->apo_count, &err) != MS_OK)
        fail_msg("%s", err.text);
    check_against_fresh(r, f, header);
    ms_render_frame_stats st;
    ms_render_frame_stats_get(r, &st);
    t->rebuilt += st.cells_rebuilt;
    t->neighbours_moved += st.neighbours_moved;
    t->neighbours_kept += st.cells_derived - st.cells_changed - st.neighbours_moved;
    uint32_t present = 0;
    for (size_t k = 0; k < f->mesh.run_count; ++k)
        present += f->mesh.run_first[k + 1] > f->mesh.run_first[k];
    assert_int_equal(st.cells_present, present);
    if (previous && f->generation == previous->generation + 1) {
        assert_int_equal(st.cells_changed, f->work.cells_changed);
        assert_int_equal(st.cells_left, f->work.cells_removed);
        assert_true(st.cells_derived >= st.cells_changed);
        if (f->work.cells_changed == 0 && f->work.cells_removed == 0)
            assert_int_equal(st.cells_derived, 0);
    }
    /* made again: the changed cells and the neighbours whose normals moved,
     * no other; queued for upload: only meshes made again */
    assert_int_equal(st.cells_rebuilt, st.cells_changed + st.neighbours_moved);
    assert_true(st.neighbours_moved <= st.cells_derived - st.cells_changed);
    assert_true(st.cells_queued <= st.cells_rebuilt);
    ms_render_upload_stats up;
    if (ms_render_upload(r, UINT64_MAX / 2, &up, &err) != MS_OK)
        fail_msg("%s", err.text);
    /* what goes up: the meshes queued (all of them, the budget being
     * unbounded here), and cells whose APO prefix alone changed */
    assert_true(up.cells_completed >= st.cells_queued);
    assert_true(up.cells_completed <= st.cells_queued + f->apo_count);
    assert_int_equal(up.cells_pending, 0);
    /* the same frame again: no cell changed, none derived, nothing to send */
    if (ms_render_set_frame(r, &f->mesh, f->apo, f->apo_count, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_render_frame_stats_get(r, &st);
    assert_int_equal(st.cells_changed, 0);
    assert_int_equal(st.cells_left, 0);
    assert_int_equal(st.cells_derived, 0);
    assert_int_equal(st.vertex_fans, 0);
    assert_int_equal(st.cells_rebuilt, 0);
    assert_int_equal(st.cells_queued, 0);
    assert_int_equal(st.triangles_walked, 0);
    if (ms_render_upload(r, UINT64_MAX / 2, &up, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(up.bytes, 0);
    assert_int_equal(up.cells_completed, 0);
}

static void test_frames_cell_by_cell(void **state)
{
    (void)state;
    char dir[512], file[700];
    ms_test_tmpdir(dir, sizeof dir);
    ms_archive *archive = ms_test_render_bake_demo(50, dir, 16, 1500, 6);
    ms_archive_header header = *ms_archive_get_header(archive);
    ms_archive_close(archive);
    snprintf(file, sizeof file, "%s/demo.msa", dir);
    ms_camera_path path;
    ms_error err;
    if (ms_camera_path_load(PATH_FILE, &path, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_render *r;
    if (ms_render_new(NULL, NULL, &r, &err) != MS_OK || ms_render_set_model(r, &header, &err) != MS_OK)
        fail_msg("%s", err.text);

    ms_core_options o = {0};
    o.archive_path = file;
    o.tolerance_px = 1.0;
    o.hysteresis_bits = 0.5;
    o.apo_levels = 11;
    o.bandwidth = 400e3;
    o.window_bytes = 16384;
    o.export_frames = true;
    ms_core *core;
    if (ms_core_start(&o, &core, &err) != MS_OK)
        fail_msg("%s", err.text);
    totals t = {0};
    ms_core_frame *previous = NULL;
    ms_core_stats st = {0};
    for (size_t k = 0; k < path.count; ++k) {
        ms_camera cam = ms_test_core_key_camera(&path, k);
        ms_core_set_camera(core, &cam);
        double until = ms_now_seconds() + WAIT_SECONDS;
        for (;;) {
            ms_core_get_stats(core, &st);
            ms_core_frame *f = ms_core_take_frame(core);
            if (f) {
                if (previous && f->generation == previous->generation + 1)
                    check_against_previous(previous, f, &t);
                render_frame(r, f, previous, &header, &t);
                ms_core_frame_free(previous);
                previous = f;
            }
            if ((st.view_complete && st.camera_serial > 0 && !f) || st.error[0] ||
                ms_now_seconds() > until)
                break;
            ms_test_sleep_s(0.001);
        }
        if (st.error[0] || !st.view_complete)
            fail_msg("keyframe %zu not complete: '%s'", k, st.error);
    }
    /* the camera again, unchanged: a pass that changes nothing publishes no frame */
    ms_camera cam = ms_test_core_key_camera(&path, path.count - 1);
    ms_core_set_camera(core, &cam);
    ms_test_sleep_s(0.3);
    ms_core_frame *none = ms_core_take_frame(core);
    assert_null(none);
    ms_core_stop(core);
    printf("frames checked against their predecessor: %u (%u refining); APO chunks shared %llu, "
           "copied %llu; bytes copied %llu of %llu shown; cells stitched %llu of %llu drawn\n",
           t.exact_frames, t.refining, (unsigned long long)t.chunks_shared, (unsigned long long)t.chunks_copied,
           (unsigned long long)t.bytes_copied, (unsigned long long)t.bytes_shown,
           (unsigned long long)t.cells_stitched, (unsigned long long)t.cells_drawn);
    printf("renderer: meshes made again %llu, of them neighbours whose normals moved %llu; neighbours kept %llu\n",
           (unsigned long long)t.rebuilt, (unsigned long long)t.neighbours_moved,
           (unsigned long long)t.neighbours_kept);
    assert_true(t.exact_frames >= 5);
    assert_true(t.refining >= 3);
    assert_true(t.chunks_shared > 0);
    assert_true(t.bytes_copied < t.bytes_shown);
    assert_true(t.cells_stitched < t.cells_drawn);
    ms_core_frame_free(previous);
    ms_render_free(r);
    ms_camera_path_free(&path);
    ms_test_rmdir(dir);
}

static int setup(void **state)
{
    (void)state;
    ms_test_gl_start(&gl);
    return 0;
}

static int teardown(void **state)
{
    (void)state;
    ms_test_gl_stop(&gl);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_frames_cell_by_cell),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
