/* The client core's index: the view over a whole index, or over one that comes
 * by subtree (docs/CLIENT.md, "An index by subtree"). With a partial index
 * (ms_archive_open_head) the view learns the root subtree at once and each
 * further subtree as it arrives; every pass keeps exactly the subtrees the cut
 * needs (those holding a cell of the cut, and those holding the children of a
 * cell that would split or is within a bit of splitting), asks for the missing
 * ones ahead of the cells they unblock, and forgets the others with their
 * cells' bytes. Decode thread only (the figures under the lock). */
#include "ms_client_core_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_subtree.h"

/* ---- the table of subtrees (sorted by id) --------------------------------- */

static size_t subtree_find(const ms_core *c, uint32_t id, bool *found)
{
    size_t lo = 0, hi = c->dec.subtree_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (c->dec.subtrees[mid].id < id)
            lo = mid + 1;
        else
            hi = mid;
    }
    *found = lo < c->dec.subtree_count && c->dec.subtrees[lo].id == id;
    return lo;
}

static subtree_entry *subtree_get(ms_core *c, uint32_t id)
{
    bool found;
    size_t k = subtree_find(c, id, &found);
    return found ? &c->dec.subtrees[k] : NULL;
}

/* The entry of subtree id, made (RECEIVING) when absent; NULL out of memory. */
static subtree_entry *subtree_add(ms_core *c, uint32_t id, uint32_t parent)
{
    bool found;
    size_t k = subtree_find(c, id, &found);
    if (found)
        return &c->dec.subtrees[k];
    if (c->dec.subtree_count == c->dec.subtree_cap) {
        size_t cap = c->dec.subtree_cap ? 2 * c->dec.subtree_cap : 64;
        subtree_entry *g = realloc(c->dec.subtrees, cap * sizeof *g);
        if (!g)
            return NULL;
        c->dec.subtrees = g;
        c->dec.subtree_cap = cap;
    }
    memmove(&c->dec.subtrees[k + 1], &c->dec.subtrees[k], (c->dec.subtree_count - k) * sizeof *c->dec.subtrees);
    c->dec.subtree_count++;
    c->dec.subtrees[k] = (subtree_entry){.id = id, .parent = parent, .state = SUBTREE_RECEIVING};
    return &c->dec.subtrees[k];
}

static void subtree_remove(ms_core *c, size_t k)
{
    ms_core_rx_free(&c->dec.subtrees[k].buf);
    memmove(&c->dec.subtrees[k], &c->dec.subtrees[k + 1],
            (c->dec.subtree_count - k - 1) * sizeof *c->dec.subtrees);
    c->dec.subtree_count--;
}

/* The view learns the records of subtree id (held by the index). */
static ms_status learn_subtree(ms_core *c, uint32_t id, ms_error *err)
{
    const uint32_t *ids;
    const ms_archive_cell *recs;
    size_t n;
    if (!ms_archive_held_subtree(c->index, id, &ids, &recs, &n))
        return ms_error_set(err, MS_ERR_CORRUPT, "subtree %u is not held", id);
    ms_status s = ms_view_learn(c->dec.view, ids, recs, n, err);
    if (s == MS_OK && !ms_core_dcells_grow(c, ids, n))
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory for subtree %u's cells", id);
    return s;
}

static void note_index_held(ms_core *c)
{
    c->dec.index_bytes_held = ms_archive_index_bytes_held(c->index);
    pthread_mutex_lock(&c->lock);
    c->stats.index_bytes_held = c->dec.index_bytes_held;
    if (c->dec.index_bytes_held > c->stats.peak_index_bytes_held)
        c->stats.peak_index_bytes_held = c->dec.index_bytes_held;
    c->stats.subtrees_held = ms_archive_subtrees_held(c->index);
    pthread_mutex_unlock(&c->lock);
}

