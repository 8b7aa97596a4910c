/* The colour decoder (docs/COLOUR.md, "Decoding"): forward only, driven by the
 * geometry's cells; coarser colours are computed from the decoded level by the
 * rule, finer cells take their ancestor's colour. */
#include "ms_colour_internal.h"

#include <stdlib.h>
#include <string.h>
#include <zlib.h>

struct ms_colour_decoder {
    uint8_t *data;
    size_t size;
    ms_colour_header h;
    bool skip_crc;
    bool failed;
    bool started;   /* base decoded, cur holds the cells of `level` */
    unsigned level; /* the decoded kd-level */
    cc_level cur, nxt;
    cc_model model;
    cc_coder coder;
    uint64_t *base_cells; /* base_given: the caller's base (ms_colour_decoder_set_base) */
    uint8_t *base_col;    /* 4 per base cell, reduced to the stream's precision */
    size_t base_n;
    uint64_t *pre;  /* scratch: prefixes of the caller's cells */
    size_t pre_cap;
    cc_graph graph;
};

ms_status ms_colour_decoder_create(const uint8_t *data, size_t size,
                                   const ms_colour_decoder_options *options,
                                   ms_colour_decoder **out, ms_error *err)
{
    *out = NULL;
    ms_colour_header h;
    bool skip = options && options->skip_crc;
    ms_status st = cc_read_header(data, size, &h, !skip, err);
    if (st != MS_OK)
        return st;
    size_t total = h.header_size + h.body_size;
    if (size > total)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: %zu bytes, the header declares "
                            "%zu", size, total);
    ms_colour_decoder *d = calloc(1, sizeof *d);
    if (d)
        d->data = malloc(size);
    if (!d || !d->data) {
        free(d);
        return ms_error_set(err, MS_ERR_NOMEM, "colour decoder: out of memory");
    }
    memcpy(d->data, data, size);
    d->size = size;
    d->h = h;
    d->skip_crc = skip;
    d->level = 3 * h.p_min;
    cc_model_init(&d->model);
    d->coder.bits = h.colour_bits;
    d->coder.slots = h.alpha ? 4 : 3;
    d->coder.m = &d->model;
    *out = d;
    return MS_OK;
}

void ms_colour_decoder_destroy(ms_colour_decoder *d)
{
    if (!d)
        return;
    cc_level_free(&d->cur);
    cc_level_free(&d->nxt);
    free(d->pre);
    free(d->base_cells);
    free(d->base_col);
    cc_graph_free(&d->graph);
    free(d->data);
    free(d);
}

ms_status ms_colour_decoder_set_base(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                                     const uint8_t *rgba, ms_error *err)
{
    if (!d->h.base_given || d->started || d->base_cells)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: %s",
                            !d->h.base_given ? "the stream codes its own base colours"
                                             : "base colours given twice or too late");
    if (n != d->h.start_cells)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: %zu base colours for %u cells", n,
                            d->h.start_cells);
    for (size_t i = 1; i < n; ++i)
        if (cells[i] <= cells[i - 1])
            return ms_error_set(err, MS_ERR_ARG, "colour decoder: base cells not increasing");
    d->base_cells = malloc((n ? n : 1) * sizeof *d->base_cells);
    d->base_col = malloc(4 * (n ? n : 1));
    if (!d->base_cells || !d->base_col) {
        free(d->base_cells);
        free(d->base_col);
        d->base_cells = NULL;
        d->base_col = NULL;
        return ms_error_set(err, MS_ERR_NOMEM, "colour decoder: out of memory");
    }
    unsigned c = d->h.colour_bits;
    memcpy(d->base_cells, cells, n * sizeof *cells);
    for (size_t i = 0; i < n; ++i)
        for (unsigned k = 0; k < 4; ++k)
            d->base_col[4 * i + k] = k == 3 && !d->h.alpha ? (uint8_t)((1u << c) - 1)
                                                           : (uint8_t)(rgba[4 * i + k] >> (8 - c));
    d->base_n = n;
    return MS_OK;
}

