/* APO builder: level-by-level adaptive octree around m, then the leaves sampled
 * from M (ms_apo_sample.c) and the means. */
#include "ms_apo_build.h"

#include <embree3/rtcore.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_correct.h"
#include "ms_apo_local_mesh.h"
#include "ms_apo_sample.h"
#include "ms_apo_u32vec.h"
#include "ms_parallel.h"
#include "ms_progress.h"
#include "ms_tri_box.h"

struct ms_apo_builder {
    RTCDevice device;
};

/* ---------------------------------------------------------------- octree levels */

/* One level under construction: its nodes' cells and the triangle lists. */
typedef struct build_level {
    size_t count;
    uint32_t *cell;      /* 3 per node */
    uint64_t *m_off;     /* count + 1 offsets into m_idx */
    uint32_t *m_idx;
    uint64_t *big_off;   /* count + 1 offsets into big_idx (M-triangles) */
    uint32_t *big_idx;
    uint8_t *child_mask; /* decided while splitting */
} build_level;

static void build_level_free_big(build_level *l)
{
    free(l->big_off);
    free(l->big_idx);
    l->big_off = NULL;
    l->big_idx = NULL;
}

/* Once level l is split: its M lists for its leaves only, which sample with
 * them; the internal nodes' are dropped (the children hold theirs). */
static ms_status keep_leaf_lists(build_level *l, ms_error *err)
{
    if (!l->big_off)
        return MS_OK;
    size_t kept = 0;
    for (size_t i = 0; i < l->count; ++i)
        if (!l->child_mask || !l->child_mask[i])
            kept += (size_t)(l->big_off[i + 1] - l->big_off[i]);
    uint32_t *idx = malloc((kept + 1) * sizeof *idx);
    if (!idx)
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for the leaves' lists");
    uint64_t at = 0;
    for (size_t i = 0; i < l->count; ++i) {
        uint64_t from = l->big_off[i], to = l->big_off[i + 1];
        l->big_off[i] = at;
        if (!l->child_mask || !l->child_mask[i]) {
            memcpy(&idx[at], &l->big_idx[from], (size_t)(to - from) * sizeof *idx);
            at += to - from;
        }
    }
    l->big_off[l->count] = at;
    free(l->big_idx);
    l->big_idx = idx;
    return MS_OK;
}

static void build_level_free(build_level *l)
{
    free(l->cell);
    free(l->m_off);
    free(l->m_idx);
    free(l->child_mask);
    build_level_free_big(l);
    memset(l, 0, sizeof *l);
}

/* Output of one block of a level split: the children it created, in order. */
typedef struct split_out {
    u32vec cells;     /* 3 per child */
    u32vec m_count;   /* per child */
    u32vec big_count; /* per child */
    u32vec m_idx;
    u32vec big_idx;
    uint64_t visits;  /* list entries made: the split's work */
    bool failed;
} split_out;

static void split_out_free(split_out *s)
{
    u32vec_free(&s->cells);
    u32vec_free(&s->m_count);
    u32vec_free(&s->big_count);
    u32vec_free(&s->m_idx);
    u32vec_free(&s->big_idx);
}

typedef struct split_job {
    const ms_apo_build_options *o;
    const ms_apo_local_mesh *m, *big;
    build_level *level;
    uint32_t depth;
    bool crowded;   /* grown M lists, kept for the leaves */
    size_t block_size;
    split_out *out;
} split_job;

static double variation(const split_job *job, const uint32_t *idx, size_t n)
{
    const ms_apo_local_mesh *big = job->big;
    double s[3] = {0, 0, 0}, weight = 0.0;
    if (job->o->measure == MS_APO_MEASURE_CLASSIC) {
        for (size_t i = 0; i < n; ++i) {
            uint32_t t = idx[i];
            if (big->area[t] <= 0.0f)
                continue;
            for (int a = 0; a < 3; ++a)
                s[a] += big->fnormal[3 * t + a];
            weight += 1.0;
        }
        if (weight == 0.0)
            return 0.0;
        /* sum |n_i - mean|^2 = N - |S|^2 / N for unit n_i. */
        return weight - (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) / weight;
    }
    for (size_t i = 0; i < n; ++i) {
        uint32_t t = idx[i];
        double a_t = big->area[t];
        for (int a = 0; a < 3; ++a)
            s[a] += a_t * big->fnormal[3 * t + a];
        weight += a_t;
    }
    if (weight <= 0.0)
        return 0.0;
    double mean_len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]) / weight;
    double chord2 = 2.0 * (1.0 - mean_len);
    return chord2 > 0.0 ? sqrt(chord2) : 0.0;
}

