/* The client core's publication: the frames handed to the caller (the view's
 * stitched mesh, each shown cell's precision and APO prefix), the first
 * display, and each pass's wants and figures. */
#include "ms_client_core_internal.h"

#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ms_progress.h"

void ms_core_frames_free(ms_core *c)
{
    free(c->dec.last_run_cell);
    free(c->dec.last_run_version);
    c->dec.last_run_cell = NULL;
    c->dec.last_run_version = NULL;
    c->dec.last_run_count = c->dec.last_run_cap = 0;
}

/* The frame's chunk of cell i: the bytes of the previous frames when its
 * prefix did not change since (shared), else a copy made once and kept in
 * the dcell for the frames after. False when out of memory. */
static bool share_apo(dcell *d, ms_core_frame_work *work, ms_core_apo_chunk *chunk)
{
    size_t shared_length = 0;
    if (d->apo_shared)
        (void)ms_core_bytes_data(d->apo_shared, &shared_length);
    if (!d->apo_shared || shared_length != d->apo_given) {
        ms_core_bytes *b = ms_core_bytes_copy(d->apo.buf, d->apo_given);
        if (!b)
            return false;
        ms_core_bytes_release(d->apo_shared);
        d->apo_shared = b;
        work->apo_bytes_copied += d->apo_given;
        work->apo_chunks_copied++;
    } else {
        work->apo_chunks_shared++;
    }
    chunk->shared = ms_core_bytes_retain(d->apo_shared);
    chunk->data = ms_core_bytes_data(d->apo_shared, &chunk->length);
    return true;
}

/* The frame's drawing cells (runs with triangles) against the previous
 * frame's: the cells new or with another version, and those gone; then this
 * frame's become the previous. O(cells drawing), never the triangles. */
static bool count_changes(ms_core *c, ms_core_frame *f)
{
    const ms_view_mesh *m = &f->mesh;
    size_t n = 0;
    for (size_t k = 0; k < m->run_count; ++k)
        n += m->run_first[k + 1] > m->run_first[k];
    uint32_t *cells = malloc((n ? n : 1) * sizeof *cells);
    uint64_t *versions = malloc((n ? n : 1) * sizeof *versions);
    if (!cells || !versions) {
        free(cells);
        free(versions);
        return false;
    }
    size_t j = 0, w = 0;
    for (size_t k = 0; k < m->run_count; ++k) {
        if (m->run_first[k + 1] == m->run_first[k])
            continue;
        uint32_t cell = m->run_cell[k];
        while (j < c->dec.last_run_count && c->dec.last_run_cell[j] < cell)
            j++, f->work.cells_removed++;
        bool same = j < c->dec.last_run_count && c->dec.last_run_cell[j] == cell;
        f->work.cells_changed += !same || c->dec.last_run_version[j] != m->run_version[k];
        j += same;
        cells[w] = cell;
        versions[w++] = m->run_version[k];
    }
    f->work.cells_removed += (uint32_t)(c->dec.last_run_count - j);
    free(c->dec.last_run_cell);
    free(c->dec.last_run_version);
    c->dec.last_run_cell = cells;
    c->dec.last_run_version = versions;
    c->dec.last_run_count = w;
    return true;
}

/* The view as a frame for the caller (NULL and err when out of memory). Its
 * arrays are sized by the cut (cells shown or split), never by the model. */