ms_status ms_colour_decoder_extend(ms_colour_decoder *d, const uint8_t *data, size_t size,
                                   ms_error *err)
{
    if (size < d->size || memcmp(data, d->data, d->size) != 0)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: the bytes do not continue the "
                            "stream");
    if (size > d->h.header_size + d->h.body_size)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: %zu bytes, the header declares "
                            "%zu", size, d->h.header_size + d->h.body_size);
    uint8_t *grown = realloc(d->data, size ? size : 1);
    if (!grown)
        return ms_error_set(err, MS_ERR_NOMEM, "colour decoder: out of memory");
    size_t offset = d->coder.dec.data ? (size_t)(d->coder.dec.data - d->data) : 0;
    d->data = grown;
    if (d->coder.dec.data)
        d->coder.dec.data = d->data + offset;
    memcpy(d->data + d->size, data + d->size, size - d->size);
    d->size = size;
    return MS_OK;
}

const ms_colour_header *ms_colour_decoder_header(const ms_colour_decoder *d)
{
    return &d->h;
}

unsigned ms_colour_decoder_min_level(const ms_colour_decoder *d)
{
    return 3 * d->h.p_min;
}

unsigned ms_colour_decoder_max_level(const ms_colour_decoder *d)
{
    return 3 * d->h.p_max;
}

static bool chunk_complete(const ms_colour_decoder *d, unsigned i)
{
    return d->h.header_size + d->h.chunk_end[i] <= d->size;
}

bool ms_colour_decoder_has_base(const ms_colour_decoder *d)
{
    return chunk_complete(d, 0);
}

unsigned ms_colour_decoder_available_level(const ms_colour_decoder *d)
{
    unsigned n = d->h.p_max - d->h.p_min, i = 0;
    if (!chunk_complete(d, 0))
        return 3 * d->h.p_min;
    while (i < n && chunk_complete(d, i + 1))
        ++i;
    return 3 * (d->h.p_min + i);
}

unsigned ms_colour_decoder_level(const ms_colour_decoder *d)
{
    return d->level;
}

/* Starts the range decoder on chunk i after checking its CRC. */
static ms_status open_chunk(ms_colour_decoder *d, unsigned i, ms_error *err)
{
    size_t from = i ? d->h.chunk_end[i - 1] : 0, len = d->h.chunk_end[i] - from;
    const uint8_t *p = d->data + d->h.header_size + from;
    if (!d->skip_crc && crc32(0L, p, (uInt)len) != d->h.chunk_crc[i]) {
        d->failed = true;
        return ms_error_set(err, MS_ERR_CORRUPT, "colour stream: chunk %u CRC mismatch", i);
    }
    ms_rc_decoder_init(&d->coder.dec, p, len);
    return MS_OK;
}

static ms_status close_chunk(ms_colour_decoder *d, unsigned i, ms_error *err)
{
    if (!ms_rc_decoder_clean_end(&d->coder.dec)) {
        d->failed = true;
        return ms_error_set(err, MS_ERR_CORRUPT, "colour stream: chunk %u not consumed exactly "
                            "(corrupted)", i);
    }
    d->coder.dec.data = NULL;
    return MS_OK;
}

/* The distinct prefixes of cells (at cells_level) at kd-level `level` into
 * d->pre; returns their count. */
static size_t prefixes(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                       unsigned cells_level, unsigned level)
{
    unsigned shift = cells_level - level;
    size_t m = 0;
    for (size_t i = 0; i < n; ++i) {
        uint64_t p = cells[i] >> shift;
        if (m == 0 || d->pre[m - 1] != p)
            d->pre[m++] = p;
    }
    return m;
}

