/* Per-cell APO chunks: see ms_bake_apo.h. */
#include "ms_bake_apo.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_chunk.h"
#include "ms_apo_stream.h"
#include "ms_apo_traverse.h"
#include "ms_radix_sort.h"
#include "ms_tri_unify.h"

void ms_bake_apo_params_default(ms_bake_apo_params *p)
{
    memset(p, 0, sizeof *p);
    p->enabled = true;
    p->lead = 1;
    p->max_depth = 10;
    p->init_depth = 0;
    p->tolerance = 0.2;
    p->correction = 0.2;
    p->budget = MS_BAKE_APO_BUDGET;
    p->zlib_level = 6;
    p->sample_agreement = MS_BAKE_APO_AGREEMENT;
}

ms_status ms_bake_apo_params_check(const ms_bake_apo_params *p, ms_error *err)
{
    if (p->lead > MS_BAKE_APO_MAX_LEAD)
        return ms_error_set(err, MS_ERR_ARG, "--apo-lead must be at most %u", MS_BAKE_APO_MAX_LEAD);
    if (p->max_depth > MS_BAKE_APO_MAX_DEPTH)
        return ms_error_set(err, MS_ERR_ARG, "--apo-max-depth must be at most %u", MS_BAKE_APO_MAX_DEPTH);
    if (!(p->tolerance >= 0.0 && p->tolerance < 1e12))
        return ms_error_set(err, MS_ERR_ARG, "--apo-tol must be a number >= 0");
    if (!(p->correction >= 0.0 && p->correction <= 3.2))
        return ms_error_set(err, MS_ERR_ARG, "--apo-correction must be a number from 0 to 3.2");
    if (!(p->budget >= 0.0 && p->budget <= MS_BAKE_APO_MAX_BUDGET))
        return ms_error_set(err, MS_ERR_ARG, "--apo-budget must be a number from 0 (no budget) to %g",
                            MS_BAKE_APO_MAX_BUDGET);
    if (p->zlib_level < 0 || p->zlib_level > 9)
        return ms_error_set(err, MS_ERR_ARG, "APO zlib level must be 0..9");
    if (!(p->sample_agreement >= 0.0 && p->sample_agreement <= 3.2))
        return ms_error_set(err, MS_ERR_ARG, "APO sample agreement must be a number from 0 to 3.2");
    return MS_OK;
}

uint32_t ms_bake_apo_depth(const ms_nsp_shape *shape, unsigned depth, unsigned bits_max,
                           const ms_bake_apo_params *p)
{
    unsigned above = shape->log2n * depth;
    uint32_t finest = bits_max > above ? bits_max - above : 0;
    uint32_t d = finest + p->lead;
    return d < p->max_depth ? d : p->max_depth;
}

void ms_bake_apo_cube(const ms_nsp_shape *shape, const ms_quant_box *box, unsigned depth,
                      const uint32_t position[3], double origin[3], double *size)
{
    /* box->size / n^depth is exact (a power of two), so is position * width. */
    double width = box->size / (double)(1ull << (shape->log2n * depth));
    for (int a = 0; a < 3; ++a)
        origin[a] = box->origin[a] + (double)position[a] * width;
    *size = width;
}

void ms_bake_apo_result_free(ms_bake_apo_result *r)
{
    free(r->data);
    memset(r, 0, sizeof *r);
}

bool ms_bake_apo_same_tree(const ms_apo_tree *a, const ms_apo_tree *b, size_t *node)
{
    *node = 0;
    if (a->node_count != b->node_count || a->level_count != b->level_count)
        return false;
    for (size_t i = 0; i < a->node_count; ++i) {
        const ms_apo_node *x = &a->nodes[i], *y = &b->nodes[i];
        *node = i;
        if (x->first_child != y->first_child || x->child_mask != y->child_mask || x->depth != y->depth ||
            memcmp(x->cell, y->cell, sizeof x->cell) != 0 || (x->smooth != 0) != (y->smooth != 0) ||
            (!x->smooth && ms_apo_normal_encode(x->normal) != ms_apo_normal_encode(y->normal)))
            return false;
    }
    return true;
}

