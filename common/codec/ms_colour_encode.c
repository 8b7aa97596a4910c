/* The colour encoder (docs/COLOUR.md, "Encoding"): the colours of every level
 * bottom-up with the split details, then the decoder's level step in encode
 * mode, top-down, one chunk per precision bit. */
#include "ms_colour_internal.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

/* The parents of l's cells into up (the rule), and the detail (lower - upper,
 * r g b a) of each split appended in key order to *det. */
static ms_status coarsen_details(const cc_level *l, cc_level *up, int16_t *det, size_t *ndet,
                                 ms_error *err)
{
    ms_status st = cc_coarsen(l, up, err);
    if (st != MS_OK)
        return st;
    size_t m = 0;
    for (size_t i = 0; i + 1 < l->n; ++i) {
        if (l->cells[i + 1] >> 1 != l->cells[i] >> 1)
            continue;
        const uint8_t *a = l->col + 4 * i, *b = a + 4;
        for (int k = 0; k < 4; ++k)
            det[4 * m + (unsigned)k] = (int16_t)(a[k] - b[k]);
        ++m;
        ++i;
    }
    *ndet = m;
    return MS_OK;
}

/* The distinct prefixes of the sorted keys at `shift` bits up into out. */
static size_t prefixes(const uint64_t *keys, size_t n, unsigned shift, uint64_t *out)
{
    size_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        uint64_t p = keys[i] >> shift;
        if (m == 0 || out[m - 1] != p)
            out[m++] = p;
    }
    return m;
}

static ms_status check_input(const ms_codec_state *full, const ms_colour_encode_params *p,
                             unsigned c, ms_error *err)
{
    if (!full || full->vertex_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "colour encoder: no vertex");
    if (full->bits < 1 || full->bits > MS_CODEC_MAX_BITS || full->level != 3 * full->bits)
        return ms_error_set(err, MS_ERR_ARG, "colour encoder: cells must be at full precision "
                            "(level %u, %u bits)", full->level, full->bits);
    if (p->p_min > full->bits)
        return ms_error_set(err, MS_ERR_ARG, "colour encoder: p_min %u above %u bits", p->p_min,
                            full->bits);
    if (c < 1 || c > MS_COLOUR_MAX_BITS)
        return ms_error_set(err, MS_ERR_ARG, "colour encoder: colour precision %u outside 1..%d",
                            c, MS_COLOUR_MAX_BITS);
    if (full->vertex_count > MS_CODEC_MAX_VERTICES)
        return ms_error_set(err, MS_ERR_ARG, "colour encoder: %zu vertices, at most %u",
                            full->vertex_count, (unsigned)MS_CODEC_MAX_VERTICES);
    uint64_t limit = 3 * full->bits == 64 ? UINT64_MAX : (1ull << (3 * full->bits)) - 1;
    for (size_t t = 0; t < 3 * full->tri_count; ++t)
        if (full->tris[t] >= full->vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "colour encoder: triangle index out of range");
    for (size_t e = 0; e < 2 * full->edge_count; ++e)
        if (full->edges[e] >= full->vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "colour encoder: edge index out of range");
    for (size_t i = 0; i < full->vertex_count; ++i)
        if (full->cells[i] > limit || (i > 0 && full->cells[i] <= full->cells[i - 1]))
            return ms_error_set(err, MS_ERR_ARG,
                                "colour encoder: cells not strictly increasing keys (vertex %zu)",
                                i);
    return MS_OK;
}

typedef struct enc_work {
    cc_level lv, tmp;
    int16_t *det;          /* details of every level, level-major */
    size_t *det_at;        /* per kd-level: first detail */
    uint64_t *next;
    cc_model model;
    cc_coder coder;
    cc_graph graph;
} enc_work;

static void work_free(enc_work *w)
{
    cc_level_free(&w->lv);
    cc_level_free(&w->tmp);
    free(w->det);
    free(w->det_at);
    free(w->next);
    cc_graph_free(&w->graph);
    ms_rc_encoder_free(&w->coder.enc);
}

/* Bottom-up: w->lv ends at kd-level 3 p_min, the details of kd-level L (its
 * splits into L + 1) at w->det + 4 w->det_at[L] .. 4 w->det_at[L + 1]. */
static ms_status bottom_up(enc_work *w, const ms_codec_state *full, const uint8_t *rgba,
                           unsigned c, bool alpha, unsigned L0, ms_error *err)
{
    unsigned D = full->level;
    size_t V = full->vertex_count;
    ms_status st = cc_level_reserve(&w->lv, V, err);
    if (st != MS_OK)
        return st;
    memcpy(w->lv.cells, full->cells, V * sizeof *full->cells);
    for (size_t i = 0; i < V; ++i)
        for (int k = 0; k < 4; ++k)
            w->lv.col[4 * i + (unsigned)k] =
                k == 3 && !alpha ? (uint8_t)((1u << c) - 1) : (uint8_t)(rgba[4 * i + (unsigned)k] >> (8 - c));
    w->lv.n = V;
    w->det = malloc(4 * V * sizeof *w->det);
    w->det_at = calloc(D + 2, sizeof *w->det_at);
    if (!w->det || !w->det_at)
        return ms_error_set(err, MS_ERR_NOMEM, "colour encoder: out of memory");
    /* levels deepest first; each level's details are placed later, so gather
     * them at the end of det and count */
    size_t used = 0;
    size_t *count = w->det_at; /* count[L] first, turned into offsets below */
    int16_t *scratch = malloc(4 * V * sizeof *scratch);
    if (!scratch)
        return ms_error_set(err, MS_ERR_NOMEM, "colour encoder: out of memory");
    for (unsigned L = D; L-- > L0;) {
        size_t m = 0;
        st = coarsen_details(&w->lv, &w->tmp, scratch, &m, err);
        if (st != MS_OK)
            break;
        /* stack the levels from the end of det: level L occupies the m details
         * just below the ones of L + 1 */
        memcpy(w->det + 4 * (V - used - m), scratch, 4 * m * sizeof *scratch);
        used += m;
        count[L] = m;
        cc_level t = w->lv;
        w->lv = w->tmp;
        w->tmp = t;
    }
    free(scratch);
    if (st != MS_OK)
        return st;
    size_t at = V - used;
    for (unsigned L = 0; L <= D; ++L) {
        size_t m = L >= L0 && L < D ? count[L] : 0;
        w->det_at[L] = at;
        at += m;
    }
    return MS_OK;
}