/* The split rule for a node at `depth` touching the M-triangles idx[0..n). */
static bool splits(const split_job *job, uint32_t depth, const uint32_t *idx, size_t n)
{
    if (depth >= job->o->max_depth)
        return false;
    if (depth < job->o->init_depth)
        return true;
    return n > 0 && variation(job, idx, n) > job->o->tolerance;
}

/* A triangle with a vertex in the closed cube (centre c, half-width half)
 * touches it: no axis to test. On a crowded M most list entries are slivers
 * around a shared vertex, and every node near it holds them all. */
static bool vertex_in_cube(const float c[3], float half, const float *p0, const float *p1, const float *p2)
{
    const float *p[3] = {p0, p1, p2};
    for (int k = 0; k < 3; ++k)
        if (fabsf(p[k][0] - c[0]) <= half && fabsf(p[k][1] - c[1]) <= half && fabsf(p[k][2] - c[2]) <= half)
            return true;
    return false;
}

/* Which of the `wanted` children of the cell (centre c; children of half-width
 * `quarter`) triangle t touches: a bit mask of octants. */
static uint32_t child_octants(const ms_apo_local_mesh *lm, uint32_t t, const float c[3], float quarter, uint32_t wanted)
{
    /* The triangle's stored bounds: its corners are fetched only where it
     * straddles a mid-plane (most triangles, small against the cell, do not). */
    const float *b = &lm->box[6 * t];
    /* Octants on the lower / upper side of each axis, as masks (x is bit 2). */
    uint32_t x = (b[0] <= c[0] ? 0x0Fu : 0u) | (b[3] >= c[0] ? 0xF0u : 0u);
    uint32_t y = (b[1] <= c[1] ? 0x33u : 0u) | (b[4] >= c[1] ? 0xCCu : 0u);
    uint32_t z = (b[2] <= c[2] ? 0x55u : 0u) | (b[5] >= c[2] ? 0xAAu : 0u);
    uint32_t mask = x & y & z;
    /* A single candidate needs no test: the triangle touches the parent, and
     * its bounds lie on one side of every mid-plane. */
    if ((mask & (mask - 1u)) == 0)
        return mask & wanted;
    mask &= wanted;
    const uint32_t *v = &lm->tri[3 * t];
    const float *p[3] = {&lm->pos[3 * v[0]], &lm->pos[3 * v[1]], &lm->pos[3 * v[2]]};
    /* A vertex in a child's closed cube settles it without the 13 axes: most
     * triangles that straddle a mid-plane have one in each octant they touch
     * (on a crowded M, slivers around a shared vertex). The children each
     * vertex lies in, from the same tests vertex_in_cube makes per child (the
     * child's centre c +- quarter on each axis), made once per vertex and axis. */
    const uint32_t lower[3] = {0x0Fu, 0x33u, 0x55u};
    uint32_t holds = 0;
    for (int k = 0; k < 3; ++k) {
        uint32_t in = 0xFFu;
        for (int a = 0; a < 3; ++a)
            in &= (fabsf(p[k][a] - (c[a] + -quarter)) <= quarter ? lower[a] : 0u) |
                  (fabsf(p[k][a] - (c[a] + quarter)) <= quarter ? (uint32_t)~lower[a] & 0xFFu : 0u);
        holds |= in;
    }
    uint32_t kept = mask & holds;
    for (uint32_t left = mask & ~holds; left; left &= left - 1u) {
        uint32_t o = (uint32_t)__builtin_ctz(left);
        float cc[3] = {c[0] + ((o >> 2 & 1u) ? quarter : -quarter), c[1] + ((o >> 1 & 1u) ? quarter : -quarter),
                       c[2] + ((o & 1u) ? quarter : -quarter)};
        if (ms_tri_cube_overlap(cc, quarter, p[0], p[1], p[2]))
            kept |= 1u << o;
    }
    return kept;
}

/* Crowded M (ms_apo_crowding above MS_APO_CROWDED): each node keeps the list
 * of the M-triangles touching its cube grown to MS_APO_LIST_REACH times its
 * half-width around its centre (capped: MS_APO_LIST_CAP), and a leaf answers
 * its rays and closest points from its list alone (ms_apo_sample_leaf; M
 * strays from m by up to h, often beyond the leaf itself). The grown cubes
 * nest (a child's lies inside its parent's for any reach >= 1), so each list
 * is its parent's, filtered. Uncrowded M: lists of the nodes' own cubes, none
 * for the leaves, every query by Embree, which answers those fastest. */
