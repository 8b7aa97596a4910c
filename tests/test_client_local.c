/* The client core's local mode (ms_core_options.archive_path: an archive read
 * from disk, no server) and the two ways a front end lists models (a server's
 * catalogue, ms_client_fetch_catalogue; a directory's catalog.json,
 * ms_catalog_load). On the built-in demo model, small (about 30,000
 * triangles), baked here with APO chunks:
 *   - for the demo close-up's last keyframe, the local mode's frame at view
 *     complete equals, byte for byte (mesh, cut, APO chunk prefixes), the frame
 *     of the network mode against meshserve for the same camera and tolerance;
 *   - the local mode completes every keyframe of the path;
 *   - a missing file, a file that is no archive, a truncated archive and a
 *     corrupted payload give one clear line each (error or failed cell), with
 *     nothing leaked (AddressSanitizer's leak check);
 *   - the catalogue of the server and of the directory list the model.
 * Every wait is bounded. */
#include <pthread.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_camera_path.h"
#include "ms_catalog.h"
#include "ms_client.h"
#include "ms_client_core.h"
#include "ms_nsp_check.h"
#include "ms_progress.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_test_net.h"

#define MODEL "demo"
#define PATH_FILE "scripts/paths/demo-closeup.cam"
#define TRIANGLES 30000
#define WAIT_SECONDS 60.0
#define APO_LEVELS 11

static ms_test_served *g;

static int group_setup(void **state)
{
    (void)state;
    ms_test_served *f = ms_test_served_new(MODEL);
    if (!f)
        return -1;
    /* APO chunks on the leaf cells too (by default their geometry renders the
     * input and they have none): the close-up shows leaf cells, and this test
     * is about how the client fetches and hands over chunks */
    if (ms_nsp_test_bake_demo(f->dir, TRIANGLES, f->archives, MODEL, 2000, true) != 0 ||
        ms_test_served_open(f, PATH_FILE) != 0)
        return -1;
    ms_test_served_launch(f, 0);
    g = f;
    return 0;
}

static int group_teardown(void **state)
{
    (void)state;
    ms_test_served_free(g);
    g = NULL;
    return 0;
}

static ms_camera key_camera(size_t k) { return ms_test_core_key_camera(&g->path, k); }

static ms_core_options network_options(void)
{
    ms_core_options o = ms_test_served_core_options(g, MODEL);
    o.apo_levels = APO_LEVELS;
    o.export_frames = true;
    return o;
}

static ms_core_options local_options(const char *file)
{
    ms_core_options o = network_options();
    o.host = NULL, o.port = 0, o.model = NULL;
    o.archive_path = file;
    return o;
}

