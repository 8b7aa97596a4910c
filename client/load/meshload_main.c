/* meshload: the client core (ms_client_core.h) without a window, following a
 * scripted camera path, for N virtual clients at once; or, with --baseline
 * draco, the same clients downloading the whole model compressed with Draco
 * from meshserve's HTTP side door and decoding it with draco_decoder.
 *
 * Each streaming client runs two phases, each on a fresh core (empty cache):
 *   cold  the camera opens directly at the path's last keyframe: time to first
 *         display and time to view complete, from the connection's start;
 *   path  the camera follows the path in real time, its clock held at each
 *         keyframe until the view is complete there (or --keyframe-timeout):
 *         the wait at each keyframe is its time to view complete.
 * Everything is bounded by --duration. */
#include <errno.h>
#include <fcntl.h>
#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <event2/event.h>
#include <math.h>
#include <netinet/in.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "ms_camera_path.h"
#include "ms_json_out.h"
#include "ms_load_work.h"
#include "ms_progress.h"
#include "ms_client_core.h"
#include "ms_http_get.h"
#include "ms_load_options.h"
#include "ms_version.h"

extern char **environ;

#define MAX_KEYS 256


typedef struct key_result {
    double arrive, wait, error_px, tolerance_px;
    bool complete;
    bool preview_limited; /* complete at a public preview: a token gives more */
} key_result;

typedef struct client_result {
    /* cold phase */
    double first_display, view_complete, cold_last_byte;
    bool cold_complete;
    uint64_t cold_bytes, cold_apo_bytes; /* payload, and of it APO */
    /* a public preview (ms_core_stats): the precision this reader may have,
     * and whether a view the core completed wanted more */
    bool preview, cold_preview_limited;
    unsigned preview_bits;
    /* the cold phase's index: by subtree or whole (ms_core_stats) */
    bool index_by_subtree;
    uint64_t subtrees_received, index_bytes_received, peak_index_bytes_held;
    uint64_t state_bytes_held; /* per-cell bookkeeping at the cold phase's end */
    uint32_t state_cells;
    ms_core_decode_work cold_work; /* the decode passes' work to the cold view complete */
    /* path phase */
    key_result keys[MAX_KEYS];
    size_t key_count;
    uint64_t bytes, apo_bytes, requests, cancels, reconnects, evictions;
    double longest_outage; /* seconds from a lost connection to the model open again */
    unsigned model_changes; /* fresh cores started because a rescan replaced the model */
    uint32_t cells_shown, cells_failed;
    double decode_seconds, p50, p99;
    uint64_t peak_memory;
    double path_seconds;
    /* baseline */
    double download_seconds, decode_draco_seconds;
    uint64_t draco_bytes;
    char error[256];
    char warning[256]; /* the core's last warning: why a phase did not complete */
} client_result;

typedef struct run {
    const ms_load_options *o;
    ms_camera_path path;
    double deadline; /* monotonic seconds */
} run;

typedef struct worker {
    run *r;
    unsigned number;
    client_result result;
    pthread_t thread;
} worker;

static void sleep_s(double s)
{
    struct timespec ts = {(time_t)s, (long)((s - floor(s)) * 1e9)};
    nanosleep(&ts, NULL);
}

static ms_core_options core_options(const ms_load_options *o)
{
    ms_core_options co = {0};
    co.host = o->host, co.port = o->port, co.model = o->model, co.token = o->token;
    co.archive_path = o->archive;
    co.agent = "meshload/0.1";
    co.tolerance_px = o->tolerance;
    co.hysteresis_bits = o->hysteresis;
    co.culled_bits_less = o->culled_less;
    co.raw_index = o->raw_index;
    co.whole_index = o->whole_index;
    co.decode_threads = o->decode_threads;
    co.apo_levels = o->apo_levels;
    co.memory_target = (uint64_t)(o->memory_target * 1048576.0);
    co.memory_ceiling = (uint64_t)(o->memory_ceiling * 1048576.0);
    co.bandwidth = o->bandwidth;
    co.answer_timeout = 5.0;
    co.give_up_seconds = 20.0;
    return co;
}

/* The model's box: the content bounds the core works out at open
 * (ms_core_wait_open), else the index's cube. */
typedef struct model_box {
    double lo[3], hi[3];
} model_box;