#define MS_APO_LIST_REACH 2.0f
#define MS_APO_CROWDED 64.0

/* Crowded M: a node keeps at most this many of the M-triangles touching its
 * grown cube, every k-th of them in M's order where more do (k the smallest
 * that fits), so that a node's work is bounded whatever the number of slivers
 * crossing it: the split rule weighs the kept ones, the leaves sample them.
 * On a fan the kept slivers are evenly spread in angle (M's order is the
 * fan's), their normals those of their dropped neighbours. */
#define MS_APO_LIST_CAP 256u

/* Which of the `wanted` children's grown cubes (centres c +- quarter, half-width
 * reach) triangle t touches: a bit mask of octants. */
static uint32_t child_reach(const ms_apo_local_mesh *lm, uint32_t t, const float c[3], float quarter, float reach,
                            uint32_t wanted)
{
    const uint32_t *v = &lm->tri[3 * t];
    const float *p0 = &lm->pos[3 * v[0]], *p1 = &lm->pos[3 * v[1]], *p2 = &lm->pos[3 * v[2]];
    uint32_t side[3];
    const float *lo3 = &lm->box[6 * t], *hi3 = lo3 + 3;
    const uint32_t lower[3] = {0x0Fu, 0x33u, 0x55u};
    for (int a = 0; a < 3; ++a) {
        float lo = lo3[a], hi = hi3[a];
        side[a] = (lo <= c[a] - quarter + reach && hi >= c[a] - quarter - reach ? lower[a] : 0u) |
                  (lo <= c[a] + quarter + reach && hi >= c[a] + quarter - reach ? (uint32_t)~lower[a] & 0xFFu : 0u);
    }
    uint32_t mask = side[0] & side[1] & side[2] & wanted, kept = 0;
    for (uint32_t o = 0; o < 8; ++o) {
        if (!(mask >> o & 1u))
            continue;
        float cc[3] = {c[0] + ((o >> 2 & 1u) ? quarter : -quarter), c[1] + ((o >> 1 & 1u) ? quarter : -quarter),
                       c[2] + ((o & 1u) ? quarter : -quarter)};
        /* bounds inside the cube: touching without the 13 axes */
        if ((lo3[0] >= cc[0] - reach && hi3[0] <= cc[0] + reach && lo3[1] >= cc[1] - reach &&
             hi3[1] <= cc[1] + reach && lo3[2] >= cc[2] - reach && hi3[2] <= cc[2] + reach) ||
            vertex_in_cube(cc, reach, p0, p1, p2) || ms_tri_cube_overlap(cc, reach, p0, p1, p2))
            kept |= 1u << o;
    }
    return kept;
}

/* The entries of a node's grown list that touch its own cube (centre c,
 * half-width half): what the split rule weighs, in the list's order. */
static bool own_list(const ms_apo_local_mesh *lm, const uint32_t *idx, size_t n, const float c[3], float half,
                     u32vec *out)
{
    out->n = 0;
    for (size_t k = 0; k < n; ++k) {
        const uint32_t *v = &lm->tri[3 * idx[k]];
        const float *p0 = &lm->pos[3 * v[0]], *p1 = &lm->pos[3 * v[1]], *p2 = &lm->pos[3 * v[2]];
        if ((vertex_in_cube(c, half, p0, p1, p2) || ms_tri_cube_overlap(c, half, p0, p1, p2)) &&
            !u32vec_push(out, idx[k]))
            return false;
    }
    return true;
}