bool ms_core_take_index(ms_core *c, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    if (ms_view_create_partial(h, &c->dec.view, err) != MS_OK)
        return false;
    c->dec.by_subtree = ms_archive_is_partial(c->index);
    if (c->dec.by_subtree) {
        c->dec.subtree_levels = ms_archive_subtree_levels(c->index);
        if (c->dec.subtree_levels < 1) {
            ms_error_set(err, MS_ERR_CORRUPT, "index head: no subtree depth");
            return false;
        }
        subtree_entry *root = subtree_add(c, 0, MS_ARCHIVE_NONE);
        if (!root) {
            ms_error_set(err, MS_ERR_NOMEM, "out of memory for the subtrees");
            return false;
        }
        root->state = SUBTREE_HELD;
        if (learn_subtree(c, 0, err) != MS_OK)
            return false;
        note_index_held(c);
        pthread_mutex_lock(&c->lock);
        c->stats.index_by_subtree = true;
        pthread_mutex_unlock(&c->lock);
        return true;
    }
    /* a whole index: every record at once */
    uint32_t *ids = malloc((size_t)h->cell_count * sizeof *ids);
    ms_archive_cell *recs = malloc((size_t)h->cell_count * sizeof *recs);
    ms_status s = MS_OK;
    if (!ids || !recs)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
    for (uint32_t i = 0; s == MS_OK && i < h->cell_count; ++i) {
        ids[i] = i;
        recs[i] = *ms_archive_get_cell(c->index, i);
    }
    if (s == MS_OK)
        s = ms_view_learn(c->dec.view, ids, recs, h->cell_count, err);
    if (s == MS_OK && !ms_core_dcells_grow(c, ids, h->cell_count))
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory for %u cells", h->cell_count);
    free(ids);
    free(recs);
    /* held whatever the view: outside the budget, in the figures */
    pthread_mutex_lock(&c->lock);
    c->stats.index_bytes_held = c->stats.peak_index_bytes_held =
        ms_archive_index_bytes_held(c->index);
    pthread_mutex_unlock(&c->lock);
    return s == MS_OK;
}

/* ---- reception -------------------------------------------------------------- */

/* A subtree that failed: fetched once more, then given up (its cell stays). */
static void subtree_trouble(ms_core *c, subtree_entry *e, const char *what)
{
    ms_core_rx_free(&e->buf);
    e->total = 0;
    e->retries++;
    pthread_mutex_lock(&c->lock);
    c->stats.refetches += e->retries == 1;
    pthread_mutex_unlock(&c->lock);
    if (e->retries >= 2 && e->state != SUBTREE_FAILED) {
        e->state = SUBTREE_FAILED;
        char text[256];
        snprintf(text, sizeof text, "subtree %u: %.150s (after a refetch); cell %u stays "
                 "unsplit", e->id, what, e->parent);
        ms_core_warn(c, text);
    }
}

void ms_core_subtree_chunk(ms_core *c, const chunk_msg *m)
{
    pthread_mutex_lock(&c->lock);
    c->stats.index_bytes_received += m->length;
    pthread_mutex_unlock(&c->lock);
    subtree_entry *e = subtree_get(c, m->cell);
    if (!e || e->state != SUBTREE_RECEIVING)
        return; /* no longer wanted, or already held */
    if (m->failed) {
        subtree_trouble(c, e, "the server answered its request with an error");
        return;
    }
    if (m->total && (e->total == 0 || e->buf.end == 0))
        e->total = m->total;
    /* no subtree stores more than its raw blob's bound (every record and table
     * word of the model) and zlib's few bytes: a larger size is a lie */
    const ms_archive_header *h = ms_archive_get_header(c->index);
    uint64_t bound = 24 + 84 * (uint64_t)h->cell_count + 4 * (uint64_t)h->table_words + 4096;
    if (e->total > bound) {
        subtree_trouble(c, e, "its stored size exceeds any subtree of the model");
        return;
    }
    if (!e->total || (m->total && m->total != e->total) ||
        (uint64_t)m->offset + m->length > e->total) {
        subtree_trouble(c, e, "its pieces disagree on its size");
        return;
    }
    if (!ms_core_rx_add(&e->buf, m->offset, m->data, m->length)) {
        ms_core_warn(c, "out of memory for a subtree");
        return;
    }
    if (e->buf.end < e->total)
        return;
    ms_error err;
    if (ms_archive_add_subtree(c->index, e->id, e->buf.buf, e->total, &err) != MS_OK) {
        subtree_trouble(c, e, err.text);
        return;
    }
    ms_core_rx_free(&e->buf);
    e->state = SUBTREE_HELD;
    if (learn_subtree(c, e->id, &err) != MS_OK) {
        /* the archive took it, the view did not: forget it on both sides */
        ms_archive_drop_subtree(c->index, e->id);
        e->state = SUBTREE_RECEIVING;
        subtree_trouble(c, e, err.text);
        return;
    }
    pthread_mutex_lock(&c->lock);
    c->stats.subtrees_received++;
    pthread_mutex_unlock(&c->lock);
    c->dec.subtrees_changed = true;
    note_index_held(c);
}

