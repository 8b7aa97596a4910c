/* Per-vertex colour for a bake: see ms_bake_colour.h. */
#include "ms_bake_colour.h"

#include <stdlib.h>
#include <string.h>

#include "ms_colour.h"
#include "ms_mesh_reader.h"
#include "ms_radix_sort.h"

/* ---- reading: (key, colour) per input vertex, then welded ---------------- */

typedef struct reader {
    const ms_quant_box *box;
    unsigned bits;
    uint64_t *keys;  /* per input vertex */
    uint32_t *rgba;
    size_t count, cap, coloured;
} reader;

static ms_status grow(reader *r, size_t more, ms_error *err)
{
    if (r->count + more <= r->cap)
        return MS_OK;
    size_t cap = r->cap ? r->cap : 1 << 16;
    while (cap < r->count + more)
        cap *= 2;
    uint64_t *k = realloc(r->keys, cap * sizeof *k);
    if (k)
        r->keys = k;
    uint32_t *c = k ? realloc(r->rgba, cap * sizeof *c) : NULL;
    if (c)
        r->rgba = c;
    if (!k || !c)
        return ms_error_set(err, MS_ERR_NOMEM, "colour: out of memory for %zu vertices", cap);
    r->cap = cap;
    return MS_OK;
}

static ms_status on_vertices(void *context, const double *positions, size_t count, ms_error *err)
{
    reader *r = context;
    ms_status s = grow(r, count, err);
    for (size_t i = 0; s == MS_OK && i < count; ++i) {
        uint32_t q[3];
        for (int a = 0; a < 3; ++a)
            q[a] = ms_quantise(r->box, r->bits, a, positions[3 * i + (size_t)a]);
        r->keys[r->count + i] = ms_quant_key(q[0], q[1], q[2], r->bits);
        r->rgba[r->count + i] = 0xFFFFFFFFu;
    }
    if (s == MS_OK)
        r->count += count;
    return s;
}

