/* The client core's decode thread: reception buffers per cell and stream,
 * verification (the codec header against the index, each precision bit
 * against its CRC, a whole APO chunk against its CRC), the view decoder, and
 * the pass (dec_step) whose steps the other parts provide: scheduling, the
 * budget and publication. Everything here is the decode thread's own. */
#include "ms_client_core_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <zlib.h>

#include "ms_progress.h"

void ms_core_rx_free(rx *r)
{
    free(r->buf);
    memset(r, 0, sizeof *r);
}

/* Forgets what was received beyond `keep` (>= base). */
static void rx_cut(rx *r, uint32_t keep)
{
    if (r->end > keep)
        r->end = keep;
    r->niv = 0;
}

uint64_t ms_core_rx_cap_for(const rx *r, uint64_t end)
{
    if (end <= r->base || end - r->base <= r->cap)
        return r->cap;
    uint64_t cap = r->cap ? r->cap : 4096;
    while (cap < end - r->base)
        cap *= 2;
    return cap;
}

/* Adds received bytes; ignores what is already held or below base. */
bool ms_core_rx_add(rx *r, uint32_t offset, const uint8_t *data, uint32_t length)
{
    uint64_t end = (uint64_t)offset + length;
    if (end <= r->end)
        return true;
    if (offset < r->end) {
        data += r->end - offset;
        length -= r->end - offset;
        offset = r->end;
    }
    if (end - r->base > r->cap) {
        uint64_t cap = ms_core_rx_cap_for(r, end);
        uint8_t *b = realloc(r->buf, cap);
        if (!b)
            return false;
        r->buf = b;
        r->cap = (uint32_t)cap;
    }
    memcpy(r->buf + (offset - r->base), data, length);
    if (offset == r->end) {
        r->end = (uint32_t)end;
    } else if (r->niv < 8) {
        r->iv[r->niv][0] = offset, r->iv[r->niv][1] = (uint32_t)end;
        r->niv++;
    }
    /* absorb pieces that now touch the contiguous part */
    for (bool moved = true; moved;) {
        moved = false;
        for (unsigned i = 0; i < r->niv; ++i) {
            if (r->iv[i][0] <= r->end) {
                if (r->iv[i][1] > r->end)
                    r->end = r->iv[i][1];
                r->iv[i][0] = r->iv[--r->niv][0];
                r->iv[i][1] = r->iv[r->niv][1];
                moved = true;
                break;
            }
        }
    }
    return true;
}

/* Drops bytes below `upto` from the buffer (the consumer took them). */
static void rx_consume(rx *r, uint32_t upto)
{
    if (upto <= r->base)
        return;
    uint32_t drop = upto - r->base;
    uint32_t held = r->end > upto ? r->end - upto : 0;
    uint32_t span = 0;
    for (unsigned i = 0; i < r->niv; ++i)
        if (r->iv[i][1] - upto > span)
            span = r->iv[i][1] - upto;
    if (span < held)
        span = held;
    if (span == 0) {
        free(r->buf);
        r->buf = NULL;
        r->cap = 0;
    } else {
        memmove(r->buf, r->buf + drop, span);
    }
    r->base = upto;
}

/* A corrupt or failed range of cell: fetch it once more, then give up. */
static void cell_trouble(ms_core *c, uint32_t cell, const char *what)
{
    dcell *d = ms_core_dcell(c, cell);
    rx_cut(&d->geo, d->given);
    d->retries++;
    pthread_mutex_lock(&c->lock);
    c->stats.refetches += d->retries == 1;
    pthread_mutex_unlock(&c->lock);
    if (d->retries >= 2 && !d->failed) {
        d->failed = true;
        char text[256];
        snprintf(text, sizeof text, "cell %u: %.180s (after a refetch); cell left at its "
                 "last good precision", cell, what);
        ms_core_warn(c, text);
    }
}