static void split_block(void *ctx, size_t block)
{
    split_job *job = ctx;
    build_level *l = job->level;
    split_out *out = &job->out[block];
    size_t first = block * job->block_size, last = first + job->block_size;
    if (last > l->count)
        last = l->count;
    uint32_t depth = job->depth;
    float width = ldexpf(1.0f, -(int)depth), quarter = width * 0.25f;
    u32vec child_m[8], child_big[8], own = {0};
    memset(child_m, 0, sizeof child_m);
    memset(child_big, 0, sizeof child_big);
    for (size_t i = first; i < last && !out->failed; ++i) {
        l->child_mask[i] = 0;
        const uint32_t *big_idx = &l->big_idx[l->big_off[i]];
        size_t big_n = (size_t)(l->big_off[i + 1] - l->big_off[i]);
        const uint32_t *cell = &l->cell[3 * i];
        float c[3];
        for (int a = 0; a < 3; ++a)
            c[a] = ((float)cell[a] + 0.5f) * width;
        /* The rule weighs the triangles touching the node's own cube. */
        bool decide = depth < job->o->max_depth && depth >= job->o->init_depth;
        if (job->crowded && decide && !own_list(job->big, big_idx, big_n, c, 0.5f * width, &own)) {
            out->failed = true;
            break;
        }
        /* Uncrowded, below the root, the parent has weighed this list already
         * (a child keeps it only where the rule splits it, below): a list is
         * the answer. */
        bool split = decide && !job->crowded && depth > 0
                         ? big_n > 0
                         : splits(job, depth, job->crowded ? own.v : big_idx,
                                  !decide ? 0 : job->crowded ? own.n : big_n);
        if (!split)
            continue;
        for (int o = 0; o < 8; ++o) {
            child_m[o].n = 0;
            child_big[o].n = 0;
        }
        bool ok = true;
        for (uint64_t k = l->m_off[i]; k < l->m_off[i + 1] && ok; ++k) {
            uint32_t t = l->m_idx[k], mask = child_octants(job->m, t, c, quarter, 0xFFu);
            for (; mask && ok; mask &= mask - 1u) /* the set bits, lowest first */
                ok = u32vec_push(&child_m[__builtin_ctz(mask)], t);
        }
        uint32_t exist = 0;
        for (uint32_t o = 0; o < 8; ++o)
            if (child_m[o].n)
                exist |= 1u << o;
        /* Crowded: every child keeps its (grown) M list, a leaf samples with
         * it. Else children at the maximum depth never decide a split: they
         * need no M list. */
        bool children_split = depth + 1 < job->o->max_depth;
        for (size_t k = 0; k < big_n && ok && exist && (children_split || job->crowded); ++k) {
            uint32_t t = big_idx[k];
            uint32_t mask = job->crowded ? child_reach(job->big, t, c, quarter, MS_APO_LIST_REACH * quarter, exist)
                                         : child_octants(job->big, t, c, quarter, exist);
            for (; mask && ok; mask &= mask - 1u)
                ok = u32vec_push(&child_big[__builtin_ctz(mask)], t);
        }
        for (uint32_t o = 0; o < 8 && ok; ++o) {
            if (!(exist >> o & 1u))
                continue;
            /* Uncrowded, a child that will not split needs no M list: with an
             * empty list the rule above gives it the same answer (no split). */
            size_t big_keep = job->crowded || splits(job, depth + 1, child_big[o].v, child_big[o].n) ? child_big[o].n : 0;
            if (job->crowded && big_keep > MS_APO_LIST_CAP) {
                size_t stride = (big_keep + MS_APO_LIST_CAP - 1) / MS_APO_LIST_CAP, kept = 0;
                for (size_t k = 0; k < big_keep; k += stride)
                    child_big[o].v[kept++] = child_big[o].v[k];
                big_keep = child_big[o].n = kept;
            }
            job->out[block].visits += child_m[o].n + child_big[o].n;
            ok = u32vec_push(&out->cells, 2 * cell[0] + (o >> 2 & 1u)) &&
                 u32vec_push(&out->cells, 2 * cell[1] + (o >> 1 & 1u)) &&
                 u32vec_push(&out->cells, 2 * cell[2] + (o & 1u)) &&
                 u32vec_push(&out->m_count, (uint32_t)child_m[o].n) &&
                 u32vec_push(&out->big_count, (uint32_t)big_keep);
            ok = ok && u32vec_append(&out->m_idx, child_m[o].v, child_m[o].n) &&
                 u32vec_append(&out->big_idx, child_big[o].v, big_keep);
        }
        if (!ok)
            out->failed = true;
        l->child_mask[i] = (uint8_t)exist;
    }
    for (int o = 0; o < 8; ++o) {
        u32vec_free(&child_m[o]);
        u32vec_free(&child_big[o]);
    }
    u32vec_free(&own);
}

/* ---------------------------------------------------------------- sampling */

typedef struct sample_job {
    const ms_apo_build_options *o;
    float *predicted;              /* 3 per node, or NULL: m's smooth normal at the leaf's samples */
    const ms_apo_local_mesh *m;
    const ms_apo_sampler *sampler;
    ms_apo_tree *tree;
    const build_level *levels;
    double h;                      /* m-to-M distance estimate */
    size_t block_size;
    ms_apo_sample_counts *counts;  /* per block */
} sample_job;