/* Inflate, load, decode: the stored bytes must give back the built tree. */
static ms_status verify_stored(const ms_apo_tree *built, const ms_bake_apo_result *r, ms_error *err)
{
    ms_apo_chunk back;
    ms_status st = ms_apo_stream_inflate(r->data, r->size, r->level_table, r->levels, &back, err);
    if (st != MS_OK)
        return st;
    ms_apo_view view;
    ms_apo_tree decoded;
    memset(&decoded, 0, sizeof decoded);
    st = ms_apo_view_of_chunk(&view, &back, err);
    if (st == MS_OK)
        st = ms_apo_view_decode(&view, &decoded, err);
    size_t node;
    if (st == MS_OK && !ms_bake_apo_same_tree(built, &decoded, &node))
        st = ms_error_set(err, MS_ERR_CORRUPT, "APO chunk does not decode to the built tree (node %zu)", node);
    ms_apo_tree_free(&decoded);
    ms_apo_chunk_free(&back);
    return st;
}

void ms_bake_apo_accuracy_add(ms_bake_apo_accuracy *a, const ms_bake_apo_accuracy *b)
{
    a->points += b->points;
    a->sum_degrees += b->sum_degrees;
    for (unsigned i = 0; i < MS_BAKE_APO_ANGLE_BINS; ++i)
        a->bins[i] += b->bins[i];
}

double ms_bake_apo_accuracy_quantile(const ms_bake_apo_accuracy *a, double q)
{
    if (a->points == 0)
        return 0.0;
    uint64_t want = (uint64_t)(q * (double)(a->points - 1)), seen = 0;
    unsigned i = 0;
    for (; i + 1 < MS_BAKE_APO_ANGLE_BINS; ++i) {
        seen += a->bins[i];
        if (seen > want)
            break;
    }
    return 0.1 * ((double)i + 0.5);
}

/* The chunk's normals at the reference's centroids against its face normals. */
static ms_status measure(const ms_apo_chunk *chunk, const double origin[3], double size, const ms_mesh *ref,
                         ms_bake_apo_accuracy *acc, ms_error *err)
{
    ms_apo_view view;
    ms_status st = ms_apo_view_of_chunk(&view, chunk, err);
    for (size_t t = 0; st == MS_OK && t < ref->triangle_count; ++t) {
        const uint32_t *v = &ref->triangles[3 * t];
        const double *a = &ref->positions[3 * v[0]], *b = &ref->positions[3 * v[1]], *c = &ref->positions[3 * v[2]];
        double e1[3], e2[3], n[3];
        float at[3];
        for (int i = 0; i < 3; ++i) {
            e1[i] = b[i] - a[i];
            e2[i] = c[i] - a[i];
            at[i] = (float)(((a[i] + b[i] + c[i]) / 3.0 - origin[i]) / size);
        }
        n[0] = e1[1] * e2[2] - e1[2] * e2[1];
        n[1] = e1[2] * e2[0] - e1[0] * e2[2];
        n[2] = e1[0] * e2[1] - e1[1] * e2[0];
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        if (!(len > 0))
            continue;
        ms_apo_lookup_result r;
        ms_apo_lookup(&view, at, MS_APO_MAX_DEPTH, MS_APO_MISSING_NEAREST, &r);
        double dot = (r.normal[0] * n[0] + r.normal[1] * n[1] + r.normal[2] * n[2]) / len;
        double deg = acos(dot > 1 ? 1 : dot < -1 ? -1 : dot) * (180.0 / M_PI);
        unsigned bin = (unsigned)(deg * 10.0);
        acc->bins[bin < MS_BAKE_APO_ANGLE_BINS ? bin : MS_BAKE_APO_ANGLE_BINS - 1]++;
        acc->points++;
        acc->sum_degrees += deg;
    }
    return st;
}

void ms_bake_apo_part_free(ms_bake_apo_part *part)
{
    ms_mesh_free(&part->mesh);
    free(part->weight);
    memset(part, 0, sizeof *part);
}

