/* Embree probes of M for the APO builder (see ms_apo_sample.h). */
#include "ms_apo_sample.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_parallel.h"

typedef struct closest_query {
    const ms_apo_local_mesh *big;
    float point[3];
    double best_d2;
    uint32_t best_prim;
    float best_uv[2];
} closest_query;

/* Closest point of triangle (a, b, c) to p, as barycentric weights of b and c. */
static double closest_on_triangle(const float p[3], const float a[3], const float b[3], const float c[3],
                                  float *wb, float *wc)
{
    double ab[3], ac[3], ap[3];
    for (int k = 0; k < 3; ++k) {
        ab[k] = (double)b[k] - a[k];
        ac[k] = (double)c[k] - a[k];
        ap[k] = (double)p[k] - a[k];
    }
#define DOT(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT(ab, ap), d2 = DOT(ac, ap);
    double v, w;
    if (d1 <= 0 && d2 <= 0) {
        v = 0;
        w = 0;
    } else {
        double bp[3], cp[3];
        for (int k = 0; k < 3; ++k) {
            bp[k] = (double)p[k] - b[k];
            cp[k] = (double)p[k] - c[k];
        }
        double d3 = DOT(ab, bp), d4 = DOT(ac, bp), d5 = DOT(ab, cp), d6 = DOT(ac, cp);
        double vc = d1 * d4 - d3 * d2, vb = d5 * d2 - d1 * d6, va = d3 * d6 - d5 * d4;
        if (d3 >= 0 && d4 <= d3) {
            v = 1;
            w = 0;
        } else if (d6 >= 0 && d5 <= d6) {
            v = 0;
            w = 1;
        } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
            v = d1 / (d1 - d3);
            w = 0;
        } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
            v = 0;
            w = d2 / (d2 - d6);
        } else if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
            w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            v = 1 - w;
        } else {
            double sum = va + vb + vc;
            if (!(sum > 0)) { /* degenerate triangle: fall back to vertex a */
                v = 0;
                w = 0;
            } else {
                v = vb / sum;
                w = vc / sum;
            }
        }
    }
#undef DOT
    double d2sum = 0;
    for (int k = 0; k < 3; ++k) {
        double q = a[k] + v * ab[k] + w * ac[k] - p[k];
        d2sum += q * q;
    }
    *wb = (float)v;
    *wc = (float)w;
    return d2sum;
}

static bool closest_callback(struct RTCPointQueryFunctionArguments *args)
{
    closest_query *q = args->userPtr;
    uint32_t prim = args->primID;
    const uint32_t *v = &q->big->tri[3 * prim];
    const float *pos = q->big->pos;
    float wb, wc;
    double d2 = closest_on_triangle(q->point, &pos[3 * v[0]], &pos[3 * v[1]], &pos[3 * v[2]], &wb, &wc);
    double r = args->query->radius;
    if (d2 > r * r)
        return false;
    if (d2 < q->best_d2 || (d2 == q->best_d2 && prim < q->best_prim)) {
        q->best_d2 = d2;
        q->best_prim = prim;
        q->best_uv[0] = wb;
        q->best_uv[1] = wc;
        args->query->radius = (float)sqrt(d2);
        return true;
    }
    return false;
}

/* Closest point of M to p within radius: true and its normal, or false. */
static bool closest_normal(RTCScene scene, const ms_apo_local_mesh *big, const float p[3], float radius, double n[3])
{
    closest_query q = {.big = big, .best_d2 = INFINITY, .best_prim = UINT32_MAX};
    memcpy(q.point, p, sizeof q.point);
    struct RTCPointQuery query = {.x = p[0], .y = p[1], .z = p[2], .time = 0.0f, .radius = radius};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(scene, &query, &ctx, closest_callback, &q);
    if (q.best_prim == UINT32_MAX)
        return false;
    ms_apo_local_mesh_normal_at(big, q.best_prim, q.best_uv[0], q.best_uv[1], n);
    return true;
}