static ms_core_frame *make_frame(ms_core *c, ms_error *err)
{
    size_t shown = 0, cut = 0, apo = 0;
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i)) {
        ms_view_cell_state st = ms_view_state(c->dec.view, i);
        cut += st != MS_VIEW_HIDDEN;
        shown += st == MS_VIEW_SHOWN;
        apo += st == MS_VIEW_SHOWN && ms_core_dcell(c, i)->apo_given > 0;
    }
    ms_core_frame *f = calloc(1, sizeof *f);
    if (f) {
        f->cell_count = ms_view_cell_count(c->dec.view);
        f->cut_cells = malloc((cut ? cut : 1) * sizeof *f->cut_cells);
        f->cut_bits = malloc(cut ? cut : 1);
        f->record_ids = malloc((shown ? shown : 1) * sizeof *f->record_ids);
        f->records = malloc((shown ? shown : 1) * sizeof *f->records);
        f->apo = calloc(apo ? apo : 1, sizeof *f->apo);
    }
    if (!f || !f->cut_cells || !f->cut_bits || !f->record_ids || !f->records || !f->apo) {
        ms_core_frame_free(f);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
        return NULL;
    }
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i)) {
        ms_view_cell_state st = ms_view_state(c->dec.view, i);
        if (st == MS_VIEW_HIDDEN)
            continue;
        f->cut_cells[f->cut_count] = i;
        f->cut_bits[f->cut_count++] = st == MS_VIEW_SHOWN ? (uint8_t)ms_view_bits(c->dec.view, i)
                                                          : MS_VIEW_TARGET_SPLIT;
        if (st != MS_VIEW_SHOWN)
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        f->record_ids[f->record_count] = i;
        f->records[f->record_count++] = *rec;
        dcell *d = ms_core_dcell(c, i);
        if (d->apo_given == 0)
            continue;
        /* complete levels: ms_archive_apo_prefix(depth) ends depth's level */
        unsigned levels = 0;
        for (unsigned depth = 0; depth < rec->apo_levels; ++depth)
            if (ms_archive_apo_prefix(c->index, i, depth, NULL) <= d->apo_given)
                levels = depth + 1;
        ms_core_apo_chunk *chunk = &f->apo[f->apo_count];
        *chunk = (ms_core_apo_chunk){.cell = i, .levels = levels};
        if (!share_apo(d, &f->work, chunk)) {
            ms_core_frame_free(f);
            ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
            return NULL;
        }
        f->apo_count++;
    }
    size_t held = 0;
    for (size_t k = 0; k < c->dec.subtree_count; ++k)
        held += c->dec.subtrees[k].state == SUBTREE_HELD;
    if (held && !(f->subtrees = malloc(held * sizeof *f->subtrees))) {
        ms_core_frame_free(f);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
        return NULL;
    }
    for (size_t k = 0; k < c->dec.subtree_count; ++k)
        if (c->dec.subtrees[k].state == SUBTREE_HELD)
            f->subtrees[f->subtree_count++] = c->dec.subtrees[k].id;
    if (ms_view_stitch(c->dec.view, NULL, &f->mesh, err) != MS_OK) {
        ms_core_frame_free(f);
        return NULL;
    }
    f->work.cells_stitched = (uint32_t)f->mesh.cells_stitched;
    f->work.triangles_stitched = f->mesh.triangles_stitched;
    if (!count_changes(c, f)) {
        ms_core_frame_free(f);
        ms_error_set(err, MS_ERR_NOMEM, "out of memory for a frame");
        return NULL;
    }
    return f;
}

/* Whether some shown cell in view already has a triangle to draw (a child
 * shown at bits_min right after its parent split has its share of the
 * parent's triangles: the frame that shows it is a display). */
static bool something_drawn(ms_core *c, const frame_view *fv)
{
    for (uint32_t i = 0; i != MS_ARCHIVE_NONE; i = ms_view_next_known(c->dec.view, i)) {
        if (ms_view_state(c->dec.view, i) != MS_VIEW_SHOWN)
            continue;
        const ms_archive_cell *rec = ms_archive_get_cell(c->index, i);
        if (rec->geometry_length == 0)
            continue;
        bool visible;
        ms_core_cell_need(c, fv, i, &visible);
        if (!visible)
            continue;
        ms_codec_state s;
        if (ms_view_cell_state_copy(c->dec.view, i, &s, NULL) != MS_OK)
            continue;
        bool drawn = s.tri_count > 0;
        ms_codec_state_free(&s);
        if (drawn)
            return true;
    }
    return false;
}