/* Runs a core on options for camera until view complete; returns its frame. */
static ms_core_frame *complete_frame(const ms_core_options *o, const ms_camera *cam,
                                     ms_core_stats *st)
{
    ms_core *core;
    ms_error err;
    if (ms_core_start(o, &core, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_core_set_camera(core, cam);
    ms_core_frame *frame = NULL;
    if (!ms_test_core_wait_complete(core, WAIT_SECONDS, st, &frame))
        fail_msg("%s: view not complete: '%s' '%s'", o->archive_path ? "local" : "network",
                 st->error, st->warning);
    ms_core_stop(core);
    assert_non_null(frame);
    return frame;
}


/* APO by footprint: the frame holds, for every visible shown cell with a
 * chunk, exactly the levels ms_apo_footprint_levels gives (tolerance 1 px,
 * at most APO_LEVELS), and nothing else; returns the bytes held. */
static uint64_t check_apo_footprint(const ms_core_frame *f, const ms_camera *cam)
{
    const ms_archive_header *h = ms_archive_get_header(g->archive);
    ms_frustum fr;
    ms_camera_frustum(cam, &fr);
    uint64_t bytes = 0;
    size_t k = 0, clipped = 0;
    for (uint32_t i = 0; i < f->cell_count; ++i) {
        const ms_archive_cell *rec = ms_archive_get_cell(g->archive, i);
        double side = h->box_side, lo[3], hi[3];
        for (unsigned l = 0; l < rec->level; ++l)
            side /= h->n;
        for (int a = 0; a < 3; ++a) {
            lo[a] = h->box_origin[a] + side * rec->position[a];
            hi[a] = lo[a] + side;
        }
        bool wanted = ms_core_frame_cell_bits(f, i) < MS_VIEW_TARGET_SPLIT && rec->apo_length > 0 &&
                      ms_frustum_keeps_box(&fr, lo, hi, 0);
        if (!wanted) {
            assert_true(k == f->apo_count || f->apo[k].cell != i);
            continue;
        }
        assert_true(k < f->apo_count);
        assert_int_equal(f->apo[k].cell, i);
        unsigned cap = rec->apo_levels < APO_LEVELS ? rec->apo_levels : APO_LEVELS;
        unsigned levels = ms_apo_footprint_levels(cam, lo, side, 1.0, cap);
        if (f->apo[k].levels != levels)
            fail_msg("cell %u (level %u, %u APO levels): %u levels held (%zu bytes), footprint %u "
                     "(prefixes %u %u %u)", i, rec->level, rec->apo_levels, f->apo[k].levels,
                     f->apo[k].length, levels,
                     ms_archive_apo_prefix(g->archive, i, levels - 2, NULL),
                     ms_archive_apo_prefix(g->archive, i, levels - 1, NULL),
                     ms_archive_apo_prefix(g->archive, i, levels, NULL));
        /* ms_archive_apo_prefix(depth): the bytes of levels 0 .. depth */
        assert_int_equal(f->apo[k].length, ms_archive_apo_prefix(g->archive, i, levels - 1, NULL));
        clipped += levels < cap;
        bytes += f->apo[k].length;
        k++;
    }
    assert_int_equal(k, f->apo_count);
    assert_true(clipped > 0); /* the footprint, not the cap, decides somewhere */
    return bytes;
}

/* The close-up's last keyframe: the local frame is the network frame. */
static void test_local_equals_network(void **state)
{
    (void)state;
    ms_camera cam = key_camera(g->path.count - 1);
    ms_core_options on = network_options(), ol = local_options(g->file);
    ms_core_stats sn, sl;
    ms_core_frame *fn = complete_frame(&on, &cam, &sn);
    ms_core_frame *fl = complete_frame(&ol, &cam, &sl);
    assert_true(fn->mesh.triangle_count > 1000);
    uint32_t shown = 0;
    for (size_t i = 0; i < fn->cut_count; ++i)
        shown += fn->cut_bits[i] < MS_VIEW_TARGET_SPLIT;
    assert_true(shown > 1);    /* a real cut, not the root alone */
    assert_true(fn->apo_count > 0);
    ms_test_core_assert_frames_equal(fl, fn);
    uint64_t apo_held = check_apo_footprint(fl, &cam);
    /* from cold at a fixed camera, nothing but those prefixes is fetched (a
     * cell about to split fetches no APO) */
    assert_int_equal(sl.apo_bytes_received, apo_held);
    assert_int_equal(sn.apo_bytes_received, apo_held);
    /* the local figures: what was handed over, by stream; no socket */
    assert_true(sl.model_open);
    assert_int_equal(sl.error[0], 0);
    assert_int_equal(sl.cells_failed, 0);
    assert_int_equal(sl.socket_bytes, 0);
    assert_int_equal(sl.bytes_in_flight, 0);
    assert_true(sl.geometry_bytes_received > 0 && sl.apo_bytes_received > 0);
    assert_int_equal(sl.bytes_received, sl.geometry_bytes_received + sl.apo_bytes_received);
    assert_int_equal(sn.bytes_received, sn.geometry_bytes_received + sn.apo_bytes_received);
    assert_true(sl.first_display >= 0);
    ms_core_frame_free(fn);
    ms_core_frame_free(fl);
}

/* Along the path, each keyframe completes locally; throttled (64 KiB a
 * hand-over at 200 kB/s), the view refines over several passes: the first
 * frame that draws something is not yet the complete one. Geometry only, at
 * 1 px, so that there are bytes enough to spread. */
static void test_local_path(void **state)
{
    (void)state;
    ms_core_options o = local_options(g->file);
    o.hysteresis_bits = 0.5;
    o.apo_levels = 0;
    o.bandwidth = 200e3;
    o.window_bytes = 65536;
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_frame *first = NULL, *frame = NULL;
    ms_core_stats st;
    for (size_t k = 0; k < g->path.count; ++k) {
        ms_camera cam = key_camera(k);
        ms_core_set_camera(core, &cam);
        double until = ms_now_seconds() + WAIT_SECONDS;
        while (k == 0 && !first && ms_now_seconds() < until) {
            ms_core_frame *f = ms_core_take_frame(core);
            if (f && f->mesh.triangle_count > 0)
                first = f;
            else
                ms_core_frame_free(f);
            ms_test_sleep_s(0.002);
        }
        if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, &frame))
            fail_msg("keyframe %zu not complete: %s", k, st.error);
        if (k == 0) {
            assert_non_null(first);
            assert_non_null(frame);
            assert_true(frame->mesh.triangle_count != first->mesh.triangle_count ||
                        frame->cut_count != first->cut_count ||
                        memcmp(frame->cut_bits, first->cut_bits, frame->cut_count) != 0 ||
                        memcmp(frame->cut_cells, first->cut_cells,
                               frame->cut_count * sizeof *frame->cut_cells) != 0);
            fprintf(stderr, "local path: first drawn frame %zu triangles, complete %zu\n",
                    first->mesh.triangle_count, frame->mesh.triangle_count);
        }
    }
    fprintf(stderr, "local path: %llu bytes in %.2f s\n", (unsigned long long)st.bytes_received,
            st.time);
    assert_int_equal(st.apo_bytes_received, 0);
    assert_int_equal(st.geometry_bytes_received, st.bytes_received);
    assert_int_equal(st.cells_failed, 0);
    assert_true(st.requests > 0);
    ms_core_frame_free(first);
    ms_core_frame_free(frame);
    ms_core_stop(core);
}

