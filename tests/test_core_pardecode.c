/* Decoding on every core (issue 35, item 2; docs/CLIENT.md, "Decoding on
 * every core"): the view's shown cells refined and split in waves on the
 * decode pool (ms_view_refine_parallel), on the built-in demo model (small,
 * baked here), in process:
 *   - for a near and a far camera and back, the view refined in waves on a
 *     pool of one helper (and stitched on it: ms_view_set_pool), in waves on
 *     the caller alone, and by ms_view_apply alone holds the same cut and
 *     stitches the same mesh, byte for byte;
 *     the waves' job counts do not depend on the threads, and with every
 *     byte at hand apply has no refinement or split left to do;
 *   - the client core in local mode with decode_threads 1 and 2 completes
 *     the same view with the same frame (cut and mesh); with 2 a helper ran
 *     jobs, every split was a job of the pool's waves and ms_view_apply
 *     decoded nothing itself (the serial share of the decoding steps: 0 of
 *     them, counted, not timed).
 * Every wait is bounded. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_client_core.h"
#include "ms_nsp_check.h"
#include "ms_parallel.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_view_decoder.h"
#include "ms_view_refine.h"

#define MODEL "demo"
#define TRIANGLES 60000
#define WAIT_SECONDS 60.0
/* runs of the core with 2 threads until a helper has run a job: a loaded
 * machine may leave the helper unscheduled through one whole run */
#define HELPER_TRIES 5

typedef ms_nsp_test_demo fixture;

static fixture *g;

static int group_setup(void **state)
{
    (void)state;
    g = ms_nsp_test_demo_new(TRIANGLES, 1000);
    return g ? 0 : -1;
}

static int group_teardown(void **state)
{
    (void)state;
    ms_nsp_test_demo_free(g);
    g = NULL;
    return 0;
}

/* Looking at a point off the model's centre from `distance` box sides away. */
static ms_camera camera_at(double distance)
{
    double target[3] = {g->centre[0] + 0.2 * g->side, g->centre[1], g->centre[2] + 0.3 * g->side};
    double pos[3] = {target[0] + 0.3 * distance * g->side, target[1] + 0.2 * distance * g->side,
                     target[2] + distance * g->side};
    double up[3] = {0, 1, 0};
    ms_camera cam;
    ms_error err;
    if (ms_camera_look_at(pos, target, up, 45.0, 1280, 720, 1e-3 * g->side, 1e3 * g->side, &cam,
                          &err) != MS_OK)
        fail_msg("%s", err.text);
    return cam;
}

/* The two views hold the same cut: every cell in the same state and precision. */
static void assert_same_cut(const ms_view *a, const ms_view *b)
{
    assert_int_equal(ms_view_cell_count(a), ms_view_cell_count(b));
    for (uint32_t c = 0; c < ms_view_cell_count(a); ++c) {
        if (ms_view_state(a, c) != ms_view_state(b, c) || ms_view_bits(a, c) != ms_view_bits(b, c))
            fail_msg("cell %u: state %d at %u bits against %d at %u", c, ms_view_state(a, c),
                     ms_view_bits(a, c), ms_view_state(b, c), ms_view_bits(b, c));
    }
}

static void assert_same_mesh(const ms_view_mesh *a, const ms_view_mesh *b)
{
    assert_int_equal(a->vertex_count, b->vertex_count);
    assert_int_equal(a->triangle_count, b->triangle_count);
    assert_memory_equal(a->positions, b->positions, 3 * a->vertex_count * sizeof *a->positions);
    assert_memory_equal(a->keys, b->keys, a->vertex_count * sizeof *a->keys);
    assert_memory_equal(a->levels, b->levels, a->vertex_count * sizeof *a->levels);
    assert_memory_equal(a->triangles, b->triangles, 3 * a->triangle_count * sizeof *a->triangles);
    assert_memory_equal(a->triangle_cell, b->triangle_cell,
                        a->triangle_count * sizeof *a->triangle_cell);
}

static ms_view *open_view(ms_archive **archive)
{
    ms_error err;
    ms_view *v;
    if (ms_archive_open(g->file, archive, &err) != MS_OK ||
        ms_view_create_from_archive(*archive, &v, &err) != MS_OK)
        fail_msg("%s", err.text);
    return v;
}

/* Near, far and near again: three views (waves on a pool of one helper, waves
 * on the caller alone, apply alone) agree at every step. */