/* Hands the newly received, verified geometry bytes of cell to the view. */
void ms_core_hand_over(ms_core *c, uint32_t cell)
{
    dcell *d = ms_core_dcell(c, cell);
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, cell);
    if (d->geo.end <= d->given)
        return;
    if (!d->header) {
        /* the header sits at the start: parse it once prefix(bits_min) arrived */
        uint32_t hsize = ms_archive_geometry_prefix(c->index, cell, rec->bits_min);
        if (d->geo.end < hsize || d->given != 0)
            return;
        ms_codec_header h;
        ms_error err;
        if (ms_codec_read_header(d->geo.buf, d->geo.end, &h, &err) != MS_OK ||
            h.header_size != hsize || h.p_min != rec->bits_min || h.p_max != rec->bits_max) {
            cell_trouble(c, cell, "payload header does not match the index");
            return;
        }
        for (unsigned k = 0; k < h.p_max - h.p_min; ++k)
            if (h.header_size + h.chunk_end[k] !=
                ms_archive_geometry_prefix(c->index, cell, h.p_min + k + 1)) {
                cell_trouble(c, cell, "payload header does not match the index");
                return;
            }
        d->header = malloc(sizeof *d->header);
        if (!d->header)
            return;
        *d->header = h;
    }
    const ms_codec_header *h = d->header;
    uint32_t good = d->given;
    for (unsigned k = 0; k < h->p_max - h->p_min; ++k) {
        uint32_t a = (uint32_t)h->header_size + (k ? h->chunk_end[k - 1] : 0);
        uint32_t b = (uint32_t)h->header_size + h->chunk_end[k];
        if (b <= d->given)
            continue;
        if (b > d->geo.end)
            break;
        if (a < d->given)
            break; /* cannot happen: given ends on a chunk boundary */
        uint32_t crc = (uint32_t)crc32(0L, d->geo.buf + (a - d->geo.base), b - a);
        if (crc != h->chunk_crc[k]) {
            char what[96];
            snprintf(what, sizeof what, "precision bit %u fails its CRC", h->p_min + k + 1);
            rx_cut(&d->geo, good);
            cell_trouble(c, cell, what);
            return;
        }
        good = b;
    }
    if (good == d->given)
        return;
    /* The view's decoder restarts from the cell's first bit whenever it gets
     * more bytes, so hand over in few steps: the first bits at once (something
     * to show; the root bit by bit), then when the target's prefix is
     * complete, or every 0.25 s. */
    double t = ms_core_since_start(c);
    if (d->given > 0 && rec->level > 0 && good < d->goal_bytes && good < rec->geometry_length &&
        t - d->handed_at < 0.25) {
        d->pending = true;
        return;
    }
    d->pending = false;
    d->handed_at = t;
    ms_error err;
    if (ms_view_append_bytes(c->view, cell, d->geo.buf + (d->given - d->geo.base),
                             good - d->given, &err) != MS_OK) {
        ms_core_warn(c, err.text);
        return;
    }
    d->given = good;
    rx_consume(&d->geo, good);
}

/* APO chunks have no per-level checksum: a complete chunk is checked whole. */
static void dec_apo_received(ms_core *c, uint32_t cell)
{
    dcell *d = ms_core_dcell(c, cell);
    const ms_archive_cell *rec = ms_archive_get_cell(c->index, cell);
    if (d->apo.end < rec->apo_length) {
        d->apo_given = d->apo.end;
        return;
    }
    ms_error err;
    if (ms_archive_check_payload(c->index, cell, true, d->apo.buf, d->apo.end, &err) != MS_OK) {
        ms_core_apo_drop(d);
        d->retries++;
        if (d->retries >= 2 && !d->failed) {
            d->failed = true;
            ms_core_warn(c, err.text);
        }
        return;
    }
    d->apo_given = d->apo.end;
}

/* Colour bytes received contiguously from 0 go to the view (each of the
 * stream's chunks carries its own CRC, which the colour decoder checks); the
 * whole stream is checked against the index's CRC once complete. True when
 * the view got new bytes. */
static bool dec_colour_received(ms_core *c, uint32_t cell)
{
    dcell *d = ms_core_dcell(c, cell);
    if (d->col.end <= d->colour_given)
        return false;
    ms_error err;
    if (d->col.end == ms_archive_colour_length(c->index, cell) &&
        ms_archive_check_colour(c->index, cell, d->col.buf, d->col.end, &err) != MS_OK) {
        ms_core_rx_free(&d->col);
        d->colour_given = 0;
        if (!d->failed) {
            d->failed = true;
            ms_core_warn(c, err.text);
        }
        return false;
    }
    if (ms_view_set_colour_bytes(c->view, cell, d->col.buf, d->col.end, &err) != MS_OK) {
        ms_core_warn(c, err.text);
        return false;
    }
    d->colour_given = d->col.end;
    return true;
}