/* The grid cell of x at `bits` (x lies inside the box). */
static uint64_t cell_key(const ms_quant_box *box, unsigned bits, const double *x)
{
    uint64_t key = 0;
    double cells = (double)(1u << bits);
    for (int a = 0; a < 3; ++a) {
        double t = floor((x[a] - box->origin[a]) / box->size * cells);
        uint64_t q = t < 0 ? 0 : t >= cells ? (1u << bits) - 1 : (uint64_t)t;
        key = key << 21 | q;
    }
    return key;
}

static bool inside_cube(const double *x, const double origin[3], double size)
{
    for (int a = 0; a < 3; ++a)
        if (!(x[a] >= origin[a] && x[a] < origin[a] + size))
            return false;
    return true;
}

typedef struct vertex_key {
    uint32_t bits;   /* the vertex is (bits, grid cell key) */
    uint64_t key;
    uint32_t weight; /* owned: weight; foreign: 0 */
    uint32_t copy;   /* weight of the copy, for the choice among foreign ones */
    uint32_t seq;    /* index in the concatenated parts */
} vertex_key;

/* The same vertex (bits, cell key) together, in each group the copy to keep
 * first: owned (weight > 0) before foreign, then the heavier copy, then the
 * lower seq. Three stable radix passes from the least significant field (the
 * input is in seq order), where qsort's comparisons were 2 % of the dragon's
 * bake. */
static ms_status sort_vertex_keys(vertex_key *vk, size_t n, ms_error *err)
{
    uint64_t *key = malloc((n + 1) * sizeof *key);
    uint32_t *perm = malloc((n + 1) * sizeof *perm);
    vertex_key *out = malloc((n + 1) * sizeof *out);
    ms_status s = key && perm && out ? MS_OK : ms_error_set(err, MS_ERR_NOMEM, "out of memory joining meshes");
    for (size_t i = 0; s == MS_OK && i < n; ++i) {
        perm[i] = (uint32_t)i;
        key[i] = (uint64_t)(vk[i].weight > 0 ? 0u : 1u) << 32 | (uint64_t)(UINT32_MAX - vk[i].copy);
    }
    if (s == MS_OK)
        s = ms_radix_sort_pairs(key, perm, n, 33, err);
    for (size_t i = 0; s == MS_OK && i < n; ++i)
        key[i] = vk[perm[i]].key;
    if (s == MS_OK)
        s = ms_radix_sort_pairs(key, perm, n, 63, err);
    for (size_t i = 0; s == MS_OK && i < n; ++i)
        key[i] = vk[perm[i]].bits;
    if (s == MS_OK)
        s = ms_radix_sort_pairs(key, perm, n, 32, err);
    if (s == MS_OK) {
        for (size_t i = 0; i < n; ++i)
            out[i] = vk[perm[i]];
        memcpy(vk, out, n * sizeof *vk);
    }
    free(key);
    free(perm);
    free(out);
    return s;
}

/* ms_tri_unify over the triangles of M whose three vertices are all shared
 * (shared[v]: joined from copies in two or more parts): the only ones that can
 * repeat another, when no part repeats a triangle of its own (a cell's m is a
 * complex) and no two vertices of one part were joined (the caller's check). The
 * same triangles are dropped as by ms_tri_unify over all of M (the later copy of
 * each vertex set), in the same order, for a sort of the shared strips along
 * the children's borders instead of all of M. */
static ms_status unify_shared(ms_mesh *M, const uint8_t *shared, ms_error *err)
{
    size_t nt = M->triangle_count, nc = 0;
    uint32_t *t = M->triangles;
    for (size_t i = 0; i < nt; ++i)
        nc += shared[t[3 * i]] && shared[t[3 * i + 1]] && shared[t[3 * i + 2]];
    uint32_t *cand = malloc((3 * nc + 1) * sizeof *cand);
    if (!cand)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory joining the children's meshes");
    size_t c = 0;
    for (size_t i = 0; i < nt; ++i)
        if (shared[t[3 * i]] && shared[t[3 * i + 1]] && shared[t[3 * i + 2]])
            memcpy(&cand[3 * c++], &t[3 * i], 3 * sizeof *t);
    size_t kept = nc;
    ms_status s = ms_tri_unify(cand, &kept, NULL, NULL, err);
    /* The kept candidates are the candidates in order, less the dropped: a
     * dropped one repeats an earlier kept one, so it cannot equal the next
     * kept one, which repeats nothing before it. */
    size_t w = 0, k = 0;
    for (size_t i = 0; s == MS_OK && i < nt; ++i) {
        const uint32_t *x = &t[3 * i];
        if (shared[x[0]] && shared[x[1]] && shared[x[2]]) {
            if (!(k < kept && memcmp(x, &cand[3 * k], 3 * sizeof *x) == 0))
                continue; /* dropped */
            ++k;
        }
        if (w != i)
            memmove(&t[3 * w], x, 3 * sizeof *x);
        ++w;
    }
    if (s == MS_OK)
        M->triangle_count = w;
    free(cand);
    return s;
}

