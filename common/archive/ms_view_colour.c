/* The view decoder's colour: each cell's colour stream (docs/ARCHIVE.md,
 * "Colour streams") decoded in lockstep with its geometry, and the colours of
 * its stitching cache (ms_view_decoder.h, ms_view_set_colour_bytes). */
#include <stdlib.h>
#include <string.h>

#include "ms_view_decoder_internal.h"

void ms_view_colour_drop(vcell *c)
{
    ms_colour_decoder_destroy(c->cdec);
    c->cdec = NULL;
    c->colour_based = false;
    free(c->top_cells);
    free(c->top_colours);
    c->top_cells = NULL;
    c->top_colours = NULL;
    c->top_n = 0;
    free(c->cache_colours);
    c->cache_colours = NULL;
    c->colour_valid = false;
}

void ms_view_colour_free(vcell *c)
{
    ms_view_colour_drop(c);
    free(c->colour_bytes);
    c->colour_bytes = NULL;
    c->colour_nbytes = 0;
    c->colour_rev++;
}

ms_status ms_view_set_colour_bytes(ms_view *v, uint32_t cell, const uint8_t *data, size_t length,
                                   ms_error *err)
{
    const vcell *c = ms_view_vcell(v, cell);
    if (!c || length <= c->colour_nbytes)
        return ms_view_append_colour_bytes(v, cell, data, 0, err); /* its checks, nothing added */
    return ms_view_append_colour_bytes(v, cell, data + c->colour_nbytes, length - c->colour_nbytes, err);
}

ms_status ms_view_append_colour_bytes(ms_view *v, uint32_t cell, const uint8_t *data, size_t added,
                                      ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u known", cell);
    if (!v->header.has_colour)
        return ms_error_set(err, MS_ERR_ARG, "cell %u: the model has no colour", cell);
    if (added == 0)
        return MS_OK;
    size_t length = c->colour_nbytes + added;
    uint8_t *b = realloc(c->colour_bytes, length);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's colour", cell);
    memcpy(b + c->colour_nbytes, data, added);
    c->colour_bytes = b;
    c->colour_nbytes = length;
    c->colour_rev++;
    c->colour_valid = false;
    if (c->cdec) {
        ms_error inner;
        if (ms_colour_decoder_extend(c->cdec, b, length, &inner) != MS_OK)
            ms_view_colour_drop(c); /* decoded again from the bytes when needed */
    }
    return MS_OK;
}

size_t ms_view_held_colour_bytes(const ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    return c ? c->colour_nbytes : 0;
}

bool ms_view_colour_ready(const vcell *c)
{
    return c->colour_valid && c->cache_colours;
}

static ms_status colour_fail(vcell *c, uint32_t cell, ms_status st, const ms_error *inner,
                             ms_error *err)
{
    ms_view_colour_drop(c);
    return ms_error_set(err, st, "cell %u: %s", cell, inner->text); /* the inner line names the colour stream */
}

static ms_status parent_top(ms_view *v, uint32_t cell, bool *ok, ms_error *err);

/* The cell's colour decoder with its base: *ready false while the bytes or
 * (a stream whose base its parent gives) the parent's whole colour are not
 * there yet. */
static ms_status colour_decoder(ms_view *v, uint32_t cell, vcell *c, bool *ready, ms_error *err)
{
    *ready = false;
    ms_error inner;
    ms_status st = MS_OK;
    if (c->colour_nbytes == 0)
        return MS_OK;
    if (!c->cdec &&
        (st = ms_colour_decoder_create(c->colour_bytes, c->colour_nbytes, NULL, &c->cdec, &inner)) !=
            MS_OK) {
        c->cdec = NULL;
        /* a prefix shorter than the longest header (docs/COLOUR.md §4) may
         * just not hold the header yet: no colour until more comes */
        return st == MS_ERR_FORMAT && c->colour_nbytes < 32u + 12u * MS_CODEC_MAX_BITS
                   ? MS_OK
                   : colour_fail(c, cell, st, &inner, err);
    }
    if (!c->colour_based && ms_colour_decoder_header(c->cdec)->base_given) {
        bool ok = false;
        if (!c->has_start || c->rec.parent == MS_ARCHIVE_NONE)
            return c->rec.parent == MS_ARCHIVE_NONE
                       ? ms_error_set(err, MS_ERR_CORRUPT,
                                      "cell %u: colour stream: the root's takes no base", cell)
                       : MS_OK;
        if ((st = parent_top(v, c->rec.parent, &ok, err)) != MS_OK || !ok)
            return st;
        const vcell *p = ms_view_vcell(v, c->rec.parent);
        size_t n = c->start.vertex_count;
        uint8_t *rgba = malloc(4 * (n ? n : 1));
        if (!rgba)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's colours", cell);
        size_t j = 0;
        for (size_t i = 0; i < n && st == MS_OK; ++i) {
            while (j < p->top_n && p->top_cells[j] < c->start.cells[i])
                ++j;
            if (j == p->top_n || p->top_cells[j] != c->start.cells[i])
                st = ms_error_set(err, MS_ERR_CORRUPT, "cell %u: start cell not in its parent", cell);
            else
                memcpy(rgba + 4 * i, p->top_colours + 4 * j, 4);
        }
        if (st == MS_OK &&
            (st = ms_colour_decoder_set_base(c->cdec, c->start.cells, n, rgba, &inner)) != MS_OK)
            st = colour_fail(c, cell, st, &inner, err);
        free(rgba);
        if (st != MS_OK)
            return st;
    }
    c->colour_based = true;
    *ready = ms_colour_decoder_has_base(c->cdec);
    return MS_OK;
}