/* The path's camera at t, its near and far planes framing the model's box
 * from the eye (ms_camera_path_sample_framing, as meshview's), so that a
 * model in micrometres or kilometres is in view as one in metres. */
static bool camera_at(const run *r, double t, const model_box *box, ms_camera *cam)
{
    return ms_camera_path_sample_framing(&r->path, t, r->o->width, r->o->height, box->lo, box->hi,
                                         cam, NULL) == MS_OK;
}

/* Waits until `until` at most for the model to open and fills *box; false
 * with res->error set when the model did not open. */
static bool model_box_of(ms_core *core, double until, model_box *box, client_result *res)
{
    double left = until - ms_now_seconds();
    ms_core_opening opening;
    ms_error err;
    if (ms_core_wait_open(core, left > 0.01 ? left : 0.01, &opening, &err) != MS_OK) {
        ms_core_stats st;
        ms_core_get_stats(core, &st); /* why it did not open: the last warning */
        if (st.error[0] || !st.warning[0])
            snprintf(res->error, sizeof res->error, "%.250s", err.text);
        else
            snprintf(res->error, sizeof res->error, "the model did not open in time (%.200s)",
                     st.warning);
        return false;
    }
    for (int a = 0; a < 3; ++a) {
        box->lo[a] = opening.content_known ? opening.content_lo[a] : opening.header.box_origin[a];
        box->hi[a] = opening.content_known ? opening.content_hi[a]
                                           : opening.header.box_origin[a] + opening.header.box_side;
    }
    ms_core_opening_free(&opening);
    return true;
}

/* Waits until the core's view is complete for its latest camera, or until
 * `until`; returns whether it completed. */
static bool wait_complete(ms_core *core, double until, ms_core_stats *st, double *last_byte)
{
    uint64_t seen = 0;
    for (;;) {
        ms_core_get_stats(core, st);
        if (last_byte && st->bytes_received != seen) {
            seen = st->bytes_received;
            *last_byte = st->time;
        }
        if (st->view_complete || st->error[0])
            return st->view_complete;
        if (ms_now_seconds() >= until)
            return false;
        sleep_s(0.002);
    }
}

/* A rescan replaced the model under a core (stats.model_changed): what it
 * holds is of the old version, so a fresh core streams the new one from its
 * root, with the same camera. At most MAX_MODEL_CHANGES times per phase (a
 * model replaced again and again is an error). False, with res->error set,
 * when the fresh core does not start. */
#define MAX_MODEL_CHANGES 3

/* A core started with the run's options; NULL with the error in res->error. */
static ms_core *start_core(const run *r, client_result *res)
{
    ms_core_options co = core_options(r->o);
    ms_core *core;
    ms_error err;
    if (ms_core_start(&co, &core, &err) != MS_OK) {
        snprintf(res->error, sizeof res->error, "%.250s", err.text);
        return NULL;
    }
    return core;
}

static bool restart_core(const run *r, ms_core **core, const ms_camera *cam, client_result *res)
{
    ms_core_stop(*core);
    res->model_changes++;
    if (!(*core = start_core(r, res)))
        return false;
    ms_core_set_camera(*core, cam);
    return true;
}

static void cold_phase(worker *w)
{
    run *r = w->r;
    client_result *res = &w->result;
    ms_core *core = start_core(r, res);
    if (!core)
        return;
    double until = ms_now_seconds() + r->o->keyframe_timeout;
    if (until > r->deadline)
        until = r->deadline;
    model_box box;
    if (!model_box_of(core, until, &box, res)) {
        ms_core_stop(core);
        return;
    }
    ms_camera cam;
    camera_at(r, ms_camera_path_duration(&r->path), &box, &cam);
    ms_core_set_camera(core, &cam);
    ms_core_stats st;
    res->cold_complete = wait_complete(core, until, &st, &res->cold_last_byte);
    for (int again = 0; !res->cold_complete && st.model_changed && again < MAX_MODEL_CHANGES;
         ++again) {
        if (!restart_core(r, &core, &cam, res))
            return;
        res->cold_complete = wait_complete(core, until, &st, &res->cold_last_byte);
    }
    res->view_complete = res->cold_complete ? st.time : -1;
    res->first_display = st.first_display;
    res->cold_bytes = st.bytes_received;
    res->cold_apo_bytes = st.apo_bytes_received;
    res->preview = st.preview, res->preview_bits = st.preview_bits;
    res->cold_preview_limited = st.preview_limited;
    res->index_by_subtree = st.index_by_subtree;
    res->subtrees_received = st.subtrees_received;
    res->index_bytes_received = st.index_bytes_received;
    res->peak_index_bytes_held = st.peak_index_bytes_held;
    res->state_bytes_held = st.state_bytes_held;
    res->state_cells = st.state_cells;
    res->cold_work = st.decode_work;
    snprintf(res->warning, sizeof res->warning, "%.250s", st.warning);
    if (st.error[0])
        snprintf(res->error, sizeof res->error, "%.250s", st.error);
    else if (res->cold_complete && st.first_display < 0)
        snprintf(res->error, sizeof res->error,
                 "nothing of the model is in view at the path's last keyframe (t=%g s)",
                 ms_camera_path_duration(&r->path));
    ms_core_stop(core);
}