/* Received bytes into their cells' reception buffers, verified and handed to
 * the view; true when new APO bytes changed the frame (as new geometry does). */
static bool dec_take_chunks(ms_core *c, chunk_msg *chunks)
{
    bool apo_changed = false;
    while (chunks) {
        chunk_msg *m = chunks;
        chunks = m->next;
        c->consumed_seq = m->seq;
        dcell *d = m->stream == STREAM_INDEX ? NULL : ms_core_dcell(c, m->cell);
        bool apo = m->stream == STREAM_APO;
        if (m->stream == STREAM_COLOUR) {
            if (d && !m->failed) {
                if (!ms_core_rx_add(&d->col, m->offset, m->data, m->length))
                    ms_core_warn(c, "out of memory for received bytes");
                else
                    apo_changed |= dec_colour_received(c, m->cell);
            }
        } else if (m->stream == STREAM_INDEX) {
            if (c->o.index_filter && !m->failed)
                c->o.index_filter(m->cell, m->offset, m->data, m->length,
                                  c->o.payload_filter_arg);
            ms_core_subtree_chunk(c, m);
        } else if (d) { /* else its record was forgotten since it was asked for */
            if (m->failed) {
                if (!apo)
                    cell_trouble(c, m->cell, "the server answered a request with an error");
            } else {
                if (c->o.payload_filter)
                    c->o.payload_filter(m->cell, apo, m->offset, m->data, m->length,
                                        c->o.payload_filter_arg);
                if (!ms_core_rx_add(apo ? &d->apo : &d->geo, m->offset, m->data, m->length))
                    ms_core_warn(c, "out of memory for received bytes");
                else if (!apo)
                    ms_core_hand_over(c, m->cell);
                else {
                    uint32_t before = d->apo_given;
                    dec_apo_received(c, m->cell);
                    apo_changed |= d->apo_given != before;
                }
            }
        }
        free(m);
    }
    return apo_changed;
}

/* The pass's camera, tolerance and selection parameters. */
static void dec_pass_begin(ms_core *c, const ms_camera *cam, dec_pass *pass)
{
    const ms_archive_header *h = ms_archive_get_header(c->index);
    memset(pass, 0, sizeof *pass);
    pass->cam = cam;
    pass->apo_on = c->o.apo_levels > 0 && h->has_apo;
    pass->fv.cam = *cam;
    ms_camera_frustum(cam, &pass->fv.frustum);
    pass->base_tol = pass->apo_on ? c->o.apo_geometry_tolerance_px : c->o.tolerance_px;
    ms_core_budget_sync(c);
    pass->factor = c->tolerance_factor;
    pass->fv.tolerance = pass->base_tol * pass->factor;
    /* With APO on, geometry refines only to apo_geometry_tolerance_px where a
     * chunk carries the shading; a cell baked without one (its geometry renders
     * the input: every leaf, docs/APO.md) is shaded by its triangles alone, so
     * it refines to tolerance_px as with APO off. */
    double chunkless = pass->apo_on ? c->o.tolerance_px / c->o.apo_geometry_tolerance_px : 0.0;
    /* A public preview: no cell is wanted beyond what this reader may read
     * (PROTOCOL.md sections 4.10 and 8: a client need never trip FORBIDDEN). */
    pthread_mutex_lock(&c->lock);
    c->preview_steps = c->permitted_geometry_steps;
    /* colour: from a local archive, or a connection that negotiated CAP_COLOUR */
    pass->colour_on = h->has_colour && c->colour_served;
    unsigned sections = c->section_count;
    double planes[MS_SECTIONS_MAX][4];
    memcpy(planes, c->sections, sizeof planes);
    pthread_mutex_unlock(&c->lock);
    /* the sections cull as the frustum's sides do (selection and schedule) */
    for (unsigned k = 0; k < sections; ++k)
        ms_frustum_add_section(&pass->fv.frustum, planes[k]);
    pass->sp = (ms_view_select_params){.tolerance_px = pass->fv.tolerance,
                                       .margin = c->o.frustum_margin,
                                       .hysteresis = c->o.hysteresis_bits,
                                       .culled_bits_less = c->o.culled_bits_less + c->culled_give_up,
                                       .chunkless_tolerance_scale = chunkless,
                                       .permitted_steps = c->preview_steps,
                                       .section_count = sections};
    memcpy(pass->sp.sections, planes, sizeof planes);
}

