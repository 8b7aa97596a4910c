/* View-dependent decoding of an nSP archive: see ms_view_decoder.h. */
#include "ms_view_decoder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_nsp.h"
#include "ms_view_decoder_internal.h"

void ms_view_cache_drop(vcell *c)
{
    ms_view_piece_free(c);
    ms_codec_state_free(&c->cache);
    free(c->out_index);
    free(c->owner);
    free(c->levels);
    free(c->positions);
    c->positions = NULL;
    c->out_index = c->owner = NULL;
    c->levels = NULL;
    c->cache_valid = false;
    free(c->cache_colours);
    c->cache_colours = NULL;
    c->colour_valid = false;
}

/* The cell's codec decoder, freed: a later decode starts again from its bytes. */
static void decoder_drop(vcell *c)
{
    if (c->dec)
        ms_codec_decoder_destroy(c->dec);
    c->dec = NULL;
    c->dec_bytes = 0;
}

static void cell_reset(vcell *c)
{
    ms_view_cache_drop(c);
    ms_view_colour_drop(c);
    decoder_drop(c);
    ms_codec_state_free(&c->start);
    c->has_start = false;
    c->state = MS_VIEW_HIDDEN;
    c->bits = 0;
}

ms_status ms_view_create_partial(const ms_archive_header *h, ms_view **out, ms_error *err)
{
    *out = NULL;
    ms_view *v = calloc(1, sizeof *v);
    if (!v)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a view");
    v->header = *h;
    ms_status s = ms_nsp_shape_init(&v->shape, h->bits, h->n, h->root_bits, err);
    if (s != MS_OK) {
        free(v);
        return s;
    }
    v->group_size = (uint32_t)h->n * h->n * h->n;
    if (h->cell_count < 1 || h->cell_count > MS_ARCHIVE_MAX_CELLS ||
        (h->cell_count - 1) % v->group_size != 0) {
        free(v);
        return ms_error_set(err, MS_ERR_ARG, "bad cell count %u", h->cell_count);
    }
    v->count = h->cell_count;
    v->group_count = 1 + (v->count - 1) / v->group_size;
    v->groups = calloc(v->group_count, sizeof *v->groups);
    if (!v->groups) {
        free(v);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a view");
    }
    *out = v;
    return MS_OK;
}

/* The tree rules one record must keep, alone and against its known parent. */
static bool record_fits(const ms_view *v, uint32_t id, const ms_archive_cell *c)
{
    const uint32_t nc = v->group_size;
    bool ok = id < v->count && c->bits_min <= c->bits_max && c->bits_max <= v->header.bits;
    if (ok && c->first_child != MS_ARCHIVE_NONE)
        ok = c->first_child > id && c->first_child <= v->count - nc &&
             (c->first_child - 1) % nc == 0;
    if (ok && id > 0) {
        ok = c->parent < id;
        const vcell *p = ok ? ms_view_vcell(v, c->parent) : NULL;
        if (p)
            ok = p->rec.first_child != MS_ARCHIVE_NONE && p->rec.first_child <= id &&
                 id - p->rec.first_child < nc && c->level == p->rec.level + 1u;
    }
    return ok;
}

ms_status ms_view_learn(ms_view *v, const uint32_t *ids, const ms_archive_cell *recs,
                        size_t count, ms_error *err)
{
    for (size_t k = 0; k < count; ++k)
        if (!record_fits(v, ids[k], &recs[k]))
            return ms_error_set(err, MS_ERR_ARG, "cell %u: record breaks the tree rules",
                                ids[k]);
    for (size_t k = 0; k < count; ++k) {
        uint32_t g = ms_view_group_of(v, ids[k]);
        if (v->groups[g])
            continue;
        v->groups[g] = calloc(g == 0 ? 1 : v->group_size, sizeof *v->groups[g]);
        if (v->groups[g])
            v->block_cells += g == 0 ? 1 : v->group_size;
        if (!v->groups[g]) {
            /* give back the blocks this call made, none of which is used yet */
            for (size_t j = 0; j < k; ++j) {
                uint32_t gj = ms_view_group_of(v, ids[j]);
                vcell *b = v->groups[gj];
                bool used = false;
                for (uint32_t m = 0; b && m < (gj == 0 ? 1 : v->group_size); ++m)
                    used |= b[m].known;
                if (b && !used) {
                    free(b);
                    v->groups[gj] = NULL;
                    v->block_cells -= gj == 0 ? 1 : v->group_size;
                }
            }
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu cell records", count);
        }
    }
    for (size_t k = 0; k < count; ++k) {
        uint32_t id = ids[k];
        vcell *block = v->groups[ms_view_group_of(v, id)];
        vcell *c = &block[id == 0 ? 0 : (id - 1) % v->group_size];
        if (c->known)
            continue; /* the same subtree again */
        memset(c, 0, sizeof *c);
        c->rec = recs[k];
        c->known = true;
        c->target = MS_VIEW_TARGET_HIDDEN;
        v->known++;
        if (id == 0) {
            c->state = MS_VIEW_SHOWN;
            c->bits = c->rec.bits_min;
        }
    }
    return MS_OK;
}

