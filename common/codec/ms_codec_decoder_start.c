/* The codec decoder's first step (ms_codec_internal.h): the caller's start
 * state, checked against the stream's header, loaded into the complex. */
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_codec_internal.h"
#include "ms_complex.h"
#include "ms_quant.h"

ms_status ms_codec_decoder_load_start(ms_codec_decoder *d, const ms_codec_state *start,
                                      ms_error *err)
{
    ms_complex *cx = &d->cx;
    const ms_codec_header *h = &d->h;
    if (!start) {
        if (h->p_min != 0)
            return ms_error_set(err, MS_ERR_ARG, "a stream from precision %u needs a start state",
                                h->p_min);
        uint32_t c[3] = {0, 0, 0};
        ms_status r = ms_cx_reserve(cx, 1, 0, 0, err);
        if (r != MS_OK)
            return r;
        d->order[0] = ms_cx_add_vertex(cx, 0, 0, c);
        d->norder = 1;
        return MS_OK;
    }
    /* Cells are kd prefixes at level 3 p_min whatever the key space of the
     * decoder that produced them (a parent nSP cell's stream ends at p_min). */
    if (start->level != d->Lmin)
        return ms_error_set(err, MS_ERR_ARG, "start state at kd-level %u does not match the "
                            "stream's first level %u", start->level, d->Lmin);
    if (start->vertex_count != h->start_vertices || start->tri_count != h->start_tris ||
        start->edge_count != h->start_edges)
        return ms_error_set(err, MS_ERR_ARG, "start state counts differ from the stream's");
    ms_codec_state canon = {0};
    canon.bits = start->bits;
    canon.level = start->level;
    canon.vertex_count = start->vertex_count;
    canon.tri_count = start->tri_count;
    canon.edge_count = start->edge_count;
    canon.cells = malloc((start->vertex_count ? start->vertex_count : 1) * sizeof *canon.cells);
    canon.tris = malloc((start->tri_count ? start->tri_count : 1) * 3 * sizeof *canon.tris);
    canon.edges = malloc((start->edge_count ? start->edge_count : 1) * 2 * sizeof *canon.edges);
    if (!canon.cells || !canon.tris || !canon.edges) {
        ms_codec_state_free(&canon);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory loading a start state");
    }
    memcpy(canon.cells, start->cells, start->vertex_count * sizeof *canon.cells);
    for (size_t i = 0; i < 3 * start->tri_count; ++i) {
        if (start->tris[i] >= start->vertex_count) {
            ms_codec_state_free(&canon);
            return ms_error_set(err, MS_ERR_ARG, "start state triangle index out of range");
        }
        canon.tris[i] = start->tris[i];
    }
    for (size_t i = 0; i < 2 * start->edge_count; ++i) {
        if (start->edges[i] >= start->vertex_count) {
            ms_codec_state_free(&canon);
            return ms_error_set(err, MS_ERR_ARG, "start state edge index out of range");
        }
        canon.edges[i] = start->edges[i];
    }
    ms_status r = ms_codec_state_canonicalise(&canon, err);
    /* The encoder's forward pass (d->enc) loads the start state whose checksum
     * it has just written into the header: only a decoder has one to check. */
    if (r == MS_OK && !d->enc && ms_codec_state_checksum(&canon) != h->start_checksum)
        r = ms_error_set(err, MS_ERR_ARG, "start state does not match the stream (checksum)");
    uint64_t lim = d->Lmin >= 64 ? UINT64_MAX : (1ull << d->Lmin);
    for (size_t i = 0; r == MS_OK && i < canon.vertex_count; ++i)
        if (canon.cells[i] >= lim || (i > 0 && canon.cells[i] == canon.cells[i - 1]))
            r = ms_error_set(err, MS_ERR_ARG, "start state cells invalid or repeated");
    if (r == MS_OK)
        r = ms_cx_reserve(cx, (uint32_t)canon.vertex_count, (uint32_t)canon.tri_count,
                          (uint32_t)canon.edge_count, err);
    if (r != MS_OK) {
        ms_codec_state_free(&canon);
        return r;
    }
    unsigned shift = d->D - d->Lmin;
    for (size_t i = 0; i < canon.vertex_count; ++i) {
        uint64_t key = shift >= 64 ? 0 : canon.cells[i] << shift;
        uint32_t c[3];
        ms_quant_unkey(key, h->p_max, c);
        d->order[i] = ms_cx_add_vertex(cx, key, d->Lmin, c);
    }
    d->norder = (uint32_t)canon.vertex_count;
    /* Births: the level at which a cell separated from its neighbours in key order. */
    for (size_t i = 0; i < canon.vertex_count; ++i) {
        unsigned b = 0;
        if (i > 0) {
            unsigned l = ms_key_lcp(cx->v[d->order[i - 1]].key, cx->v[d->order[i]].key, d->D) + 1;
            b = l > b ? l : b;
        }
        if (i + 1 < canon.vertex_count) {
            unsigned l = ms_key_lcp(cx->v[d->order[i]].key, cx->v[d->order[i + 1]].key, d->D) + 1;
            b = l > b ? l : b;
        }
        cx->v[d->order[i]].birth = (uint8_t)(b < d->Lmin ? b : d->Lmin);
    }
    for (size_t t = 0; t < canon.tri_count; ++t) {
        const uint32_t *x = &canon.tris[3 * t];
        if (x[0] == x[1] || x[1] == x[2] || x[0] == x[2]) {
            ms_codec_state_free(&canon);
            return ms_error_set(err, MS_ERR_ARG, "start state triangle repeats a vertex");
        }
        ms_cx_add_tri(cx, d->order[x[0]], d->order[x[1]], d->order[x[2]]);
    }
    for (size_t k = 0; k < canon.edge_count; ++k) {
        const uint32_t *x = &canon.edges[2 * k];
        if (x[0] == x[1]) {
            ms_codec_state_free(&canon);
            return ms_error_set(err, MS_ERR_ARG, "start state edge repeats a vertex");
        }
        ms_cx_add_edge(cx, d->order[x[0]], d->order[x[1]]);
    }
    ms_codec_state_free(&canon);
    return cx->nomem ? ms_error_set(err, MS_ERR_NOMEM, "out of memory loading a start state")
                     : MS_OK;
}