/* Selects the cells for the camera, refines in parallel what can go up, and
 * applies the splits and merges; false when decoding failed (then fatal). */
static bool dec_select(ms_core *c, dec_pass *pass)
{
    ms_view_select(c->view, pass->cam, &pass->sp, &c->report);
    size_t refined_in_parallel = ms_view_refine_parallel(c->view, c->pool, &c->jobs);
    ms_view_apply_report report;
    ms_error err;
    if (ms_view_apply(c->view, &report, &err) != MS_OK) {
        pthread_mutex_lock(&c->lock);
        ms_core_fail_locked(c, "decoding failed: %.200s", err.text);
        pthread_mutex_unlock(&c->lock);
        return false;
    }
    pass->changed |= refined_in_parallel || report.splits || report.merges || report.refined ||
                     report.coarsened;
    ms_core_content_note(c);
    return true;
}

/* One pass: take inputs, decode, select, plan, publish. Before the caller's
 * first camera, passes serve the content bounds' camera while they are
 * pending (ms_client_core_content.c). */
static void dec_step(ms_core *c, chunk_msg *chunks, const ms_camera *cam, uint64_t serial,
                     bool have_camera)
{
    double t_start = ms_now_seconds();
    bool apo_changed = dec_take_chunks(c, chunks);
    ms_camera content_camera;
    bool for_content = !have_camera && ms_core_content_camera(c, &content_camera);
    if (!have_camera && !for_content)
        return;
    dec_pass pass;
    dec_pass_begin(c, for_content ? &content_camera : cam, &pass);
    pass.apo_on &= !for_content; /* the root's geometry alone */
    pass.for_content = for_content;
    pass.changed = apo_changed;
    if (!dec_select(c, &pass) || !ms_core_budget_ceiling(c, &pass))
        return;
    ms_core_schedule(c, &pass);    /* what is missing, and in which order */
    ms_core_budget_step(c, &pass); /* memory: the budget */
    pass.complete &= !for_content; /* no caller's view to be complete */
    ms_core_publish(c, &pass, serial, t_start);
}

void *ms_core_decode_main(void *arg)
{
    ms_core *c = arg;
    pthread_mutex_lock(&c->lock);
    uint64_t done_serial = 0;
    for (;;) {
        while (!c->stopping && !c->fatal && !c->inbox && !c->index_new &&
               !(c->view && c->have_camera && (c->camera_serial != done_serial || c->republish))) {
            struct timespec until;
            clock_gettime(CLOCK_REALTIME, &until);
            until.tv_nsec += 20 * 1000000L;
            if (until.tv_nsec >= 1000000000L)
                until.tv_sec++, until.tv_nsec -= 1000000000L;
            if (pthread_cond_timedwait(&c->wake, &c->lock, &until) == ETIMEDOUT)
                break; /* periodic pass: budget steps, memory figures */
        }
        if (c->stopping || c->fatal)
            break;
        if (c->index_new) {
            c->index_new = false;
            pthread_mutex_unlock(&c->lock);
            ms_error err;
            bool ok = ms_core_take_index(c, &err);
            pthread_mutex_lock(&c->lock);
            if (!ok) {
                ms_core_fail_locked(c, "%.240s", err.text);
                break;
            }
        }
        if (!c->view)
            continue;
        chunk_msg *chunks = c->inbox;
        c->inbox = c->inbox_tail = NULL;
        c->bytes_queued = 0; /* this pass takes them all */
        ms_camera cam = c->camera;
        uint64_t serial = c->camera_serial;
        bool have = c->have_camera;
        pthread_mutex_unlock(&c->lock);
        dec_step(c, chunks, &cam, serial, have);
        done_serial = serial;
        pthread_mutex_lock(&c->lock);
    }
    pthread_mutex_unlock(&c->lock);
    return NULL;
}