static void sample_block(void *ctx, size_t block)
{
    sample_job *job = ctx;
    ms_apo_tree *tree = job->tree;
    size_t first = block * job->block_size, last = first + job->block_size;
    if (last > tree->node_count)
        last = tree->node_count;
    for (size_t i = first; i < last; ++i) {
        ms_apo_node *node = &tree->nodes[i];
        if (node->child_mask)
            continue;
        const build_level *l = &job->levels[node->depth];
        size_t li = i - tree->level_start[node->depth];
        float width = ldexpf(1.0f, -(int)node->depth);
        float centre[3];
        for (int a = 0; a < 3; ++a)
            centre[a] = ((float)node->cell[a] + 0.5f) * width;
        float s = job->o->search_distance > 0 ? (float)job->o->search_distance
                                               : (float)(2.0 * job->h + 0.8660254037844386 * width);
        ms_apo_leaf_probe probe = {.half_width = 0.5f * width * MS_APO_LIST_REACH,
                                   .m_tris = &l->m_idx[l->m_off[li]],
                                   .m_count = (size_t)(l->m_off[li + 1] - l->m_off[li])};
        if (l->big_off) { /* crowded M: the leaf's own list */
            probe.big_tris = &l->big_idx[l->big_off[li]];
            probe.big_count = (size_t)(l->big_off[li + 1] - l->big_off[li]);
            probe.listed = true;
        }
        probe.agreement = (float)job->o->sample_agreement;
        job->counts[block].leaves++;
        memcpy(probe.centre, centre, sizeof centre);
        ms_apo_sample_leaf(job->sampler, job->m, &probe, s, node->normal,
                           job->predicted ? &job->predicted[3 * i] : NULL, &job->counts[block]);
    }
}

/* ---------------------------------------------------------------- driver */

void ms_apo_build_options_default(ms_apo_build_options *o)
{
    memset(o, 0, sizeof *o);
    o->cube_size = 1.0;
    o->init_depth = 0;
    o->max_depth = 12;
    o->tolerance = 0.05;
    o->measure = MS_APO_MEASURE_SPREAD;
    o->correction = false;
    o->correction_tolerance = 0.2;
    o->crease_angle = M_PI / 3.0;
    o->vertex_error = 0.0;
}

ms_status ms_apo_builder_create(ms_apo_builder **builder, ms_error *err)
{
    *builder = NULL;
    ms_apo_builder *b = calloc(1, sizeof *b);
    if (!b)
        return ms_error_set(err, MS_ERR_NOMEM, "apo builder: no memory");
    b->device = rtcNewDevice(NULL);
    if (!b->device) {
        free(b);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "apo builder: Embree device creation failed");
    }
    *builder = b;
    return MS_OK;
}

void ms_apo_builder_destroy(ms_apo_builder *builder)
{
    if (!builder)
        return;
    rtcReleaseDevice(builder->device);
    free(builder);
}

#define SPLIT_BLOCKS_MAX 512u
#define SPLIT_BLOCK_MIN 64u

static size_t block_size_for(size_t count, size_t max_blocks, size_t min_size)
{
    size_t bs = (count + max_blocks - 1) / max_blocks;
    return bs < min_size ? min_size : bs;
}