static void path_phase(worker *w)
{
    run *r = w->r;
    client_result *res = &w->result;
    ms_core *core = start_core(r, res);
    if (!core)
        return;
    double open_until = ms_now_seconds() + r->o->keyframe_timeout;
    model_box box;
    if (!model_box_of(core, open_until < r->deadline ? open_until : r->deadline, &box, res)) {
        ms_core_stop(core);
        return;
    }
    double started = ms_now_seconds();
    double clock = 0, last = started;
    size_t next_key = 0;
    ms_core_stats st;
    memset(&st, 0, sizeof st);
    while (next_key < r->path.count && next_key < MAX_KEYS && ms_now_seconds() < r->deadline) {
        double t = ms_now_seconds();
        double key_time = r->path.keys[next_key].time;
        clock += t - last;
        last = t;
        if (clock >= key_time) {
            clock = key_time;
            ms_camera cam;
            camera_at(r, clock, &box, &cam);
            ms_core_set_camera(core, &cam);
            key_result *k = &res->keys[next_key];
            k->arrive = t - started;
            double until = t + r->o->keyframe_timeout;
            if (until > r->deadline)
                until = r->deadline;
            k->complete = wait_complete(core, until, &st, NULL);
            for (int again = 0; !k->complete && st.model_changed && again < MAX_MODEL_CHANGES;
                 ++again) {
                if (!restart_core(r, &core, &cam, res))
                    return;
                k->complete = wait_complete(core, until, &st, NULL);
            }
            k->wait = ms_now_seconds() - t;
            k->error_px = st.achieved_error_px;
            k->tolerance_px = st.tolerance_px;
            k->preview_limited = st.preview_limited;
            res->key_count = ++next_key;
            last = ms_now_seconds();
            if (st.error[0])
                break;
            continue;
        }
        ms_camera cam;
        camera_at(r, clock, &box, &cam);
        ms_core_set_camera(core, &cam);
        sleep_s(0.02);
    }
    ms_core_get_stats(core, &st);
    res->path_seconds = ms_now_seconds() - started;
    res->bytes = st.bytes_received;
    res->apo_bytes = st.apo_bytes_received;
    res->requests = st.requests, res->cancels = st.cancels, res->reconnects = st.reconnects;
    res->longest_outage = st.longest_outage;
    res->evictions = st.evictions;
    res->cells_shown = st.cells_shown, res->cells_failed = st.cells_failed;
    res->decode_seconds = st.decode_seconds;
    res->p50 = st.latency_p50, res->p99 = st.latency_p99;
    res->peak_memory = st.peak_memory;
    snprintf(res->warning, sizeof res->warning, "%.250s", st.warning);
    bool all_complete = res->key_count == r->path.count;
    for (size_t k = 0; k < res->key_count; ++k)
        all_complete = all_complete && res->keys[k].complete;
    if (st.preview)
        res->preview = true, res->preview_bits = st.preview_bits;
    if (st.error[0] && !res->error[0])
        snprintf(res->error, sizeof res->error, "%.250s", st.error);
    else if (st.warning[0] && !res->error[0] &&
             (st.cells_failed || (!st.view_complete && strncmp(st.warning, "memory budget", 13) == 0)))
        snprintf(res->error, sizeof res->error, "%.250s", st.warning); /* why it did not complete */
    else if (!res->error[0] && all_complete && st.first_display < 0)
        snprintf(res->error, sizeof res->error,
                 "nothing of the model was in view at any keyframe of the path");
    ms_core_stop(core);
}

