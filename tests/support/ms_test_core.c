/* Helpers for tests that drive the client core (ms_test_core.h). */
#include "ms_test_core.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <time.h>
#include <cmocka.h>

#include "ms_progress.h"
#include "ms_test.h"
#include "ms_test_net.h"

void ms_test_sleep_s(double seconds)
{
    struct timespec ts = {(time_t)seconds, (long)((seconds - floor(seconds)) * 1e9)};
    nanosleep(&ts, NULL);
}

void ms_test_core_assert_frames_equal(const ms_core_frame *a, const ms_core_frame *b)
{
    assert_int_equal(a->cell_count, b->cell_count);
    assert_int_equal(a->cut_count, b->cut_count);
    assert_memory_equal(a->cut_cells, b->cut_cells, a->cut_count * sizeof *a->cut_cells);
    assert_memory_equal(a->cut_bits, b->cut_bits, a->cut_count);
    const ms_view_mesh *x = &a->mesh, *y = &b->mesh;
    assert_int_equal(x->vertex_count, y->vertex_count);
    assert_int_equal(x->triangle_count, y->triangle_count);
    assert_memory_equal(x->positions, y->positions, 3 * x->vertex_count * sizeof *x->positions);
    assert_memory_equal(x->keys, y->keys, x->vertex_count * sizeof *x->keys);
    assert_memory_equal(x->levels, y->levels, x->vertex_count);
    assert_memory_equal(x->triangles, y->triangles, 3 * x->triangle_count * sizeof *x->triangles);
    assert_memory_equal(x->triangle_cell, y->triangle_cell,
                        x->triangle_count * sizeof *x->triangle_cell);
    assert_int_equal(a->apo_count, b->apo_count);
    for (size_t i = 0; i < a->apo_count; ++i) {
        assert_int_equal(a->apo[i].cell, b->apo[i].cell);
        assert_int_equal(a->apo[i].levels, b->apo[i].levels);
        assert_int_equal(a->apo[i].length, b->apo[i].length);
        assert_memory_equal(a->apo[i].data, b->apo[i].data, a->apo[i].length);
    }
}

/* Replaces *frame by the core's newest frame, if one was published. */
static void keep_newest_frame(ms_core *core, ms_core_frame **frame)
{
    ms_core_frame *f = ms_core_take_frame(core);
    if (f) {
        ms_core_frame_free(*frame);
        *frame = f;
    }
}

bool ms_test_core_wait_complete(ms_core *core, double seconds, ms_core_stats *stats,
                                ms_core_frame **frame)
{
    double until = ms_now_seconds() + seconds;
    for (;;) {
        if (frame)
            keep_newest_frame(core, frame);
        ms_core_get_stats(core, stats);
        if (stats->view_complete || stats->error[0] || ms_now_seconds() > until) {
            if (frame && stats->view_complete)
                keep_newest_frame(core, frame);
            return stats->view_complete;
        }
        ms_test_sleep_s(0.005);
    }
}

ms_camera ms_test_core_key_camera(const ms_camera_path *path, size_t k)
{
    ms_camera cam;
    ms_error err;
    double t = path->keys[k < path->count ? k : path->count - 1].time;
    if (ms_camera_path_sample(path, t, 640, 480, 1e-4, 1e4, &cam, &err) != MS_OK)
        fail_msg("%s", err.text);
    return cam;
}

ms_test_served *ms_test_served_new(const char *model)
{
    ms_test_served *s = calloc(1, sizeof *s);
    assert_non_null(s);
    ms_test_tmpdir(s->dir, sizeof s->dir);
    snprintf(s->archives, sizeof s->archives, "%s/archive", s->dir);
    snprintf(s->file, sizeof s->file, "%s/%s.msa", s->archives, model);
    snprintf(s->log, sizeof s->log, "%s/meshserve.log", s->dir);
    snprintf(s->port_file, sizeof s->port_file, "%s/ports", s->dir);
    if (mkdir(s->archives, 0755) != 0) {
        free(s);
        return NULL;
    }
    return s;
}

int ms_test_served_open(ms_test_served *s, const char *path_file)
{
    ms_error err;
    if (ms_archive_open(s->file, &s->archive, &err) != MS_OK ||
        ms_camera_path_load(path_file, &s->path, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    return 0;
}

void ms_test_served_launch(ms_test_served *s, uint16_t port)
{
    s->pid = ms_test_meshserve_start(s->archives, NULL, port, s->port_file, s->log, &s->port,
                                     &s->http_port);
    if (!s->pid)
        fail_msg("meshserve did not start (see %s)", s->log);
}

void ms_test_served_free(ms_test_served *s)
{
    if (!s)
        return;
    if (s->pid)
        ms_test_stop(s->pid, SIGTERM, 10.0);
    ms_archive_close(s->archive);
    ms_camera_path_free(&s->path);
    ms_test_rmdir(s->dir);
    free(s);
}

ms_core_options ms_test_served_core_options(const ms_test_served *s, const char *model)
{
    ms_core_options o = {0};
    o.host = "127.0.0.1";
    o.port = s->port;
    o.model = model;
    o.tolerance_px = 1.0;
    o.hysteresis_bits = 0.0;
    o.answer_timeout = 3.0;
    o.give_up_seconds = 20.0;
    return o;
}