/* Nearest hit along +dir or -dir within [0, s]; +dir wins ties. */
static bool ray_normal(RTCScene scene, const ms_apo_local_mesh *big, const float o[3], const double dir[3], float s,
                       double n[3], uint64_t *rays)
{
    float best_t = INFINITY, best_u = 0, best_v = 0;
    uint32_t best_prim = UINT32_MAX;
    for (int sign = 1; sign >= -1; sign -= 2) {
        struct RTCRayHit rh;
        memset(&rh, 0, sizeof rh);
        rh.ray.org_x = o[0];
        rh.ray.org_y = o[1];
        rh.ray.org_z = o[2];
        rh.ray.dir_x = (float)(sign * dir[0]);
        rh.ray.dir_y = (float)(sign * dir[1]);
        rh.ray.dir_z = (float)(sign * dir[2]);
        rh.ray.tnear = 0.0f;
        rh.ray.tfar = best_t < s ? best_t : s; /* the second ray only needs to beat the first */
        rh.ray.mask = UINT32_MAX;
        rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
        rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
        struct RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        rtcIntersect1(scene, &ctx, &rh);
        ++*rays;
        if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID && rh.ray.tfar < best_t) {
            best_t = rh.ray.tfar;
            best_u = rh.hit.u;
            best_v = rh.hit.v;
            best_prim = rh.hit.primID;
        }
    }
    if (best_prim == UINT32_MAX)
        return false;
    ms_apo_local_mesh_normal_at(big, best_prim, best_u, best_v, n);
    return true;
}

ms_status ms_apo_sampler_init(ms_apo_sampler *sampler, RTCDevice device, const ms_apo_local_mesh *big,
                              ms_error *err)
{
    memset(sampler, 0, sizeof *sampler);
    RTCScene scene = rtcNewScene(device);
    RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!scene || !g) {
        if (scene)
            rtcReleaseScene(scene);
        if (g)
            rtcReleaseGeometry(g);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "apo build: Embree could not create a scene");
    }
    /* Embree reads M from the local mesh's own arrays (shared, not copied: 24
     * bytes per triangle less at the root's build); the local mesh outlives the
     * scene and its positions carry the padding Embree's 16-byte loads need. An
     * empty M gets one degenerate triangle of its own: never hit. */
    size_t nt = big->triangle_count;
    bool ok;
    if (nt && big->vertex_count) {
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, big->pos, 0, 3 * sizeof(float),
                                   big->vertex_count);
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, big->tri, 0, 3 * sizeof(unsigned),
                                   nt);
        ok = rtcGetDeviceError(device) == RTC_ERROR_NONE;
    } else {
        float *vb = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float), 1);
        unsigned *ib = rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), 1);
        ok = vb && ib;
        if (ok) {
            memset(vb, 0, 3 * sizeof(float));
            memset(ib, 0, 3 * sizeof(unsigned));
        }
    }
    if (!ok) {
        rtcReleaseGeometry(g);
        rtcReleaseScene(scene);
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: Embree buffers for %zu triangles", nt);
    }
    /* A few million rays per build: a fast (Morton) BVH build beats a better BVH. */
    rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_LOW);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_LOW);
    /* Compact leaves (vertex indices, not copies): a smaller BVH for the large M
     * of internal cells, which bound the bake's peak memory. */
    rtcSetSceneFlags(scene, RTC_SCENE_FLAG_COMPACT);
    rtcCommitGeometry(g);
    rtcAttachGeometry(scene, g);
    rtcReleaseGeometry(g);
    rtcCommitScene(scene);
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) {
        rtcReleaseScene(scene);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "apo build: Embree failed to build the scene");
    }
    sampler->scene = scene;
    sampler->big = big;
    return MS_OK;
}

void ms_apo_sampler_release(ms_apo_sampler *sampler)
{
    if (sampler->scene)
        rtcReleaseScene(sampler->scene);
    memset(sampler, 0, sizeof *sampler);
}


/* Leaf-local answers. A hit (or closest point) nearer to the leaf's centre
 * than its grown cube's faces, by a margin (a sixteenth of the half-width:
 * the float rounding of the triangle/box test that made the list), is inside
 * the cube, as is every nearer one: their triangles touch the cube and are in
 * the leaf's M-list, and the answer is M's. */

/* Ray o + t d against M-triangle tri (Moeller-Trumbore, double; both sides, as
 * Embree): true with t and the barycentric weights of vertices 1 and 2. */