static void test_waves_equal_apply(void **state)
{
    (void)state;
    ms_archive *archive[3];
    ms_view *v[3];
    for (int k = 0; k < 3; ++k)
        v[k] = open_view(&archive[k]);
    ms_pool *pool;
    ms_error err;
    assert_int_equal(ms_pool_new(1, &pool, &err), MS_OK);
    ms_view_set_pool(v[0], pool); /* its stitch's caches and pieces on the pool too */
    ms_view_refine_jobs jobs[2] = {{0}, {0}};
    ms_view_mesh mesh[3];
    memset(mesh, 0, sizeof mesh);
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    const double distances[] = {0.3, 8.0, 0.3};
    size_t splits_seen = 0;
    for (size_t step = 0; step < sizeof distances / sizeof *distances; ++step) {
        ms_camera cam = camera_at(distances[step]);
        ms_view_apply_report report[3];
        for (int k = 0; k < 3; ++k) {
            ms_view_select(v[k], &cam, &params, NULL);
            if (k < 2)
                (void)ms_view_refine_parallel(v[k], k == 0 ? pool : NULL, &jobs[k]);
            assert_int_equal(ms_view_apply(v[k], &report[k], &err), MS_OK);
            assert_int_equal(ms_view_stitch(v[k], NULL, &mesh[k], &err), MS_OK);
        }
        for (int k = 0; k < 2; ++k) {
            /* every byte at hand: the waves left apply nothing to decode */
            assert_int_equal(report[k].refined, 0);
            assert_int_equal(report[k].splits, 0);
            assert_int_equal(report[k].waiting, 0);
        }
        splits_seen += report[2].splits;
        assert_same_cut(v[0], v[2]);
        assert_same_cut(v[1], v[2]);
        assert_same_mesh(&mesh[0], &mesh[2]);
        assert_same_mesh(&mesh[1], &mesh[2]);
        /* the jobs are the work's, not the threads' */
        assert_int_equal(jobs[0].stats.jobs, jobs[1].stats.jobs);
        assert_int_equal(jobs[0].stats.splits, jobs[1].stats.splits);
        assert_int_equal(jobs[0].stats.waves, jobs[1].stats.waves);
        assert_int_equal(jobs[1].stats.jobs_on_helpers, 0);
        assert_int_equal(jobs[0].stats.splits, splits_seen);
    }
    assert_true(mesh[0].triangle_count > 1000);
    assert_true(splits_seen > 3); /* a real cut, split on more than one level */
    assert_true(jobs[0].stats.waves > 2);
    for (int k = 0; k < 3; ++k) {
        ms_view_mesh_free(&mesh[k]);
        ms_view_destroy(v[k]);
        ms_archive_close(archive[k]);
    }
    for (int k = 0; k < 2; ++k)
        ms_view_refine_jobs_free(&jobs[k]);
    ms_pool_free(pool);
}

/* The core on the local archive with decode_threads `threads`, to view
 * complete at cam; its frame and figures. */
static ms_core_frame *core_frame(unsigned threads, const ms_camera *cam, ms_core_stats *st)
{
    ms_core_options o = {0};
    o.archive_path = g->file;
    o.tolerance_px = 1.0;
    o.apo_levels = 0;
    o.export_frames = true;
    o.decode_threads = threads;
    ms_core *core;
    ms_error err;
    if (ms_core_start(&o, &core, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_core_set_camera(core, cam);
    ms_core_frame *frame = NULL;
    if (!ms_test_core_wait_complete(core, WAIT_SECONDS, st, &frame))
        fail_msg("%u threads: view not complete: '%s' '%s'", threads, st->error, st->warning);
    ms_core_stop(core);
    assert_non_null(frame);
    return frame;
}

static void test_core_one_and_two_threads(void **state)
{
    (void)state;
    ms_camera cam = camera_at(0.3);
    ms_core_stats s1, s2;
    ms_core_frame *f1 = core_frame(1, &cam, &s1);
    assert_true(f1->mesh.triangle_count > 1000);
    assert_true(s1.cells_split > 1);
    /* one thread: the waves ran on the decode thread alone */
    assert_int_equal(s1.decode_work.jobs_on_helpers, 0);
    assert_true(s1.decode_work.helper_cpu == 0.0);
    ms_core_frame *f2 = NULL;
    for (int tries = 0; tries < HELPER_TRIES; ++tries) {
        ms_core_frame_free(f2);
        f2 = core_frame(2, &cam, &s2);
        ms_test_core_assert_frames_equal(f1, f2);
        if (s2.decode_work.jobs_on_helpers > 0)
            break;
    }
    const ms_core_decode_work *w = &s2.decode_work;
    assert_true(w->jobs_on_helpers > 0);
    assert_true(w->jobs_on_helpers <= w->jobs);
    assert_true(w->helper_cpu > 0.0);
    /* every split of the cut was a pool job, and apply decoded nothing: the
     * decoding steps outside the pool's waves are 0 of w->jobs */
    assert_int_equal(w->splits, s2.cells_split);
    assert_int_equal(w->apply_splits, 0);
    assert_int_equal(w->apply_refined, 0);
    assert_true(w->jobs >= s2.cells_split);
    assert_true(w->passes > 0 && w->waves > 0);
    assert_int_equal(s1.decode_work.splits, w->splits);
    ms_core_frame_free(f1);
    ms_core_frame_free(f2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_waves_equal_apply),
        cmocka_unit_test(test_core_one_and_two_threads),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
