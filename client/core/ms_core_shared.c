/* What the client core's threads share (ms_client_core_internal.h, "shared,
 * under lock"): the inbox of received chunks (the one queue from the byte
 * source to the decoder) and the figures every part reports into: the
 * error, the warning, the clock. Each takes the core's lock for a copy;
 * nothing here calls into another file of the core. */
#include "ms_client_core_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_progress.h"

double ms_core_since_start(const ms_core *c) { return ms_now_seconds() - c->t0; }

uint64_t ms_core_window(uint64_t window_bytes, double bandwidth)
{
    uint64_t w = window_bytes ? window_bytes : bandwidth > 0 ? (uint64_t)(bandwidth / 4) : (1u << 20);
    return w < 65536 ? 65536 : w;
}

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
    if (m->stream != STREAM_INDEX)
        c->bytes_queued += m->length;
    if (c->inbox_tail)
        c->inbox_tail->next = m;
    else
        c->inbox = m;
    c->inbox_tail = m;
    pthread_cond_broadcast(&c->wake);
    pthread_mutex_unlock(&c->lock);
}

char *ms_core_copy_text(const char *s, bool *fail)
{
    if (!s)
        return NULL;
    char *d = strdup(s);
    if (!d)
        *fail = true;
    return d;
}

void ms_core_keep_opening(ms_core *c, const ms_archive *index, bool by_subtree)
{
    if (c->have_opening)
        return;
    ms_core_opening *o = &c->opening;
    o->header = *ms_archive_get_header(index);
    o->by_subtree = by_subtree;
    if (!c->o.export_frames) { /* the header and the bounds only (meshload): no copy of records */
        pthread_mutex_lock(&c->lock);
        c->have_opening = true;
        pthread_mutex_unlock(&c->lock);
        return;
    }
    size_t known = 0;
    for (uint32_t i = 0; i < o->header.cell_count; ++i)
        known += ms_archive_get_cell(index, i) != NULL;
    o->ids = malloc((known ? known : 1) * sizeof *o->ids);
    o->records = malloc((known ? known : 1) * sizeof *o->records);
    if (!o->ids || !o->records) {
        ms_core_opening_free(o);
        return;
    }
    for (uint32_t i = 0; i < o->header.cell_count; ++i) {
        const ms_archive_cell *rec = ms_archive_get_cell(index, i);
        if (rec) {
            o->ids[o->count] = i;
            o->records[o->count++] = *rec;
        }
    }
    pthread_mutex_lock(&c->lock);
    c->have_opening = true;
    pthread_mutex_unlock(&c->lock);
}

void ms_core_opening_free(ms_core_opening *o)
{
    if (!o)
        return;
    free(o->ids);
    free(o->records);
    memset(o, 0, sizeof *o);
}