/* A budget below what the root alone needs at the close-up (the camera in
 * the model's box: the root must split whatever the tolerance): the tolerance
 * climbs to its 4096x limit, the view never completes, and the core says so
 * once, in one line, instead of leaving the user to wait.
 * The warning and the tolerance it names are one snapshot: every snapshot
 * read here that carries the warning carries the 4096x tolerance too. (The
 * warning was once published mid-pass, and the tolerance at the pass's end,
 * one step short of 4096x until the next pass, 20 ms or more later: read
 * every half millisecond, that snapshot was seen nearly every run.) */
static void test_local_budget_below_the_root(void **state)
{
    (void)state;
    ms_core_options o = local_options(g->file);
    o.memory_target = 10000; /* ceiling 12,500 bytes */
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_camera cam = key_camera(g->path.count - 1);
    ms_core_set_camera(core, &cam);
    ms_core_stats st;
    double until = ms_now_seconds() + WAIT_SECONDS;
    do {
        ms_test_sleep_s(0.0005);
        ms_core_get_stats(core, &st);
        if (st.warning[0] && st.tolerance_px < 4096.0 * 0.999)
            fail_msg("a snapshot with the warning '%s' and the tolerance %.1f px", st.warning,
                     st.tolerance_px);
    } while (!st.warning[0] && !st.view_complete && ms_now_seconds() < until);
    assert_false(st.view_complete);
    assert_string_equal(st.warning, "memory budget too small: 0.01 MB cannot hold this view even "
                                    "at its coarsest (the tolerance is 4096x)");
    assert_string_equal(st.error, "");
    /* the warning is set as the factor reaches its limit; the figures carry
     * it from the pass that publishes next (bounded wait) */
    for (double more = ms_now_seconds() + 10; st.tolerance_px < 4096.0 * 0.999 &&
                                              ms_now_seconds() < more;) {
        ms_test_sleep_s(0.02);
        ms_core_get_stats(core, &st);
    }
    assert_true(st.tolerance_px >= 4096.0 * 0.999);
    ms_core_stop(core);
}

/* The budget's evictions as the test hook sees them, in order. */
typedef struct eviction_log {
    pthread_mutex_t lock;
    size_t count, out_of_view, in_view_after_coarsening;
    size_t first_in_view;       /* index of the first in-view eviction, count if none */
    double largest_factor;      /* the tolerance factor at any eviction */
} eviction_log;