ms_status ms_colour_encode(const ms_codec_state *full, const uint8_t *rgba,
                           const ms_colour_encode_params *params, uint8_t **out,
                           size_t *out_size, ms_error *err)
{
    *out = NULL;
    *out_size = 0;
    ms_colour_encode_params p = params ? *params : (ms_colour_encode_params){0};
    unsigned c = p.colour_bits ? p.colour_bits : MS_COLOUR_DEFAULT_BITS;
    ms_status st = check_input(full, &p, c, err);
    if (st != MS_OK)
        return st;
    unsigned D = full->level, L0 = 3 * p.p_min;
    size_t V = full->vertex_count;
    enc_work w;
    memset(&w, 0, sizeof w);
    ms_colour_header h;
    memset(&h, 0, sizeof h);
    st = bottom_up(&w, full, rgba, c, p.alpha, L0, err);
    w.next = st == MS_OK ? malloc(V * sizeof *w.next) : NULL;
    if (st == MS_OK && !w.next)
        st = ms_error_set(err, MS_ERR_NOMEM, "colour encoder: out of memory");
    if (st != MS_OK) {
        work_free(&w);
        return st;
    }
    h.version = MS_COLOUR_VERSION;
    h.p_min = p.p_min;
    h.p_max = full->bits;
    h.colour_bits = c;
    h.alpha = p.alpha;
    h.base_given = p.base_given;
    h.start_cells = (uint32_t)w.lv.n;
    h.end_cells = (uint32_t)V;
    h.chunk_cells[0] = h.start_cells;
    cc_model_init(&w.model);
    w.coder.encoding = true;
    w.coder.bits = c;
    w.coder.slots = p.alpha ? 4 : 3;
    w.coder.m = &w.model;
    ms_rc_encoder_init(&w.coder.enc);
    if (!p.base_given)
        st = cc_code_base(&w.coder, &w.lv, err);
    else /* the lineages start without activity, as cc_code_base leaves them */
        memset(w.lv.act, 0, w.lv.n * CC_SLOTS * sizeof *w.lv.act);
    ms_rc_encoder_flush(&w.coder.enc);
    h.chunk_end[0] = (uint32_t)w.coder.enc.size;
    for (unsigned L = L0; L < D && st == MS_OK; ++L) {
        size_t n = prefixes(full->cells, V, D - L - 1, w.next);
        w.coder.src = w.det + 4 * w.det_at[L];
        w.coder.src_n = w.det_at[L + 1] - w.det_at[L];
        w.coder.src_at = 0;
        st = cc_graph_build(full, L + 1, w.next, n, &w.graph, err);
        if (st == MS_OK)
            st = cc_step(&w.coder, &w.lv, L, w.next, n, &w.graph, &w.tmp, err);
        if (st == MS_OK && w.coder.src_at != w.coder.src_n)
            st = ms_error_set(err, MS_ERR_ARG, "colour encoder: split count mismatch");
        cc_level t = w.lv;
        w.lv = w.tmp;
        w.tmp = t;
        if ((L + 1 - L0) % 3 == 0) {
            unsigned b = (L + 1 - L0) / 3;
            ms_rc_encoder_flush(&w.coder.enc);
            h.chunk_end[b] = (uint32_t)w.coder.enc.size;
            h.chunk_cells[b] = (uint32_t)w.lv.n;
        }
    }
    /* self-check: the forward pass ends at the input colours */
    for (size_t i = 0; st == MS_OK && i < V; ++i)
        for (int k = 0; k < (p.alpha ? 4 : 3); ++k)
            if (w.lv.col[4 * i + (unsigned)k] != rgba[4 * i + (unsigned)k] >> (8 - c))
                st = ms_error_set(err, MS_ERR_ARG, "colour encoder: internal mismatch at %zu", i);
    if (st == MS_OK && w.coder.enc.failed)
        st = ms_error_set(err, MS_ERR_NOMEM, "colour encoder: out of memory");
    if (st == MS_OK) {
        unsigned nchunks = h.p_max - h.p_min;
        for (unsigned i = 0; i <= nchunks; ++i) {
            uint32_t from = i ? h.chunk_end[i - 1] : 0;
            h.chunk_crc[i] = (uint32_t)crc32(0L, w.coder.enc.buf + from,
                                             (uInt)(h.chunk_end[i] - from));
        }
        size_t hs = cc_write_header(NULL, &h);
        *out = malloc(hs + w.coder.enc.size);
        if (!*out) {
            st = ms_error_set(err, MS_ERR_NOMEM, "colour encoder: out of memory");
        } else {
            cc_write_header(*out, &h);
            memcpy(*out + hs, w.coder.enc.buf, w.coder.enc.size);
            *out_size = hs + w.coder.enc.size;
        }
    }
    work_free(&w);
    return st;
}