static ms_status check_cells(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                             unsigned cells_level, ms_error *err)
{
    if (d->failed)
        return ms_error_set(err, MS_ERR_CORRUPT, "colour decoder: unusable after an error");
    if (cells_level < 3 * d->h.p_min || cells_level > 3 * d->h.p_max)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: kd-level %u outside the stream's "
                            "[%u, %u]", cells_level, 3 * d->h.p_min, 3 * d->h.p_max);
    if (n == 0 || n > d->h.end_cells)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: %zu cells, the stream has 1..%u",
                            n, d->h.end_cells);
    uint64_t limit = cells_level == 0 ? 0 : (UINT64_MAX >> (64 - cells_level));
    for (size_t i = 0; i < n; ++i)
        if (cells[i] > limit || (i > 0 && cells[i] <= cells[i - 1]))
            return ms_error_set(err, MS_ERR_ARG, "colour decoder: cells not strictly increasing "
                                "kd prefixes of level %u", cells_level);
    if (d->pre_cap < n) {
        uint64_t *p = realloc(d->pre, n * sizeof *p);
        if (!p)
            return ms_error_set(err, MS_ERR_NOMEM, "colour decoder: out of memory");
        d->pre = p;
        d->pre_cap = n;
    }
    return MS_OK;
}

static ms_status mismatch(ms_error *err, unsigned level)
{
    return ms_error_set(err, MS_ERR_ARG, "colour decoder: the cells at kd-level %u differ from "
                        "the colour stream's", level);
}

/* Decodes the base chunk for the cells' prefixes at the first level. */
static ms_status start(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                       unsigned cells_level, ms_error *err)
{
    if (d->started)
        return MS_OK;
    unsigned L0 = 3 * d->h.p_min;
    size_t m = prefixes(d, cells, n, cells_level, L0);
    if (m != d->h.start_cells)
        return mismatch(err, L0);
    if (!chunk_complete(d, 0))
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: truncated before its base "
                            "colours");
    ms_status st = cc_level_reserve(&d->cur, m, err);
    if (st != MS_OK)
        return st;
    memcpy(d->cur.cells, d->pre, m * sizeof *d->pre);
    d->cur.n = m;
    if (d->h.base_given && (!d->base_cells || d->base_n != m ||
                            memcmp(d->base_cells, d->pre, m * sizeof *d->pre) != 0))
        return ms_error_set(err, MS_ERR_ARG, "colour stream: %s", d->base_cells
                                ? "the base colours given are not the cells' at its first level"
                                : "its base colours were not given");
    if ((st = open_chunk(d, 0, err)) != MS_OK)
        return st;
    if (d->h.base_given) {
        memcpy(d->cur.col, d->base_col, 4 * m);
        memset(d->cur.act, 0, m * CC_SLOTS * sizeof *d->cur.act);
    } else {
        st = cc_code_base(&d->coder, &d->cur, err);
    }
    if (st == MS_OK)
        st = close_chunk(d, 0, err);
    if (st != MS_OK) {
        d->failed = true;
        return st;
    }
    d->started = true;
    return MS_OK;
}

/* Whether the cells' prefixes at the decoded level are the decoded cells. */
static bool continues(ms_colour_decoder *d, const uint64_t *cells, size_t n, unsigned cells_level)
{
    size_t m = prefixes(d, cells, n, cells_level, d->level);
    return m == d->cur.n && memcmp(d->pre, d->cur.cells, m * sizeof *d->pre) == 0;
}

