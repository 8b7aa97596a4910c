/* The study's Embree scene and its closest-point query (ms_study_scene.h). */
#include "ms_study_scene.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_study_scene_internal.h"

/* Squared distance from p to triangle (a, b, c), all in doubles: the closest
 * point is found by the Voronoi region of p among the vertices, edges and face
 * (the classic region test); inside the face's region the distance is the
 * distance to the plane. A degenerate triangle gives its nearest edge point. */
static double triangle_distance2(const double p[3], const double a[3], const double b[3], const double c[3])
{
    double ab[3], ac[3], ap[3], bp[3], cp[3];
    for (int k = 0; k < 3; ++k) {
        ab[k] = b[k] - a[k];
        ac[k] = c[k] - a[k];
        ap[k] = p[k] - a[k];
        bp[k] = p[k] - b[k];
        cp[k] = p[k] - c[k];
    }
#define DOT3(u, v) ((u)[0] * (v)[0] + (u)[1] * (v)[1] + (u)[2] * (v)[2])
    double d1 = DOT3(ab, ap), d2 = DOT3(ac, ap);
    double d3 = DOT3(ab, bp), d4 = DOT3(ac, bp);
    double d5 = DOT3(ab, cp), d6 = DOT3(ac, cp);
#undef DOT3
    double v, w; /* closest = a + v ab + w ac */
    double va = d3 * d6 - d5 * d4, vb = d5 * d2 - d1 * d6, vc = d1 * d4 - d3 * d2;
    if (d1 <= 0 && d2 <= 0) {
        v = 0, w = 0;
    } else if (d3 >= 0 && d4 <= d3) {
        v = 1, w = 0;
    } else if (d6 >= 0 && d5 <= d6) {
        v = 0, w = 1;
    } else if (vc <= 0 && d1 >= 0 && d3 <= 0) {
        v = d1 / (d1 - d3), w = 0;
    } else if (vb <= 0 && d2 >= 0 && d6 <= 0) {
        v = 0, w = d2 / (d2 - d6);
    } else if (va <= 0 && d4 - d3 >= 0 && d5 - d6 >= 0) {
        w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        v = 1 - w;
    } else {
        double sum = va + vb + vc;
        if (!(sum > 0)) {
            /* degenerate (collinear) triangle: the nearest of its three edges */
            double best = INFINITY;
            const double *ends[3][2] = {{a, b}, {b, c}, {c, a}};
            for (int e = 0; e < 3; ++e) {
                double dir[3], rel[3], len2 = 0, t = 0;
                for (int k = 0; k < 3; ++k) {
                    dir[k] = ends[e][1][k] - ends[e][0][k];
                    rel[k] = p[k] - ends[e][0][k];
                    len2 += dir[k] * dir[k];
                    t += dir[k] * rel[k];
                }
                t = len2 > 0 ? fmin(1, fmax(0, t / len2)) : 0;
                double d = 0;
                for (int k = 0; k < 3; ++k) {
                    double q = rel[k] - t * dir[k];
                    d += q * q;
                }
                best = fmin(best, d);
            }
            return best;
        }
        /* Inside the face's region: the distance to its plane, (ap . n)^2 / |n|^2,
         * which is exactly 0 for a point in the plane of an axis-aligned face
         * (no rounding through the barycentrics). */
        double n[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
        double h = ap[0] * n[0] + ap[1] * n[1] + ap[2] * n[2];
        return h * h / (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    double d = 0;
    for (int k = 0; k < 3; ++k) {
        double q = ap[k] - v * ab[k] - w * ac[k];
        d += q * q;
    }
    return d;
}

ms_status ms_study_scene_new(const double *positions, size_t vertex_count, const uint32_t *triangles,
                             size_t triangle_count, ms_study_scene **out, ms_error *err)
{
    *out = NULL;
    if (vertex_count > UINT32_MAX || triangle_count > UINT32_MAX)
        return ms_error_set(err, MS_ERR_ARG, "study scene: %zu vertices / %zu triangles exceed 32-bit indices",
                            vertex_count, triangle_count);
    for (size_t i = 0; i < 3 * triangle_count; ++i)
        if (triangles[i] >= vertex_count)
            return ms_error_set(err, MS_ERR_ARG, "study scene: triangle %zu refers to vertex %u of %zu", i / 3,
                                triangles[i], vertex_count);
    ms_study_scene *s = calloc(1, sizeof *s);
    if (!s)
        return ms_error_set(err, MS_ERR_NOMEM, "study scene: out of memory");
    for (int k = 0; k < 3; ++k) {
        s->lo[k] = INFINITY;
        s->hi[k] = -INFINITY;
    }
    for (size_t i = 0; i < vertex_count; ++i)
        for (int k = 0; k < 3; ++k) {
            double x = positions[3 * i + k];
            if (!isfinite(x)) {
                free(s);
                return ms_error_set(err, MS_ERR_RANGE, "study scene: vertex %zu has a non-finite coordinate", i);
            }
            s->lo[k] = fmin(s->lo[k], x);
            s->hi[k] = fmax(s->hi[k], x);
        }
    for (int k = 0; k < 3; ++k)
        s->origin[k] = vertex_count ? 0.5 * (s->lo[k] + s->hi[k]) : 0;
    s->vertex_count = vertex_count;
    s->triangle_count = triangle_count;
    s->local = malloc((3 * vertex_count + 1) * sizeof *s->local);
    s->local_f = malloc((3 * vertex_count + 4) * sizeof *s->local_f);
    s->triangles = malloc((3 * triangle_count + 1) * sizeof *s->triangles);
    s->face_normal = malloc((3 * triangle_count + 1) * sizeof *s->face_normal);
    s->vertex_normal = calloc(3 * vertex_count + 1, sizeof *s->vertex_normal);
    if (!s->local || !s->local_f || !s->triangles || !s->face_normal || !s->vertex_normal) {
        ms_study_scene_free(s);
        return ms_error_set(err, MS_ERR_NOMEM, "study scene: out of memory for %zu vertices", vertex_count);
    }
    for (size_t i = 0; i < 3 * vertex_count; ++i) {
        s->local[i] = positions[i] - s->origin[i % 3];
        s->local_f[i] = (float)s->local[i];
    }
    memset(&s->local_f[3 * vertex_count], 0, 4 * sizeof *s->local_f);
    if (triangle_count)
        memcpy(s->triangles, triangles, 3 * triangle_count * sizeof *triangles);
    for (size_t t = 0; t < triangle_count; ++t) {
        const double *a = &s->local[3 * triangles[3 * t]], *b = &s->local[3 * triangles[3 * t + 1]],
                     *c = &s->local[3 * triangles[3 * t + 2]];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, v[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
        double len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; ++k) {
            s->face_normal[3 * t + k] = len > 0 ? n[k] / len : 0;
            /* |n| is twice the area: the sum weights faces by area */
            for (int corner = 0; corner < 3; ++corner)
                s->vertex_normal[3 * triangles[3 * t + corner] + k] += n[k];
        }
    }
    for (size_t v = 0; v < vertex_count; ++v) {
        double *n = &s->vertex_normal[3 * v], len = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; ++k)
            n[k] = len > 0 ? n[k] / len : 0;
    }
    s->device = rtcNewDevice(NULL);
    if (!s->device) {
        ms_study_scene_free(s);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "study scene: Embree could not create a device");
    }
    s->rtc = rtcNewScene(s->device);
    if (!s->rtc) {
        ms_study_scene_free(s);
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "study scene: Embree could not create a scene");
    }
    if (triangle_count) {
        RTCGeometry g = rtcNewGeometry(s->device, RTC_GEOMETRY_TYPE_TRIANGLE);
        if (!g) {
            ms_study_scene_free(s);
            return ms_error_set(err, MS_ERR_UNSUPPORTED, "study scene: Embree could not create a geometry");
        }
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, s->local_f, 0,
                                   3 * sizeof(float), vertex_count);
        rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, s->triangles, 0,
                                   3 * sizeof(uint32_t), triangle_count);
        /* Rendering casts a ray per pixel and measuring a query per sample: a
         * better BVH pays for its build. */
        rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_HIGH);
        rtcCommitGeometry(g);
        rtcAttachGeometry(s->rtc, g);
        rtcReleaseGeometry(g);
    }
    rtcSetSceneBuildQuality(s->rtc, RTC_BUILD_QUALITY_HIGH);
    rtcSetSceneFlags(s->rtc, RTC_SCENE_FLAG_ROBUST);
    rtcCommitScene(s->rtc);
    if (rtcGetDeviceError(s->device) != RTC_ERROR_NONE) {
        ms_study_scene_free(s);
        return ms_error_set(err, MS_ERR_NOMEM, "study scene: Embree failed to build %zu triangles", triangle_count);
    }
    *out = s;
    return MS_OK;
}