/* Splits level `d` into level d+1 (possibly empty). */
static ms_status split_level(const ms_apo_build_options *o, unsigned threads, const ms_apo_local_mesh *m,
                             const ms_apo_local_mesh *big, bool crowded, build_level *l, uint32_t d,
                             build_level *next, uint64_t *visits, ms_error *err)
{
    memset(next, 0, sizeof *next);
    size_t bs = block_size_for(l->count, SPLIT_BLOCKS_MAX, SPLIT_BLOCK_MIN);
    size_t blocks = (l->count + bs - 1) / bs;
    split_out *out = calloc(blocks, sizeof *out);
    l->child_mask = calloc(l->count + 1, 1);
    if (!out || !l->child_mask) {
        free(out);
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory to split level %u", d);
    }
    split_job job = {.o = o, .m = m, .big = big, .level = l, .depth = d, .crowded = crowded, .block_size = bs,
                     .out = out};
    ms_status st = ms_parallel_for(threads, blocks, split_block, &job, err);
    size_t children = 0, m_total = 0, big_total = 0;
    for (size_t b = 0; b < blocks && st == MS_OK; ++b) {
        if (out[b].failed)
            st = ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory while splitting level %u", d);
        children += out[b].m_count.n;
        *visits += out[b].visits;
        m_total += out[b].m_idx.n;
        big_total += out[b].big_idx.n;
    }
    if (st == MS_OK && children > 0) {
        next->count = children;
        next->cell = malloc(3 * children * sizeof *next->cell);
        next->m_off = malloc((children + 1) * sizeof *next->m_off);
        next->big_off = malloc((children + 1) * sizeof *next->big_off);
        next->m_idx = malloc((m_total + 1) * sizeof *next->m_idx);
        next->big_idx = malloc((big_total + 1) * sizeof *next->big_idx);
        if (!next->cell || !next->m_off || !next->big_off || !next->m_idx || !next->big_idx) {
            st = ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for level %u", d + 1);
        } else {
            size_t c = 0, mi = 0, bi = 0;
            next->m_off[0] = 0;
            next->big_off[0] = 0;
            for (size_t b = 0; b < blocks; ++b) {
                split_out *s = &out[b];
                if (s->cells.n)
                    memcpy(&next->cell[3 * c], s->cells.v, s->cells.n * sizeof *s->cells.v);
                if (s->m_idx.n)
                    memcpy(&next->m_idx[mi], s->m_idx.v, s->m_idx.n * sizeof *s->m_idx.v);
                if (s->big_idx.n)
                    memcpy(&next->big_idx[bi], s->big_idx.v, s->big_idx.n * sizeof *s->big_idx.v);
                for (size_t k = 0; k < s->m_count.n; ++k) {
                    next->m_off[c + k + 1] = next->m_off[c + k] + s->m_count.v[k];
                    next->big_off[c + k + 1] = next->big_off[c + k] + s->big_count.v[k];
                }
                c += s->m_count.n;
                mi += s->m_idx.n;
                bi += s->big_idx.n;
            }
        }
    }
    for (size_t b = 0; b < blocks; ++b)
        split_out_free(&out[b]);
    free(out);
    if (st != MS_OK)
        build_level_free(next);
    return st;
}

/* The root level: every m- and M-triangle that touches the cube (none when
 * no m-triangle does: *level_count stays 0). */
static ms_status root_level(const ms_apo_local_mesh *m, const ms_apo_local_mesh *big, float reach,
                            build_level *root, uint32_t *level_count, ms_error *err)
{
    u32vec mi = {0}, bi = {0};
    const float c[3] = {0.5f, 0.5f, 0.5f};
    bool ok = true;
    /* A corner in the cube settles it without the 13 axes (most triangles of
     * the cell's own m and M lie inside its cube). */
    for (uint32_t t = 0; t < m->triangle_count && ok; ++t) {
        const uint32_t *v = &m->tri[3 * t];
        const float *p0 = &m->pos[3 * v[0]], *p1 = &m->pos[3 * v[1]], *p2 = &m->pos[3 * v[2]];
        if (vertex_in_cube(c, 0.5f, p0, p1, p2) || ms_tri_cube_overlap(c, 0.5f, p0, p1, p2))
            ok = u32vec_push(&mi, t);
    }
    for (uint32_t t = 0; t < big->triangle_count && ok && mi.n; ++t) {
        const uint32_t *v = &big->tri[3 * t];
        const float *p0 = &big->pos[3 * v[0]], *p1 = &big->pos[3 * v[1]], *p2 = &big->pos[3 * v[2]];
        if (vertex_in_cube(c, 0.5f * reach, p0, p1, p2) || ms_tri_cube_overlap(c, 0.5f * reach, p0, p1, p2))
            ok = u32vec_push(&bi, t);
    }
    if (ok && mi.n) {
        root->count = 1;
        root->cell = calloc(3, sizeof *root->cell);
        root->m_off = malloc(2 * sizeof *root->m_off);
        root->big_off = malloc(2 * sizeof *root->big_off);
        ok = root->cell && root->m_off && root->big_off;
        if (ok) {
            root->m_off[0] = root->big_off[0] = 0;
            root->m_off[1] = mi.n;
            root->big_off[1] = bi.n;
            root->m_idx = mi.v;
            root->big_idx = bi.v ? bi.v : malloc(sizeof(uint32_t));
            mi.v = NULL;
            bi.v = NULL;
            ok = root->big_idx != NULL;
        }
        *level_count = 1;
    }
    u32vec_free(&mi);
    u32vec_free(&bi);
    if (!ok)
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for the root");
    return MS_OK;
}