ms_status ms_colour_decoder_refine(ms_colour_decoder *d, const ms_codec_state *geo,
                                   unsigned level, ms_error *err)
{
    const uint64_t *cells = geo->cells;
    size_t n = geo->vertex_count;
    unsigned cells_level = geo->level;
    ms_status st = check_cells(d, cells, n, cells_level, err);
    if (st != MS_OK)
        return st;
    for (size_t t = 0; t < 3 * geo->tri_count; ++t)
        if (geo->tris[t] >= n)
            return ms_error_set(err, MS_ERR_ARG, "colour decoder: triangle index out of range");
    for (size_t e = 0; e < 2 * geo->edge_count; ++e)
        if (geo->edges[e] >= n)
            return ms_error_set(err, MS_ERR_ARG, "colour decoder: edge index out of range");
    if (level > cells_level)
        return ms_error_set(err, MS_ERR_ARG, "colour decoder: kd-level %u above the cells' %u",
                            level, cells_level);
    if ((st = start(d, cells, n, cells_level, err)) != MS_OK)
        return st;
    if (level <= d->level || cells_level < d->level) {
        /* only a check: the cells against the decoded ones (cells coarser than
         * the decoded level are checked by ms_colour_decoder_colours) */
        if (cells_level >= d->level && !continues(d, cells, n, cells_level))
            return mismatch(err, d->level);
        return MS_OK;
    }
    if (!continues(d, cells, n, cells_level))
        return mismatch(err, d->level);
    unsigned L0 = 3 * d->h.p_min;
    if (level > ms_colour_decoder_available_level(d))
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: truncated at kd-level %u, "
                            "kd-level %u asked", ms_colour_decoder_available_level(d), level);
    for (unsigned e = d->level + 1; e <= level; ++e)
        if ((e - L0) % 3 == 0 &&
            prefixes(d, cells, n, cells_level, e) != d->h.chunk_cells[(e - L0) / 3])
            return mismatch(err, e);
    while (d->level < level) {
        unsigned L = d->level, chunk = (L - L0) / 3 + 1;
        if ((L - L0) % 3 == 0 && (st = open_chunk(d, chunk, err)) != MS_OK)
            return st;
        size_t m = prefixes(d, cells, n, cells_level, L + 1);
        st = cc_graph_build(geo, L + 1, d->pre, m, &d->graph, err);
        if (st != MS_OK)
            return st; /* out of memory */
        st = cc_step(&d->coder, &d->cur, L, d->pre, m, &d->graph, &d->nxt, err);
        if (st != MS_OK) {
            d->failed = true;
            return st;
        }
        cc_level t = d->cur;
        d->cur = d->nxt;
        d->nxt = t;
        d->level = L + 1;
        if ((L + 1 - L0) % 3 == 0 && (st = close_chunk(d, chunk, err)) != MS_OK)
            return st;
    }
    return MS_OK;
}

static void widen(const ms_colour_decoder *d, const uint8_t *col, uint8_t *out)
{
    for (int k = 0; k < 3; ++k)
        out[k] = ms_colour_widen(col[k], d->h.colour_bits);
    out[3] = d->h.alpha ? ms_colour_widen(col[3], d->h.colour_bits) : 255;
}

ms_status ms_colour_decoder_colours(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                                    unsigned cells_level, uint8_t *rgba, ms_error *err)
{
    ms_status st = check_cells(d, cells, n, cells_level, err);
    if (st == MS_OK)
        st = start(d, cells, n, cells_level, err);
    if (st != MS_OK)
        return st;
    if (cells_level >= d->level) {
        if (!continues(d, cells, n, cells_level))
            return mismatch(err, d->level);
        unsigned shift = cells_level - d->level;
        size_t j = 0;
        for (size_t i = 0; i < n; ++i) {
            while (d->cur.cells[j] != cells[i] >> shift)
                ++j; /* continues() guarantees every prefix is there, in order */
            widen(d, d->cur.col + 4 * j, rgba + 4 * i);
        }
        return MS_OK;
    }
    /* coarser than decoded: apply the rule upwards */
    cc_level a = {0}, b = {0};
    const cc_level *from = &d->cur;
    for (unsigned L = d->level; L > cells_level && st == MS_OK; --L) {
        cc_level *to = from == &a ? &b : &a;
        st = cc_coarsen(from, to, err);
        from = to;
    }
    if (st == MS_OK && (from->n != n || memcmp(from->cells, cells, n * sizeof *cells) != 0))
        st = mismatch(err, cells_level);
    for (size_t i = 0; st == MS_OK && i < n; ++i)
        widen(d, from->col + 4 * i, rgba + 4 * i);
    cc_level_free(&a);
    cc_level_free(&b);
    return st;
}