static bool ray_triangle(const ms_apo_local_mesh *big, uint32_t tri, const double o[3], const double d[3], double *t,
                         double *u, double *v)
{
    const uint32_t *vi = &big->tri[3 * tri];
    const float *p0 = &big->pos[3 * vi[0]], *p1 = &big->pos[3 * vi[1]], *p2 = &big->pos[3 * vi[2]];
    double e1[3], e2[3], so[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = (double)p1[a] - p0[a];
        e2[a] = (double)p2[a] - p0[a];
        so[a] = o[a] - p0[a];
    }
    double pv[3] = {d[1] * e2[2] - d[2] * e2[1], d[2] * e2[0] - d[0] * e2[2], d[0] * e2[1] - d[1] * e2[0]};
    double det = e1[0] * pv[0] + e1[1] * pv[1] + e1[2] * pv[2];
    if (det == 0.0 || !isfinite(det))
        return false; /* parallel, or a degenerate triangle: Embree never hits those */
    double inv = 1.0 / det;
    double uu = (so[0] * pv[0] + so[1] * pv[1] + so[2] * pv[2]) * inv;
    if (!(uu >= 0.0 && uu <= 1.0))
        return false;
    double q[3] = {so[1] * e1[2] - so[2] * e1[1], so[2] * e1[0] - so[0] * e1[2], so[0] * e1[1] - so[1] * e1[0]};
    double vv = (d[0] * q[0] + d[1] * q[1] + d[2] * q[2]) * inv;
    if (!(vv >= 0.0 && uu + vv <= 1.0))
        return false;
    *t = (e2[0] * q[0] + e2[1] * q[1] + e2[2] * q[2]) * inv;
    *u = uu;
    *v = vv;
    return true;
}

typedef struct local_hit {
    double t;
    double u, v;
    uint32_t prim;
    bool found;
} local_hit;

static void keep_nearer(local_hit *h, double t, double u, double v, uint32_t prim)
{
    if (!h->found || t < h->t || (t == h->t && prim < h->prim)) {
        h->t = t;
        h->u = u;
        h->v = v;
        h->prim = prim;
        h->found = true;
    }
}

/* ray_normal over the leaf's M-triangles (the triangles touching its cube
 * grown MS_APO_LIST_REACH times): true (and the normal) when one of them is
 * hit within [-s, s]. The nearest such hit is M's nearest when it lies inside
 * the grown cube by a margin (see above); beyond, a triangle outside
 * the grown cube could be hit first, and the leaf's own hit is kept anyway:
 * Embree's queries on a crowded M cost a visit of a good part of M each (a
 * fan's sliver boxes all hold its hub), the leaf's list only its own. */
static bool local_ray_normal(const ms_apo_local_mesh *big, const ms_apo_leaf_probe *leaf, const double dir[3],
                             float s, double n[3], ms_apo_sample_counts *counts)
{
    /* Embree's rays: float origin and direction. */
    double o[3], d[3], dmax = 0.0;
    for (int a = 0; a < 3; ++a) {
        o[a] = leaf->centre[a];
        d[a] = (float)dir[a];
        if (fabs(d[a]) > dmax)
            dmax = fabs(d[a]);
    }
    if (!(dmax > 0.0) || leaf->big_count == 0)
        return false;
    local_hit plus = {0}, minus = {0};
    for (size_t k = 0; k < leaf->big_count; ++k) {
        double t, u, v;
        uint32_t prim = leaf->big_tris[k];
        if (!ray_triangle(big, prim, o, d, &t, &u, &v))
            continue;
        if (t >= 0.0 && t <= s)
            keep_nearer(&plus, t, u, v, prim);
        if (t <= 0.0 && -t <= s)
            keep_nearer(&minus, -t, u, v, prim);
    }
    counts->triangle_tests += leaf->big_count;
    /* +dir wins ties, as in ray_normal */
    const local_hit *best = plus.found && (!minus.found || plus.t <= minus.t) ? &plus : minus.found ? &minus : NULL;
    if (!best)
        return false;
    ms_apo_local_mesh_normal_at(big, best->prim, (float)best->u, (float)best->v, n);
    counts->local_answers++;
    return true;
}

/* closest_normal over the leaf's M-triangles, with the same distances and ties:
 * true when one lies within radius (M's closest point when inside the grown
 * cube by the margin; kept beyond it too, as local_ray_normal's hits). */
static bool local_closest_normal(const ms_apo_local_mesh *big, const ms_apo_leaf_probe *leaf, float radius,
                                 double n[3], ms_apo_sample_counts *counts)
{
    double best_d2 = INFINITY, r2 = (double)radius * radius;
    uint32_t best_prim = UINT32_MAX;
    float best_uv[2] = {0, 0};
    for (size_t k = 0; k < leaf->big_count; ++k) {
        uint32_t prim = leaf->big_tris[k];
        const uint32_t *v = &big->tri[3 * prim];
        float wb, wc;
        double d2 = closest_on_triangle(leaf->centre, &big->pos[3 * v[0]], &big->pos[3 * v[1]], &big->pos[3 * v[2]],
                                        &wb, &wc);
        if (d2 > r2)
            continue;
        if (d2 < best_d2 || (d2 == best_d2 && prim < best_prim)) {
            best_d2 = d2;
            best_prim = prim;
            best_uv[0] = wb;
            best_uv[1] = wc;
        }
    }
    counts->triangle_tests += leaf->big_count;
    if (best_prim == UINT32_MAX)
        return false;
    ms_apo_local_mesh_normal_at(big, best_prim, best_uv[0], best_uv[1], n);
    counts->local_answers++;
    return true;
}

