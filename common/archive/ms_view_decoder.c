/* View-dependent decoding of an nSP archive: see ms_view_decoder.h. */
#include "ms_view_decoder.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_codec.h"
#include "ms_nsp.h"

typedef struct vcell {
    ms_archive_cell rec;
    uint8_t state;
    uint8_t bits;           /* current precision (SHOWN), bits_max (SPLIT) */
    bool has_start;         /* start state held (non-root cells once their parent split) */
    ms_codec_state start;
    ms_codec_decoder *dec;
    size_t dec_bytes;       /* bytes the decoder was created from */
    uint8_t *bytes;
    size_t nbytes;
    /* stitching cache: the complex at `cache_bits` */
    bool cache_valid;
    uint8_t cache_bits;
    ms_codec_state cache;
    uint32_t *out_index;    /* per cache vertex: index in the stitched mesh, or NONE */
    uint32_t *owner;        /* per cache vertex: shown cell holding it, NONE = finer cells */
    uint8_t *levels;        /* per cache vertex: its kd-level, when some foreign vertex is
                             * frozen coarser than the cell (else NULL: all at its level) */
} vcell;

struct ms_view {
    ms_archive_header header;
    ms_nsp_shape shape;
    uint32_t count;
    vcell *cells;
    uint32_t stamp_epoch;
};

#define NONE 0xFFFFFFFFu
#define OWNER_FINER 0xFFFFFFFEu

static void cache_drop(vcell *c)
{
    ms_codec_state_free(&c->cache);
    free(c->out_index);
    free(c->owner);
    free(c->levels);
    c->out_index = c->owner = NULL;
    c->levels = NULL;
    c->cache_valid = false;
}

static void cell_reset(vcell *c)
{
    cache_drop(c);
    if (c->dec)
        ms_codec_decoder_destroy(c->dec);
    c->dec = NULL;
    c->dec_bytes = 0;
    ms_codec_state_free(&c->start);
    c->has_start = false;
    c->state = MS_VIEW_HIDDEN;
    c->bits = 0;
}

ms_status ms_view_create(const ms_archive_header *h, const ms_archive_cell *cells, ms_view **out,
                         ms_error *err)
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
    if (h->cell_count < 1 || h->cell_count > MS_ARCHIVE_MAX_CELLS) {
        free(v);
        return ms_error_set(err, MS_ERR_ARG, "bad cell count %u", h->cell_count);
    }
    v->count = h->cell_count;
    v->cells = calloc(v->count, sizeof *v->cells);
    if (!v->cells) {
        free(v);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory creating a view");
    }
    const uint32_t nc = h->n * h->n * h->n;
    for (uint32_t i = 0; i < v->count; ++i) {
        const ms_archive_cell *c = &cells[i];
        v->cells[i].rec = *c;
        bool ok = c->bits_min <= c->bits_max && c->bits_max <= h->bits;
        if (c->first_child != MS_ARCHIVE_NONE)
            ok = ok && c->first_child > i && c->first_child <= v->count - nc;
        if (i > 0)
            ok = ok && c->parent < i;
        if (!ok) {
            ms_view_destroy(v);
            return ms_error_set(err, MS_ERR_ARG, "cell %u: record breaks the tree rules", i);
        }
    }
    v->cells[0].state = MS_VIEW_SHOWN;
    v->cells[0].bits = v->cells[0].rec.bits_min;
    *out = v;
    return MS_OK;
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
    for (uint32_t i = 0; i < v->count; ++i) {
        cell_reset(&v->cells[i]);
        free(v->cells[i].bytes);
    }
    free(v->cells);
    free(v);
}

const ms_archive_header *ms_view_header(const ms_view *v) { return &v->header; }

uint32_t ms_view_cell_count(const ms_view *v) { return v->count; }

const ms_archive_cell *ms_view_cell(const ms_view *v, uint32_t cell)
{
    return cell < v->count ? &v->cells[cell].rec : NULL;
}