/* The colours of a (split) cell's complex at bits_max, decoded from its whole
 * colour stream, kept for its children's bases: *ok false while they cannot
 * be had yet. */
static ms_status parent_top(ms_view *v, uint32_t cell, bool *ok, ms_error *err)
{
    *ok = false;
    vcell *p = ms_view_vcell(v, cell);
    if (!p || p->state == MS_VIEW_HIDDEN)
        return MS_OK;
    if (p->top_colours) {
        *ok = true;
        return MS_OK;
    }
    bool ready;
    ms_status st = colour_decoder(v, cell, p, &ready, err);
    unsigned top = 3u * p->rec.bits_max;
    if (st != MS_OK || !ready || ms_colour_decoder_available_level(p->cdec) < top)
        return st;
    ms_codec_state s;
    memset(&s, 0, sizeof s);
    const ms_codec_state *at = &s;
    if (p->cache_valid && p->cache_bits == p->rec.bits_max)
        at = &p->cache;
    else if ((st = ms_view_cell_state_copy(v, cell, &s, err)) != MS_OK)
        return st;
    ms_error inner;
    size_t n = at->vertex_count;
    p->top_cells = malloc((n ? n : 1) * sizeof *p->top_cells);
    p->top_colours = malloc(4 * (n ? n : 1));
    if (!p->top_cells || !p->top_colours)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's colours", cell);
    else if (ms_colour_decoder_level(p->cdec) < top &&
             (st = ms_colour_decoder_refine(p->cdec, at, top, &inner)) != MS_OK)
        st = colour_fail(p, cell, st, &inner, err);
    else if ((st = ms_colour_decoder_colours(p->cdec, at->cells, n, at->level, p->top_colours,
                                             &inner)) != MS_OK)
        st = colour_fail(p, cell, st, &inner, err);
    if (st == MS_OK) {
        memcpy(p->top_cells, at->cells, n * sizeof *at->cells);
        p->top_n = n;
        *ok = true;
    } else if (p->top_cells || p->top_colours) {
        free(p->top_cells);
        free(p->top_colours);
        p->top_cells = NULL;
        p->top_colours = NULL;
    }
    ms_codec_state_free(&s);
    return st;
}

ms_status ms_view_colour_refresh(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->colour_valid || c->colour_nbytes == 0 || !c->cache_valid)
        return MS_OK;
    size_t n = c->cache.vertex_count;
    if (n == 0)
        return MS_OK;
    bool ready;
    ms_status st = colour_decoder(v, cell, c, &ready, err);
    if (st != MS_OK || !ready)
        return st;
    ms_error inner;
    unsigned target = c->cache.level, available = ms_colour_decoder_available_level(c->cdec);
    if (target > available)
        target = available;
    if (target > ms_colour_decoder_level(c->cdec) &&
        (st = ms_colour_decoder_refine(c->cdec, &c->cache, target, &inner)) != MS_OK)
        return colour_fail(c, cell, st, &inner, err);
    uint8_t *rgba = realloc(c->cache_colours, 4 * n);
    if (!rgba)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's colours", cell);
    c->cache_colours = rgba;
    if ((st = ms_colour_decoder_colours(c->cdec, c->cache.cells, n, c->cache.level, rgba,
                                        &inner)) != MS_OK)
        return colour_fail(c, cell, st, &inner, err);
    c->colour_valid = true;
    c->colour_rev++; /* its stitched triangles' colours changed (run_version) */
    return MS_OK;
}