static ms_status on_colours(void *context, const uint8_t *rgba, size_t count, ms_error *err)
{
    reader *r = context;
    if (count > r->count - r->coloured)
        return ms_error_set(err, MS_ERR_FORMAT, "colour: more colours than vertices");
    for (size_t i = 0; i < count; ++i) {
        const uint8_t *p = rgba + 4 * i;
        r->rgba[r->coloured + i] =
            (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    }
    r->coloured += count;
    return MS_OK;
}

/* Sorts by key and keeps one entry per key: per channel the rounded mean
 * (halves up) of its vertices' colours. */
static ms_status weld(reader *r, ms_bake_colours *out, ms_error *err)
{
    ms_status s = ms_radix_sort_pairs(r->keys, r->rgba, r->count, 3 * r->bits, err);
    if (s != MS_OK)
        return s;
    size_t w = 0;
    for (size_t i = 0; i < r->count;) {
        size_t j = i;
        uint64_t sum[4] = {0, 0, 0, 0};
        for (; j < r->count && r->keys[j] == r->keys[i]; ++j)
            for (unsigned k = 0; k < 4; ++k)
                sum[k] += (r->rgba[j] >> (8 * k)) & 0xFFu;
        uint64_t n = j - i;
        uint32_t v = 0;
        for (unsigned k = 0; k < 4; ++k)
            v |= (uint32_t)((2 * sum[k] + n) / (2 * n)) << (8 * k);
        r->keys[w] = r->keys[i];
        r->rgba[w] = v;
        ++w;
        i = j;
    }
    out->count = w;
    /* 12 bytes a welded vertex from here on */
    uint64_t *k = realloc(r->keys, (w ? w : 1) * sizeof *k);
    if (k)
        r->keys = k;
    uint32_t *c = realloc(r->rgba, (w ? w : 1) * sizeof *c);
    if (c)
        r->rgba = c;
    out->keys = r->keys;
    out->rgba = r->rgba;
    r->keys = NULL;
    r->rgba = NULL;
    return MS_OK;
}

ms_status ms_bake_colours_read(const char *path, const ms_quant_box *box, unsigned bits,
                               ms_bake_colours *out, bool *present, ms_error *err)
{
    memset(out, 0, sizeof *out);
    *present = false;
    reader r = {.box = box, .bits = bits};
    ms_mesh_sink sink = {.context = &r, .vertices = on_vertices, .colours = on_colours};
    ms_mesh_read_report report;
    ms_status s = ms_mesh_read(path, &sink, &report, err);
    if (s == MS_OK && report.colour) {
        if (r.coloured != r.count)
            s = ms_error_set(err, MS_ERR_FORMAT, "%s: %zu colours for %zu vertices", path,
                             r.coloured, r.count);
        if (s == MS_OK)
            s = weld(&r, out, err);
        if (s == MS_OK) {
            out->bits = bits;
            out->alpha = report.colour_alpha;
            *present = true;
        }
    }
    free(r.keys);
    free(r.rgba);
    return s;
}

void ms_bake_colours_free(ms_bake_colours *c)
{
    free(c->keys);
    free(c->rgba);
    memset(c, 0, sizeof *c);
}

/* ---- the rule of docs/COLOUR.md §1 over the model's vertices ------------- */

static size_t lower_bound(const uint64_t *keys, size_t lo, size_t hi, uint64_t key)
{
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* The rule's colour (channels reduced to c bits, packed) of the vertices
 * [lo, hi) (at least one), which share their kd prefix down to where they
 * part: a single vertex is its own colour at every level; otherwise the cell
 * where they part has two occupied halves, whose colours are floor-averaged. */
static uint32_t rule(const ms_bake_colours *t, size_t lo, size_t hi, unsigned c)
{
    if (hi - lo == 1) {
        uint32_t v = t->rgba[lo], q = 0;
        for (unsigned k = 0; k < 4; ++k)
            q |= (((v >> (8 * k)) & 0xFFu) >> (8 - c)) << (8 * k);
        return q;
    }
    uint64_t diff = t->keys[lo] ^ t->keys[hi - 1];
    unsigned top = 63;
    while (!(diff >> top))
        --top;
    uint64_t half = (t->keys[lo] >> top | 1) << top; /* first key of the upper half */
    size_t m = lower_bound(t->keys, lo, hi, half);
    uint32_t a = rule(t, lo, m, c), b = rule(t, m, hi, c), out = 0;
    for (unsigned k = 0; k < 4; ++k)
        out |= ((((a >> (8 * k)) & 0xFFu) + ((b >> (8 * k)) & 0xFFu)) / 2) << (8 * k);
    return out;
}

ms_status ms_bake_colour_of(const ms_bake_colours *t, uint64_t key, unsigned level,
                            unsigned colour_bits, uint32_t *rgba, ms_error *err)
{
    unsigned shift = 3 * t->bits - level;
    uint64_t first = key << shift, end = (key + 1) << shift;
    size_t lo = lower_bound(t->keys, 0, t->count, first);
    size_t hi = level == 0 ? t->count : lower_bound(t->keys, lo, t->count, end);
    if (lo == hi)
        return ms_error_set(err, MS_ERR_ARG, "colour: no vertex in kd-cell %llx at level %u",
                            (unsigned long long)key, level);
    uint32_t q = rule(t, lo, hi, colour_bits), out = 0;
    for (unsigned k = 0; k < 4; ++k)
        out |= (((q >> (8 * k)) & 0xFFu) << (8 - colour_bits)) << (8 * k);
    *rgba = out;
    return MS_OK;
}

/* Whether a cell's stream takes its base from its parent: not the root, and
 * every cube of the chain lies at or above its cell's first level. */
static bool base_from_parent(const ms_bake_colour_cube *chain, size_t chain_n)
{
    if (chain_n < 2)
        return false;
    for (size_t i = 0; i < chain_n; ++i)
        if (chain[i].cube_level > 3 * chain[i].lo)
            return false;
    return true;
}

ms_status ms_bake_colour_decoded(const ms_bake_colours *t, const ms_bake_colour_cube *chain,
                                 size_t chain_n, uint64_t key, unsigned level,
                                 unsigned colour_bits, uint32_t *rgba, ms_error *err)
{
    for (size_t i = 0; i + 1 < chain_n; ++i) {
        const ms_bake_colour_cube *x = &chain[i];
        if (key >> (level - x->cube_level) == x->cube)
            break; /* inside the cell's cube: its own colour */
        /* foreign: its ancestor at the cell's first level, as the parent gives it */
        key >>= level - 3 * x->lo;
        level = 3 * x->lo;
    }
    return ms_bake_colour_of(t, key, level, colour_bits, rgba, err);
}

ms_status ms_bake_colour_cell(const ms_bake_colours *t, const ms_codec_state *st,
                              const uint8_t *freeze, const ms_bake_colour_cube *chain,
                              size_t chain_n, unsigned colour_bits, uint8_t **out, size_t *size,
                              uint32_t *table, ms_error *err)
{
    *out = NULL;
    *size = 0;
    size_t n = st->vertex_count;
    if (n == 0)
        return MS_OK;
    unsigned lo = chain[0].lo;
    bool given = base_from_parent(chain, chain_n);
    if (st->level != 3 * st->bits || st->bits > t->bits || lo > st->bits)
        return ms_error_set(err, MS_ERR_ARG, "colour: a cell's complex at level %u of %u bits",
                            st->level, st->bits);
    uint64_t *cells = malloc(n * sizeof *cells);
    uint8_t *rgba = malloc(4 * n);
    ms_status s = cells && rgba ? MS_OK : ms_error_set(err, MS_ERR_NOMEM, "colour: out of memory");
    for (size_t v = 0; s == MS_OK && v < n; ++v) {
        uint32_t c = 0;
        s = given ? ms_bake_colour_decoded(t, chain, chain_n, st->cells[v], st->level, colour_bits,
                                           &c, err)
                  : ms_bake_colour_of(t, st->cells[v], st->level, colour_bits, &c, err);
        for (unsigned k = 0; k < 4; ++k)
            rgba[4 * v + k] = (uint8_t)(c >> (8 * k));
        cells[v] = st->cells[v];
        if (freeze && freeze[v] != MS_CODEC_NO_FREEZE) {
            unsigned drop = 3 * st->bits - freeze[v];
            cells[v] = st->cells[v] >> drop << drop; /* as ms_codec_decoder_state gives it */
        }
    }
    ms_codec_state coded = *st;
    coded.cells = cells;
    coded.rep = NULL;
    ms_colour_encode_params par = {
        .p_min = lo, .colour_bits = colour_bits, .alpha = t->alpha, .base_given = given};
    if (s == MS_OK)
        s = ms_colour_encode(&coded, rgba, &par, out, size, err);
    ms_colour_header h;
    if (s == MS_OK)
        s = ms_colour_read_header(*out, *size, &h, err);
    if (s == MS_OK && *size > UINT32_MAX)
        s = ms_error_set(err, MS_ERR_RANGE, "colour: a stream over 4 GiB");
    for (unsigned k = 0; s == MS_OK && k <= st->bits - lo; ++k)
        table[k] = (uint32_t)(h.header_size + h.chunk_end[k]);
    if (s != MS_OK) {
        free(*out);
        *out = NULL;
        *size = 0;
    }
    free(cells);
    free(rgba);
    return s;
}