static void log_eviction(uint32_t cell, bool in_view, double tolerance_factor,
                         double culled_give_up, void *arg)
{
    (void)cell, (void)culled_give_up;
    eviction_log *l = arg;
    pthread_mutex_lock(&l->lock);
    if (in_view && l->first_in_view == SIZE_MAX)
        l->first_in_view = l->count;
    l->out_of_view += !in_view;
    if (tolerance_factor > l->largest_factor)
        l->largest_factor = tolerance_factor;
    l->count++;
    pthread_mutex_unlock(&l->lock);
}

/* Plays the close-up keyframe by keyframe on a local core with options o,
 * each until complete; the largest memory at a complete keyframe in
 * *largest, per keyframe checks when `check` (the budget's test). */
static void play_path(const ms_core_options *o, double *reference_error, uint64_t *largest,
                      ms_core_stats *last)
{
    bool check = o->eviction_hook != NULL;
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(o, &core, &err), MS_OK);
    *largest = 0;
    for (size_t k = 0; k < g->path.count; ++k) {
        ms_camera cam = key_camera(k);
        ms_core_set_camera(core, &cam);
        ms_core_stats st;
        if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, NULL))
            fail_msg("keyframe %zu not complete: '%s' '%s'", k, st.error, st.warning);
        if (check) {
            fprintf(stderr, "  keyframe %zu: error %.3f px at tolerance %.3f px, memory %llu "
                    "(peak %llu), %llu evictions\n", k, st.achieved_error_px, st.tolerance_px,
                    (unsigned long long)st.memory, (unsigned long long)st.peak_memory,
                    (unsigned long long)st.evictions);
            /* the view is complete at the tolerance asked for: nothing in view
             * was coarsened for memory */
            assert_true(st.tolerance_px == 1.0);
            /* (above 1 px only where the archive's precision ends, as without
             * a budget) */
            assert_true(st.achieved_error_px <= fmax(1.0, reference_error[k]) + 1e-9);
            assert_true(st.memory <= o->memory_target);
            assert_true(st.peak_memory <= o->memory_ceiling);
        }
        if (!check)
            reference_error[k] = st.achieved_error_px;
        if (st.memory > *largest)
            *largest = st.memory;
        *last = st;
    }
    ms_core_stop(core);
}

/* A zoom-in under a budget that holds every keyframe's view but not the whole
 * path's: each keyframe completes at the tolerance (1 px), the memory stays
 * under the budget, and what is evicted is what left the view, before any
 * cell in view is given up (docs/CLIENT.md, "Memory budget"). */
static void test_local_budget_zoom_in(void **state)
{
    (void)state;
    ms_core_options o = local_options(g->file);
    o.export_frames = false;
    /* a budget that never binds (split cells keep no decoder under one) */
    o.memory_target = 1ull << 40;
    o.memory_ceiling = 1ull << 41;
    uint64_t view_need = 0;
    for (size_t k = 0; k < g->path.count; ++k) {
        ms_core *core;
        ms_error err;
        assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
        ms_camera cam = key_camera(k);
        ms_core_set_camera(core, &cam);
        ms_core_stats st;
        if (!ms_test_core_wait_complete(core, WAIT_SECONDS, &st, NULL))
            fail_msg("keyframe %zu alone not complete: '%s'", k, st.error);
        if (st.memory > view_need)
            view_need = st.memory;
        ms_core_stop(core);
    }
    ms_core_stats st;
    uint64_t path_total;
    double reference_error[64];
    assert_true(g->path.count <= 64);
    play_path(&o, reference_error, &path_total, &st);
    assert_int_equal(st.evictions, 0);
    fprintf(stderr, "zoom-in: the largest view holds %llu bytes alone, the whole path %llu\n",
            (unsigned long long)view_need, (unsigned long long)path_total);
    /* the test's premise: the path holds clearly more than any view */
    assert_true(path_total > view_need + view_need / 8);
    eviction_log log = {.first_in_view = SIZE_MAX, .largest_factor = 0};
    pthread_mutex_init(&log.lock, NULL);
    o.memory_target = view_need + (path_total - view_need) / 3;
    o.memory_ceiling = o.memory_target + o.memory_target / 4;
    o.eviction_hook = log_eviction;
    o.eviction_hook_arg = &log;
    uint64_t largest;
    play_path(&o, reference_error, &largest, &st);
    pthread_mutex_destroy(&log.lock);
    fprintf(stderr, "zoom-in under %llu bytes: %zu evictions, %zu of them out of view, the "
            "first in view at %zu, tolerance factor at most %.2f\n",
            (unsigned long long)o.memory_target, log.count, log.out_of_view,
            log.first_in_view == SIZE_MAX ? log.count : log.first_in_view,
            log.largest_factor);
    assert_true(log.count > 0);
    assert_true(st.evictions <= log.count); /* and APO chunks of cells out of view */
    /* every eviction while nothing in view was coarsened */
    assert_true(log.largest_factor == 1.0);
    /* what left the view first */
    assert_true(log.out_of_view > 0);
    assert_true(log.first_in_view >= log.out_of_view || log.first_in_view == SIZE_MAX);
}

