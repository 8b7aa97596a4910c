/* A connection shared by client cores (ms_core_link, ms_client_core.h): the
 * link's life (options, thread, event loop), members joining and leaving,
 * and its figures. What the link's thread does with the connection is in
 * ms_client_core_net.c. */
#include "ms_client_core_internal.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"

static bool figure_ok(double x) { return isfinite(x) && x >= 0; }

ms_status ms_core_link_new(const ms_core_link_options *o, ms_core_link **out, ms_error *err)
{
    *out = NULL;
    if (!o || !o->host || !o->host[0] || o->port == 0)
        return ms_error_set(err, MS_ERR_ARG, "client link: host and port are required");
    if (!figure_ok(o->bandwidth) || !figure_ok(o->answer_timeout) ||
        !figure_ok(o->give_up_seconds))
        return ms_error_set(err, MS_ERR_ARG, "client link: bad bandwidth or time-out");
    ms_core_link *l = calloc(1, sizeof *l);
    if (!l)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    l->o = *o;
    if (l->o.answer_timeout == 0)
        l->o.answer_timeout = 5.0;
    if (l->o.give_up_seconds == 0)
        l->o.give_up_seconds = 30.0;
    l->window = ms_core_window(o->window_bytes, o->bandwidth);
    bool fail = false;
    l->host = ms_core_copy_text(o->host, &fail);
    l->token = ms_core_copy_text(o->token, &fail);
    l->agent = ms_core_copy_text(o->agent ? o->agent : "meshstream-client", &fail);
    l->o.host = l->host, l->o.token = l->token, l->o.agent = l->agent;
    l->t0 = ms_now_seconds();
    l->down_since = -1;
    l->backoff = 0.1;
    for (size_t k = 0; k < sizeof l->slot_buckets / sizeof *l->slot_buckets; ++k)
        l->slot_buckets[k] = NO_SLOT;
    pthread_mutex_init(&l->lock, NULL);
    pthread_cond_init(&l->left, NULL);
    l->base = event_base_new();
    if (fail || !l->base || !(l->tick = event_new(l->base, -1, EV_PERSIST, ms_core_net_tick, l))) {
        ms_core_link_free(l);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory starting the client link");
    }
    if (pthread_create(&l->thread, NULL, ms_core_net_main, l) != 0) {
        ms_core_link_free(l);
        return ms_error_set(err, MS_ERR_IO, "cannot start the network thread");
    }
    l->started = true;
    *out = l;
    return MS_OK;
}

void ms_core_link_free(ms_core_link *l)
{
    if (!l)
        return;
    pthread_mutex_lock(&l->lock);
    l->stopping = true;
    pthread_mutex_unlock(&l->lock);
    if (l->started)
        pthread_join(l->thread, NULL);
    if (l->client)
        ms_client_free(l->client);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        free(l->members[i].wants);
    if (l->tick)
        event_free(l->tick);
    if (l->base)
        event_base_free(l->base);
    pthread_mutex_destroy(&l->lock);
    pthread_cond_destroy(&l->left);
    free(l->host);
    free(l->token);
    free(l->agent);
    free(l);
}

ms_status ms_core_link_join(ms_core_link *l, ms_core *c, ms_error *err)
{
    pthread_mutex_lock(&l->lock);
    link_member *found = NULL;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS && !found; ++i) {
        link_member *m = &l->members[i];
        if (m->state == MEMBER_FREE)
            found = m;
    }
    if (found) {
        want *keep = found->wants;
        size_t cap = found->want_cap;
        *found = (link_member){.state = MEMBER_JOINING, .core = c, .down_since = -1,
                               .wants = keep, .want_cap = cap};
    }
    pthread_mutex_unlock(&l->lock);
    if (!found)
        return ms_error_set(err, MS_ERR_ARG, "shared link: already %d cores share it",
                            MS_CORE_LINK_MAX_MEMBERS);
    return MS_OK;
}

void ms_core_link_leave(ms_core_link *l, ms_core *c)
{
    pthread_mutex_lock(&l->lock);
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i) {
        link_member *m = &l->members[i];
        if (m->core != c || m->state == MEMBER_FREE)
            continue;
        if (m->state == MEMBER_JOINING) { /* the link's thread never saw it */
            m->state = MEMBER_FREE;
            m->core = NULL;
            break;
        }
        m->state = MEMBER_LEAVING;
        /* the link's thread retires it at its next tick (5 ms) */
        while (m->state != MEMBER_FREE)
            pthread_cond_wait(&l->left, &l->lock);
        break;
    }
    pthread_mutex_unlock(&l->lock);
}

void ms_core_link_get_stats(ms_core_link *l, ms_core_link_stats *out)
{
    memset(out, 0, sizeof *out);
    pthread_mutex_lock(&l->lock);
    out->connected = l->connected;
    for (unsigned i = 0; i < MS_CORE_LINK_MAX_MEMBERS; ++i)
        out->members += l->members[i].state != MEMBER_FREE;
    out->connections = l->connections;
    out->socket_bytes = l->socket_bytes;
    out->requests = l->requests;
    pthread_mutex_unlock(&l->lock);
}