/* One candidate sample of a leaf: an m-triangle and its closest point to the centre. */
typedef struct leaf_candidate {
    double d2;
    uint32_t tri;
    float wb, wc;
} leaf_candidate;

static bool candidate_before(const leaf_candidate *a, const leaf_candidate *b)
{
    return a->d2 < b->d2 || (a->d2 == b->d2 && a->tri < b->tri);
}

size_t ms_apo_leaf_samples(size_t big_count)
{
    size_t n = big_count ? MS_APO_LOCAL_TESTS / big_count : MS_APO_SAMPLES_PER_LEAF;
    return n < 1 ? 1 : n > MS_APO_SAMPLES_PER_LEAF ? MS_APO_SAMPLES_PER_LEAF : n;
}

void ms_apo_sample_leaf(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, const ms_apo_leaf_probe *leaf,
                        float search, float normal[3], float smooth[3], ms_apo_sample_counts *counts)
{
    /* The nearest MS_APO_SAMPLES_PER_LEAF m-triangles, kept sorted (insertion:
     * the list is short), so that the rays cast do not grow with the leaf's list. */
    leaf_candidate kept[MS_APO_SAMPLES_PER_LEAF];
    size_t kept_n = 0, limit = ms_apo_leaf_samples(leaf->big_count);
    const float *centre = leaf->centre;
    for (size_t k = 0; k < leaf->m_count; ++k) {
        leaf_candidate c = {.tri = leaf->m_tris[k]};
        const uint32_t *v = &m->tri[3 * c.tri];
        c.d2 = closest_on_triangle(centre, &m->pos[3 * v[0]], &m->pos[3 * v[1]], &m->pos[3 * v[2]], &c.wb, &c.wc);
        if (kept_n == limit && !candidate_before(&c, &kept[kept_n - 1]))
            continue;
        size_t at = kept_n < limit ? kept_n++ : kept_n - 1;
        while (at > 0 && candidate_before(&c, &kept[at - 1])) {
            kept[at] = kept[at - 1];
            --at;
        }
        kept[at] = c;
    }
    counts->triangle_tests += leaf->m_count;
    /* Adaptive: two samples first, the rest only where they disagree. */
    double agree_cos = leaf->agreement > 0.0f ? cos((double)leaf->agreement) : 2.0;
    double sum[3] = {0, 0, 0}, first_sample[3] = {0, 0, 1}, pred[3] = {0, 0, 0};
    bool have_closest = false, closest_done = false;
    double closest[3] = {0, 0, 0};
    double prev_dir[3] = {0, 0, 0}, prev_n[3] = {0, 0, 0};
    uint64_t *prev_count = &counts->unsampled;
    for (size_t k = 0; k < kept_n; ++k) {
        double dir[3], n[3];
        ms_apo_local_mesh_normal_at(m, kept[k].tri, kept[k].wb, kept[k].wc, dir);
        counts->samples++;
        /* A degenerate m-triangle whose vertices touch no valid face has no
         * direction: it can only use the closest point, else +z. */
        bool has_dir = dir[0] != 0.0 || dir[1] != 0.0 || dir[2] != 0.0;
        if (!has_dir)
            dir[2] = 1.0;
        /* The same direction as the previous sample (two m-triangles whose
         * closest point to the centre is their shared vertex): the same rays
         * from the same centre, the same answer, none cast again. */
        if (k > 0 && memcmp(dir, prev_dir, sizeof dir) == 0) {
            memcpy(n, prev_n, sizeof n);
            ++*prev_count;
        } else if (has_dir && (local_ray_normal(sampler->big, leaf, dir, search, n, counts) ||
                        (leaf->big_count == 0 && !leaf->listed &&
                         ray_normal(sampler->scene, sampler->big, centre, dir, search, n, &counts->rays)))) {
            counts->ray_hits++;
            prev_count = &counts->ray_hits;
        } else {
            if (!closest_done) {
                have_closest = local_closest_normal(sampler->big, leaf, search, closest, counts);
                if (!have_closest && !leaf->listed) {
                    have_closest = closest_normal(sampler->scene, sampler->big, centre, search, closest);
                    counts->point_queries++;
                }
                closest_done = true;
            }
            if (have_closest) {
                counts->closest_points++;
                memcpy(n, closest, sizeof n);
                prev_count = &counts->closest_points;
            } else {
                counts->unsampled++;
                memcpy(n, dir, sizeof n);
                prev_count = &counts->unsampled;
            }
        }
        memcpy(prev_dir, dir, sizeof dir);
        memcpy(prev_n, n, sizeof n);
        if (k == 0)
            memcpy(first_sample, n, sizeof n);
        for (int a = 0; a < 3; ++a)
            sum[a] += n[a];
        if (smooth) { /* what the client draws at the same point without a texel */
            double p[3];
            ms_apo_local_mesh_smooth_at(m, kept[k].tri, kept[k].wb, kept[k].wc, p);
            for (int a = 0; a < 3; ++a)
                pred[a] += p[a];
        }
        if (k == 1 && kept_n > 2 &&
            first_sample[0] * n[0] + first_sample[1] * n[1] + first_sample[2] * n[2] >= agree_cos) {
            counts->agreed++;
            break;
        }
    }
    double len = sqrt(sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]);
    for (int a = 0; a < 3; ++a)
        normal[a] = (float)(len > 1e-12 ? sum[a] / len : first_sample[a]);
    if (smooth) {
        double plen = sqrt(pred[0] * pred[0] + pred[1] * pred[1] + pred[2] * pred[2]);
        for (int a = 0; a < 3; ++a)
            smooth[a] = (float)(plen > 1e-12 ? pred[a] / plen : 0.0);
    }
}