ms_status ms_view_unlearn(ms_view *v, const uint32_t *ids, size_t count, ms_error *err)
{
    for (size_t k = 0; k < count; ++k) {
        const vcell *c = ms_view_vcell(v, ids[k]);
        if (c && (ids[k] == 0 || c->state != MS_VIEW_HIDDEN))
            return ms_error_set(err, MS_ERR_RANGE, "cell %u is %s: its record stays", ids[k],
                                ids[k] == 0 ? "the root" : "in the cut");
    }
    for (size_t k = 0; k < count; ++k) {
        vcell *c = ms_view_vcell(v, ids[k]);
        if (!c)
            continue;
        cell_reset(c);
        free(c->bytes);
        ms_view_colour_free(c);
        memset(c, 0, sizeof *c);
        v->known--;
        uint32_t g = ms_view_group_of(v, ids[k]);
        bool used = false;
        for (uint32_t m = 0; m < v->group_size && !used; ++m)
            used = v->groups[g][m].known;
        if (!used) {
            free(v->groups[g]);
            v->groups[g] = NULL;
            v->block_cells -= v->group_size; /* never the root's: it stays */
        }
    }
    return MS_OK;
}

uint32_t ms_view_state_cells(const ms_view *v) { return v->block_cells; }

size_t ms_view_cell_state_size(void) { return sizeof(vcell); }

bool ms_view_known(const ms_view *v, uint32_t cell) { return ms_view_vcell(v, cell) != NULL; }

uint32_t ms_view_known_count(const ms_view *v) { return v->known; }

uint32_t ms_view_next_known(const ms_view *v, uint32_t after)
{
    uint32_t id = after == MS_ARCHIVE_NONE ? 0 : after + 1;
    while (id < v->count) {
        uint32_t g = ms_view_group_of(v, id);
        const vcell *block = v->groups[g];
        if (!block) {
            id = ms_view_group_first(v, g + 1); /* the next group */
            continue;
        }
        if (block[id == 0 ? 0 : (id - 1) % v->group_size].known)
            return id;
        id++;
    }
    return MS_ARCHIVE_NONE;
}

bool ms_view_children_known(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    if (!c || c->rec.first_child == MS_ARCHIVE_NONE)
        return false;
    const vcell *block = v->groups[ms_view_group_of(v, c->rec.first_child)];
    if (!block)
        return false;
    for (uint32_t k = 0; k < v->group_size; ++k)
        if (!block[k].known)
            return false;
    return true;
}

ms_status ms_view_create(const ms_archive_header *h, const ms_archive_cell *cells, ms_view **out,
                         ms_error *err)
{
    ms_status s = ms_view_create_partial(h, out, err);
    if (s != MS_OK)
        return s;
    uint32_t *ids = malloc((size_t)h->cell_count * sizeof *ids);
    if (!ids) {
        ms_view_destroy(*out);
        *out = NULL;
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a view");
    }
    for (uint32_t i = 0; i < h->cell_count; ++i)
        ids[i] = i;
    /* in id order, each parent is known before its children are checked */
    for (uint32_t i = 0; i < h->cell_count && s == MS_OK; ++i)
        s = ms_view_learn(*out, &ids[i], &cells[i], 1, err);
    free(ids);
    if (s != MS_OK) {
        ms_view_destroy(*out);
        *out = NULL;
    }
    return s;
}

