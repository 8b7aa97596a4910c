/* The client core's caller's API: see ms_client_core.h for what it does and
 * ms_client_core_internal.h for its parts (network or local byte source,
 * decode thread, scheduling, budget, frames). Starting a core starts its
 * parts; nothing of them calls back into this file. */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"
#include "ms_proto.h"

/* A core given a shared link leaves the connection's settings to it. */
static bool connection_fields_unset(const ms_core_options *o)
{
    return !o->host && !o->port && !o->token && !o->agent && o->bandwidth == 0 &&
           o->window_bytes == 0 && o->answer_timeout == 0 && o->give_up_seconds == 0 &&
           !o->raw_index && !o->whole_index;
}

static ms_status check_options(const ms_core_options *o, ms_error *err)
{
    bool local = o && o->archive_path;
    if (local && !o->archive_path[0])
        return ms_error_set(err, MS_ERR_ARG, "client core: empty archive path");
    if (o && o->shared_link && (local || !connection_fields_unset(o) || !o->model))
        return ms_error_set(err, MS_ERR_ARG, "client core: a shared link holds the connection's "
                            "settings (leave host, port, token, agent, bandwidth, window, "
                            "time-outs and index options unset; no archive path) and needs "
                            "a model");
    if (!o || (!local && !o->shared_link && (!o->host || !o->model || o->port == 0)))
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
    return MS_OK;
}

/* The byte source from a server: the shared link, or a private link of one
 * made from the core's own connection settings; c joins it. */
static ms_status join_link(ms_core *c, ms_error *err)
{
    if (c->o.shared_link) {
        c->link = c->o.shared_link;
    } else {
        ms_core_link_options lo = {.host = c->o.host, .port = c->o.port, .token = c->o.token,
                                   .agent = c->o.agent, .bandwidth = c->o.bandwidth,
                                   .window_bytes = c->o.window_bytes,
                                   .answer_timeout = c->o.answer_timeout,
                                   .give_up_seconds = c->o.give_up_seconds,
                                   .raw_index = c->o.raw_index, .whole_index = c->o.whole_index};
        ms_status st = ms_core_link_new(&lo, &c->link, err);
        if (st != MS_OK)
            return st;
        c->own_link = true;
    }
    ms_status st = ms_core_link_join(c->link, c, err);
    c->joined = st == MS_OK;
    return st;
}

ms_status ms_core_start(const ms_core_options *o, ms_core **out, ms_error *err)
{
    *out = NULL;
    ms_status st = check_options(o, err);
    if (st != MS_OK)
        return st;
    bool local = o->archive_path != NULL;
    ms_core *c = calloc(1, sizeof *c);
    if (!c)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    c->o = *o;
    c->shared = o->shared_budget;
    c->member = -1;
    if (c->o.tolerance_px == 0)
        c->o.tolerance_px = 1.0;
    if (c->o.hysteresis_bits < 0)
        c->o.hysteresis_bits = MS_SELECT_HYSTERESIS_DEFAULT;
    if (c->o.culled_bits_less == 0)
        c->o.culled_bits_less = 6.0;
    /* Geometry as fine with APO as without: coarser geometry where APO carries
     * the shading (4 px was the default) cost more image error than the bytes
     * it saved with the default bake (docs/ACCURACY.md). */
    if (c->o.apo_geometry_tolerance_px == 0)
        c->o.apo_geometry_tolerance_px = c->o.tolerance_px;
    if (c->o.memory_target && !c->o.memory_ceiling)
        c->o.memory_ceiling = c->o.memory_target + c->o.memory_target / 4;
    c->window = ms_core_window(c->o.window_bytes, c->o.bandwidth);
    bool fail = false;
    c->model = ms_core_copy_text(o->model, &fail);
    c->archive_path = ms_core_copy_text(o->archive_path, &fail);
    c->latencies = malloc(LATENCY_KEEP * sizeof *c->latencies);
    c->t0 = ms_now_seconds();
    c->stats.first_display = -1;
    pthread_mutex_init(&c->lock, NULL);
    pthread_cond_init(&c->wake, NULL);
    c->locked = true;
    if (fail || !c->latencies) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory starting the client core");
    }
    unsigned helpers = c->o.decode_threads ? c->o.decode_threads - 1 : 1;
    if (c->shared && ms_core_budget_join(c->shared, &c->member, err) != MS_OK) {
        ms_core_stop(c);
        return MS_ERR_ARG;
    }
    ms_status pool_status = ms_core_decoder_init(c, helpers, err);
    if (pool_status != MS_OK) {
        ms_core_stop(c);
        return pool_status;
    }
    if (pthread_create(&c->dec_thread, NULL, ms_core_decode_main, c) != 0) {
        ms_core_stop(c);
        return ms_error_set(err, MS_ERR_IO, "cannot start the decode thread");
    }
    c->dec_started = true;
    if (local) {
        if (pthread_create(&c->local_thread, NULL, ms_core_local_main, c) != 0) {
            ms_core_stop(c);
            return ms_error_set(err, MS_ERR_IO, "cannot start the local responder thread");
        }
        c->local_started = true;
    } else if ((st = join_link(c, err)) != MS_OK) {
        ms_core_stop(c);
        return st;
    }
    c->o.host = c->o.token = c->o.agent = NULL; /* the caller's: the link keeps copies */
    *out = c;
    return MS_OK;
}

void ms_core_stop(ms_core *c)
{
    if (!c)
        return;
    if (c->locked) {
        pthread_mutex_lock(&c->lock);
        c->stopping = true;
        pthread_cond_broadcast(&c->wake);
        pthread_mutex_unlock(&c->lock);
    }
    if (c->joined)
        ms_core_link_leave(c->link, c); /* the link touches c no more */
    if (c->own_link)
        ms_core_link_free(c->link);
    if (c->local_started)
        pthread_join(c->local_thread, NULL);
    if (c->dec_started)
        pthread_join(c->dec_thread, NULL);
    if (c->member >= 0)
        ms_core_budget_leave(c->shared, c->member);
    if (c->locked) {
        pthread_mutex_destroy(&c->lock);
        pthread_cond_destroy(&c->wake);
    }
    while (c->inbox) {
        chunk_msg *m = c->inbox;
        c->inbox = m->next;
        free(m);
    }
    ms_core_decoder_free(c);
    ms_archive_close(c->index);
    ms_core_opening_free(&c->opening);
    free(c->wants);
    if (c->frame)
        ms_core_frame_free(c->frame);
    free(c->latencies);
    free(c->model);
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

ms_status ms_core_set_sections(ms_core *c, const double (*planes)[4], size_t count, ms_error *err)
{
    if (count > MS_SECTIONS_MAX || (count && !planes))
        return ms_error_set(err, MS_ERR_ARG, "core: %zu section planes, at most %d", count, MS_SECTIONS_MAX);
    ms_frustum check = {0};
    for (size_t k = 0; k < count; ++k)
        if (!ms_frustum_add_section(&check, planes[k]))
            return ms_error_set(err, MS_ERR_ARG, "core: section plane %zu has a zero normal or a number not finite", k);
    pthread_mutex_lock(&c->lock);
    c->section_count = (unsigned)count;
    for (size_t k = 0; k < count; ++k)
        memcpy(c->sections[k], planes[k], sizeof c->sections[k]);
    c->camera_serial++; /* a new pass for the same camera */
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
    return MS_OK;
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
    out->preview = c->permitted_geometry_steps > 0;
    out->preview_bits = out->preview ? c->permitted_geometry_steps - 1u : 0;
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