/* Starts a local core on file and waits for an error or view complete. */
static void run_local(const char *file, ms_core_stats *st)
{
    ms_core_options o = local_options(file);
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_camera cam = key_camera(0);
    ms_core_set_camera(core, &cam);
    double until = ms_now_seconds() + WAIT_SECONDS;
    do {
        ms_test_sleep_s(0.01);
        ms_core_get_stats(core, st);
    } while (!st->error[0] && !st->view_complete && !st->cells_failed && ms_now_seconds() < until);
    ms_test_sleep_s(0.2); /* a pass more: the failed cell stays failed, nothing else happens */
    ms_core_get_stats(core, st);
    ms_core_stop(core);
}

static void test_local_bad_archives(void **state)
{
    (void)state;
    ms_core_stats st;
    ms_core *core = NULL;
    ms_error err;
    ms_core_options o = local_options("");
    assert_int_equal(ms_core_start(&o, &core, &err), MS_ERR_ARG);
    assert_null(core);

    char path[800];
    snprintf(path, sizeof path, "%s/missing.msa", g->dir);
    run_local(path, &st);
    assert_non_null(strstr(st.error, path));
    assert_false(st.model_open);
    assert_false(st.view_complete);

    snprintf(path, sizeof path, "%s/catalog.json", g->archives);
    run_local(path, &st);
    assert_non_null(strstr(st.error, "not a meshstream archive"));

    size_t size;
    unsigned char *bytes = ms_test_read_file(g->file, &size);
    snprintf(path, sizeof path, "%s/truncated.msa", g->dir);
    ms_test_write_file(path, bytes, size - 1000);
    run_local(path, &st);
    assert_non_null(strstr(st.error, path));
    assert_false(st.model_open);
    assert_int_equal(st.bytes_received, 0);

    /* the last byte of the root's third precision bit, flipped */
    const ms_archive_header *h = ms_archive_get_header(g->archive);
    const ms_archive_cell *root = ms_archive_get_cell(g->archive, 0);
    uint64_t at = MS_ARCHIVE_HEADER_SIZE + h->index_stored_size + root->geometry_offset +
                  ms_archive_geometry_prefix(g->archive, 0, root->bits_min + 3u) - 1;
    assert_true(at < size);
    bytes[at] ^= 0x5A;
    snprintf(path, sizeof path, "%s/corrupt.msa", g->dir);
    ms_test_write_file(path, bytes, size);
    free(bytes);
    run_local(path, &st);
    assert_int_equal(st.error[0], 0);
    assert_true(st.model_open);
    assert_false(st.view_complete);
    assert_int_equal(st.cells_failed, 1);
    assert_int_equal(st.refetches, 1);
    assert_non_null(strstr(st.warning, "cell 0"));
    assert_non_null(strstr(st.warning, "CRC"));
}