ms_status ms_view_create_from_archive(const ms_archive *a, ms_view **out, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_archive_cell *recs = malloc((size_t)h->cell_count * sizeof *recs);
    if (!recs)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    for (uint32_t i = 0; i < h->cell_count; ++i)
        recs[i] = *ms_archive_get_cell(a, i);
    ms_status s = ms_view_create(h, recs, out, err);
    free(recs);
    for (uint32_t i = 0; s == MS_OK && i < h->cell_count; ++i) {
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, i, &len);
        if (!g)
            break; /* an index without payloads: the bytes will come later */
        if ((s = ms_archive_verify_payload(a, i, err)) == MS_OK)
            s = ms_view_set_bytes(*out, i, g, len, err);
        const uint8_t *colour = ms_archive_colour(a, i, &len);
        if (s == MS_OK && colour && len)
            s = ms_view_set_colour_bytes(*out, i, colour, len, err);
    }
    if (s != MS_OK) {
        ms_view_destroy(*out);
        *out = NULL;
    }
    return s;
}

void ms_view_destroy(ms_view *v)
{
    if (!v)
        return;
    for (uint32_t g = 0; g < v->group_count; ++g) {
        vcell *block = v->groups[g];
        for (uint32_t k = 0; block && k < (g == 0 ? 1 : v->group_size); ++k) {
            if (!block[k].known)
                continue;
            cell_reset(&block[k]);
            free(block[k].bytes);
            ms_view_colour_free(&block[k]);
        }
        free(block);
    }
    free(v->groups);
    free(v);
}

const ms_archive_header *ms_view_header(const ms_view *v) { return &v->header; }

uint32_t ms_view_cell_count(const ms_view *v) { return v->count; }

const ms_archive_cell *ms_view_cell(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? &c->rec : NULL;
}

ms_view_cell_state ms_view_state(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? (ms_view_cell_state)c->state : MS_VIEW_HIDDEN;
}

unsigned ms_view_bits(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? c->bits : 0;
}

ms_status ms_view_set_bytes(ms_view *v, uint32_t cell, const uint8_t *data, size_t length,
                            ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u known", cell);
    if (length > c->rec.geometry_length)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u: %zu bytes for a %u-byte payload", cell,
                            length, c->rec.geometry_length);
    if (length <= c->nbytes)
        return MS_OK;
    uint8_t *b = realloc(c->bytes, length);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's bytes", cell);
    memcpy(b + c->nbytes, data + c->nbytes, length - c->nbytes);
    c->bytes = b;
    c->nbytes = length;
    return MS_OK;
}

ms_status ms_view_append_bytes(ms_view *v, uint32_t cell, const uint8_t *data, size_t length,
                               ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u known", cell);
    if (length > c->rec.geometry_length - c->nbytes)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u: %zu more bytes for a %u-byte payload "
                            "of which %zu are held", cell, length, c->rec.geometry_length,
                            c->nbytes);
    if (length == 0)
        return MS_OK;
    uint8_t *b = realloc(c->bytes, c->nbytes + length);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's bytes", cell);
    memcpy(b + c->nbytes, data, length);
    c->bytes = b;
    c->nbytes += length;
    return MS_OK;
}

ms_status ms_view_forget(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_HIDDEN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not hidden", cell);
    cell_reset(c);
    free(c->bytes);
    c->bytes = NULL;
    c->nbytes = 0;
    ms_view_colour_free(c);
    return MS_OK;
}

size_t ms_view_held_bytes(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? c->nbytes : 0;
}

/* Highest bit whose prefix the held bytes cover, from the codec header. */
static unsigned held_bits(const vcell *c)
{
    if (c->rec.geometry_length == 0)
        return c->rec.bits_max;
    ms_codec_header h;
    if (ms_codec_read_header(c->bytes, c->nbytes, &h, NULL) != MS_OK)
        return c->rec.bits_min;
    unsigned b = h.p_min;
    for (unsigned k = 0; k < h.p_max - h.p_min; ++k)
        if (h.header_size + h.chunk_end[k] <= c->nbytes)
            b = h.p_min + k + 1;
    return b;
}

unsigned ms_view_available_bits(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? held_bits(c) : 0;
}

