/* The decoder's reception (decode thread): received chunks into their cells'
 * reception buffers, verified (the codec header against the index, each
 * precision bit against its CRC, a whole APO chunk or colour stream against
 * its CRC), a corrupt range fetched once more, then the cell given up, and
 * the verified geometry bytes handed to the view decoder in few steps.
 * Subtree chunks go to the index's part (ms_client_core_subtrees.c). */
#include "ms_client_core_internal.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* A corrupt or failed range of cell: fetch it once more, then give up. */
static void cell_trouble(ms_core *c, uint32_t cell, const char *what)
{
    dcell *d = ms_core_dcell(c, cell);
    ms_core_rx_cut(&d->geo, d->given);
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
            ms_core_rx_cut(&d->geo, good);
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
    if (ms_view_append_bytes(c->dec.view, cell, d->geo.buf + (d->given - d->geo.base),
                             good - d->given, &err) != MS_OK) {
        ms_core_warn(c, err.text);
        return;
    }
    d->given = good;
    ms_core_rx_consume(&d->geo, good);
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
    if (ms_view_set_colour_bytes(c->dec.view, cell, d->col.buf, d->col.end, &err) != MS_OK) {
        ms_core_warn(c, err.text);
        return false;
    }
    d->colour_given = d->col.end;
    return true;
}

/* Received bytes into their cells' reception buffers, verified and handed to
 * the view; true when new APO bytes changed the frame (as new geometry does). */
bool ms_core_take_chunks(ms_core *c, chunk_msg *chunks)
{
    bool apo_changed = false;
    while (chunks) {
        chunk_msg *m = chunks;
        chunks = m->next;
        c->dec.consumed_seq = m->seq;
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
