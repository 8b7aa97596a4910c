/* Checks shared by the nSP tests: see ms_nsp_check.h. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_nsp_check.h"

#include "ms_archive.h"
#include "ms_codec.h"
#include "ms_demo_model.h"
#include "ms_mesh_io.h"
#include "ms_nsp.h"
#include "ms_ref_coarsen.h"
#include "ms_test.h"

void ms_nsp_test_bake_options(const char *input, const char *dir, const char *name, ms_bake_options *o)
{
    ms_bake_options_default(o);
    o->apo.enabled = false; /* geometry only: APO has its own tests */
    o->input = input;
    o->archive_dir = dir;
    o->name = name;
    o->threads = 2;
}

void ms_nsp_test_bake(const char *input, const char *dir, const char *name, unsigned bits,
                      uint32_t min_triangles, ms_bake_report *report)
{
    ms_bake_options o;
    ms_nsp_test_bake_options(input, dir, name, &o);
    o.bits = bits;
    o.min_triangles = min_triangles;
    o.mem_mb = 64;
    ms_error err;
    ms_error_clear(&err);
    ms_status s = ms_bake(&o, report, &err);
    if (s != MS_OK)
        fail_msg("bake of %s failed: %s", input, err.text);
}

void ms_nsp_test_reference(const char *input, unsigned bits, ms_qmesh *q)
{
    ms_mesh m = {0};
    ms_error err;
    if (ms_mesh_load(input, &m, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    if (ms_quantise_mesh(&m, bits, q, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_mesh_free(&m);
}

void ms_nsp_test_demo_ply(const char *path, uint64_t triangles)
{
    ms_demo_model d = {.grid = ms_demo_grid_for_triangles(triangles), .seed = 0};
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_demo_build(&d, &m, &err), MS_OK);
    if (ms_ply_write(path, &m, true, true, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_mesh_free(&m);
}

static void decode_below(ms_view *v, uint32_t cell)
{
    ms_error err;
    const ms_archive_cell *c = ms_view_cell(v, cell);
    if (ms_view_set_bits(v, cell, c->bits_max, &err) != MS_OK)
        fail_msg("cell %u: %s", cell, err.text);
    if (c->first_child == MS_ARCHIVE_NONE)
        return;
    if (ms_view_split(v, cell, &err) != MS_OK)
        fail_msg("cell %u: %s", cell, err.text);
    const ms_archive_header *h = ms_view_header(v);
    for (unsigned k = 0; k < (unsigned)h->n * h->n * h->n; ++k)
        decode_below(v, c->first_child + k);
}

int ms_nsp_test_bake_demo(const char *work_dir, uint64_t triangles, const char *archive_dir, const char *name,
                          uint32_t min_triangles, bool every_cell)
{
    char ply[700];
    snprintf(ply, sizeof ply, "%s/demo.ply", work_dir);
    ms_nsp_test_demo_ply(ply, triangles);
    ms_bake_options o;
    ms_bake_options_default(&o); /* APO on */
    o.apo.every_cell = every_cell;
    o.apo.full_normals = every_cell;
    if (every_cell)
        o.apo.budget = 0; /* the former rule's chunks whole, as the tests measure them */
    o.input = ply;
    o.archive_dir = archive_dir;
    o.name = name;
    o.min_triangles = min_triangles;
    o.threads = 2;
    o.mem_mb = 64;
    ms_bake_report report;
    ms_error err;
    if (ms_bake(&o, &report, &err) != MS_OK) {
        fprintf(stderr, "bake: %s\n", err.text);
        return -1;
    }
    return 0;
}

int ms_nsp_test_demo_archive(char *dir, size_t dir_size, char *archives, size_t archives_size)
{
    ms_test_tmpdir(dir, dir_size);
    int n = snprintf(archives, archives_size, "%s/archive", dir);
    if (n < 0 || (size_t)n >= archives_size || mkdir(archives, 0755) != 0) {
        fprintf(stderr, "%s/archive: cannot be made\n", dir);
        return -1;
    }
    return ms_nsp_test_bake_demo(dir, 4000, archives, "demo", 1500, false);
}

int ms_nsp_test_demo_bake(ms_nsp_test_demo *d, uint64_t triangles, uint32_t min_triangles)
{
    ms_test_tmpdir(d->dir, sizeof d->dir);
    snprintf(d->archives, sizeof d->archives, "%s/archive", d->dir);
    snprintf(d->file, sizeof d->file, "%s/demo.msa", d->archives);
    if (mkdir(d->archives, 0755) != 0) {
        fprintf(stderr, "%s: cannot be made\n", d->archives);
        return -1;
    }
    if (ms_nsp_test_bake_demo(d->dir, triangles, d->archives, "demo", min_triangles, false) != 0)
        return -1;
    ms_error err;
    ms_archive *archive;
    if (ms_archive_open(d->file, &archive, &err) != MS_OK) {
        fprintf(stderr, "%s\n", err.text);
        return -1;
    }
    const ms_archive_header *h = ms_archive_get_header(archive);
    d->side = h->box_side;
    for (int a = 0; a < 3; ++a)
        d->centre[a] = h->box_origin[a] + h->box_side / 2;
    ms_archive_close(archive);
    return 0;
}

ms_nsp_test_demo *ms_nsp_test_demo_new(uint64_t triangles, uint32_t min_triangles)
{
    ms_nsp_test_demo *d = calloc(1, sizeof *d);
    if (!d || ms_nsp_test_demo_bake(d, triangles, min_triangles) != 0) {
        free(d);
        return NULL;
    }
    return d;
}

void ms_nsp_test_demo_free(ms_nsp_test_demo *d)
{
    if (!d)
        return;
    ms_test_rmdir(d->dir);
    free(d);
}

void ms_nsp_test_decode_all(ms_view *v)
{
    decode_below(v, 0);
}

static int cmp_u64(const void *x, const void *y)
{
    uint64_t a = *(const uint64_t *)x, b = *(const uint64_t *)y;
    return a < b ? -1 : a > b;
}

static int cmp_u64x2(const void *x, const void *y)
{
    const uint64_t *a = x, *b = y;
    for (int i = 0; i < 2; ++i)
        if (a[i] != b[i])
            return a[i] < b[i] ? -1 : 1;
    return 0;
}

static int cmp_u64x3(const void *x, const void *y)
{
    const uint64_t *a = x, *b = y;
    for (int i = 0; i < 3; ++i)
        if (a[i] != b[i])
            return a[i] < b[i] ? -1 : 1;
    return 0;
}

static void sort3(uint64_t *t)
{
    uint64_t x;
    if (t[0] > t[1])
        x = t[0], t[0] = t[1], t[1] = x;
    if (t[1] > t[2])
        x = t[1], t[1] = t[2], t[2] = x;
    if (t[0] > t[1])
        x = t[0], t[0] = t[1], t[1] = x;
}

/* Rotates an oriented triple so that its smallest entry comes first. */
static void rotate_min(uint64_t *t)
{
    while (t[0] > t[1] || t[0] > t[2]) {
        uint64_t x = t[0];
        t[0] = t[1], t[1] = t[2], t[2] = x;
    }
}

/* A vertex identity: kd-cell (level, aligned key) as one integer, the aligned key
 * shifted left by one with a marker bit just below the prefix (D + 1 <= 61 bits). */
static uint64_t vid(unsigned D, unsigned level, uint64_t aligned)
{
    return aligned << 1 | 1ull << (D - level);
}

static unsigned vid_level(unsigned D, uint64_t id)
{
    return D - (unsigned)__builtin_ctzll(id);
}

static uint64_t vid_aligned(unsigned D, uint64_t id)
{
    return (id - (1ull << (D - vid_level(D, id)))) >> 1;
}

/* Level of the shown cell holding full key `key`. */
static unsigned shown_level(const ms_view *v, const ms_nsp_shape *shape, uint64_t key)
{
    uint32_t xyz[3];
    ms_quant_unkey(key, shape->bits, xyz);
    uint32_t cell = 0;
    while (ms_view_state(v, cell) == MS_VIEW_SPLIT) {
        const ms_archive_cell *c = ms_view_cell(v, cell);
        cell = c->first_child + ms_nsp_child_offset(shape, c->level, xyz);
    }
    assert_int_equal(ms_view_state(v, cell), MS_VIEW_SHOWN);
    return 3 * ms_view_bits(v, cell);
}

/* Sorted unique triples; returns the count and the number of repeats removed. */
static size_t unique3(uint64_t *t, size_t n, size_t *repeats)
{
    qsort(t, n, 24, cmp_u64x3);
    size_t w = 0;
    for (size_t i = 0; i < n; ++i)
        if (w == 0 || cmp_u64x3(&t[3 * i], &t[3 * (w - 1)]) != 0) {
            memmove(&t[3 * w], &t[3 * i], 24);
            w++;
        } else if (repeats) {
            (*repeats)++;
        }
    return w;
}

/* Sorted unique triples with how many times each occurred (counts[]). */
static size_t unique3_count(uint64_t *t, size_t n, uint32_t *counts)
{
    qsort(t, n, 24, cmp_u64x3);
    size_t w = 0;
    for (size_t i = 0; i < n; ++i)
        if (w == 0 || cmp_u64x3(&t[3 * i], &t[3 * (w - 1)]) != 0) {
            memmove(&t[3 * w], &t[3 * i], 24);
            counts[w++] = 1;
        } else {
            counts[w - 1]++;
        }
    return w;
}

/* Sorted edge pairs with a single incident triangle, from n triples; with tri
 * non-NULL, *tri receives each such edge's triangle. */
static size_t boundary_pairs_of(const uint64_t *tris, size_t n, uint64_t **out, uint32_t **tri)
{
    uint64_t *e = malloc((9 * n + 3) * sizeof *e);
    assert_non_null(e);
    for (size_t t = 0; t < n; ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = tris[3 * t + (size_t)k], b = tris[3 * t + (size_t)(k + 1) % 3];
            uint64_t *x = &e[9 * t + 3 * (size_t)k];
            x[0] = a < b ? a : b;
            x[1] = a < b ? b : a;
            x[2] = t;
        }
    qsort(e, 3 * n, 24, cmp_u64x3);
    uint64_t *pairs = malloc((2 * 3 * n + 2) * sizeof *pairs);
    uint32_t *owner = malloc((3 * n + 1) * sizeof *owner);
    assert_true(pairs && owner);
    size_t w = 0;
    for (size_t i = 0; i < 3 * n;) {
        size_t j = i + 1;
        while (j < 3 * n && cmp_u64x2(&e[3 * j], &e[3 * i]) == 0)
            ++j;
        if (j - i == 1) {
            pairs[2 * w] = e[3 * i];
            pairs[2 * w + 1] = e[3 * i + 1];
            owner[w] = (uint32_t)e[3 * i + 2];
            w++;
        }
        i = j;
    }
    free(e);
    *out = pairs;
    if (tri)
        *tri = owner;
    else
        free(owner);
    return w;
}

/* Sorted edge pairs with a single incident triangle, from n triples. */
static size_t boundary_pairs(const uint64_t *tris, size_t n, uint64_t **out)
{
    uint64_t *e = malloc((6 * n + 2) * sizeof *e);
    assert_non_null(e);
    for (size_t t = 0; t < n; ++t)
        for (int k = 0; k < 3; ++k) {
            uint64_t a = tris[3 * t + (size_t)k], b = tris[3 * t + (size_t)(k + 1) % 3];
            e[6 * t + 2 * (size_t)k] = a < b ? a : b;
            e[6 * t + 2 * (size_t)k + 1] = a < b ? b : a;
        }
    qsort(e, 3 * n, 16, cmp_u64x2);
    size_t w = 0;
    for (size_t i = 0; i < 3 * n;) {
        size_t j = i + 1;
        while (j < 3 * n && cmp_u64x2(&e[2 * j], &e[2 * i]) == 0)
            ++j;
        if (j - i == 1) {
            e[2 * w] = e[2 * i];
            e[2 * w + 1] = e[2 * i + 1];
            w++;
        }
        i = j;
    }
    *out = e;
    return w;
}

/* The stitched mesh m (its triangles st as vertex identities) is exactly q:
 * vertices (isolated included, keys key) and oriented triangles. */
static void check_exactly_q(const ms_view_mesh *m, const ms_qmesh *q, const uint64_t *key,
                            const uint64_t *st, unsigned D)
{
    assert_int_equal(m->vertex_count, q->vertex_count);
    uint64_t *kv = malloc((m->vertex_count + 1) * sizeof *kv);
    assert_non_null(kv);
    for (size_t i = 0; i < m->vertex_count; ++i) {
        assert_int_equal(m->levels[i], D);
        kv[i] = m->keys[i];
    }
    qsort(kv, m->vertex_count, 8, cmp_u64);
    uint64_t *kq = malloc((q->vertex_count + 1) * sizeof *kq);
    assert_non_null(kq);
    memcpy(kq, key, q->vertex_count * sizeof *kq);
    qsort(kq, q->vertex_count, 8, cmp_u64);
    assert_memory_equal(kv, kq, q->vertex_count * 8);
    free(kv);
    free(kq);
    assert_int_equal(m->triangle_count, q->tri_count);
    uint64_t *a = malloc((3 * q->tri_count + 3) * sizeof *a);
    uint64_t *b = malloc((3 * q->tri_count + 3) * sizeof *b);
    assert_true(a && b);
    for (size_t t = 0; t < q->tri_count; ++t) {
        for (int k = 0; k < 3; ++k) {
            a[3 * t + (size_t)k] = vid(D, D, key[q->tris[3 * t + (size_t)k]]);
            b[3 * t + (size_t)k] = st[3 * t + (size_t)k];
        }
        rotate_min(&a[3 * t]);
        rotate_min(&b[3 * t]);
    }
    qsort(a, q->tri_count, 24, cmp_u64x3);
    qsort(b, q->tri_count, 24, cmp_u64x3);
    assert_memory_equal(a, b, 24 * q->tri_count);
    free(a);
    free(b);
}

/* The distinct kd-levels of the shown cells with geometry (into levels, at
 * most 64); counts the shown cells into r. */
static unsigned shown_levels(ms_view *v, unsigned levels[64], ms_nsp_view_check *r)
{
    unsigned nl = 0;
    for (uint32_t c = 0; c < ms_view_cell_count(v); ++c) {
        if (ms_view_state(v, c) != MS_VIEW_SHOWN)
            continue;
        r->shown_cells++;
        if (ms_view_cell(v, c)->geometry_length == 0)
            continue;
        unsigned L = 3 * ms_view_bits(v, c);
        bool seen = false;
        for (unsigned i = 0; i < nl; ++i)
            seen |= levels[i] == L;
        if (!seen)
            levels[nl++] = L;
    }
    return nl;
}

/* The crack criterion: each boundary edge of the stitched triangles st (nbe
 * of them, be / be_tri) must be a boundary edge of q coarsened to one of the
 * shown levels, the image of one of q's boundary edges with its two ends at
 * their own levels, or a fold; the others count as cracks in r. */
static void count_cracks(const ms_qmesh *q, const uint64_t *st, const uint64_t *be,
                         const uint32_t *be_tri, size_t nbe, const unsigned *levels, unsigned nl,
                         const uint64_t *ref, size_t nref, const uint32_t *mult, unsigned D,
                         ms_nsp_view_check *r)
{
    ms_error err;
    ms_codec_state fullst = {0};
    assert_int_equal(ms_codec_state_from_qmesh(q, &fullst, &err), MS_OK);
    uint8_t *ok = calloc(nbe, 1);
    assert_non_null(ok);
    for (unsigned li = 0; li < nl; ++li) {
        unsigned L = levels[li];
        ms_codec_state u;
        ms_ref_coarsen(&fullst, L, &u);
        uint64_t *ut = malloc((3 * u.tri_count + 3) * sizeof *ut);
        assert_non_null(ut);
        for (size_t t = 0; t < 3 * u.tri_count; ++t)
            ut[t] = u.cells[u.tris[t]];
        uint64_t *ub;
        size_t nub = boundary_pairs(ut, u.tri_count, &ub);
        for (size_t e = 0; e < nbe; ++e) {
            if (ok[e])
                continue;
            unsigned la = vid_level(D, be[2 * e]), lb = vid_level(D, be[2 * e + 1]);
            if (L > la || L > lb)
                continue;
            uint64_t pa = L == 0 ? 0 : vid_aligned(D, be[2 * e]) >> (D - L);
            uint64_t pb = L == 0 ? 0 : vid_aligned(D, be[2 * e + 1]) >> (D - L);
            if (pa == pb)
                continue;
            uint64_t pair[2] = {pa < pb ? pa : pb, pa < pb ? pb : pa};
            ok[e] = bsearch(pair, ub, nub, 16, cmp_u64x2) != NULL;
        }
        free(ub);
        free(ut);
        ms_codec_state_free(&u);
    }
    /* The image of one of the model's own boundary edges, its ends rounded to
     * their two levels: the rim of a hole or a border that one of those
     * levels alone closes (a hole smaller than its cells), so no uniform
     * level has it, though the mixed image rightly does. */
    uint64_t *ft = malloc((3 * fullst.tri_count + 3) * sizeof *ft), *fb;
    assert_non_null(ft);
    for (size_t t = 0; t < 3 * fullst.tri_count; ++t)
        ft[t] = fullst.cells[fullst.tris[t]];
    size_t nfb = boundary_pairs(ft, fullst.tri_count, &fb);
    free(ft);
    for (size_t e = 0; e < nbe; ++e) {
        unsigned la = vid_level(D, be[2 * e]), lb = vid_level(D, be[2 * e + 1]);
        uint64_t a = vid_aligned(D, be[2 * e]), b = vid_aligned(D, be[2 * e + 1]);
        for (size_t k = 0; !ok[e] && k < nfb; ++k) {
            uint64_t u = fb[2 * k], w = fb[2 * k + 1];
            ok[e] = ((u >> (D - la)) == (a >> (D - la)) && (w >> (D - lb)) == (b >> (D - lb))) ||
                    ((w >> (D - la)) == (a >> (D - la)) && (u >> (D - lb)) == (b >> (D - lb)));
        }
    }
    free(fb);
    for (size_t e = 0; e < nbe; ++e) {
        if (ok[e])
            continue;
        /* A fold: the edge's one triangle is the image of several original
         * triangles (two sheets pressed together and unified), so the edge is
         * covered on both sides, by the same triangle. */
        uint64_t tri[3];
        memcpy(tri, &st[3 * (size_t)be_tri[e]], sizeof tri);
        sort3(tri);
        const uint64_t *hit = bsearch(tri, ref, nref, 24, cmp_u64x3);
        assert_non_null(hit);
        if (mult[(size_t)(hit - ref) / 3] >= 2) {
            r->folds++;
            continue;
        }
        r->cracks++;
        if (getenv("MS_NSP_DEBUG"))
            print_message("crack edge: levels %u %u keys %llx %llx\n",
                          vid_level(D, be[2 * e]), vid_level(D, be[2 * e + 1]),
                          (unsigned long long)vid_aligned(D, be[2 * e]),
                          (unsigned long long)vid_aligned(D, be[2 * e + 1]));
    }
    free(ok);
    ms_codec_state_free(&fullst);
}

void ms_nsp_test_check_view(ms_view *v, const ms_qmesh *q, bool full, ms_nsp_view_check *r)
{
    memset(r, 0, sizeof *r);
    const ms_archive_header *h = ms_view_header(v);
    ms_nsp_shape shape;
    ms_error err;
    assert_int_equal(ms_nsp_shape_init(&shape, h->bits, h->n, h->root_bits, &err), MS_OK);
    const unsigned P = h->bits, D = 3 * P;
    ms_view_mesh m = {0};
    if (ms_view_stitch(v, NULL, &m, &err) != MS_OK)
        fail_msg("stitch: %s", err.text);
    assert_int_equal(m.unresolved, 0);
    r->triangles = m.triangle_count;
    r->snapped_frozen = m.snapped_frozen;

    /* Stitched triangles as vertex identities. */
    uint64_t *st = malloc((3 * m.triangle_count + 3) * sizeof *st);
    assert_non_null(st);
    for (size_t t = 0; t < m.triangle_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint32_t x = m.triangles[3 * t + (size_t)k];
            st[3 * t + (size_t)k] = vid(D, m.levels[x], m.keys[x]);
        }
    /* Reference: the mixed clustering's image of q. */
    uint64_t *key = malloc((q->vertex_count + 1) * sizeof *key);
    uint64_t *phi = malloc((q->vertex_count + 1) * sizeof *phi);
    uint64_t *ref = malloc((3 * q->tri_count + 3) * sizeof *ref);
    assert_true(key && phi && ref);
    for (size_t i = 0; i < q->vertex_count; ++i) {
        key[i] = ms_quant_key(q->coords[3 * i], q->coords[3 * i + 1], q->coords[3 * i + 2], P);
        unsigned L = shown_level(v, &shape, key[i]);
        phi[i] = vid(D, L, L == 0 ? 0 : key[i] >> (D - L) << (D - L));
    }
    size_t nref = 0;
    for (size_t t = 0; t < q->tri_count; ++t) {
        uint64_t a = phi[q->tris[3 * t]], b = phi[q->tris[3 * t + 1]], c = phi[q->tris[3 * t + 2]];
        if (a == b || b == c || a == c)
            continue;
        ref[3 * nref] = a, ref[3 * nref + 1] = b, ref[3 * nref + 2] = c;
        sort3(&ref[3 * nref]);
        nref++;
    }
    uint32_t *mult = malloc((nref + 1) * sizeof *mult);
    assert_non_null(mult);
    nref = unique3_count(ref, nref, mult);
    uint64_t *sorted = malloc((3 * m.triangle_count + 3) * sizeof *sorted);
    assert_non_null(sorted);
    memcpy(sorted, st, 3 * m.triangle_count * sizeof *st);
    for (size_t t = 0; t < m.triangle_count; ++t)
        sort3(&sorted[3 * t]);
    size_t ns = unique3(sorted, m.triangle_count, &r->duplicates);
    for (size_t i = 0, j = 0; i < nref || j < ns;) {
        int c = i == nref ? 1 : j == ns ? -1 : cmp_u64x3(&ref[3 * i], &sorted[3 * j]);
        if (c == 0)
            ++i, ++j;
        else if (c < 0)
            r->missing++, ++i;
        else
            r->extra++, ++j;
    }

    if (full)
        check_exactly_q(&m, q, key, st, D);

    /* Crack criterion. */
    unsigned levels[64];
    unsigned nl = shown_levels(v, levels, r);
    r->levels = nl;
    uint64_t *be;
    uint32_t *be_tri;
    size_t nbe = boundary_pairs_of(st, m.triangle_count, &be, &be_tri);
    r->boundary_edges = nbe;
    if (nbe > 0)
        count_cracks(q, st, be, be_tri, nbe, levels, nl, ref, nref, mult, D, r);
    free(be);
    free(be_tri);
    free(mult);
    free(sorted);
    free(st);
    free(key);
    free(phi);
    free(ref);
    ms_view_mesh_free(&m);
}
