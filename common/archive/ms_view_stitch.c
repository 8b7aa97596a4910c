/* The view decoder's stitching: the shown cells' complexes as one mesh
 * (ms_view_stitch, ms_view_decoder.h). */
#include <stdlib.h>
#include <string.h>

#include "ms_grow.h"
#include "ms_view_decoder_internal.h"

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
    free(m->colours);
    free(m->run_cell);
    free(m->run_first);
    free(m->run_version);
    memset(m, 0, sizeof *m);
}

/* Kd-cell (prefix, level) on the model's grid: its corner and its width on
 * each axis, in grid units of box_side / 2^p. Kd-level l halves axis l mod 3,
 * so after `level` levels axis a is cut (level + 2 - a) / 3 times. */
static void kd_cell_grid(const ms_view *v, uint64_t prefix, unsigned level, uint32_t xyz[3],
                         uint32_t width[3])
{
    ms_nsp_prefix_corner(&v->shape, prefix, level, xyz);
    for (int a = 0; a < 3; ++a)
        width[a] = 1u << (v->shape.bits - (level + 2u - (unsigned)a) / 3u);
}

/* The point the stream draws for vertex i of the cell's cache (geometry
 * ahead), else its kd-cell's centre, world units. */
static void vertex_position(const ms_view *v, const vcell *c, size_t i, double out[3])
{
    uint32_t xyz[3], width[3];
    kd_cell_grid(v, c->cache.cells[i], c->cache.level, xyz, width);
    double unit = v->header.box_side / (double)(1u << v->shape.bits);
    const uint16_t *rep = c->cache.rep ? &c->cache.rep[3 * i] : NULL;
    for (int a = 0; a < 3; ++a)
        out[a] = v->header.box_origin[a] + ((double)xyz[a] + (rep ? rep[a] / 65536.0 : 0.5) * width[a]) * unit;
}