/* Under the lock: the pass's wants (when they changed, or a republish was
 * asked for), the chunks it consumed, its frame and its figures. */
static void publish_locked(ms_core *c, dec_pass *pass, uint64_t serial, ms_core_frame *frame,
                           double busy, double frame_busy)
{
    want_list *wl = &pass->wl;
    bool same = wl->n == c->want_count &&
                (wl->n == 0 || !memcmp(wl->w, c->wants, wl->n * sizeof *wl->w));
    if (!same || c->republish) {
        free(c->wants);
        c->wants = wl->w;
        c->want_count = wl->n;
        c->want_serial++;
        c->republish = false;
        wl->w = NULL;
    }
    if (c->want_consumed_seq != c->dec.consumed_seq) {
        c->want_consumed_seq = c->dec.consumed_seq;
        c->want_serial += same; /* let the network thread release finished requests */
    }
    pthread_cond_broadcast(&c->wake); /* the local responder waits for a new list */
    ms_core_stats *st = &c->stats;
    if (frame) {
        if (c->frame)
            ms_core_frame_free(c->frame);
        c->frame = frame;
        st->frames_made++;
        st->frame_triangles += frame->mesh.triangle_count;
        for (size_t i = 0; i < frame->apo_count; ++i)
            st->frame_apo_bytes += frame->apo[i].length;
        ms_core_frame_work *w = &st->frame_work;
        w->apo_bytes_copied += frame->work.apo_bytes_copied;
        w->apo_chunks_copied += frame->work.apo_chunks_copied;
        w->apo_chunks_shared += frame->work.apo_chunks_shared;
        w->cells_stitched += frame->work.cells_stitched;
        w->triangles_stitched += frame->work.triangles_stitched;
        w->cells_changed += frame->work.cells_changed;
        w->cells_removed += frame->work.cells_removed;
    }
    st->view_complete = pass->complete && serial == c->camera_serial;
    st->camera_serial = serial;
    st->achieved_error_px = pass->worst;
    st->preview_limited = c->dec.preview_steps && c->dec.report.capped_count > 0;
    st->tolerance_px = pass->fv.tolerance;
    st->cells_shown = pass->shown, st->cells_split = pass->split, st->cells_cached = pass->cached;
    st->cells_loading = pass->loading, st->cells_failed = pass->failed;
    st->state_cells = c->dec.view ? ms_view_state_cells(c->dec.view) : 0;
    st->state_bytes_held = ms_core_state_bytes_held(c);
    st->memory = pass->memory;
    if (pass->memory > st->peak_memory)
        st->peak_memory = pass->memory;
    st->decode_seconds += busy;
    st->frame_seconds += frame_busy;
    if (pass->warning[0])
        snprintf(st->warning, sizeof st->warning, "%s", pass->warning);
}

void ms_core_publish(ms_core *c, dec_pass *pass, uint64_t serial, double t_start)
{
    double t_now = ms_core_since_start(c);
    /* only the caller's camera displays: the content bounds' camera of the
     * passes before it sees the whole model (a path that never looks at the
     * model must not count as displayed) */
    bool look = !c->dec.first_display_seen && !pass->for_content &&
                (pass->changed || !c->dec.display_checked || c->dec.display_checked_serial != serial);
    if (look) {
        c->dec.display_checked = true;
        c->dec.display_checked_serial = serial;
    }
    bool first_display = look && something_drawn(c, &pass->fv);
    ms_core_frame *frame = NULL;
    double frame_busy = 0.0;
    if (c->o.export_frames &&
        (pass->changed || c->dec.generation == 0 || (c->dec.frame_for_content && !pass->for_content))) {
        ms_error err;
        double t_frame = ms_now_seconds();
        frame = make_frame(c, &err);
        frame_busy = ms_now_seconds() - t_frame;
        if (frame) {
            frame->generation = ++c->dec.generation;
            frame->time = t_now;
            c->dec.frame_for_content = pass->for_content;
        }
    }
    double busy = ms_now_seconds() - t_start;
    pthread_mutex_lock(&c->lock);
    if (first_display) {
        c->dec.first_display_seen = true;
        c->stats.first_display = t_now;
        c->stats.first_display_generation = frame ? frame->generation : 0;
    }
    publish_locked(c, pass, serial, frame, busy, frame_busy);
    pthread_mutex_unlock(&c->lock);
    free(pass->wl.w);
    pass->wl.w = NULL;
}