/* h: the largest distance from m's vertices and face centroids to M. */
typedef struct distance_job {
    const ms_apo_local_mesh *m;
    const ms_apo_sampler *sampler;
    size_t block_size, points;
    double *block_max;
} distance_job;

static void distance_block(void *ctx, size_t block)
{
    distance_job *job = ctx;
    size_t first = block * job->block_size, last = first + job->block_size;
    if (last > job->points)
        last = job->points;
    double worst = 0.0;
    for (size_t i = first; i < last; ++i) {
        float p[3];
        if (i < job->m->vertex_count) {
            memcpy(p, &job->m->pos[3 * i], sizeof p);
        } else {
            const uint32_t *v = &job->m->tri[3 * (i - job->m->vertex_count)];
            for (int a = 0; a < 3; ++a)
                p[a] = (job->m->pos[3 * v[0] + a] + job->m->pos[3 * v[1] + a] + job->m->pos[3 * v[2] + a]) / 3.0f;
        }
        closest_query q = {.big = job->sampler->big, .best_d2 = INFINITY, .best_prim = UINT32_MAX};
        memcpy(q.point, p, sizeof p);
        struct RTCPointQuery query = {.x = p[0], .y = p[1], .z = p[2], .time = 0.0f, .radius = INFINITY};
        struct RTCPointQueryContext pctx;
        rtcInitPointQueryContext(&pctx);
        rtcPointQuery(job->sampler->scene, &query, &pctx, closest_callback, &q);
        if (q.best_prim != UINT32_MAX && sqrt(q.best_d2) > worst)
            worst = sqrt(q.best_d2);
    }
    job->block_max[block] = worst;
}

ms_status ms_apo_sampler_distance(const ms_apo_sampler *sampler, const ms_apo_local_mesh *m, unsigned threads,
                                  double *h, ms_error *err)
{
    *h = 0.0;
    if (sampler->big->triangle_count == 0)
        return MS_OK;
    size_t points = m->vertex_count + m->triangle_count;
    size_t bs = points / 256 + 1 > 256 ? points / 256 + 1 : 256, blocks = (points + bs - 1) / bs;
    double *block_max = calloc(blocks + 1, sizeof *block_max);
    if (!block_max)
        return ms_error_set(err, MS_ERR_NOMEM, "apo build: no memory");
    distance_job dj = {.m = m, .sampler = sampler, .block_size = bs, .points = points, .block_max = block_max};
    ms_status st = ms_parallel_for(threads, blocks, distance_block, &dj, err);
    for (size_t b = 0; b < blocks; ++b)
        if (block_max[b] > *h)
            *h = block_max[b];
    free(block_max);
    return st;
}