ms_status ms_bake_apo_union(const ms_bake_apo_part *parts, size_t count, const ms_quant_box *box, ms_mesh *M,
                            uint32_t **owned, ms_error *err)
{
    memset(M, 0, sizeof *M);
    *owned = NULL;
    size_t nv = 0, nt = 0;
    for (size_t k = 0; k < count; ++k) {
        nv += parts[k].mesh.vertex_count;
        nt += parts[k].mesh.triangle_count;
    }
    if (nv >= UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "an APO sampling surface of %zu vertices", nv);
    vertex_key *vk = malloc((nv + 1) * sizeof *vk);
    uint32_t *id = malloc((nv + 1) * sizeof *id);
    const double **from = malloc((nv + 1) * sizeof *from);
    uint32_t *part_of = malloc((nv + 1) * sizeof *part_of); /* each copy's part */
    uint8_t *shared = calloc(nv + 1, 1);                     /* per kept vertex: joined from several parts */
    if (!vk || !id || !from || !part_of || !shared) {
        free(vk);
        free(id);
        free(from);
        free(part_of);
        free(shared);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory joining the children's meshes");
    }
    size_t w = 0;
    for (size_t k = 0; k < count; ++k) {
        const ms_bake_apo_part *pt = &parts[k];
        for (size_t v = 0; v < pt->mesh.vertex_count; ++v, ++w) {
            part_of[w] = (uint32_t)k;
            const double *x = &pt->mesh.positions[3 * v];
            from[w] = x;
            vk[w].bits = pt->bits;
            vk[w].key = cell_key(box, pt->bits, x);
            vk[w].copy = pt->weight[v];
            vk[w].weight = inside_cube(x, pt->origin, pt->size) ? pt->weight[v] : 0;
            vk[w].seq = (uint32_t)w;
        }
    }
    ms_status s = sort_vertex_keys(vk, nv, err);
    if (s != MS_OK) {
        free(vk);
        free(id);
        free(from);
        free(part_of);
        free(shared);
        return s;
    }
    size_t distinct = 0; /* vk[0..distinct) becomes the kept copies, in order */
    /* The parts of the current group's copies (up to a few; more, or two from
     * one part, and M is unified whole). */
    uint32_t group_parts[8];
    size_t group_n = 0;
    bool whole = false;
    for (size_t i = 0; i < nv; ++i) {
        uint32_t seq = vk[i].seq;
        if (distinct == 0 || vk[i].key != vk[distinct - 1].key || vk[i].bits != vk[distinct - 1].bits) {
            vk[distinct++] = vk[i];
            group_n = 0;
        } else {
            shared[distinct - 1] = 1;
        }
        for (size_t g = 0; g < group_n; ++g)
            whole |= group_parts[g] == part_of[seq];
        if (group_n < 8)
            group_parts[group_n++] = part_of[seq];
        else
            whole = true;
        id[seq] = (uint32_t)(distinct - 1);
    }
    s = ms_mesh_reserve(M, distinct, nt, err);
    *owned = s == MS_OK ? malloc((distinct + 1) * sizeof **owned) : NULL;
    if (s == MS_OK && !*owned)
        s = ms_error_set(err, MS_ERR_NOMEM, "out of memory joining the children's meshes");
    if (s == MS_OK) {
        for (size_t v = 0; v < distinct; ++v) {
            memcpy(&M->positions[3 * v], from[vk[v].seq], 3 * sizeof(double));
            (*owned)[v] = vk[v].weight;
        }
        M->vertex_count = distinct;
        size_t base = 0, t3 = 0;
        for (size_t k = 0; k < count; ++k) {
            for (size_t i = 0; i < 3 * parts[k].mesh.triangle_count; ++i)
                M->triangles[t3++] = id[base + parts[k].mesh.triangles[i]];
            base += parts[k].mesh.vertex_count;
        }
        M->triangle_count = nt;
        s = whole ? ms_tri_unify(M->triangles, &M->triangle_count, NULL, NULL, err) : unify_shared(M, shared, err);
    }
    free(vk);
    free(id);
    free(from);
    free(part_of);
    free(shared);
    if (s != MS_OK) {
        ms_mesh_free(M);
        free(*owned);
        *owned = NULL;
    }
    return s;
}