/* ---- each pass ---------------------------------------------------------------- */

const ms_sched_subtree *ms_core_subtrees_snapshot(ms_core *c, size_t *count)
{
    *count = 0;
    if (!c->dec.by_subtree || !c->dec.subtree_count)
        return NULL;
    if (c->dec.subtree_count > c->dec.sched_subtrees_cap) {
        ms_sched_subtree *g = realloc(c->dec.sched_subtrees, c->dec.subtree_count * sizeof *g);
        if (!g)
            return NULL;
        c->dec.sched_subtrees = g;
        c->dec.sched_subtrees_cap = c->dec.subtree_count;
    }
    for (size_t k = 0; k < c->dec.subtree_count; ++k) {
        const subtree_entry *e = &c->dec.subtrees[k];
        c->dec.sched_subtrees[k] = (ms_sched_subtree){e->id, e->state, e->buf.end, e->total};
    }
    *count = c->dec.subtree_count;
    return c->dec.sched_subtrees;
}

/* Forgets subtree k's records and its cells' bytes; false when the view still
 * shows one of them (then it stays). */
static bool drop_subtree(ms_core *c, size_t k)
{
    subtree_entry *e = &c->dec.subtrees[k];
    if (e->state == SUBTREE_HELD) {
        const uint32_t *ids;
        const ms_archive_cell *recs;
        size_t n;
        ms_error err;
        if (!ms_archive_held_subtree(c->index, e->id, &ids, &recs, &n) ||
            ms_view_unlearn(c->dec.view, ids, n, &err) != MS_OK)
            return false;
        ms_core_dcells_release(c, ids, n);
        ms_archive_drop_subtree(c->index, e->id);
    }
    subtree_remove(c, k);
    return true;
}

void ms_core_subtrees_keep(ms_core *c, dec_pass *pass, const ms_sched_need *needs, size_t count)
{
    if (!c->dec.by_subtree)
        return;
    for (size_t k = 0; k < c->dec.subtree_count; ++k)
        c->dec.subtrees[k].needed = c->dec.subtrees[k].id == 0;
    /* the ones the cut needs stay; a missing one starts being received (the
     * scheduler asked for it) */
    for (size_t k = 0; k < count; ++k) {
        subtree_entry *e = subtree_add(c, needs[k].id, needs[k].parent);
        if (e)
            e->needed = true;
    }
    /* the others go, deepest first (a subtree's id exceeds its parent's) */
    bool dropped = false;
    for (size_t k = c->dec.subtree_count; k-- > 0;)
        if (!c->dec.subtrees[k].needed)
            dropped |= drop_subtree(c, k);
    if (dropped) {
        note_index_held(c);
        c->dec.subtrees_changed = true;
    }
    /* a frame lists the subtrees held: a new list is a new frame */
    pass->changed |= c->dec.subtrees_changed;
    c->dec.subtrees_changed = false;
    for (size_t k = 0; k < c->dec.subtree_count; ++k)
        if (c->dec.subtrees[k].state == SUBTREE_FAILED)
            pass->complete = false;
}

void ms_core_subtrees_free(ms_core *c)
{
    for (size_t k = 0; k < c->dec.subtree_count; ++k)
        ms_core_rx_free(&c->dec.subtrees[k].buf);
    free(c->dec.subtrees);
    c->dec.subtrees = NULL;
    c->dec.subtree_count = c->dec.subtree_cap = 0;
    ms_view_select_report_free(&c->dec.report);
    ms_view_select_report_free(&c->dec.what_if_report);
    free(c->dec.sched_subtrees);
    c->dec.sched_subtrees = NULL;
    c->dec.sched_subtrees_cap = 0;
}
