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
    vcell *c = ms_view_vcell(v, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u known", cell);
    if (!v->header.has_colour)
        return ms_error_set(err, MS_ERR_ARG, "cell %u: the model has no colour", cell);
    if (length <= c->colour_nbytes)
        return MS_OK;
    uint8_t *b = realloc(c->colour_bytes, length);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for cell %u's colour", cell);
    memcpy(b + c->colour_nbytes, data + c->colour_nbytes, length - c->colour_nbytes);
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
    return ms_error_set(err, st, "cell %u: colour stream: %s", cell, inner->text);
}

ms_status ms_view_colour_refresh(vcell *c, uint32_t cell, ms_error *err)
{
    if (c->colour_valid || c->colour_nbytes == 0 || !c->cache_valid)
        return MS_OK;
    size_t n = c->cache.vertex_count;
    if (n == 0)
        return MS_OK;
    ms_error inner;
    ms_status st = MS_OK;
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
    if (!ms_colour_decoder_has_base(c->cdec))
        return MS_OK;
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
    return MS_OK;
}
