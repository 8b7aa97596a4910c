/* The codec decoder's read-outs and release: its levels and counts, the
 * current complex as a state or a mesh (ms_codec.h). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_codec_internal.h"
#include "ms_complex.h"

unsigned ms_codec_decoder_min_level(const ms_codec_decoder *d) { return d->Lmin; }
unsigned ms_codec_decoder_max_level(const ms_codec_decoder *d) { return d->D; }
unsigned ms_codec_decoder_available_level(const ms_codec_decoder *d) { return d->avail_level; }
const ms_codec_header *ms_codec_decoder_header(const ms_codec_decoder *d) { return &d->h; }
size_t ms_codec_decoder_vertex_count(const ms_codec_decoder *d) { return d->cx.live_v; }
size_t ms_codec_decoder_tri_count(const ms_codec_decoder *d) { return d->cx.live_t; }
size_t ms_codec_decoder_edge_count(const ms_codec_decoder *d) { return d->cx.live_e; }

void ms_codec_decoder_destroy(ms_codec_decoder *d)
{
    if (!d)
        return;
    free(d->data);
    ms_cx_free(&d->cx);
    free(d->order);
    free(d->order2);
    free(d->model);
    free(d->snap);
    free(d->snap_valid);
    free(d->crc_ok);
    for (unsigned i = 0; i < 3 * MS_CODEC_MAX_BITS; ++i)
        free(d->births[i].b);
    ms_cx_star_free(&d->star);
    free(d->code);
    free(d->side);
    free(d->cov);
    free(d->partners);
    free(d->vote);
    free(d->pivot);
    free(d->tcode);
    free(d);
}

/* b as a float no smaller than b (an upper bound stays one). */
static float float_up(double b)
{
    float f = (float)b;
    return (double)f < b ? nextafterf(f, INFINITY) : f;
}

ms_status ms_codec_decoder_state(const ms_codec_decoder *d, ms_codec_state *out, ms_error *err)
{
    if (d->broken) {
        memset(out, 0, sizeof *out);
        return ms_error_set(err, MS_ERR_CORRUPT, "decoder stopped after a corrupted stream");
    }
    float *bound = malloc((d->norder ? d->norder : 1) * sizeof *bound);
    if (!bound) {
        memset(out, 0, sizeof *out);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory exporting a complex");
    }
    unsigned depth = ms_ahead_state_depth(d);
    for (uint32_t i = 0; i < d->norder; ++i)
        bound[i] = float_up(ms_ahead_cell_bound(&d->cx, d->order[i], depth));
    ms_status s = ms_codec_export_complex(&d->cx, d->order, d->norder, d->level, bound, out, err);
    free(bound);
    return s;
}

double ms_codec_decoder_error_bound(const ms_codec_decoder *d)
{
    const ms_codec_region *region = d->h.has_region ? &d->h.region : NULL;
    unsigned depth = ms_ahead_state_depth(d);
    double worst = 0;
    for (uint32_t i = 0; i < d->norder; ++i) {
        uint32_t s = d->order[i];
        if (region && cell_outside(&d->cx, region, s))
            continue;
        double b = ms_ahead_cell_bound(&d->cx, s, depth);
        if (b > worst)
            worst = b;
    }
    return worst;
}

size_t ms_codec_decoder_vertex_levels(const ms_codec_decoder *d, uint8_t *levels)
{
    for (uint32_t i = 0; i < d->norder; ++i)
        levels[i] = (uint8_t)ms_cx_level(&d->cx, d->order[i]);
    return d->frozen;
}

ms_status ms_codec_decoder_mesh(const ms_codec_decoder *d, ms_mesh *out, ms_error *err)
{
    if (d->broken)
        return ms_error_set(err, MS_ERR_CORRUPT, "decoder stopped after a corrupted stream");
    if (!d->has_box && !d->enc) /* an encoder's pass has its box (ms_codec_encode_params.box) */
        return ms_error_set(err, MS_ERR_ARG, "a compact codec stream needs its archive's box "
                            "for world positions");
    const ms_complex *cx = &d->cx;
    ms_status r = ms_mesh_reserve(out, d->norder, cx->live_t, err);
    if (r != MS_OK)
        return r;
    /* rank of each slot: reuse the triangle export order (slot -> vertex index) */
    uint32_t *rank = malloc((size_t)(cx->nv ? cx->nv : 1) * sizeof *rank);
    if (!rank)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory exporting a mesh");
    double scale = d->h.box.size / (double)(1u << cx->P);
    int32_t (*at)[4] = cx->rep ? cx->rep : cx->cen; /* drawn points, with geometry ahead */
    for (uint32_t i = 0; i < d->norder; ++i) {
        uint32_t s = d->order[i];
        rank[s] = i;
        for (int a = 0; a < 3; ++a)
            out->positions[3 * i + a] = d->h.box.origin[a] + 0.5 * at[s][a] * scale;
    }
    size_t w = 0;
    for (uint32_t t = 0; t < cx->nt; ++t) {
        if (cx->tri[t][0] == MS_CX_NONE)
            continue;
        for (int k = 0; k < 3; ++k)
            out->triangles[3 * w + k] = rank[cx->tri[t][k]];
        w++;
    }
    out->vertex_count = d->norder;
    out->triangle_count = w;
    free(rank);
    return MS_OK;
}