/* A fresh decoder of cell from its bytes (and its start state, below the
 * root) at `bits`: the complex a split cell had before its decoder was
 * dropped (ms_view_drop_decoder). Decoding is deterministic, so this is the
 * very complex the dropped decoder held. */
static ms_status decoder_at(const ms_view *v, const vcell *c, uint32_t cell, unsigned bits,
                            ms_codec_decoder **out, ms_error *err)
{
    *out = NULL;
    ms_quant_box box = {{v->header.box_origin[0], v->header.box_origin[1], v->header.box_origin[2]},
                        v->header.box_side};
    ms_codec_decoder_options o = {.box = &box};
    ms_codec_decoder *d;
    ms_status s = ms_codec_decoder_create(c->bytes, c->nbytes, cell == 0 ? NULL : &c->start, &o,
                                          &d, err);
    if (s != MS_OK)
        return s;
    if (ms_codec_decoder_available_level(d) < 3 * bits)
        s = ms_error_set(err, MS_ERR_FORMAT, "cell %u: bytes for %u bits not held", cell, bits);
    else
        s = ms_codec_decoder_set_level(d, 3 * bits, err);
    if (s != MS_OK) {
        ms_codec_decoder_destroy(d);
        return s;
    }
    *out = d;
    return MS_OK;
}

ms_status ms_view_drop_decoder(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SPLIT)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not split", cell);
    decoder_drop(c);
    return MS_OK;
}

bool ms_view_holds_decoder(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c && c->dec;
}

/* Makes sure the cell's decoder exists and can reach `bits` (extending it with
 * the bytes that came since, so decoding goes on from its current level). */
static ms_status ensure_decoder(ms_view *v, uint32_t cell, unsigned bits, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (c->dec && ms_codec_decoder_available_level(c->dec) >= 3 * bits)
        return MS_OK;
    if (c->dec && c->nbytes == c->dec_bytes)
        return ms_error_set(err, MS_ERR_FORMAT, "cell %u: bytes for %u bits not received yet",
                            cell, bits);
    if (c->dec) {
        ms_status s = ms_codec_decoder_extend(c->dec, c->bytes, c->nbytes, err);
        if (s != MS_OK)
            return s;
        c->dec_bytes = c->nbytes;
        if (ms_codec_decoder_available_level(c->dec) < 3 * bits)
            return ms_error_set(err, MS_ERR_FORMAT, "cell %u: bytes for %u bits not received "
                                "yet", cell, bits);
        return MS_OK;
    }
    if (cell != 0 && !c->has_start)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not shown", cell);
    ms_codec_decoder *d;
    /* archive streams leave the box to the archive (compact headers) */
    ms_quant_box box = {{v->header.box_origin[0], v->header.box_origin[1], v->header.box_origin[2]},
                        v->header.box_side};
    ms_codec_decoder_options o = {.box = &box};
    ms_status s = ms_codec_decoder_create(c->bytes, c->nbytes, cell == 0 ? NULL : &c->start, &o,
                                          &d, err);
    if (s != MS_OK)
        return s;
    const ms_codec_header *h = ms_codec_decoder_header(d);
    if (h->p_min != c->rec.bits_min || h->p_max != c->rec.bits_max) {
        ms_codec_decoder_destroy(d);
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: stream window [%u, %u] differs from "
                            "the index", cell, h->p_min, h->p_max);
    }
    c->dec = d;
    c->dec_bytes = c->nbytes;
    if (ms_codec_decoder_available_level(d) < 3 * bits)
        return ms_error_set(err, MS_ERR_FORMAT, "cell %u: bytes for %u bits not received yet",
                            cell, bits);
    return MS_OK;
}

ms_status ms_view_set_bits(ms_view *v, uint32_t cell, unsigned bits, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SHOWN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not shown", cell);
    if (bits < c->rec.bits_min || bits > c->rec.bits_max)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u: %u bits outside its window [%u, %u]",
                            cell, bits, c->rec.bits_min, c->rec.bits_max);
    if (bits == c->bits)
        return MS_OK;
    if (c->rec.geometry_length == 0) { /* empty cell: nothing to decode */
        c->bits = (uint8_t)bits;
        return MS_OK;
    }
    ms_status s = ensure_decoder(v, cell, bits, err);
    if (s != MS_OK)
        return s;
    if ((s = ms_codec_decoder_set_level(c->dec, 3 * bits, err)) != MS_OK)
        return s;
    c->bits = (uint8_t)bits;
    return MS_OK;
}