ms_view_cell_state ms_view_state(const ms_view *v, uint32_t cell)
{
    return cell < v->count ? (ms_view_cell_state)v->cells[cell].state : MS_VIEW_HIDDEN;
}

unsigned ms_view_bits(const ms_view *v, uint32_t cell)
{
    return cell < v->count ? v->cells[cell].bits : 0;
}

ms_status ms_view_set_bytes(ms_view *v, uint32_t cell, const uint8_t *data, size_t length,
                            ms_error *err)
{
    if (cell >= v->count)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u", cell);
    vcell *c = &v->cells[cell];
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
    if (cell >= v->count)
        return ms_error_set(err, MS_ERR_RANGE, "no cell %u", cell);
    vcell *c = &v->cells[cell];
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
    if (cell >= v->count || v->cells[cell].state != MS_VIEW_HIDDEN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not hidden", cell);
    vcell *c = &v->cells[cell];
    cell_reset(c);
    free(c->bytes);
    c->bytes = NULL;
    c->nbytes = 0;
    return MS_OK;
}

size_t ms_view_held_bytes(const ms_view *v, uint32_t cell)
{
    return cell < v->count ? v->cells[cell].nbytes : 0;
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
    return cell < v->count ? held_bits(&v->cells[cell]) : 0;
}

/* Makes sure the cell's decoder exists and can reach `bits` (extending it with
 * the bytes that came since, so decoding goes on from its current level). */
static ms_status ensure_decoder(ms_view *v, uint32_t cell, unsigned bits, ms_error *err)
{
    vcell *c = &v->cells[cell];
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
    if (cell >= v->count || v->cells[cell].state != MS_VIEW_SHOWN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not shown", cell);
    vcell *c = &v->cells[cell];
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
    if (cell >= v->count || v->cells[cell].state == MS_VIEW_HIDDEN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not decoded", cell);
    const vcell *c = &v->cells[cell];
    if (c->dec) {
        ms_status s = ms_codec_decoder_state(c->dec, out, err);
        if (s == MS_OK)
            s = ms_codec_state_canonicalise(out, err);
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
    if (cell >= v->count || v->cells[cell].state != MS_VIEW_SHOWN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not shown", cell);
    vcell *c = &v->cells[cell];
    if (c->rec.first_child == MS_ARCHIVE_NONE)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is a leaf", cell);
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
        vcell *ch = &v->cells[id];
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
    cache_drop(c);
    if (s != MS_OK)
        (void)ms_view_merge(v, cell, NULL);
    return s;
}

ms_status ms_view_merge(ms_view *v, uint32_t cell, ms_error *err)
{
    if (cell >= v->count || v->cells[cell].state != MS_VIEW_SPLIT)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not split", cell);
    vcell *c = &v->cells[cell];
    const unsigned nc = v->shape.n * v->shape.n * v->shape.n;
    for (unsigned k = 0; k < nc; ++k) {
        uint32_t id = c->rec.first_child + k;
        if (v->cells[id].state == MS_VIEW_SPLIT)
            (void)ms_view_merge(v, id, NULL);
        cell_reset(&v->cells[id]);
    }
    c->state = MS_VIEW_SHOWN;
    c->bits = c->rec.bits_max;
    return MS_OK;
}

/* ---- selection ------------------------------------------------------------ */

static void cell_box(const ms_view *v, const ms_archive_cell *c, double lo[3], double hi[3])
{
    double side = v->header.box_side / (double)(1u << (v->shape.log2n * c->level));
    for (int a = 0; a < 3; ++a) {
        lo[a] = v->header.box_origin[a] + side * c->position[a];
        hi[a] = lo[a] + side;
    }
}

void ms_view_select_params_default(ms_view_select_params *p)
{
    p->tolerance_px = 1.0;
    p->margin = 0.0;
    p->hysteresis = 0.5;
    p->culled_bits_less = 2.0;
    p->tolerance_scale = NULL;
}

static double cell_tolerance(const ms_view_select_params *p, uint32_t cell)
{
    return p->tolerance_scale ? p->tolerance_px * p->tolerance_scale[cell] : p->tolerance_px;
}

double ms_view_cell_need(const ms_view *v, const ms_camera *cam, uint32_t cell,
                         const ms_view_select_params *p)
{
    double lo[3], hi[3];
    cell_box(v, &v->cells[cell].rec, lo, hi);
    ms_frustum f;
    ms_camera_frustum(cam, &f);
    if (!ms_frustum_keeps_box(&f, lo, hi, p->margin))
        return -1.0;
    double d = ms_camera_box_distance(cam, lo, hi);
    return ms_screen_bits_needed(cam, v->header.box_side, d, cell_tolerance(p, cell));
}

static void select_cell(const ms_view *v, const ms_camera *cam, const ms_frustum *f,
                        const ms_view_select_params *p, uint32_t cell, uint8_t *target)
{
    const vcell *c = &v->cells[cell];
    double lo[3], hi[3];
    cell_box(v, &c->rec, lo, hi);
    double need = ms_screen_bits_needed(cam, v->header.box_side,
                                        ms_camera_box_distance(cam, lo, hi),
                                        cell_tolerance(p, cell));
    if (!ms_frustum_keeps_box(f, lo, hi, p->margin))
        need -= p->culled_bits_less;
    unsigned current = c->state == MS_VIEW_SHOWN ? c->bits
                       : c->state == MS_VIEW_SPLIT ? c->rec.bits_max + 1u
                                                   : c->rec.bits_min;
    if (current > v->header.bits)
        current = v->header.bits;
    unsigned want = ms_select_bits(need, current, c->rec.bits_min, v->header.bits, p->hysteresis);
    if (want > c->rec.bits_max && c->rec.first_child != MS_ARCHIVE_NONE) {
        target[cell] = MS_VIEW_TARGET_SPLIT;
        const unsigned nc = v->shape.n * v->shape.n * v->shape.n;
        for (unsigned k = 0; k < nc; ++k)
            select_cell(v, cam, f, p, c->rec.first_child + k, target);
        return;
    }
    target[cell] = (uint8_t)(want > c->rec.bits_max ? c->rec.bits_max : want);
}

void ms_view_select(const ms_view *v, const ms_camera *cam, const ms_view_select_params *p,
                    uint8_t *target)
{
    memset(target, MS_VIEW_TARGET_HIDDEN, v->count);
    ms_frustum f;
    ms_camera_frustum(cam, &f);
    select_cell(v, cam, &f, p, 0, target);
}

static ms_status apply_cell(ms_view *v, uint32_t cell, const uint8_t *target,
                            ms_view_apply_report *r, ms_error *err)
{
    vcell *c = &v->cells[cell];
    uint8_t t = target[cell];
    ms_status s;
    if (t == MS_VIEW_TARGET_SPLIT && c->rec.first_child != MS_ARCHIVE_NONE) {
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
        const unsigned nc = v->shape.n * v->shape.n * v->shape.n;
        for (unsigned k = 0; k < nc; ++k)
            if ((s = apply_cell(v, c->rec.first_child + k, target, r, err)) != MS_OK)
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

ms_status ms_view_apply(ms_view *v, const uint8_t *target, ms_view_apply_report *report,
                        ms_error *err)
{
    ms_view_apply_report r;
    memset(&r, 0, sizeof r);
    ms_status s = apply_cell(v, 0, target, &r, err);
    if (report)
        *report = r;
    return s;
}

/* ---- stitching ------------------------------------------------------------ */

void ms_view_mesh_free(ms_view_mesh *m)
{
    if (!m)
        return;
    free(m->positions);
    free(m->keys);
    free(m->levels);
    free(m->triangles);
    free(m->triangle_cell);
    memset(m, 0, sizeof *m);
}

static ms_status refresh_cache(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = &v->cells[cell];
    if (c->cache_valid && c->cache_bits == c->bits)
        return MS_OK;
    cache_drop(c);
    ms_status s = ms_view_cell_state_copy(v, cell, &c->cache, err);
    if (s != MS_OK)
        return s;
    size_t n = c->cache.vertex_count;
    c->out_index = malloc((n ? n : 1) * sizeof *c->out_index);
    c->owner = malloc((n ? n : 1) * sizeof *c->owner);
    if (!c->out_index || !c->owner) {
        cache_drop(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    if (c->dec) {
        if (ms_codec_decoder_vertex_count(c->dec) != n) {
            cache_drop(c);
            return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: state and decoder disagree", cell);
        }
        c->levels = malloc(n ? n : 1);
        if (!c->levels) {
            cache_drop(c);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        }
        if (ms_codec_decoder_vertex_levels(c->dec, c->levels) == 0) {
            free(c->levels);
            c->levels = NULL;
        }
    }
    c->cache_valid = true;
    c->cache_bits = c->bits;
    return MS_OK;
}

/* The shown cell holding kd-cell (prefix, level), or OWNER_FINER when the kd-cell
 * spans several shown cells (all finer than `level`). */
static uint32_t owner_of(const ms_view *v, uint64_t prefix, unsigned level)
{
    uint32_t xyz[3];
    ms_nsp_prefix_corner(&v->shape, prefix, level, xyz);
    uint32_t cell = 0;
    while (v->cells[cell].state == MS_VIEW_SPLIT) {
        const ms_archive_cell *r = &v->cells[cell].rec;
        if (level < 3u * (r->level + 1u) * v->shape.log2n)
            return OWNER_FINER;
        cell = r->first_child + ms_nsp_child_offset(&v->shape, r->level, xyz);
    }
    return cell;
}

/* The vertex of s lying inside kd-cell `prefix` of level s->level - coarser (the
 * first, and for a frozen foreign cell's lone kd-cell the only, one), or NONE;
 * coarser = 0: the vertex that is that kd-cell. */
static uint32_t find_inside(const ms_codec_state *s, uint64_t prefix, unsigned coarser)
{
    uint64_t first = prefix << coarser;
    size_t lo = 0, hi = s->vertex_count;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (s->cells[mid] < first)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo < s->vertex_count && s->cells[lo] >> coarser == prefix ? (uint32_t)lo : NONE;
}

static size_t grown(size_t cap, size_t need)
{
    size_t c = cap ? cap : 1024;
    while (c < need)
        c *= 2;
    return c;
}

static ms_status mesh_room(ms_view_mesh *m, size_t vertices, size_t triangles, ms_error *err)
{
    if (vertices > m->vertex_cap) {
        size_t c = grown(m->vertex_cap, vertices);
        double *p = realloc(m->positions, 3 * c * sizeof *p);
        if (p)
            m->positions = p;
        uint64_t *k = realloc(m->keys, c * sizeof *k);
        if (k)
            m->keys = k;
        uint8_t *l = realloc(m->levels, c);
        if (l)
            m->levels = l;
        if (!p || !k || !l)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        m->vertex_cap = c;
    }
    if (triangles > m->triangle_cap) {
        size_t c = grown(m->triangle_cap, triangles);
        uint32_t *t = realloc(m->triangles, 3 * c * sizeof *t);
        if (t)
            m->triangles = t;
        uint32_t *tc = realloc(m->triangle_cell, c * sizeof *tc);
        if (tc)
            m->triangle_cell = tc;
        if (!t || !tc)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        m->triangle_cap = c;
    }
    return MS_OK;
}

/* Output index of vertex i of cell `cell`'s cache, adding it on first use. */
static ms_status out_vertex(ms_view *v, ms_view_mesh *m, uint32_t cell, uint32_t i, uint32_t *out,
                            ms_error *err)
{
    vcell *c = &v->cells[cell];
    if (c->out_index[i] != NONE) {
        *out = c->out_index[i];
        return MS_OK;
    }
    ms_status s = mesh_room(m, m->vertex_count + 1, 0, err);
    if (s != MS_OK)
        return s;
    size_t k = m->vertex_count++;
    unsigned level = c->cache.level;
    uint64_t prefix = c->cache.cells[i];
    uint32_t xyz[3];
    ms_nsp_prefix_corner(&v->shape, prefix, level, xyz);
    const unsigned p = v->shape.bits;
    double unit = v->header.box_side / (double)(1u << p);
    for (int a = 0; a < 3; ++a) {
        unsigned axis_bits = (level + 2u - (unsigned)a) / 3u;
        double width = (double)(1u << (p - axis_bits));
        m->positions[3 * k + (size_t)a] =
            v->header.box_origin[a] + ((double)xyz[a] + 0.5 * width) * unit;
    }
    unsigned shift = 3 * p - level;
    m->keys[k] = shift >= 64 ? 0 : prefix << shift;
    m->levels[k] = (uint8_t)level;
    c->out_index[i] = (uint32_t)k;
    *out = (uint32_t)k;
    return MS_OK;
}

typedef struct snapped_tri {
    uint32_t s[3]; /* sorted output vertex indices */
    uint32_t at;   /* position in the output */
} snapped_tri;

static int cmp_snapped(const void *x, const void *y)
{
    const snapped_tri *a = x, *b = y;
    for (int i = 0; i < 3; ++i)
        if (a->s[i] != b->s[i])
            return a->s[i] < b->s[i] ? -1 : 1;
    return a->at < b->at ? -1 : (a->at > b->at);
}

/* Two triangles of one cell, distinct at its precision, may become the same
 * triangle once their vertices in coarser neighbours snap (triangles of different
 * cells never can: each keeps a vertex of its own cell, and the precision rule
 * lets only one of two cells draw). Keeps the first of each such group. */
static ms_status drop_snapped_repeats(ms_view_mesh *m, size_t first, const uint8_t *snapped,
                                      ms_error *err)
{
    size_t n = 0;
    for (size_t t = first; t < m->triangle_count; ++t)
        n += snapped[t - first];
    if (n < 2)
        return MS_OK;
    snapped_tri *a = malloc(n * sizeof *a);
    uint8_t *drop = calloc(m->triangle_count - first, 1);
    if (!a || !drop) {
        free(a);
        free(drop);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    n = 0;
    for (size_t t = first; t < m->triangle_count; ++t) {
        if (!snapped[t - first])
            continue;
        uint32_t x = m->triangles[3 * t], y = m->triangles[3 * t + 1], z = m->triangles[3 * t + 2], w;
        if (x > y)
            w = x, x = y, y = w;
        if (y > z)
            w = y, y = z, z = w;
        if (x > y)
            w = x, x = y, y = w;
        a[n++] = (snapped_tri){{x, y, z}, (uint32_t)(t - first)};
    }
    qsort(a, n, sizeof *a, cmp_snapped);
    for (size_t i = 1; i < n; ++i)
        if (memcmp(a[i].s, a[i - 1].s, sizeof a[i].s) == 0)
            drop[a[i].at] = 1;
    size_t w = first;
    for (size_t t = first; t < m->triangle_count; ++t) {
        if (drop[t - first]) {
            m->dropped_snapped++;
            continue;
        }
        if (w != t) {
            memcpy(&m->triangles[3 * w], &m->triangles[3 * t], 12);
            m->triangle_cell[w] = m->triangle_cell[t];
        }
        w++;
    }
    m->triangle_count = w;
    free(a);
    free(drop);
    return MS_OK;
}

ms_status ms_view_stitch(ms_view *v, const bool *visible, ms_view_mesh *m, ms_error *err)
{
    uint8_t *snapped = NULL;
    size_t snapped_cap = 0;
    m->vertex_count = m->triangle_count = 0;
    m->dropped_finer = m->dropped_snapped = m->unresolved = m->snapped_frozen = 0;
    ms_status s = MS_OK;
    /* Caches and owners of every shown cell. */
    for (uint32_t id = 0; id < v->count && s == MS_OK; ++id) {
        vcell *c = &v->cells[id];
        if (c->state != MS_VIEW_SHOWN)
            continue;
        if ((s = refresh_cache(v, id, err)) != MS_OK)
            break;
        for (size_t i = 0; i < c->cache.vertex_count; ++i) {
            c->out_index[i] = NONE;
            c->owner[i] = owner_of(v, c->cache.cells[i], c->cache.level);
        }
    }
    for (uint32_t id = 0; id < v->count && s == MS_OK; ++id) {
        vcell *c = &v->cells[id];
        if (c->state != MS_VIEW_SHOWN || (visible && !visible[id]))
            continue;
        const unsigned Lc = c->cache.level;
        const size_t first = m->triangle_count;
        if (c->cache.tri_count > snapped_cap) {
            uint8_t *p = realloc(snapped, c->cache.tri_count);
            if (!p) {
                s = ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
                break;
            }
            snapped = p;
            snapped_cap = c->cache.tri_count;
        }
        for (size_t i = 0; i < c->cache.vertex_count && s == MS_OK; ++i)
            if (c->owner[i] == id) {
                uint32_t dummy;
                s = out_vertex(v, m, id, (uint32_t)i, &dummy, err);
            }
        for (size_t t = 0; t < c->cache.tri_count && s == MS_OK; ++t) {
            const uint32_t *x = &c->cache.tris[3 * t];
            uint32_t idx[3];
            bool keep = true, moved = false;
            for (int j = 0; j < 3 && keep; ++j) {
                uint32_t o = c->owner[x[j]];
                if (o == OWNER_FINER) {
                    keep = false;
                    m->dropped_finer++;
                    break;
                }
                if (o == id) {
                    if ((s = out_vertex(v, m, id, x[j], &idx[j], err)) != MS_OK)
                        break;
                    continue;
                }
                vcell *oc = &v->cells[o];
                unsigned Lo = oc->cache.level;
                if (Lo > Lc || (Lo == Lc && o > id)) {
                    keep = false;
                    m->dropped_finer++;
                    break;
                }
                /* a frozen foreign vertex is known only to its lone kd-cell (level
                 * lx): the holder's vertex inside it is the one it stands for */
                unsigned lx = c->levels ? c->levels[x[j]] : Lc, at = lx < Lo ? lx : Lo;
                uint32_t k = find_inside(&oc->cache, c->cache.cells[x[j]] >> (Lc - at), Lo - at);
                if (k == NONE) {
                    keep = false;
                    m->unresolved++;
                    break;
                }
                m->snapped_frozen += lx < Lo;
                if ((s = out_vertex(v, m, o, k, &idx[j], err)) != MS_OK)
                    break;
                moved = true;
            }
            if (s != MS_OK || !keep)
                continue;
            if (idx[0] == idx[1] || idx[1] == idx[2] || idx[0] == idx[2]) {
                m->dropped_snapped++;
                continue;
            }
            if ((s = mesh_room(m, 0, m->triangle_count + 1, err)) != MS_OK)
                break;
            memcpy(&m->triangles[3 * m->triangle_count], idx, sizeof idx);
            m->triangle_cell[m->triangle_count] = id;
            snapped[m->triangle_count - first] = moved;
            m->triangle_count++;
        }
        if (s == MS_OK)
            s = drop_snapped_repeats(m, first, snapped, err);
    }
    free(snapped);
    return s;
}