/* The levels as the tree's node array, breadth-first. */
static ms_status flatten_levels(const build_level *levels, uint32_t level_count, ms_apo_tree *tree,
                                ms_error *err)
{
    size_t total = 0;
    for (uint32_t d = 0; d < level_count; ++d)
        total += levels[d].count;
    tree->nodes = calloc(total, sizeof *tree->nodes);
    if (!tree->nodes)
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory for %zu nodes", total);
    size_t idx = 0;
    for (uint32_t d = 0; d < level_count; ++d) {
        tree->level_start[d] = idx;
        size_t child = idx + levels[d].count;
        for (size_t i = 0; i < levels[d].count; ++i, ++idx) {
            ms_apo_node *n = &tree->nodes[idx];
            memcpy(n->cell, &levels[d].cell[3 * i], sizeof n->cell);
            n->depth = (uint8_t)d;
            n->child_mask = levels[d].child_mask ? levels[d].child_mask[i] : 0;
            if (n->child_mask) {
                n->first_child = (uint32_t)child;
                child += (size_t)ms_apo_popcount8(n->child_mask);
            }
        }
    }
    tree->node_count = total;
    tree->level_count = level_count;
    tree->level_start[level_count] = total;
    return MS_OK;
}

/* Leaf normals sampled on M, then the means up the tree. */
static ms_status sample_normals(const ms_apo_build_options *o, unsigned threads,
                                const ms_apo_local_mesh *m, ms_apo_sampler *sampler,
                                ms_apo_tree *tree, build_level *levels, ms_apo_build_stats *stats,
                                ms_error *err)
{
    size_t bs = block_size_for(tree->node_count, 1024, 256);
    size_t blocks = (tree->node_count + bs - 1) / bs;
    ms_apo_sample_counts *counts = calloc(blocks, sizeof *counts);
    float *predicted = o->correction ? malloc(3 * tree->node_count * sizeof *predicted) : NULL;
    if (!counts || (o->correction && !predicted)) {
        free(counts);
        free(predicted);
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory");
    }
    sample_job sj = {.o = o, .predicted = predicted, .m = m, .sampler = sampler, .tree = tree, .levels = levels,
                     .h = stats->m_to_M_distance, .block_size = bs, .counts = counts};
    ms_status st = ms_parallel_for(threads, blocks, sample_block, &sj, err);
    for (size_t b = 0; b < blocks; ++b) {
        stats->samples += counts[b].samples;
        stats->ray_hits += counts[b].ray_hits;
        stats->rays += counts[b].rays;
        stats->point_queries += counts[b].point_queries;
        stats->local_answers += counts[b].local_answers;
        stats->triangle_visits += counts[b].triangle_tests;
        stats->closest_points += counts[b].closest_points;
        stats->unsampled += counts[b].unsampled;
        stats->sampled_leaves += counts[b].leaves;
        stats->agreed_leaves += counts[b].agreed;
    }
    free(counts);
    ms_apo_tree_average_normals(tree);
    if (st == MS_OK && predicted)
        st = ms_apo_correct(tree, predicted, o->correction_tolerance, &stats->smooth_leaves, err);
    free(predicted);
    return st;
}

