/* The client core's caller's API and the helpers its threads share: see
 * ms_client_core.h for what it does and ms_client_core_internal.h for its
 * parts (network or local byte source, decode thread, scheduling, budget,
 * frames). */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"
#include "ms_proto.h"

double ms_core_since_start(const ms_core *c) { return ms_now_seconds() - c->t0; }

/* Records a fatal error once (caller holds the lock). */
void ms_core_fail_locked(ms_core *c, const char *fmt, const char *text)
{
    if (c->stats.error[0])
        return;
    snprintf(c->stats.error, sizeof c->stats.error, fmt, text);
    c->fatal = true;
    pthread_cond_broadcast(&c->wake);
}

void ms_core_fail(ms_core *c, const char *fmt, const char *text)
{
    pthread_mutex_lock(&c->lock);
    ms_core_fail_locked(c, fmt, text);
    pthread_mutex_unlock(&c->lock);
}

void ms_core_warn(ms_core *c, const char *text)
{
    pthread_mutex_lock(&c->lock);
    snprintf(c->stats.warning, sizeof c->stats.warning, "%.240s", text);
    pthread_mutex_unlock(&c->lock);
}

void ms_core_push_chunk(ms_core *c, chunk_msg *m)
{
    pthread_mutex_lock(&c->lock);
    m->seq = ++c->push_seq;
    if (c->inbox_tail)
        c->inbox_tail->next = m;
    else
        c->inbox = m;
    c->inbox_tail = m;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

static char *dup_or_null(const char *s, bool *fail)
{
    if (!s)
        return NULL;
    char *d = strdup(s);
    if (!d)
        *fail = true;
    return d;
}

ms_status ms_core_start(const ms_core_options *o, ms_core **out, ms_error *err)
{
    *out = NULL;
    bool local = o && o->archive_path;
    if (local && !o->archive_path[0])
        return ms_error_set(err, MS_ERR_ARG, "client core: empty archive path");
    if (!o || (!local && (!o->host || !o->model || o->port == 0)))
        return ms_error_set(err, MS_ERR_ARG, "client core: host, port and model (or an archive "
                            "path) are required");
    if (o->model && !ms_proto_model_name_valid(o->model, strlen(o->model), NULL))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", o->model);
    if (o->tolerance_px < 0 || o->bandwidth < 0 || o->answer_timeout < 0 ||
        o->give_up_seconds < 0 || !isfinite(o->tolerance_px) || !isfinite(o->bandwidth) ||
        (o->memory_ceiling && o->memory_target > o->memory_ceiling))
        return ms_error_set(err, MS_ERR_ARG, "client core: bad tolerance, bandwidth, timeout or "
                            "budget (target above ceiling?)");
    if (o->shared_budget && (o->memory_target || o->memory_ceiling))
        return ms_error_set(err, MS_ERR_ARG, "client core: a shared budget replaces the "
                            "memory target and ceiling (leave them 0)");
    ms_core *c = calloc(1, sizeof *c);
    if (!c)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    c->o = *o;
    c->shared = o->shared_budget;
    c->member = -1;
    if (c->o.tolerance_px == 0)
        c->o.tolerance_px = 1.0;
    if (c->o.hysteresis_bits < 0)
        c->o.hysteresis_bits = 0.5;
    if (c->o.culled_bits_less == 0)
        c->o.culled_bits_less = 6.0;
    /* Geometry as fine with APO as without: coarser geometry where APO carries
     * the shading (4 px was the default) cost more image error than the bytes
     * it saved with the default bake (docs/ACCURACY.md). */
    if (c->o.apo_geometry_tolerance_px == 0)
        c->o.apo_geometry_tolerance_px = c->o.tolerance_px;
    if (c->o.answer_timeout == 0)
        c->o.answer_timeout = 5.0;
    if (c->o.give_up_seconds == 0)
        c->o.give_up_seconds = 30.0;
    if (c->o.memory_target && !c->o.memory_ceiling)
        c->o.memory_ceiling = c->o.memory_target + c->o.memory_target / 4;
    c->window = c->o.window_bytes ? c->o.window_bytes
                : c->o.bandwidth > 0 ? (uint64_t)(c->o.bandwidth / 4) : (1u << 20);
    if (c->window < 65536)
        c->window = 65536;
    bool fail = false;
    c->host = dup_or_null(o->host, &fail);
    c->model = dup_or_null(o->model, &fail);
    c->token = dup_or_null(o->token, &fail);
    c->agent = dup_or_null(o->agent ? o->agent : "meshstream-client", &fail);
    c->archive_path = dup_or_null(o->archive_path, &fail);
    c->latencies = malloc(LATENCY_KEEP * sizeof *c->latencies);
    c->t0 = ms_now_seconds();
    for (size_t k = 0; k < sizeof c->slot_buckets / sizeof *c->slot_buckets; ++k)
        c->slot_buckets[k] = NO_SLOT;
    c->tolerance_factor = 1.0;
    c->last_blocked = -1e9;
    c->down_since = -1;
    c->backoff = 0.1;
    c->stats.first_display = -1;
    c->base = event_base_new();
    if (fail || !c->latencies || !c->base ||
        !(c->tick = event_new(c->base, -1, EV_PERSIST, ms_core_net_tick, c))) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory starting the client core");
    }
    pthread_mutex_init(&c->lock, NULL);
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_cond_init(&c->wake, &ca);
    pthread_condattr_destroy(&ca);
    unsigned helpers = c->o.decode_threads ? c->o.decode_threads - 1 : 1;
    if (c->shared && ms_core_budget_join(c->shared, &c->member, err) != MS_OK) {
        ms_core_stop(c);
        return MS_ERR_ARG;
    }
    ms_status pool_status = ms_pool_new(helpers, &c->pool, err);
    if (pool_status != MS_OK) {
        ms_core_stop(c);
        return pool_status;
    }
    if (pthread_create(&c->dec_thread, NULL, ms_core_decode_main, c) != 0) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_IO, "cannot start the decode thread");
    }
    c->dec_started = true;
    if (pthread_create(&c->net_thread, NULL, local ? ms_core_local_main : ms_core_net_main, c) != 0) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_IO, "cannot start the %s thread",
                            local ? "local responder" : "network");
    }
    c->net_started = true;
    *out = c;
    return MS_OK;
}