ms_status ms_view_cell_state_copy(const ms_view *v, uint32_t cell, ms_codec_state *out,
                                  ms_error *err)
{
    memset(out, 0, sizeof *out);
    const vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state == MS_VIEW_HIDDEN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not decoded", cell);
    if (c->dec) {
        ms_status s = ms_codec_decoder_state(c->dec, out, err);
        if (s == MS_OK)
            s = ms_codec_state_canonicalise(out, err);
        return s;
    }
    if (c->state == MS_VIEW_SPLIT && c->rec.geometry_length > 0 && (cell == 0 || c->has_start)) {
        /* its decoder was dropped: decode its complex again, for this copy only */
        ms_codec_decoder *d;
        ms_status s = decoder_at(v, c, cell, c->rec.bits_max, &d, err);
        if (s == MS_OK) {
            s = ms_codec_decoder_state(d, out, err);
            if (s == MS_OK)
                s = ms_codec_state_canonicalise(out, err);
            ms_codec_decoder_destroy(d);
        }
        return s;
    }
    out->bits = c->rec.bits_max;
    out->level = 3u * c->bits;
    if (c->rec.geometry_length == 0 || !c->has_start) {
        if (cell == 0 && c->rec.geometry_length > 0) {
            /* the root before any decoding: one vertex */
            out->cells = calloc(1, sizeof *out->cells);
            out->tris = malloc(sizeof *out->tris);
            out->edges = malloc(sizeof *out->edges);
            if (!out->cells || !out->tris || !out->edges) {
                ms_codec_state_free(out);
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
            }
            out->vertex_count = 1;
        }
        return MS_OK;
    }
    /* copy of the start state */
    const ms_codec_state *st = &c->start;
    *out = *st;
    out->bound = NULL; /* not the start state's to share */
    out->rep = NULL;   /* a window's first level is drawn at its centres (docs/CODEC.md §4.1) */
    out->cells = malloc((st->vertex_count + 1) * sizeof *out->cells);
    out->tris = malloc((3 * st->tri_count + 1) * sizeof *out->tris);
    out->edges = malloc((2 * st->edge_count + 1) * sizeof *out->edges);
    if (!out->cells || !out->tris || !out->edges) {
        ms_codec_state_free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory");
    }
    memcpy(out->cells, st->cells, st->vertex_count * sizeof *out->cells);
    memcpy(out->tris, st->tris, 3 * st->tri_count * sizeof *out->tris);
    memcpy(out->edges, st->edges, 2 * st->edge_count * sizeof *out->edges);
    return MS_OK;
}

ms_status ms_view_split(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SHOWN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not shown", cell);
    if (c->rec.first_child == MS_ARCHIVE_NONE)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is a leaf", cell);
    if (!ms_view_children_known(v, cell))
        return ms_error_set(err, MS_ERR_RANGE, "cell %u: its children's records are not known",
                            cell);
    if (c->bits != c->rec.bits_max)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is at %u bits, below its window's end %u",
                            cell, c->bits, c->rec.bits_max);
    const unsigned nc = v->shape.n * v->shape.n * v->shape.n;
    ms_codec_state parent;
    ms_status s = ms_view_cell_state_copy(v, cell, &parent, err);
    if (s != MS_OK)
        return s;
    ms_codec_state *parts = calloc(nc, sizeof *parts);
    if (!parts) {
        ms_codec_state_free(&parent);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory splitting cell %u", cell);
    }
    if (parent.vertex_count > 0) {
        parent.level = 3u * c->rec.bits_max;
        s = ms_nsp_partition_state(&v->shape, &parent, c->rec.level, c->rec.position,
                                   c->rec.bits_max, parts, err);
    }
    ms_codec_state_free(&parent);
    if (s != MS_OK) {
        free(parts);
        return s;
    }
    for (unsigned k = 0; k < nc; ++k) {
        uint32_t id = c->rec.first_child + k;
        vcell *ch = ms_view_vcell(v, id);
        cell_reset(ch);
        ch->state = MS_VIEW_SHOWN;
        ch->bits = ch->rec.bits_min;
        ch->start = parts[k];
        ch->start.bits = ch->rec.bits_max;
        ch->has_start = parts[k].vertex_count > 0;
        if (!ch->has_start)
            ms_codec_state_free(&ch->start);
        if (ch->has_start != (ch->rec.geometry_length > 0))
            s = ms_error_set(err, MS_ERR_CORRUPT, "cell %u: %s but its parent says %s", id,
                             ch->rec.geometry_length > 0 ? "has a payload" : "has no payload",
                             ch->has_start ? "it is not empty" : "it is empty");
    }
    free(parts);
    c->state = MS_VIEW_SPLIT;
    ms_view_cache_drop(c);
    if (s != MS_OK)
        (void)ms_view_merge(v, cell, NULL);
    return s;
}