static int compare_cell(const void *key, const void *entry)
{
    uint32_t a = *(const uint32_t *)key, b = *(const uint32_t *)entry;
    return a < b ? -1 : a > b;
}

uint8_t ms_core_frame_cell_bits(const ms_core_frame *f, uint32_t cell)
{
    const uint32_t *at = f->cut_count ? bsearch(&cell, f->cut_cells, f->cut_count,
                                                sizeof *f->cut_cells, compare_cell)
                                      : NULL;
    return at ? f->cut_bits[at - f->cut_cells] : MS_VIEW_TARGET_HIDDEN;
}

ms_core_frame *ms_core_take_frame(ms_core *c)
{
    pthread_mutex_lock(&c->lock);
    ms_core_frame *f = c->frame;
    c->frame = NULL;
    pthread_mutex_unlock(&c->lock);
    return f;
}

void ms_core_frame_free(ms_core_frame *f)
{
    if (!f)
        return;
    ms_view_mesh_free(&f->mesh);
    for (size_t i = 0; i < f->apo_count; ++i)
        ms_core_bytes_release(f->apo[i].shared);
    free(f->apo);
    free(f->cut_cells);
    free(f->cut_bits);
    free(f->subtrees);
    free(f->record_ids);
    free(f->records);
    free(f);
}


ms_status ms_core_wait_open(ms_core *c, double timeout_s, ms_core_opening *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (!c || !(timeout_s > 0))
        return ms_error_set(err, MS_ERR_ARG, "waiting for a model needs a time-out");
    double until = ms_now_seconds() + timeout_s;
    char why[256] = "";
    bool have = false;
    int content = CONTENT_PENDING;
    double lo[3], hi[3];
    for (;;) {
        pthread_mutex_lock(&c->lock);
        have = c->have_opening;
        content = c->content;
        memcpy(lo, c->content_lo, sizeof lo);
        memcpy(hi, c->content_hi, sizeof hi);
        if (c->stats.error[0])
            snprintf(why, sizeof why, "%s", c->stats.error);
        pthread_mutex_unlock(&c->lock);
        if ((have && content != CONTENT_PENDING) || why[0] || ms_now_seconds() >= until)
            break;
        struct timespec pause = {0, 2000000}; /* 2 ms: a one-off wait at open */
        nanosleep(&pause, NULL);
    }
    if (!have)
        return ms_error_set(err, MS_ERR_IO, "%s", why[0] ? why : "no model index in time");
    /* set once before have_opening, never changed after: read without the lock */
    const ms_core_opening *o = &c->opening;
    if (!c->o.export_frames) {
        out->header = o->header;
        out->by_subtree = o->by_subtree;
    } else if (!o->ids) {
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the model's index");
    } else {
        *out = *o;
        out->ids = malloc((o->count ? o->count : 1) * sizeof *out->ids);
        out->records = malloc((o->count ? o->count : 1) * sizeof *out->records);
        if (!out->ids || !out->records) {
            ms_core_opening_free(out);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the model's index");
        }
        memcpy(out->ids, o->ids, o->count * sizeof *out->ids);
        memcpy(out->records, o->records, o->count * sizeof *out->records);
    }
    out->content_known = content == CONTENT_KNOWN;
    if (out->content_known) {
        memcpy(out->content_lo, lo, sizeof lo);
        memcpy(out->content_hi, hi, sizeof hi);
    }
    return MS_OK;
}