/* Listing models: a server's catalogue and a directory's catalog.json. */
static void test_catalogues(void **state)
{
    (void)state;
    ms_client_options co = {.host = "127.0.0.1", .port = g->port, .agent = "test"};
    ms_client_catalogue cat;
    ms_error err;
    if (ms_client_fetch_catalogue(&co, 10.0, &cat, &err) != MS_OK)
        fail_msg("%s", err.text);
    assert_int_equal(cat.count, 1);
    const ms_client_catalogue_entry *e = &cat.entries[0];
    assert_string_equal(e->name, MODEL);
    const ms_archive_header *h = ms_archive_get_header(g->archive);
    assert_int_equal(e->cell_count, h->cell_count);
    assert_int_equal(e->archive_bytes, h->file_size);
    assert_true(e->apo_steps > 0);
    char triangles[64];
    snprintf(triangles, sizeof triangles, "%llu triangles", (unsigned long long)h->triangle_count);
    if (!strstr(e->title, triangles))
        fail_msg("title '%s' lacks '%s'", e->title, triangles);
    ms_client_catalogue_free(&cat);
    assert_null(cat.entries);
    ms_client_catalogue_free(&cat); /* twice is harmless */

    /* nobody listening: a clear error, from the refusal, not from the time-out
     * (how quickly: scripts/bench-limits) */
    co.port = 1; /* nothing listens on port 1 of loopback: refused */
    assert_int_equal(ms_client_fetch_catalogue(&co, 60.0, &cat, &err), MS_ERR_IO);
    assert_non_null(strstr(err.text, "127.0.0.1:1"));
    if (strstr(err.text, "in time"))
        fail_msg("waited for the time-out: %s", err.text);
    assert_int_equal(cat.count, 0);
    co.host = NULL;
    assert_int_equal(ms_client_fetch_catalogue(&co, 5.0, &cat, &err), MS_ERR_ARG);

    ms_catalog local;
    if (ms_catalog_load(g->archives, &local, &err) != MS_OK)
        fail_msg("%s", err.text);
    const ms_catalog_entry *le = ms_catalog_find(&local, MODEL);
    assert_non_null(le);
    assert_int_equal(le->triangles, h->triangle_count);
    assert_int_equal(le->archive_bytes, h->file_size);
    ms_catalog_free(&local);
}

static uint64_t json_u64(json_t *o, const char *key)
{
    json_t *v = json_object_get(o, key);
    if (!json_is_integer(v))
        fail_msg("no integer '%s'", key);
    return (uint64_t)json_integer_value(v);
}

/* meshload on the local file: APO bytes apart from geometry bytes. */
static void test_meshload_local(void **state)
{
    (void)state;
    char bin[512], cmd[4096], out[32768];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    for (int apo = 0; apo < 2; ++apo) {
        snprintf(cmd, sizeof cmd, "%s --archive %s --path " PATH_FILE " --viewport 640x480 "
                 "--apo-levels %d --duration 60 --json 2>/dev/null", bin, g->file,
                 apo ? APO_LEVELS : 0);
        json_t *r = ms_test_run_json(cmd, 0);
        uint64_t cold = json_u64(r, "cold_bytes"), path = json_u64(r, "path_bytes");
        uint64_t cold_apo = json_u64(r, "cold_apo_bytes"), path_apo = json_u64(r, "path_apo_bytes");
        assert_int_equal(json_u64(r, "cold_geometry_bytes") + cold_apo, cold);
        assert_int_equal(json_u64(r, "path_geometry_bytes") + path_apo, path);
        assert_true(json_u64(r, "path_geometry_bytes") > 0);
        json_t *c0 = json_array_get(json_object_get(r, "per_client"), 0);
        assert_non_null(c0);
        assert_int_equal(json_u64(c0, "apo_bytes"), path_apo);
        assert_int_equal(json_u64(c0, "geometry_bytes") + path_apo, path);
        if (apo)
            assert_true(cold_apo > 0 && path_apo > cold_apo);
        else
            assert_true(cold_apo == 0 && path_apo == 0);
        json_decref(r);
    }
    /* --archive with --server is a usage error */
    snprintf(cmd, sizeof cmd, "%s --archive %s --server 127.0.0.1:1 --path " PATH_FILE, bin,
             g->file);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    /* a missing file: the core's error, exit 1 */
    snprintf(cmd, sizeof cmd, "%s --archive %s/none.msa --path " PATH_FILE " --duration 20", bin,
             g->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_non_null(strstr(out, "none.msa"));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_local_equals_network),
        cmocka_unit_test(test_local_path),
        cmocka_unit_test(test_local_bad_archives),
        cmocka_unit_test(test_local_budget_below_the_root),
        cmocka_unit_test(test_local_budget_zoom_in),
        cmocka_unit_test(test_catalogues),
        cmocka_unit_test(test_meshload_local),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