/* Merges a split cell; `rebuild`: decode its complex again if its decoder
 * was dropped (not for descendants, which are reset at once). */
static ms_status merge_cell(ms_view *v, uint32_t cell, bool rebuild, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SPLIT)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not split", cell);
    const unsigned nc = v->shape.n * v->shape.n * v->shape.n;
    for (unsigned k = 0; k < nc; ++k) {
        uint32_t id = c->rec.first_child + k;
        vcell *ch = ms_view_vcell(v, id); /* known: a split cell's children stay known */
        if (ch->state == MS_VIEW_SPLIT)
            (void)merge_cell(v, id, false, NULL);
        cell_reset(ch);
    }
    c->state = MS_VIEW_SHOWN;
    c->bits = c->rec.bits_max;
    if (rebuild && !c->dec && c->rec.geometry_length > 0 && (cell == 0 || c->has_start)) {
        ms_status s = decoder_at(v, c, cell, c->rec.bits_max, &c->dec, err);
        if (s != MS_OK)
            return s;
        c->dec_bytes = c->nbytes;
    }
    return MS_OK;
}

ms_status ms_view_merge(ms_view *v, uint32_t cell, ms_error *err)
{
    return merge_cell(v, cell, true, err);
}

/* ---- selection ------------------------------------------------------------ */

static ms_status apply_cell(ms_view *v, uint32_t cell, ms_view_apply_report *r, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    uint8_t t = c->target;
    ms_status s;
    if (t == MS_VIEW_TARGET_SPLIT && ms_view_children_known(v, cell)) {
        if (c->state == MS_VIEW_SHOWN) {
            unsigned avail = held_bits(c);
            unsigned goal = avail < c->rec.bits_max ? avail : c->rec.bits_max;
            if (goal != c->bits) {
                r->refined += goal > c->bits;
                r->coarsened += goal < c->bits;
                if ((s = ms_view_set_bits(v, cell, goal, err)) != MS_OK)
                    return s;
            }
            if (goal < c->rec.bits_max) {
                r->waiting++;
                return MS_OK;
            }
            if ((s = ms_view_split(v, cell, err)) != MS_OK)
                return s;
            r->splits++;
        }
        for (uint32_t k = 0; k < v->group_size; ++k)
            if ((s = apply_cell(v, c->rec.first_child + k, r, err)) != MS_OK)
                return s;
        return MS_OK;
    }
    unsigned want = t == MS_VIEW_TARGET_SPLIT || t == MS_VIEW_TARGET_HIDDEN ? c->rec.bits_max : t;
    if (want < c->rec.bits_min)
        want = c->rec.bits_min;
    if (want > c->rec.bits_max)
        want = c->rec.bits_max;
    if (c->state == MS_VIEW_SPLIT) {
        if ((s = ms_view_merge(v, cell, err)) != MS_OK)
            return s;
        r->merges++;
    }
    unsigned avail = held_bits(c);
    unsigned goal = want <= avail ? want : avail > c->bits ? avail : c->bits;
    if (goal < want)
        r->waiting++;
    if (goal != c->bits) {
        r->refined += goal > c->bits;
        r->coarsened += goal < c->bits;
        return ms_view_set_bits(v, cell, goal, err);
    }
    return MS_OK;
}

ms_status ms_view_apply(ms_view *v, ms_view_apply_report *report, ms_error *err)
{
    ms_view_apply_report r;
    memset(&r, 0, sizeof r);
    ms_status s = ms_view_vcell(v, 0) ? apply_cell(v, 0, &r, err) : MS_OK;
    if (report)
        *report = r;
    return s;
}
