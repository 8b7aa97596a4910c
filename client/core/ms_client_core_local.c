/* The client core's local responder (archive_path): the byte source that
 * stands where the network thread stands, answering the decode thread's want
 * lists from the archive file. */
#include "ms_client_core_internal.h"

#include <errno.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ms_subtree.h"

/* With archive_path, this thread stands where the network thread stands: it
 * opens the archive (the whole file, so the decode thread's index is the
 * archive itself), then answers the decode thread's want lists from the
 * mapping. It hands over at most `window` bytes of the best ranges, in the
 * list's order, as chunk messages like the network's, then waits until the
 * decode thread has taken them and published its next list (which then asks
 * only for what is still missing, so nothing is handed over twice and a new
 * camera reorders what comes next). With `bandwidth` it sleeps as long as the
 * bytes would take on such a link. */

/* Waits up to `seconds` unless the core stops; caller holds the lock. */
static void local_pause_locked(ms_core *c, double seconds)
{
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    double whole = floor(seconds);
    until.tv_sec += (time_t)whole;
    until.tv_nsec += (long)((seconds - whole) * 1e9);
    if (until.tv_nsec >= 1000000000L)
        until.tv_sec++, until.tv_nsec -= 1000000000L;
    while (!c->stopping && !c->fatal &&
           pthread_cond_timedwait(&c->wake, &c->lock, &until) != ETIMEDOUT)
        ;
}

/* One want as a chunk message from the archive (a failed one if the archive
 * does not hold the range, which its validated index rules out). */
static chunk_msg *local_chunk(const ms_archive *a, const want *w)
{
    size_t length = 0;
    const uint8_t *src = w->stream == STREAM_INDEX ? ms_archive_subtree(a, w->cell, &length)
                         : w->stream == STREAM_APO ? ms_archive_apo(a, w->cell, &length)
                         : w->stream == STREAM_COLOUR ? ms_archive_colour(a, w->cell, &length)
                                                   : ms_archive_geometry(a, w->cell, &length);
    uint32_t end = w->end;
    if (w->stream == STREAM_INDEX && end > length)
        end = (uint32_t)length; /* the whole subtree, as the server sends it */
    bool held = src && w->start < end && end <= length;
    uint32_t n = held ? end - w->start : 0;
    chunk_msg *m = malloc(sizeof *m + n);
    if (!m)
        return NULL;
    memset(m, 0, sizeof *m);
    m->cell = w->cell, m->stream = w->stream, m->offset = w->start, m->length = n;
    m->total = w->stream == STREAM_INDEX ? (uint32_t)length : 0;
    m->failed = !held;
    if (held)
        memcpy(m->data, src + w->start, n);
    return m;
}

void *ms_core_local_main(void *arg)
{
    ms_core *c = arg;
    ms_archive *a, *index;
    ms_error err;
    if (ms_archive_open(c->archive_path, &a, &err) != MS_OK) {
        ms_core_fail(c, "%.240s", err.text);
        return NULL;
    }
    /* The decode thread gets the index as a client of a server that offers
     * subtrees gets it: the head alone (then subtrees as it asks for them),
     * or with whole_index the archive's whole index. */
    size_t index_size;
    if (c->o.whole_index) {
        index = a;
        ms_archive_index_bytes(a, &index_size);
    } else {
        const uint8_t *head = ms_archive_index_head(a, &index_size);
        if (!head || ms_archive_open_head(head, index_size, c->model ? c->model : "local",
                                          &index, &err) != MS_OK) {
            ms_core_fail(c, "%.240s", head ? err.text : "the archive has no index head");
            ms_archive_close(a);
            return NULL;
        }
    }
    want *list = NULL;
    size_t cap = 0;
    uint64_t served_serial = 0, handed_seq = 0;
    ms_core_keep_opening(c, index, !c->o.whole_index);
    pthread_mutex_lock(&c->lock);
    c->index = index;
    c->index_new = true;
    c->stats.index_bytes_received = index_size;
    c->connected = c->model_open = true;
    c->colour_served = true;
    pthread_cond_broadcast(&c->wake);
    for (;;) {
        /* a fresh list, computed after the decode thread took what we handed */
        while (!c->stopping && !c->fatal &&
               (c->want_serial == served_serial || c->want_consumed_seq < handed_seq))
            pthread_cond_wait(&c->wake, &c->lock);
        if (c->stopping || c->fatal)
            break;
        served_serial = c->want_serial;
        size_t count = c->want_count;
        if (count > cap) {
            want *grown = realloc(list, count * sizeof *grown);
            if (!grown) {
                ms_core_fail_locked(c, "%.240s", "out of memory for the local responder");
                break;
            }
            list = grown;
            cap = count;
        }
        if (count)
            memcpy(list, c->wants, count * sizeof *list);
        pthread_mutex_unlock(&c->lock);

        uint64_t handed = 0, geometry = 0, apo = 0, colour = 0, ranges = 0;
        for (size_t i = 0; i < count && handed < c->window; ++i) {
            chunk_msg *m = local_chunk(a, &list[i]);
            if (!m) {
                ms_core_fail(c, "%.240s", "out of memory for the local responder");
                break;
            }
            handed += m->length;
            if (m->stream == STREAM_COLOUR)
                colour += m->length;
            else if (m->stream != STREAM_INDEX)
                *(m->stream == STREAM_APO ? &apo : &geometry) += m->length;
            ranges++;
            ms_core_push_chunk(c, m);
        }
        pthread_mutex_lock(&c->lock);
        c->bytes_received += geometry + apo + colour; /* payload; subtrees: index_bytes_received */
        c->geometry_bytes_received += geometry;
        c->apo_bytes_received += apo;
        c->requests += ranges;
        handed_seq = c->push_seq;
        if (c->o.bandwidth > 0 && handed > 0)
            local_pause_locked(c, (double)handed / c->o.bandwidth);
    }
    c->connected = false;
    pthread_mutex_unlock(&c->lock);
    free(list);
    if (index != a)
        ms_archive_close(a); /* the decode thread's index is its own (ms_core_stop closes it) */
    return NULL;
}