ms_status ms_bake_apo_smooth(ms_mesh *m, unsigned bits, const ms_quant_box *box, const double origin[3],
                             double size, const ms_mesh *M, const uint32_t *owned, ms_bake_apo_part *out,
                             ms_error *err)
{
    memset(out, 0, sizeof *out);
    size_t n = M->vertex_count;
    /* M's vertices by cell key, equal keys in vertex order (a stable radix sort) */
    uint64_t *kk = malloc((n + 1) * sizeof *kk);
    uint32_t *kseq = malloc((n + 1) * sizeof *kseq);
    uint32_t *weight = malloc((m->vertex_count + 1) * sizeof *weight);
    if (!kk || !kseq || !weight) {
        free(kk);
        free(kseq);
        free(weight);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory averaging a cell's vertices");
    }
    for (size_t v = 0; v < n; ++v) {
        kk[v] = cell_key(box, bits, &M->positions[3 * v]);
        kseq[v] = (uint32_t)v;
    }
    ms_status s = ms_radix_sort_pairs(kk, kseq, n, 63, err);
    if (s != MS_OK) {
        free(kk);
        free(kseq);
        free(weight);
        return s;
    }
    for (size_t v = 0; v < m->vertex_count; ++v) {
        double *x = &m->positions[3 * v];
        uint64_t key = cell_key(box, bits, x);
        size_t lo = 0, hi = n; /* first entry with kk >= key */
        while (lo < hi) {
            size_t mid = lo + (hi - lo) / 2;
            if (kk[mid] < key)
                lo = mid + 1;
            else
                hi = mid;
        }
        double sum[3] = {0, 0, 0}, any[3] = {0, 0, 0};
        uint64_t total = 0, seen = 0;
        for (size_t i = lo; i < n && kk[i] == key; ++i) {
            const double *y = &M->positions[3 * (size_t)kseq[i]];
            uint32_t wt = owned[kseq[i]];
            for (int a = 0; a < 3; ++a) {
                sum[a] += wt * y[a];
                any[a] += y[a];
            }
            total += wt;
            seen++;
        }
        if (total > 0)
            for (int a = 0; a < 3; ++a)
                x[a] = sum[a] / (double)total;
        else if (seen > 0)
            for (int a = 0; a < 3; ++a)
                x[a] = any[a] / (double)seen;
        uint64_t wv = total > 0 ? total : seen > 0 ? seen : 1;
        weight[v] = wv < UINT32_MAX ? (uint32_t)wv : UINT32_MAX;
    }
    free(kk);
    free(kseq);
    out->mesh = *m;
    memset(m, 0, sizeof *m);
    out->weight = weight;
    out->bits = bits;
    memcpy(out->origin, origin, sizeof out->origin);
    out->size = size;
    return MS_OK;
}

/* A triangle as the set of its three vertex positions: sorted lexicographically. */
typedef struct tri_key {
    double p[9];
} tri_key;

static int cmp_point(const double *a, const double *b)
{
    for (int k = 0; k < 3; ++k)
        if (a[k] != b[k])
            return a[k] < b[k] ? -1 : 1;
    return 0;
}