/* --- Draco baseline: a throttled HTTP download, then draco_decoder ---------- */

static void baseline_client(worker *w)
{
    const ms_load_options *o = w->r->o;
    client_result *res = &w->result;
    struct evbuffer *body = evbuffer_new();
    if (!body) {
        snprintf(res->error, sizeof res->error, "out of memory");
        return;
    }
    double t0 = ms_now_seconds(), left = w->r->deadline - t0;
    char path[300];
    snprintf(path, sizeof path, "/models/%s/draco", o->model);
    ms_http_get_options get = {.host = o->host, .port = o->port, .path = path, .token = o->token,
                               .bandwidth = o->bandwidth, .timeout_s = left > 1 ? left : 1};
    ms_error err;
    int status;
    if (ms_http_get(&get, body, &status, &err) != MS_OK || status != 200) {
        if (status)
            snprintf(res->error, sizeof res->error, "the server answered HTTP %d for %.200s", status,
                     path);
        else
            snprintf(res->error, sizeof res->error, "%.250s", err.text);
        evbuffer_free(body);
        return;
    }
    res->download_seconds = ms_now_seconds() - t0;
    res->draco_bytes = evbuffer_get_length(body);
    unsigned char *all = evbuffer_pullup(body, -1);
    char drc[512], ply[512];
    snprintf(drc, sizeof drc, "%s/meshload-%d-%u.drc", o->tmp_dir, (int)getpid(), w->number);
    snprintf(ply, sizeof ply, "%s/meshload-%d-%u.ply", o->tmp_dir, (int)getpid(), w->number);
    FILE *f = fopen(drc, "wb");
    bool wrote = f && (res->draco_bytes == 0 ||
                       (all && fwrite(all, 1, res->draco_bytes, f) == res->draco_bytes));
    if (f && fclose(f) != 0)
        wrote = false;
    evbuffer_free(body);
    if (!wrote) {
        snprintf(res->error, sizeof res->error, "cannot write %.200s", drc);
        unlink(drc);
        return;
    }
    double t1 = ms_now_seconds();
    char *argv[] = {(char *)o->draco_decoder, "-i", drc, "-o", ply, NULL};
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    pid_t pid;
    int rc = posix_spawnp(&pid, o->draco_decoder, &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    int ws = 0;
    if (rc != 0 || waitpid(pid, &ws, 0) < 0 || !WIFEXITED(ws) || WEXITSTATUS(ws) != 0)
        snprintf(res->error, sizeof res->error, "%s failed on %.200s", o->draco_decoder, drc);
    res->decode_draco_seconds = ms_now_seconds() - t1;
    res->view_complete = res->download_seconds + res->decode_draco_seconds;
    res->first_display = res->view_complete; /* nothing to show before the end */
    res->cold_complete = !res->error[0];
    unlink(drc);
    unlink(ply);
}

/* Every failed client says why in one line: the phase that did not complete
 * and the core's last warning (a lost connection, a protocol violation, a
 * subtree given up), when the core itself reported no error. */
static void explain_failure(const run *r, client_result *res)
{
    if (res->error[0] || r->o->baseline)
        return;
    const char *why = res->warning[0] ? res->warning : "no warning from the client";
    if (!r->o->skip_cold && !res->cold_complete) {
        snprintf(res->error, sizeof res->error,
                 "the view at the path's last keyframe did not complete in time (%.150s)", why);
        return;
    }
    for (size_t k = 0; k < res->key_count; ++k)
        if (!res->keys[k].complete) {
            snprintf(res->error, sizeof res->error,
                     "keyframe %zu did not complete within %g s (%.150s)", k,
                     r->o->keyframe_timeout, why);
            return;
        }
    if (res->key_count < r->path.count)
        snprintf(res->error, sizeof res->error,
                 "the run ended (--duration) at keyframe %zu of %zu (%.150s)", res->key_count,
                 r->path.count, why);
}

static void *worker_main(void *arg)
{
    worker *w = arg;
    sigset_t pipe_only;
    sigemptyset(&pipe_only);
    sigaddset(&pipe_only, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_only, NULL);
    if (w->r->o->baseline) {
        baseline_client(w);
        return NULL;
    }
    if (!w->r->o->skip_cold)
        cold_phase(w);
    if (!w->result.error[0])
        path_phase(w);
    explain_failure(w->r, &w->result);
    return NULL;
}

/* --- output ----------------------------------------------------------------- */

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, size_t n)
{
    if (!n)
        return -1;
    qsort(v, n, sizeof *v, compare_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* The figures over every client: medians, worst, totals, peaks. */
typedef struct summary {
    double med_first, med_complete, worst_complete, decode, p50, p99, longest_outage;
    uint64_t bytes, cold_bytes, peak, failures, draco_bytes, apo_bytes, cold_apo_bytes;
    uint64_t reconnects;
    size_t nc;
} summary;

static summary summarize(unsigned n, const worker *ws)
{
    summary m = {0};
    double *first = calloc(n, sizeof *first), *complete = calloc(n, sizeof *complete);
    size_t nf = 0;
    for (unsigned i = 0; i < n; ++i) {
        const client_result *c = &ws[i].result;
        if (c->first_display >= 0 && first)
            first[nf++] = c->first_display;
        if (c->cold_complete) {
            if (complete)
                complete[m.nc] = c->view_complete;
            m.nc++;
            if (c->view_complete > m.worst_complete)
                m.worst_complete = c->view_complete;
        }
        m.failures += c->error[0] != 0;
        m.bytes += c->bytes, m.cold_bytes += c->cold_bytes, m.decode += c->decode_seconds;
        m.apo_bytes += c->apo_bytes, m.cold_apo_bytes += c->cold_apo_bytes;
        m.draco_bytes += c->draco_bytes;
        m.reconnects += c->reconnects;
        if (c->longest_outage > m.longest_outage)
            m.longest_outage = c->longest_outage;
        if (c->peak_memory > m.peak)
            m.peak = c->peak_memory;
        if (c->p50 > m.p50)
            m.p50 = c->p50;
        if (c->p99 > m.p99)
            m.p99 = c->p99;
    }
    m.med_first = median(first, nf);
    m.med_complete = m.nc == n && complete ? median(complete, m.nc) : -1;
    free(first);
    free(complete);
    return m;
}

/* Under a public preview, whether a view of the run wanted more than the
 * preview: a token gives more. */
static bool token_gives_more(const client_result *c)
{
    bool more = c->preview && c->cold_preview_limited;
    for (size_t k = 0; k < c->key_count; ++k)
        more |= c->preview && c->keys[k].preview_limited;
    return more;
}

/* Every view of the client complete (the cold one unless skipped, every
 * keyframe) and no error. */
static bool client_complete(const client_result *c, const run *r)
{
    bool ok = !c->error[0] && (r->o->skip_cold || c->cold_complete);
    for (size_t k = 0; k < c->key_count; ++k)
        ok = ok && c->keys[k].complete;
    return ok && c->key_count >= r->path.count;
}

/* One client's figures and keyframes as a JSON object. */
static json_t *client_json(unsigned i, const client_result *c, const run *r)
{
    json_t *keyframes = json_array();
    for (size_t k = 0; k < c->key_count; ++k)
        json_array_append_new(
            keyframes,
            json_pack("{s:o, s:o, s:o, s:b, s:b, s:o, s:o}", "time",
                      ms_json_number(r->path.count > k ? r->path.keys[k].time : 0.0), "arrive",
                      ms_json_fixed(c->keys[k].arrive, 4), "time_to_view_complete",
                      ms_json_fixed(c->keys[k].wait, 4), "complete", c->keys[k].complete,
                      "preview_limited", c->keys[k].preview_limited, "error_px",
                      ms_json_fixed(isfinite(c->keys[k].error_px) ? c->keys[k].error_px : -1.0, 4),
                      "tolerance_px", ms_json_fixed(c->keys[k].tolerance_px, 4)));
    json_t *client = json_pack(
        "{s:i, s:o, s:o, s:o, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:i, s:i, s:o, "
        "s:o, s:o, s:I, s:o, s:o, s:o, s:o, s:o}",
        "client", (int)i, "time_to_first_display", ms_json_fixed(c->first_display, 4),
        "time_to_view_complete", ms_json_fixed(c->cold_complete ? c->view_complete : -1.0, 4),
        "last_byte", ms_json_fixed(c->cold_last_byte, 4),
        "cold_bytes", (json_int_t)c->cold_bytes, "cold_geometry_bytes",
        (json_int_t)(c->cold_bytes - c->cold_apo_bytes), "cold_apo_bytes",
        (json_int_t)c->cold_apo_bytes, "bytes", (json_int_t)c->bytes, "geometry_bytes",
        (json_int_t)(c->bytes - c->apo_bytes), "apo_bytes", (json_int_t)c->apo_bytes,
        "requests", (json_int_t)c->requests, "cancels", (json_int_t)c->cancels, "reconnects",
        (json_int_t)c->reconnects, "evictions", (json_int_t)c->evictions, "cells",
        (int)c->cells_shown, "failed_cells", (int)c->cells_failed, "decode_seconds",
        ms_json_fixed(c->decode_seconds, 4), "latency_p50", ms_json_fixed(c->p50, 4), "latency_p99",
        ms_json_fixed(c->p99, 4), "peak_memory", (json_int_t)c->peak_memory, "download_seconds",
        ms_json_fixed(c->download_seconds, 4), "draco_decode_seconds",
        ms_json_fixed(c->decode_draco_seconds, 4), "error", ms_json_text(c->error),
        "failover_seconds", ms_json_fixed(c->longest_outage, 4), "keyframes", keyframes);
    json_object_set_new(client, "cold_decode_work", ms_load_decode_work_json(&c->cold_work));
    json_object_set_new(client, "model_changes", json_integer((json_int_t)c->model_changes));
    json_object_set_new(client, "preview_bits",
                        c->preview ? json_integer((json_int_t)c->preview_bits) : json_null());
    json_object_set_new(client, "token_gives_more", json_boolean(token_gives_more(c)));
    json_t *index = json_pack("{s:b, s:I, s:I, s:I, s:I, s:I}", "by_subtree", c->index_by_subtree,
                              "subtrees_received", (json_int_t)c->subtrees_received,
                              "index_bytes_received", (json_int_t)c->index_bytes_received,
                              "peak_index_bytes_held", (json_int_t)c->peak_index_bytes_held,
                              "state_cells", (json_int_t)c->state_cells,
                              "state_bytes_held", (json_int_t)c->state_bytes_held);
    if (client && index)
        json_object_set_new(client, "cold_index", index);
    else
        json_decref(index);
    return client;
}

static void report_json(const ms_load_options *o, const run *r, const worker *ws, const summary *m)
{
    unsigned n = o->clients;
    double med_first = m->med_first, med_complete = m->med_complete;
    double worst_complete = m->worst_complete, decode = m->decode, p50 = m->p50, p99 = m->p99;
    uint64_t bytes = m->bytes, cold_bytes = m->cold_bytes, peak = m->peak;
    uint64_t failures = m->failures, draco_bytes = m->draco_bytes;
    uint64_t apo_bytes = m->apo_bytes, cold_apo_bytes = m->cold_apo_bytes;
    size_t nc = m->nc;
    json_t *root = json_pack(
        "{s:s, s:o, s:o, s:i, s:I, s:o, s:o, s:o, s:o, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:o, s:o, "
        "s:o, s:I, s:I, s:I, s:o}",
        "mode", o->baseline ? "draco" : "stream", "model", ms_json_text(o->model), "path",
        ms_json_text(o->path_file ? o->path_file : ""), "clients", (int)n, "bandwidth_bytes_per_s",
        (json_int_t)llround(o->bandwidth), "tolerance_px", ms_json_number(o->tolerance),
        "time_to_first_display", ms_json_fixed(med_first, 4), "time_to_view_complete",
        ms_json_fixed(med_complete, 4), "time_to_view_complete_max",
        ms_json_fixed(nc == n ? worst_complete : -1.0, 4), "cold_bytes", (json_int_t)(n ? cold_bytes / n : 0),
        "path_bytes", (json_int_t)(n ? bytes / n : 0), "cold_geometry_bytes",
        (json_int_t)(n ? (cold_bytes - cold_apo_bytes) / n : 0), "cold_apo_bytes",
        (json_int_t)(n ? cold_apo_bytes / n : 0), "path_geometry_bytes",
        (json_int_t)(n ? (bytes - apo_bytes) / n : 0), "path_apo_bytes",
        (json_int_t)(n ? apo_bytes / n : 0), "draco_bytes", (json_int_t)(n ? draco_bytes / n : 0),
        "decode_seconds", ms_json_fixed(n ? decode / n : 0.0, 4), "latency_p50", ms_json_fixed(p50, 4),
        "latency_p99", ms_json_fixed(p99, 4),
        "peak_memory", (json_int_t)peak, "failures", (json_int_t)failures,
        "reconnects", (json_int_t)m->reconnects, "failover_seconds_max",
        ms_json_fixed(m->longest_outage, 4));
    json_t *per_client = json_array();
    for (unsigned i = 0; i < n; ++i)
        json_array_append_new(per_client, client_json(i, &ws[i].result, r));
    /* the cold open's index, worst client */
    uint64_t index_received = 0, index_held = 0, subtrees = 0, state_held = 0;
    for (unsigned i = 0; i < n; ++i) {
        const client_result *c = &ws[i].result;
        if (c->index_bytes_received > index_received)
            index_received = c->index_bytes_received;
        if (c->peak_index_bytes_held > index_held)
            index_held = c->peak_index_bytes_held;
        if (c->subtrees_received > subtrees)
            subtrees = c->subtrees_received;
        if (c->state_bytes_held > state_held)
            state_held = c->state_bytes_held;
    }
    if (root) {
        json_object_set_new(root, "cold_index_bytes_received", json_integer((json_int_t)index_received));
        json_object_set_new(root, "cold_peak_index_bytes_held", json_integer((json_int_t)index_held));
        json_object_set_new(root, "cold_subtrees_received", json_integer((json_int_t)subtrees));
        json_object_set_new(root, "cold_state_bytes_held", json_integer((json_int_t)state_held));
    }
    /* a public preview: the coarsest any client had, whether every view
     * completed there, and whether a token gives more */
    bool preview = false, more = false, all_complete = true;
    unsigned preview_bits = 0;
    for (unsigned i = 0; i < n; ++i) {
        const client_result *c = &ws[i].result;
        if (c->preview && (!preview || c->preview_bits < preview_bits))
            preview_bits = c->preview_bits;
        preview |= c->preview;
        more |= token_gives_more(c);
        all_complete &= client_complete(c, r);
    }
    if (root && !o->baseline) {
        json_object_set_new(root, "preview_bits",
                            preview ? json_integer((json_int_t)preview_bits) : json_null());
        json_object_set_new(root, "complete_at_preview", json_boolean(preview && all_complete));
        json_object_set_new(root, "token_gives_more", json_boolean(more));
    }
    if (root)
        json_object_set_new(root, "per_client", per_client);
    else
        json_decref(per_client);
    ms_json_print(stdout, root, MS_JSON_SPACED);
}

static void report_text(const ms_load_options *o, const run *r, const worker *ws, const summary *m)
{
    unsigned n = o->clients;
    double med_first = m->med_first, med_complete = m->med_complete;
    double worst_complete = m->worst_complete;
    printf("meshload %s %s, %u client(s), %.0f bytes/s:\n",
           o->baseline ? "draco baseline" : "streaming", o->model, n, o->bandwidth);
    printf("  time to first display %.3f s, time to view complete %.3f s (median; worst %.3f)\n",
           med_first, med_complete, worst_complete);
    for (unsigned i = 0; i < n; ++i) {
        const client_result *c = &ws[i].result;
        if (o->baseline) {
            printf("  client %u: downloaded %llu bytes in %.3f s, %s %.3f s%s%s\n", i,
                   (unsigned long long)c->draco_bytes, c->download_seconds, o->draco_decoder,
                   c->decode_draco_seconds, c->error[0] ? "; error: " : "", c->error);
            continue;
        }
        printf("  client %u: first display %.3f s, view complete %.3f s, %llu bytes cold "
               "(%llu geometry, %llu APO), %llu bytes on the path (%llu geometry, %llu APO), "
               "%u cells, decode %.3f s, latency p50 %.1f ms p99 "
               "%.1f ms, peak memory %.1f MB%s%s\n",
               i, c->first_display, c->view_complete, (unsigned long long)c->cold_bytes,
               (unsigned long long)(c->cold_bytes - c->cold_apo_bytes),
               (unsigned long long)c->cold_apo_bytes, (unsigned long long)c->bytes,
               (unsigned long long)(c->bytes - c->apo_bytes), (unsigned long long)c->apo_bytes,
               c->cells_shown, c->decode_seconds, c->p50 * 1e3,
               c->p99 * 1e3, c->peak_memory / 1048576.0, c->error[0] ? "; error: " : "",
               c->error);
        printf("    cold index: %s, %llu bytes received (%llu subtrees), at most %llu bytes "
               "held; cell state %llu bytes (%u cells)\n",
               c->index_by_subtree ? "by subtree" : "whole",
               (unsigned long long)c->index_bytes_received,
               (unsigned long long)c->subtrees_received,
               (unsigned long long)c->peak_index_bytes_held,
               (unsigned long long)c->state_bytes_held, c->state_cells);
        if (c->preview)
            printf("    preview: %u bits without a token%s\n", c->preview_bits,
                   !client_complete(c, r)  ? ""
                   : token_gives_more(c) ? "; the view is complete at the preview, a token gives more"
                                         : "; the view is complete and needs no more");
        for (size_t k = 0; k < c->key_count; ++k)
            printf("    keyframe %zu (t=%g): view complete%s after %.3f s%s, error %.2f px "
                   "(tolerance %.2f)\n",
                   k, r->path.keys[k].time,
                   c->keys[k].complete && c->keys[k].preview_limited ? " at the preview" : "",
                   c->keys[k].wait, c->keys[k].complete ? "" : " (NOT complete)",
                   c->keys[k].error_px, c->keys[k].tolerance_px);
    }
}

static void print_report(const ms_load_options *o, const run *r, worker *ws)
{
    summary m = summarize(o->clients, ws);
    if (o->json)
        report_json(o, r, ws, &m);
    else
        report_text(o, r, ws, &m);
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshload");
    ms_load_options o;
    int rc = ms_load_options_parse(argc, argv, &o);
    if (rc)
        return rc;
    if (o.help) {
        ms_load_usage(stdout);
        return 0;
    }
    run r = {.o = &o};
    if (o.path_file) {
        ms_error err;
        if (ms_camera_path_load(o.path_file, &r.path, &err) != MS_OK) {
            fprintf(stderr, "meshload: %s\n", err.text);
            return 1;
        }
        if (r.path.count > MAX_KEYS) {
            fprintf(stderr, "meshload: %s: at most %d keyframes\n", o.path_file, MAX_KEYS);
            ms_camera_path_free(&r.path);
            return 1;
        }
    }
    double duration = o.duration > 0 ? o.duration
                                     : (r.path.count ? ms_camera_path_duration(&r.path) : 0) + 120;
    r.deadline = ms_now_seconds() + duration;
    worker *ws = calloc(o.clients, sizeof *ws);
    if (!ws) {
        fprintf(stderr, "meshload: out of memory\n");
        return 1;
    }
    unsigned started = 0;
    for (unsigned i = 0; i < o.clients; ++i) {
        ws[i].r = &r;
        ws[i].number = i;
        if (pthread_create(&ws[i].thread, NULL, worker_main, &ws[i]) != 0) {
            snprintf(ws[i].result.error, sizeof ws[i].result.error, "cannot start a thread");
            break;
        }
        started++;
    }
    for (unsigned i = 0; i < started; ++i)
        pthread_join(ws[i].thread, NULL);
    print_report(&o, &r, ws);
    int status = 0;
    for (unsigned i = 0; i < o.clients; ++i) {
        const client_result *c = &ws[i].result;
        bool ok = !c->error[0] && (o.skip_cold || c->cold_complete);
        for (size_t k = 0; k < c->key_count; ++k)
            ok = ok && c->keys[k].complete;
        if (!o.baseline && c->key_count < r.path.count)
            ok = false; /* client_complete, but for the Draco baseline's keyframes */
        if (c->error[0])
            fprintf(stderr, "meshload: client %u: %s\n", i, c->error);
        if (!ok)
            status = 1;
    }
    free(ws);
    ms_camera_path_free(&r.path);
    return status;
}