void ms_core_stop(ms_core *c)
{
    if (!c)
        return;
    if (c->base) {
        pthread_mutex_lock(&c->lock);
        c->stopping = true;
        pthread_cond_broadcast(&c->wake);
        pthread_mutex_unlock(&c->lock);
    }
    if (c->net_started)
        pthread_join(c->net_thread, NULL);
    if (c->dec_started)
        pthread_join(c->dec_thread, NULL);
    if (c->member >= 0)
        ms_core_budget_leave(c->shared, c->member);
    ms_pool_free(c->pool);
    free(c->jobs);
    if (c->client)
        ms_client_free(c->client);
    if (c->tick)
        event_free(c->tick);
    if (c->base) {
        event_base_free(c->base);
        pthread_mutex_destroy(&c->lock);
        pthread_cond_destroy(&c->wake);
    }
    while (c->inbox) {
        chunk_msg *m = c->inbox;
        c->inbox = m->next;
        free(m);
    }
    ms_core_dcells_free(c);
    ms_core_subtrees_free(c);
    ms_view_destroy(c->view);
    ms_archive_close(c->index);
    ms_core_opening_free(&c->opening);
    free(c->wants);
    free(c->net_wants);
    if (c->frame)
        ms_core_frame_free(c->frame);
    free(c->latencies);
    free(c->host);
    free(c->model);
    free(c->token);
    free(c->agent);
    free(c->archive_path);
    free(c);
}

void ms_core_set_camera(ms_core *c, const ms_camera *camera)
{
    pthread_mutex_lock(&c->lock);
    c->camera = *camera;
    c->have_camera = true;
    c->camera_serial++;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

void ms_core_get_stats(ms_core *c, ms_core_stats *out)
{
    double *copy = NULL;
    size_t n;
    pthread_mutex_lock(&c->lock);
    *out = c->stats;
    out->time = ms_core_since_start(c);
    out->connected = c->connected;
    out->model_open = c->model_open;
    out->bytes_received = c->bytes_received;
    out->geometry_bytes_received = c->geometry_bytes_received;
    out->apo_bytes_received = c->apo_bytes_received;
    out->socket_bytes = c->socket_bytes;
    out->bytes_in_flight = c->bytes_in_flight;
    out->requests = c->requests;
    out->cancels = c->cancels;
    out->reconnects = c->reconnects;
    out->longest_outage = c->longest_outage;
    if (out->camera_serial != c->camera_serial)
        out->view_complete = false;
    n = c->latency_count;
    if (n && (copy = malloc(n * sizeof *copy)))
        memcpy(copy, c->latencies, n * sizeof *copy);
    pthread_mutex_unlock(&c->lock);
    out->latency_p50 = out->latency_p99 = 0;
    if (copy) {
        qsort(copy, n, sizeof *copy, compare_double);
        size_t k50 = (size_t)ceil(0.50 * (double)n), k99 = (size_t)ceil(0.99 * (double)n);
        out->latency_p50 = copy[k50 ? k50 - 1 : 0];
        out->latency_p99 = copy[k99 ? k99 - 1 : 0];
        free(copy);
    }
}