static int cmp_tri_key(const void *x, const void *y)
{
    const tri_key *a = x, *b = y;
    for (int k = 0; k < 3; ++k) {
        int c = cmp_point(&a->p[3 * k], &b->p[3 * k]);
        if (c)
            return c;
    }
    return 0;
}

static void make_tri_key(const ms_mesh *mesh, size_t t, tri_key *key)
{
    const double *v[3];
    for (int k = 0; k < 3; ++k)
        v[k] = &mesh->positions[3 * (size_t)mesh->triangles[3 * t + k]];
    /* three elements: a fixed sorting network */
    const double *tmp;
    if (cmp_point(v[0], v[1]) > 0)
        tmp = v[0], v[0] = v[1], v[1] = tmp;
    if (cmp_point(v[1], v[2]) > 0)
        tmp = v[1], v[1] = v[2], v[2] = tmp;
    if (cmp_point(v[0], v[1]) > 0)
        tmp = v[0], v[0] = v[1], v[1] = tmp;
    for (int k = 0; k < 3; ++k)
        memcpy(&key->p[3 * k], v[k], 3 * sizeof(double));
}

static bool has_area(const ms_mesh *mesh, size_t t)
{
    const uint32_t *v = &mesh->triangles[3 * t];
    const double *a = &mesh->positions[3 * v[0]], *b = &mesh->positions[3 * v[1]], *c = &mesh->positions[3 * v[2]];
    double e1[3], e2[3];
    for (int i = 0; i < 3; ++i) {
        e1[i] = b[i] - a[i];
        e2[i] = c[i] - a[i];
    }
    double n0 = e1[1] * e2[2] - e1[2] * e2[1], n1 = e1[2] * e2[0] - e1[0] * e2[2], n2 = e1[0] * e2[1] - e1[1] * e2[0];
    return n0 != 0.0 || n1 != 0.0 || n2 != 0.0;
}

/* A hash of a key's 9 coordinates (-0.0 hashed as 0.0, which compares equal). */
static uint64_t hash_tri_key(const tri_key *key)
{
    uint64_t h = 0x9E3779B97F4A7C15u;
    for (int k = 0; k < 9; ++k) {
        double x = key->p[k] + 0.0;
        uint64_t bits;
        memcpy(&bits, &x, sizeof bits);
        h = (h ^ bits) * 0xFF51AFD7ED558CCDu;
        h ^= h >> 32;
    }
    return h;
}

/* Whether m holds a triangle with key's three corners (any order): a plain
 * pass, no table. */
static bool has_triangle(const ms_mesh *m, const tri_key *key)
{
    for (size_t t = 0; t < m->triangle_count; ++t) {
        const double *a = &m->positions[3 * (size_t)m->triangles[3 * t]];
        if (cmp_point(a, &key->p[0]) && cmp_point(a, &key->p[3]) && cmp_point(a, &key->p[6]))
            continue;
        tri_key other;
        make_tri_key(m, t, &other);
        if (cmp_tri_key(key, &other) == 0)
            return true;
    }
    return false;
}

bool ms_bake_apo_geometry_renders(const ms_mesh *m, const ms_mesh *M)
{
    /* An internal cell's M (its children's finer triangles) mostly fails on
     * its first triangle: ask m for that one before hashing all of m. */
    for (size_t t = 0; t < M->triangle_count; ++t) {
        if (!has_area(M, t))
            continue;
        tri_key first;
        make_tri_key(M, t, &first);
        if (!has_triangle(m, &first))
            return false;
        break;
    }
    /* m's keys in an open-addressing table (a power of two, at most half full) */
    size_t cap = 2;
    while (cap < 2 * m->triangle_count)
        cap *= 2;
    tri_key *keys = malloc((m->triangle_count + 1) * sizeof *keys);
    uint32_t *slot = malloc(cap * sizeof *slot); /* key index + 1; 0 empty */
    if (!keys || !slot || m->triangle_count >= UINT32_MAX) {
        free(keys);
        free(slot);
        return false;
    }
    memset(slot, 0, cap * sizeof *slot);
    for (size_t t = 0; t < m->triangle_count; ++t) {
        make_tri_key(m, t, &keys[t]);
        size_t i = (size_t)hash_tri_key(&keys[t]) & (cap - 1);
        while (slot[i])
            i = (i + 1) & (cap - 1);
        slot[i] = (uint32_t)t + 1;
    }
    bool all = true;
    for (size_t t = 0; t < M->triangle_count && all; ++t) {
        if (!has_area(M, t))
            continue;
        tri_key key;
        make_tri_key(M, t, &key);
        size_t i = (size_t)hash_tri_key(&key) & (cap - 1);
        bool found = false;
        for (; slot[i] && !found; i = (i + 1) & (cap - 1))
            found = cmp_tri_key(&key, &keys[slot[i] - 1]) == 0;
        all = found;
    }
    free(keys);
    free(slot);
    return all;
}