void ms_study_scene_free(ms_study_scene *s)
{
    if (!s)
        return;
    if (s->rtc)
        rtcReleaseScene(s->rtc);
    if (s->device)
        rtcReleaseDevice(s->device);
    free(s->local);
    free(s->local_f);
    free(s->triangles);
    free(s->face_normal);
    free(s->vertex_normal);
    free(s);
}

size_t ms_study_scene_triangle_count(const ms_study_scene *s)
{
    return s->triangle_count;
}

void ms_study_scene_bounds(const ms_study_scene *s, double lo[3], double hi[3])
{
    memcpy(lo, s->lo, sizeof s->lo);
    memcpy(hi, s->hi, sizeof s->hi);
}

double ms_study_scene_area(const ms_study_scene *s)
{
    double area = 0;
    for (size_t t = 0; t < s->triangle_count; ++t) {
        const uint32_t *v = &s->triangles[3 * t];
        const double *a = &s->local[3 * v[0]], *b = &s->local[3 * v[1]], *c = &s->local[3 * v[2]];
        double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
        area += 0.5 * sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    }
    return area;
}

typedef struct closest_query {
    const ms_study_scene *scene;
    double point[3]; /* local frame */
    double best_d2;
    uint32_t best;
} closest_query;

static bool closest_callback(struct RTCPointQueryFunctionArguments *args)
{
    closest_query *q = args->userPtr;
    const ms_study_scene *s = q->scene;
    uint32_t t = args->primID;
    const uint32_t *v = &s->triangles[3 * t];
    double d2 = triangle_distance2(q->point, &s->local[3 * v[0]], &s->local[3 * v[1]], &s->local[3 * v[2]]);
    if (d2 < q->best_d2 || (d2 == q->best_d2 && t < q->best)) {
        q->best_d2 = d2;
        q->best = t;
        /* Shrink the search, rounded up so that float rounding never prunes a
         * triangle that is as close as the best one. */
        float r = (float)(sqrt(d2) * (1 + 1e-6)) + 1e-30f;
        if (r < args->query->radius) {
            args->query->radius = r;
            return true;
        }
    }
    return false;
}

double ms_study_scene_closest(const ms_study_scene *s, const double point[3], uint32_t *triangle)
{
    closest_query q = {.scene = s, .best_d2 = INFINITY, .best = UINT32_MAX};
    for (int k = 0; k < 3; ++k)
        q.point[k] = point[k] - s->origin[k];
    if (triangle)
        *triangle = UINT32_MAX;
    if (!s->triangle_count)
        return INFINITY;
    struct RTCPointQuery query = {.x = (float)q.point[0], .y = (float)q.point[1], .z = (float)q.point[2],
                                  .time = 0.0f, .radius = INFINITY};
    struct RTCPointQueryContext ctx;
    rtcInitPointQueryContext(&ctx);
    rtcPointQuery(s->rtc, &query, &ctx, closest_callback, &q);
    if (triangle)
        *triangle = q.best;
    return sqrt(q.best_d2);
}