ms_status ms_apo_builder_build_tree(ms_apo_builder *builder, const ms_mesh *m_mesh, const ms_mesh *big_mesh,
                                    const ms_apo_build_options *o, ms_apo_tree *tree, ms_apo_build_stats *stats,
                                    ms_error *err)
{
    memset(tree, 0, sizeof *tree);
    ms_apo_build_stats st_local;
    if (!stats)
        stats = &st_local;
    memset(stats, 0, sizeof *stats);
    if (!(o->cube_size > 0.0) || !isfinite(o->cube_size) || o->max_depth > MS_APO_MAX_DEPTH ||
        !(o->tolerance >= 0.0) || !isfinite(o->cube_origin[0] + o->cube_origin[1] + o->cube_origin[2]) ||
        (o->measure != MS_APO_MEASURE_SPREAD && o->measure != MS_APO_MEASURE_CLASSIC) ||
        !(o->search_distance < 1e30) || !(o->distance_bound < 1e30) || !(o->sample_agreement < 1e30) ||
        (o->correction && (!(o->correction_tolerance >= 0.0) || !(o->crease_angle >= 0.0) ||
                           !(o->vertex_error >= 0.0) || !(o->vertex_error < 1e30) || !(o->crease_angle < 1e30))))
        return ms_error_set(err, MS_ERR_ARG, "apo build: bad options (cube size %g, max depth %u, tolerance %g)",
                            o->cube_size, o->max_depth, o->tolerance);
    unsigned threads = o->threads ? o->threads : ms_parallel_cores();
    double t0 = ms_now_seconds();
    ms_apo_local_mesh m, big;
    ms_status st = ms_apo_local_mesh_make(m_mesh, o->cube_origin, o->cube_size, "m", &m, err);
    if (st != MS_OK)
        return st;
    if (o->correction)
        st = ms_apo_local_mesh_corner_normals(&m, o->crease_angle, o->vertex_error, err);
    if (st == MS_OK)
        st = ms_apo_local_mesh_make(big_mesh, o->cube_origin, o->cube_size, "M", &big, err);
    if (st != MS_OK) {
        ms_apo_local_mesh_free(&m);
        return st;
    }
    ms_apo_sampler sampler;
    memset(&sampler, 0, sizeof sampler);
    build_level levels[MS_APO_MAX_LEVELS];
    memset(levels, 0, sizeof levels);
    uint32_t level_count = 0;

    stats->crowding = ms_apo_crowding(&big);
    bool crowded = stats->crowding > MS_APO_CROWDED;
    st = root_level(&m, &big, crowded ? MS_APO_LIST_REACH : 1.0f, &levels[0], &level_count, err);
    double t1 = ms_now_seconds();

    /* Octree, level by level. */
    for (uint32_t d = 0; st == MS_OK && d < level_count && d < MS_APO_MAX_DEPTH; ++d) {
        build_level next;
        st = split_level(o, threads, &m, &big, crowded, &levels[d], d, &next, &stats->triangle_visits, err);
        if (st == MS_OK && crowded)
            st = keep_leaf_lists(&levels[d], err);
        else
            build_level_free_big(&levels[d]);
        if (st == MS_OK && next.count) {
            levels[d + 1] = next;
            level_count = d + 2;
        }
    }
    if (st == MS_OK && level_count)
        st = flatten_levels(levels, level_count, tree, err);
    /* The triangles' bounds served the split alone: gone before Embree's
     * scene, which the octree does not need, is built (the peak is one or
     * the other, not both). */
    free(m.box);
    free(big.box);
    m.box = big.box = NULL;
    double t2 = ms_now_seconds();
    stats->seconds_octree = t2 - t1;

    /* Embree scene for M, and h. */
    if (st == MS_OK && level_count)
        st = ms_apo_sampler_init(&sampler, builder->device, &big, err);
    double td = ms_now_seconds();
    stats->seconds_scene = td - t2;
    if (st == MS_OK && level_count && o->search_distance <= 0 && o->distance_bound > 0)
        stats->m_to_M_distance = o->distance_bound;
    else if (st == MS_OK && level_count && o->search_distance <= 0)
        st = ms_apo_sampler_distance(&sampler, &m, threads, &stats->m_to_M_distance, err);
    double t3 = ms_now_seconds();
    stats->seconds_distance = t3 - td;
    stats->seconds_prepare = (t1 - t0) + (t3 - t2);
    t2 = t3;

    /* Leaf normals, then the means. */
    if (st == MS_OK && tree->node_count)
        st = sample_normals(o, threads, &m, &sampler, tree, levels, stats, err);
    stats->seconds_sample = ms_now_seconds() - t2;
    if (st == MS_OK) {
        ms_apo_tree_counts(tree, &stats->internal_nodes, &stats->leaves);
        stats->levels = tree->level_count;
    } else {
        ms_apo_tree_free(tree);
    }
    for (uint32_t d = 0; d < MS_APO_MAX_LEVELS; ++d)
        build_level_free(&levels[d]);
    ms_apo_sampler_release(&sampler);
    ms_apo_local_mesh_free(&m);
    ms_apo_local_mesh_free(&big);
    return st;
}

ms_status ms_apo_builder_build_chunk(ms_apo_builder *builder, const ms_mesh *m, const ms_mesh *M,
                                     const ms_apo_build_options *options, ms_apo_chunk *chunk,
                                     ms_apo_build_stats *stats, ms_error *err)
{
    memset(chunk, 0, sizeof *chunk);
    ms_apo_tree tree;
    ms_status st = ms_apo_builder_build_tree(builder, m, M, options, &tree, stats, err);
    if (st != MS_OK)
        return st;
    st = ms_apo_chunk_encode(&tree, chunk, err);
    ms_apo_tree_free(&tree);
    return st;
}