ms_status ms_bake_apo_cell(ms_apo_builder *builder, const ms_bake_apo_params *p, const ms_nsp_shape *shape,
                           const ms_quant_box *box, unsigned depth, const uint32_t position[3], unsigned bits_max,
                           const ms_mesh *m, const ms_mesh *M, const ms_mesh *reference, unsigned threads,
                           ms_bake_apo_result *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (!p->every_cell && ms_bake_apo_geometry_renders(m, M))
        return MS_OK; /* no chunk: the client draws m's own normals */
    ms_apo_build_options o;
    ms_apo_build_options_default(&o);
    ms_bake_apo_cube(shape, box, depth, position, o.cube_origin, &o.cube_size);
    o.max_depth = ms_bake_apo_depth(shape, depth, bits_max, p);
    o.init_depth = p->init_depth < o.max_depth ? p->init_depth : o.max_depth;
    o.tolerance = p->tolerance;
    o.measure = MS_APO_MEASURE_SPREAD;
    /* h from the grid: each vertex of m is the centre of a grid cell of its
     * precision (2^-g of the cube) that holds input, hence M, within half its
     * diagonal; a whole diagonal leaves room for points inside m's triangles.
     * Measuring h instead costs a point query per vertex and face of m, which
     * grows with M's valence (a fan's hub). */
    unsigned g = bits_max > shape->log2n * depth ? bits_max - shape->log2n * depth : 0;
    o.distance_bound = sqrt(3.0) * ldexp(1.0, -(int)g);
    o.threads = threads ? threads : 1;
    /* Corrections of what the client draws: m's smooth normals, its vertices
     * up to half a grid cell's diagonal from where they stand for (the
     * renderer's slack), the client's default crease angle. */
    o.correction = !p->full_normals;
    o.correction_tolerance = p->correction;
    o.vertex_error = 0.5 * o.distance_bound;
    o.sample_agreement = p->sample_agreement;
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    ms_apo_build_stats stats;
    ms_status st = ms_apo_builder_build_tree(builder, m, M, &o, &tree, &stats, err);
    ms_apo_chunk chunk;
    memset(&chunk, 0, sizeof chunk);
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_chunk_encode(&tree, &chunk, err);
    if (st == MS_OK && tree.level_count > 0)
        st = ms_apo_stream_compress(&chunk, p->zlib_level, &out->data, &out->size, out->level_table, err);
    if (st == MS_OK) {
        out->levels = chunk.level_count;
        memcpy(out->level_texels, chunk.level_texels, chunk.level_count * sizeof *chunk.level_texels);
        out->texels = chunk.texel_count;
        ms_apo_tree_counts(&tree, &out->internal_nodes, &out->leaves);
        out->rays = stats.rays;
        out->point_queries = stats.point_queries;
        out->triangle_visits = stats.triangle_visits;
        out->smooth_leaves = stats.smooth_leaves;
        out->samples = stats.samples;
        out->sampled_leaves = stats.sampled_leaves;
        out->agreed_leaves = stats.agreed_leaves;
        if (p->verify && out->levels > 0)
            st = verify_stored(&tree, out, err);
        if (st == MS_OK && reference && out->levels > 0)
            st = measure(&chunk, o.cube_origin, o.cube_size, reference, &out->accuracy, err);
    }
    ms_apo_chunk_free(&chunk);
    ms_apo_tree_free(&tree);
    if (st != MS_OK)
        ms_bake_apo_result_free(out);
    return st;
}