static ms_status refresh_cache(ms_view *v, uint32_t cell, ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (c->cache_valid && c->cache_bits == c->bits)
        return MS_OK;
    ms_view_cache_drop(c);
    ms_status s = ms_view_cell_state_copy(v, cell, &c->cache, err);
    /* below the archive's smoothing precision a vertex is drawn at its
     * smoothed point (docs/CODEC.md §4.4), never at full precision */
    if (s == MS_OK && v->header.smooth_rounds > 0 && c->cache.level < 3u * v->header.smooth_bits)
        s = ms_codec_state_smooth(&c->cache, v->header.smooth_rounds, err);
    if (s != MS_OK) {
        ms_view_cache_drop(c);
        return s;
    }
    size_t n = c->cache.vertex_count;
    c->out_index = malloc((n ? n : 1) * sizeof *c->out_index);
    c->owner = malloc((n ? n : 1) * sizeof *c->owner);
    c->positions = malloc(3 * (n ? n : 1) * sizeof *c->positions);
    if (!c->out_index || !c->owner || !c->positions) {
        ms_view_cache_drop(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    for (size_t i = 0; i < n; ++i)
        vertex_position(v, c, i, &c->positions[3 * i]);
    if (c->dec) {
        if (ms_codec_decoder_vertex_count(c->dec) != n) {
            ms_view_cache_drop(c);
            return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: state and decoder disagree", cell);
        }
        c->levels = malloc(n ? n : 1);
        if (!c->levels) {
            ms_view_cache_drop(c);
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
 * spans several shown cells (all finer than `level`); *end: the cell the walk
 * down from the root stopped at (the owner, or the split cell too coarse). */
static uint32_t owner_of(const ms_view *v, uint64_t prefix, unsigned level, uint32_t *end)
{
    uint32_t xyz[3];
    ms_nsp_prefix_corner(&v->shape, prefix, level, xyz);
    uint32_t cell = 0;
    const vcell *at;
    while ((at = ms_view_vcell(v, cell)) != NULL && at->state == MS_VIEW_SPLIT) {
        const ms_archive_cell *r = &at->rec;
        if (level < 3u * (r->level + 1u) * v->shape.log2n) {
            *end = cell;
            return OWNER_FINER;
        }
        cell = r->first_child + ms_nsp_child_offset(&v->shape, r->level, xyz);
    }
    *end = cell;
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
        uint8_t *rgba = m->colours ? realloc(m->colours, 4 * c) : NULL;
        if (rgba)
            m->colours = rgba;
        if (!p || !k || !l || (m->colours && !rgba))
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

ms_status ms_view_cell_bounds(ms_view *v, uint32_t cell, double lo[3], double hi[3],
                              ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state == MS_VIEW_HIDDEN)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not decoded", cell);
    ms_status s = refresh_cache(v, cell, err);
    if (s != MS_OK)
        return s;
    if (c->cache.vertex_count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "cell %u holds no vertex", cell);
    /* the cache is sorted by prefix: its first and last vertices are not the
     * extremes on every axis, so every vertex is looked at */
    uint64_t q_lo[3], q_hi[3]; /* grid units: exact */
    for (size_t i = 0; i < c->cache.vertex_count; ++i) {
        uint32_t xyz[3], width[3];
        kd_cell_grid(v, c->cache.cells[i], c->cache.level, xyz, width);
        for (int a = 0; a < 3; ++a) {
            uint64_t b = (uint64_t)xyz[a] + width[a];
            q_lo[a] = i && q_lo[a] < xyz[a] ? q_lo[a] : xyz[a];
            q_hi[a] = i && q_hi[a] > b ? q_hi[a] : b;
        }
    }
    double unit = v->header.box_side / (double)(1u << v->shape.bits);
    for (int a = 0; a < 3; ++a) {
        lo[a] = v->header.box_origin[a] + (double)q_lo[a] * unit;
        hi[a] = v->header.box_origin[a] + (double)q_hi[a] * unit;
    }
    return MS_OK;
}

/* Output index of vertex i of cell `cell`'s cache, adding it on first use. */
static ms_status out_vertex(ms_view *v, ms_view_mesh *m, uint32_t cell, uint32_t i, uint32_t *out,
                            ms_error *err)
{
    vcell *c = ms_view_vcell(v, cell);
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
    memcpy(&m->positions[3 * k], &c->positions[3 * (size_t)i], 3 * sizeof *m->positions);
    unsigned shift = 3 * v->shape.bits - level;
    m->keys[k] = shift >= 64 ? 0 : prefix << shift;
    m->levels[k] = (uint8_t)level;
    if (m->colours) {
        /* A cell without its colour yet draws in the renderers' default grey
         * (sRGB of meshview's and meshrender's albedo 0.72 0.69 0.64), as the
         * model looked before colour: no white flash while a stream arrives. */
        static const uint8_t pending[4] = {221, 216, 209, 255};
        memcpy(&m->colours[4 * k],
               ms_view_colour_ready(c) ? &c->cache_colours[4 * (size_t)i] : pending, 4);
    }
    c->out_index[i] = (uint32_t)k;
    *out = (uint32_t)k;
    return MS_OK;
}

typedef struct snapped_tri {
    uint64_t s[3]; /* its corners' vertices (cell, cache vertex), sorted */
    uint32_t at;   /* its place among the piece's triangles */
} snapped_tri;

static int cmp_snapped(const void *x, const void *y)
{
    const snapped_tri *a = x, *b = y;
    for (int i = 0; i < 3; ++i)
        if (a->s[i] != b->s[i])
            return a->s[i] < b->s[i] ? -1 : 1;
    return a->at < b->at ? -1 : (a->at > b->at);
}

/* The vertex a piece's corner stands for: (cell, cache vertex) as one word. */
static uint64_t corner_vertex(const vpiece *p, uint32_t cell, size_t own, uint32_t r)
{
    if (r < own)
        return (uint64_t)cell << 32 | r;
    const uint32_t *call = &p->calls[2 * (size_t)(r - own)];
    return (uint64_t)call[0] << 32 | call[1];
}

/* Two triangles of one cell, distinct at its precision, may become the same
 * triangle once their vertices in coarser neighbours snap (triangles of different
 * cells never can: each keeps a vertex of its own cell, and the precision rule
 * lets only one of two cells draw). Keeps the first of each such group. */
static ms_status drop_snapped_repeats(vpiece *p, uint32_t cell, size_t own, const uint8_t *snapped,
                                      ms_error *err)
{
    size_t n = 0;
    for (size_t t = 0; t < p->tri_count; ++t)
        n += snapped[t];
    if (n < 2)
        return MS_OK;
    snapped_tri *a = malloc(n * sizeof *a);
    uint8_t *drop = calloc(p->tri_count, 1);
    if (!a || !drop) {
        free(a);
        free(drop);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    n = 0;
    for (size_t t = 0; t < p->tri_count; ++t) {
        if (!snapped[t])
            continue;
        uint64_t x = corner_vertex(p, cell, own, p->corners[3 * t]),
                 y = corner_vertex(p, cell, own, p->corners[3 * t + 1]),
                 z = corner_vertex(p, cell, own, p->corners[3 * t + 2]), w;
        if (x > y)
            w = x, x = y, y = w;
        if (y > z)
            w = y, y = z, z = w;
        if (x > y)
            w = x, x = y, y = w;
        a[n++] = (snapped_tri){{x, y, z}, (uint32_t)t};
    }
    qsort(a, n, sizeof *a, cmp_snapped);
    for (size_t i = 1; i < n; ++i)
        if (memcmp(a[i].s, a[i - 1].s, sizeof a[i].s) == 0)
            drop[a[i].at] = 1;
    size_t w = 0;
    for (size_t t = 0; t < p->tri_count; ++t) {
        if (drop[t]) {
            p->dropped_snapped++;
            continue;
        }
        if (w != t)
            memcpy(&p->corners[3 * w], &p->corners[3 * t], 3 * sizeof *p->corners);
        w++;
    }
    p->tri_count = w;
    free(a);
    free(drop);
    return MS_OK;
}

/* One step of the run versions' hash (ms_view_mesh.run_version). */
static uint64_t version_mix(uint64_t h, uint64_t cell, uint64_t stamp)
{
    h = (h ^ cell) * 0x9E3779B97F4A7C15ull;
    h ^= h >> 29;
    h = (h ^ stamp) * 0xBF58476D1CE4E5B9ull;
    return h ^ h >> 32;
}

/* The running version of a cell's triangles: each cell looked at, with what
 * of it was used (its stamp; or only its level, a tag above any stamp; or
 * only that it is split too coarse), once per run of equal notes, each note
 * kept in the piece (what makes it valid again). */
typedef struct dep_note {
    uint64_t version;
    uint32_t cell;
    uint64_t word;
} dep_note;

#define DEP_FINER (UINT64_MAX - 255u)
#define DEP_LEVEL (UINT64_MAX - 254u)

static bool note_dep(vpiece *p, dep_note *d, uint32_t cell, uint64_t word)
{
    if (cell == d->cell && word == d->word)
        return true;
    d->cell = cell;
    d->word = word;
    d->version = version_mix(d->version, cell, word);
    if (!ms_grow((void **)&p->deps, &p->dep_cap, p->dep_count + 1, sizeof *p->deps))
        return false;
    p->deps[p->dep_count++] = (vpiece_dep){cell, word};
    return true;
}

void ms_view_piece_free(vcell *c)
{
    if (!c->piece)
        return;
    free(c->piece->corners);
    free(c->piece->calls);
    free(c->piece->deps);
    free(c->piece);
    c->piece = NULL;
}

void ms_view_pieces_forget(ms_view *v)
{
    for (uint32_t id = 0; id != MS_ARCHIVE_NONE; id = ms_view_next_known(v, id))
        ms_view_piece_free(ms_view_vcell(v, id));
}

/* Whether cell's kept piece still holds: every cell it looked at says what it
 * said then (a stamp the same; still shown at that level; still split). The
 * cell's own stamp is its first note's. */
static bool piece_valid(const ms_view *v, const vcell *c)
{
    const vpiece *p = c->piece;
    if (!p)
        return false;
    for (size_t i = 0; i < p->dep_count; ++i) {
        const vcell *o = ms_view_vcell(v, p->deps[i].cell);
        uint64_t w = p->deps[i].word;
        if (!o)
            return false;
        if (w == DEP_FINER) {
            if (o->state != MS_VIEW_SPLIT)
                return false;
        } else if (w >= DEP_LEVEL) {
            if (o->state != MS_VIEW_SHOWN || !o->cache_valid || o->cache.level != (unsigned)(w - DEP_LEVEL))
                return false;
        } else if (o->stamp != w || o->state != MS_VIEW_SHOWN) {
            return false;
        }
    }
    return true;
}

/* Works out cell id's triangles again into its piece: which are drawn, their
 * corners snapped to the neighbours' representatives, repeats dropped; the
 * version of the notes made. Needs every shown cell's cache and the cell's
 * owners. */
static ms_status make_piece(ms_view *v, uint32_t id, vcell *c, uint8_t **snapped, size_t *snapped_cap,
                            ms_error *err)
{
    if (!c->piece && !(c->piece = calloc(1, sizeof *c->piece)))
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    vpiece *p = c->piece;
    p->tri_count = p->call_count = p->dep_count = 0;
    p->dropped_finer = p->dropped_snapped = p->unresolved = p->snapped_frozen = 0;
    const unsigned Lc = c->cache.level;
    const size_t own = c->cache.vertex_count;
    if (own >= NONE / 2)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u: too many vertices to stitch", id);
    if (c->cache.tri_count > *snapped_cap) {
        uint8_t *q = realloc(*snapped, c->cache.tri_count);
        if (!q)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        *snapped = q;
        *snapped_cap = c->cache.tri_count;
    }
    /* the triangles' version: the cell's stamp and those of the cells each
     * corner's owner lookup ended at, as far as the loop below looks (what
     * it does depends on nothing else) */
    dep_note dep = {version_mix(0x243F6A8885A308D3ull, id, c->stamp), NONE, 0};
    bool room = ms_grow((void **)&p->deps, &p->dep_cap, 1, sizeof *p->deps);
    if (room)
        p->deps[p->dep_count++] = (vpiece_dep){id, c->stamp};
    for (size_t t = 0; t < c->cache.tri_count && room; ++t) {
        const uint32_t *x = &c->cache.tris[3 * t];
        uint32_t r[3];
        uint64_t vert[3];
        bool keep = true, moved = false;
        for (int j = 0; j < 3 && keep && room; ++j) {
            uint32_t o = c->owner[x[j]];
            if (o == OWNER_FINER) { /* depends only on the cells split above */
                uint32_t end = o;
                (void)owner_of(v, c->cache.cells[x[j]], Lc, &end);
                room = note_dep(p, &dep, end, DEP_FINER);
                keep = false;
                p->dropped_finer++;
                break;
            }
            if (o == id) {
                r[j] = x[j];
                vert[j] = (uint64_t)id << 32 | x[j];
                continue;
            }
            vcell *oc = ms_view_vcell(v, o);
            unsigned Lo = oc->cache.level;
            if (Lo > Lc || (Lo == Lc && o > id)) { /* depends only on its level */
                room = note_dep(p, &dep, o, DEP_LEVEL + Lo);
                keep = false;
                p->dropped_finer++;
                break;
            }
            room = note_dep(p, &dep, o, oc->stamp); /* its vertices: its whole state */
            /* a frozen foreign vertex is known only to its lone kd-cell (level
             * lx): the holder's vertex inside it is the one it stands for */
            unsigned lx = c->levels ? c->levels[x[j]] : Lc, at = lx < Lo ? lx : Lo;
            uint32_t k = find_inside(&oc->cache, c->cache.cells[x[j]] >> (Lc - at), Lo - at);
            if (k == NONE) {
                keep = false;
                p->unresolved++;
                break;
            }
            p->snapped_frozen += lx < Lo;
            /* the vertex goes out here, drawn or not (as the stitch asks for it) */
            if (!(room = room && ms_grow((void **)&p->calls, &p->call_cap, 2 * (p->call_count + 1),
                                            sizeof *p->calls)))
                break;
            p->calls[2 * p->call_count] = o;
            p->calls[2 * p->call_count + 1] = k;
            r[j] = (uint32_t)(own + p->call_count++);
            vert[j] = (uint64_t)o << 32 | k;
            moved = true;
        }
        if (!room || !keep)
            continue;
        if (vert[0] == vert[1] || vert[1] == vert[2] || vert[0] == vert[2]) {
            p->dropped_snapped++;
            continue;
        }
        if (!(room = ms_grow((void **)&p->corners, &p->tri_cap, 3 * (p->tri_count + 1), sizeof *p->corners)))
            break;
        memcpy(&p->corners[3 * p->tri_count], r, sizeof r);
        (*snapped)[p->tri_count++] = moved;
    }
    if (!room) {
        ms_view_piece_free(c);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    p->version = dep.version;
    ms_status s = drop_snapped_repeats(p, id, own, *snapped, err);
    if (s != MS_OK)
        ms_view_piece_free(c);
    return s;
}

/* Appends cell's run (its triangles from first on) to the mesh's runs. */
static ms_status add_run(ms_view_mesh *m, uint32_t cell, size_t first, uint64_t version, ms_error *err)
{
    if (m->run_count + 2 > m->run_cap) {
        size_t c = grown(m->run_cap, m->run_count + 2);
        uint32_t *ids = realloc(m->run_cell, c * sizeof *ids);
        if (ids)
            m->run_cell = ids;
        uint32_t *starts = realloc(m->run_first, c * sizeof *starts);
        if (starts)
            m->run_first = starts;
        uint64_t *versions = realloc(m->run_version, c * sizeof *versions);
        if (versions)
            m->run_version = versions;
        if (!ids || !starts || !versions)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        m->run_cap = c;
    }
    m->run_cell[m->run_count] = cell;
    m->run_first[m->run_count] = (uint32_t)first;
    m->run_version[m->run_count++] = version;
    m->run_first[m->run_count] = (uint32_t)m->triangle_count;
    return MS_OK;
}

/* Cell id's piece into the mesh: its own vertices, then the neighbours'
 * vertices in the order the stitch asked for them, then its triangles. */
static ms_status put_piece(ms_view *v, ms_view_mesh *m, uint32_t id, vcell *c, ms_error *err)
{
    const vpiece *p = c->piece;
    const size_t own = c->cache.vertex_count, first = m->triangle_count;
    ms_status s = MS_OK;
    uint32_t dummy;
    for (size_t i = 0; i < own && s == MS_OK; ++i)
        if (c->owner[i] == id)
            s = out_vertex(v, m, id, (uint32_t)i, &dummy, err);
    for (size_t i = 0; i < p->call_count && s == MS_OK; ++i)
        s = out_vertex(v, m, p->calls[2 * i], p->calls[2 * i + 1], &dummy, err);
    if (s == MS_OK)
        s = mesh_room(m, 0, first + p->tri_count, err);
    if (s != MS_OK)
        return s;
    for (size_t t = 0; t < p->tri_count; ++t) {
        uint32_t *out = &m->triangles[3 * (first + t)];
        for (int j = 0; j < 3; ++j) {
            uint32_t r = p->corners[3 * t + (size_t)j];
            if (r < own) {
                out[j] = c->out_index[r];
            } else {
                const uint32_t *call = &p->calls[2 * (size_t)(r - own)];
                out[j] = ms_view_vcell(v, call[0])->out_index[call[1]];
            }
        }
        m->triangle_cell[first + t] = id;
    }
    m->triangle_count = first + p->tri_count;
    m->dropped_finer += p->dropped_finer;
    m->dropped_snapped += p->dropped_snapped;
    m->unresolved += p->unresolved;
    m->snapped_frozen += p->snapped_frozen;
    return add_run(m, id, first, p->version, err);
}

/* A new stamp for every cell whose state, precision or colour bytes changed
 * since the last stitch (a cell whose group was freed and made again starts
 * hidden at 0 bits with stamp 0, so it gets one as soon as it differs). */
static void renew_stamps(ms_view *v)
{
    for (uint32_t id = 0; id != MS_ARCHIVE_NONE; id = ms_view_next_known(v, id)) {
        vcell *c = ms_view_vcell(v, id);
        if (c && (c->state != c->stitched_state || c->bits != c->stitched_bits ||
                  c->colour_rev != c->stitched_colour_rev)) {
            c->stitched_state = c->state;
            c->stitched_bits = c->bits;
            c->stitched_colour_rev = c->colour_rev;
            c->stamp = ++v->stitch_stamps;
        }
    }
}

/* Colours per vertex when some shown cell has its colour (docs/COLOUR.md §1:
 * each vertex its kd-cell's colour at the colour decoded), else NULL; the
 * array follows vertex_cap (mesh_room). */
static ms_status colour_room(ms_view_mesh *m, bool coloured, ms_error *err)
{
    if (!coloured) {
        free(m->colours);
        m->colours = NULL;
    } else if (!m->colours && !(m->colours = malloc(4 * (m->vertex_cap ? m->vertex_cap : 1)))) {
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    return MS_OK;
}

/* Each shown cell drawn is worked out again only when its kept piece no
 * longer holds (piece_valid): then its owners are looked up and its
 * triangles walked; the mesh is then put together from the pieces in cell
 * order, as one walk of every cell would have made it. */
void ms_view_set_pool(ms_view *v, ms_pool *pool)
{
    v->pool = pool;
}

/* The stitch's per-cell steps on the pool: the listed cells, each job its own
 * status and error (the first failure in the list's order is the stitch's). */
typedef struct stitch_jobs {
    ms_view *v;
    const uint32_t *cells;
    ms_status *status;
    ms_error *errors;
} stitch_jobs;

static void cache_job(void *ctx, size_t k)
{
    stitch_jobs *j = ctx;
    j->status[k] = refresh_cache(j->v, j->cells[k], &j->errors[k]);
}

static void piece_job(void *ctx, size_t k)
{
    stitch_jobs *j = ctx;
    uint32_t id = j->cells[k];
    vcell *c = ms_view_vcell(j->v, id);
    for (size_t i = 0; i < c->cache.vertex_count; ++i) {
        uint32_t end;
        c->owner[i] = owner_of(j->v, c->cache.cells[i], c->cache.level, &end);
    }
    uint8_t *snapped = NULL;
    size_t snapped_cap = 0;
    j->status[k] = make_piece(j->v, id, c, &snapped, &snapped_cap, &j->errors[k]);
    free(snapped);
}

/* Runs fn over cells[0, count) on the view's pool; the first failure. */
static ms_status stitch_run(ms_view *v, const uint32_t *cells, size_t count, ms_parallel_fn fn,
                            ms_error *err)
{
    if (count == 0)
        return MS_OK;
    stitch_jobs j = {v, cells, malloc(count * sizeof *j.status), malloc(count * sizeof *j.errors)};
    if (!j.status || !j.errors) {
        free(j.status);
        free(j.errors);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
    }
    if (v->pool)
        ms_pool_for(v->pool, count, fn, &j);
    else
        for (size_t k = 0; k < count; ++k)
            fn(&j, k);
    ms_status s = MS_OK;
    for (size_t k = 0; k < count && s == MS_OK; ++k)
        if ((s = j.status[k]) != MS_OK)
            *err = j.errors[k];
    free(j.status);
    free(j.errors);
    return s;
}

ms_status ms_view_stitch(ms_view *v, const bool *visible, ms_view_mesh *m, ms_error *err)
{
    m->vertex_count = m->triangle_count = 0;
    m->dropped_finer = m->dropped_snapped = m->unresolved = m->snapped_frozen = 0;
    m->cells_stitched = m->triangles_stitched = 0;
    m->run_count = 0;
    /* the shown cells, ascending */
    uint32_t *cells = NULL;
    size_t count = 0, cap = 0;
    for (uint32_t id = 0; id != MS_ARCHIVE_NONE; id = ms_view_next_known(v, id)) {
        vcell *c = ms_view_vcell(v, id);
        if (!c || c->state != MS_VIEW_SHOWN)
            continue;
        if (!ms_grow((void **)&cells, &cap, count + 1, sizeof *cells)) {
            free(cells);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory stitching");
        }
        cells[count++] = id;
    }
    /* Caches (on the pool: each its own cell's) and colours of every shown
     * cell, their vertices not yet out. */
    ms_status s = stitch_run(v, cells, count, cache_job, err);
    bool coloured = false;
    for (size_t k = 0; k < count && s == MS_OK; ++k) {
        vcell *c = ms_view_vcell(v, cells[k]);
        if ((s = ms_view_colour_refresh(v, cells[k], err)) != MS_OK)
            break;
        coloured |= ms_view_colour_ready(c);
        for (size_t i = 0; i < c->cache.vertex_count; ++i)
            c->out_index[i] = NONE;
    }
    /* after the caches: a cell whose colours came in this stitch renews too */
    renew_stamps(v);
    if (s == MS_OK)
        s = colour_room(m, coloured, err);
    /* the pieces that no longer hold, worked out again (on the pool: a piece
     * writes its own cell's owners and piece, and reads the others' caches) */
    size_t redo = 0;
    for (size_t k = 0; k < count && s == MS_OK; ++k) {
        vcell *c = ms_view_vcell(v, cells[k]);
        if (!(visible && !visible[cells[k]]) && !piece_valid(v, c))
            cells[redo++] = cells[k];
    }
    if (s == MS_OK)
        s = stitch_run(v, cells, redo, piece_job, err);
    for (size_t k = 0; k < redo && s == MS_OK; ++k) {
        m->cells_stitched++;
        m->triangles_stitched += ms_view_vcell(v, cells[k])->piece->tri_count;
    }
    free(cells);
    /* room for the whole mesh at once: every cell's own vertices and those it
     * asks its neighbours for (an upper bound), and its triangles */
    size_t vertices = 0, triangles = 0;
    for (uint32_t id = 0; id != MS_ARCHIVE_NONE && s == MS_OK; id = ms_view_next_known(v, id)) {
        vcell *c = ms_view_vcell(v, id);
        if (c && c->state == MS_VIEW_SHOWN && (!visible || visible[id]))
            vertices += c->cache.vertex_count + c->piece->call_count, triangles += c->piece->tri_count;
    }
    if (s == MS_OK)
        s = mesh_room(m, vertices, triangles, err);
    for (uint32_t id = 0; id != MS_ARCHIVE_NONE && s == MS_OK; id = ms_view_next_known(v, id)) {
        vcell *c = ms_view_vcell(v, id);
        if (c && c->state == MS_VIEW_SHOWN && (!visible || visible[id]))
            s = put_piece(v, m, id, c, err);
    }
    return s;
}
