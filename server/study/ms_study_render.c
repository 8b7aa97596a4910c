/* The CPU reference renderer (ms_study_render.h). */
#include "ms_study_render.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_parallel.h"
#include "ms_png.h"
#include "ms_study_scene_internal.h"
#include "ms_vec3.h"

/* Rows per parallel block: fixed, so the split never depends on the threads. */
#define ROWS_PER_BLOCK 4u

ms_status ms_study_image_alloc(ms_study_image *im, uint32_t width, uint32_t height, ms_error *err)
{
    memset(im, 0, sizeof *im);
    if (width < 1 || height < 1 || width > 65535 || height > 65535)
        return ms_error_set(err, MS_ERR_RANGE, "study image: %u x %u pixels (1 to 65535 each)", width, height);
    size_t n = (size_t)width * height;
    im->depth = malloc(n * sizeof *im->depth);
    im->triangle = malloc(n * sizeof *im->triangle);
    im->normal = calloc(3 * n, sizeof *im->normal);
    im->rgb = calloc(3 * n, 1);
    if (!im->depth || !im->triangle || !im->normal || !im->rgb) {
        ms_study_image_free(im);
        return ms_error_set(err, MS_ERR_NOMEM, "study image: out of memory for %u x %u pixels", width, height);
    }
    im->width = width;
    im->height = height;
    ms_study_image_clear(im);
    return MS_OK;
}

void ms_study_image_clear(ms_study_image *im)
{
    size_t n = (size_t)im->width * im->height;
    uint8_t bg = ms_study_srgb8(MS_STUDY_BACKGROUND);
    for (size_t p = 0; p < n; ++p) {
        im->depth[p] = INFINITY;
        im->triangle[p] = MS_STUDY_NO_HIT;
    }
    memset(im->normal, 0, 3 * n * sizeof *im->normal);
    memset(im->rgb, bg, 3 * n);
}

void ms_study_image_free(ms_study_image *im)
{
    if (!im)
        return;
    free(im->depth);
    free(im->triangle);
    free(im->normal);
    free(im->rgb);
    memset(im, 0, sizeof *im);
}

uint8_t ms_study_srgb8(double x)
{
    if (!(x > 0))
        return 0;
    if (x >= 1)
        return 255;
    double s = x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1 / 2.4) - 0.055;
    return (uint8_t)lround(255 * s);
}

double ms_study_srgb_decode(double c)
{
    return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4);
}

typedef struct render_job {
    const ms_study_scene *scene;
    const ms_camera *camera;
    const ms_study_render_options *options;
    ms_study_image *image;
    double tan_y, tan_x;
    double footprint_per_depth; /* a pixel's width in world units per unit of eye depth */
    float origin[3]; /* camera position in the scene's local frame */
} render_job;

static void shade_pixel(const render_job *job, size_t p, uint32_t t, double depth, double u, double v,
                        const double dir[3])
{
    const ms_study_scene *s = job->scene;
    ms_study_image *im = job->image;
    /* L: from the hit to the camera, i.e. -dir normalised. */
    double len = sqrt(ms_vec3_dot(dir, dir)), l[3] = {-dir[0] / len, -dir[1] / len, -dir[2] / len};
    /* Ng turned to face the camera (two-sided), `facing` the sign it took */
    double ng[3], facing = ms_vec3_dot(&s->face_normal[3 * t], l) < 0 ? -1 : 1;
    for (int k = 0; k < 3; ++k)
        ng[k] = facing * s->face_normal[3 * t + k];
    double n[3];
    memcpy(n, ng, sizeof n);
    if (job->options->smooth) {
        /* The interpolated vertex normal (the APO builder's rule for M), turned
         * over with the face; where it lies against the face's own normal (a
         * fold) Ng stands in, as in the client's shader. */
        const uint32_t *tv = &s->triangles[3 * t];
        double sm[3], len2 = 0;
        for (int k = 0; k < 3; ++k) {
            sm[k] = (1 - u - v) * s->vertex_normal[3 * tv[0] + k] + u * s->vertex_normal[3 * tv[1] + k] +
                    v * s->vertex_normal[3 * tv[2] + k];
            len2 += sm[k] * sm[k];
        }
        if (len2 > 0 && ms_vec3_dot(sm, &s->face_normal[3 * t]) >= 0)
            for (int k = 0; k < 3; ++k)
                n[k] = facing * sm[k] / sqrt(len2);
    }
    if (job->options->apo) {
        /* The hit from its barycentrics, in doubles: on the triangle, so inside
         * (or on the border of) the drawing cell's cube. */
        const uint32_t *tv = &s->triangles[3 * t];
        const double *a = &s->local[3 * tv[0]], *b = &s->local[3 * tv[1]], *cc = &s->local[3 * tv[2]];
        double x[3], apo[3];
        for (int k = 0; k < 3; ++k)
            x[k] = s->origin[k] + a[k] + u * (b[k] - a[k]) + v * (cc[k] - a[k]);
        const double smooth[3] = {facing * n[0], facing * n[1], facing * n[2]}; /* unturned */
        if (ms_study_apo_normal(job->options->apo, job->options->triangle_cell[t], x,
                                depth * job->footprint_per_depth, smooth, apo)) {
            double side = ms_vec3_dot(apo, ng) < 0 ? -1 : 1;
            for (int k = 0; k < 3; ++k)
                n[k] = side * apo[k];
        }
    }
    /* the self-shadowing factor from the normal shaded with (the client's rule) */
    double nl = fmax(0, ms_vec3_dot(n, l)), shadow = nl;
    double c = MS_STUDY_AMBIENT + shadow * (MS_STUDY_DIFFUSE * nl + MS_STUDY_SPECULAR * pow(nl, MS_STUDY_SHININESS));
    uint8_t value = ms_study_srgb8(c);
    im->depth[p] = (float)depth;
    im->triangle[p] = t;
    for (int k = 0; k < 3; ++k) {
        im->normal[3 * p + k] = (float)n[k];
        im->rgb[3 * p + k] = value;
    }
    const uint8_t *colours = job->options->colours;
    if (!colours && !job->options->albedo)
        return;
    /* the albedo: the vertex colours interpolated as sRGB values, else the
     * viewer's grey */
    double srgb[3] = {0, 0, 0};
    static const double grey[3] = {MS_STUDY_ALBEDO_R, MS_STUDY_ALBEDO_G, MS_STUDY_ALBEDO_B};
    const uint32_t *tv = &s->triangles[3 * t];
    for (int k = 0; k < 3; ++k)
        srgb[k] = colours ? ((1 - u - v) * colours[4 * (size_t)tv[0] + (size_t)k] +
                             u * colours[4 * (size_t)tv[1] + (size_t)k] + v * colours[4 * (size_t)tv[2] + (size_t)k]) /
                                255.0
                          : ms_study_srgb8(grey[k]) / 255.0;
    double lit = MS_STUDY_AMBIENT + shadow * MS_STUDY_DIFFUSE * nl, highlight = shadow * MS_STUDY_SPECULAR *
                                                                                 pow(nl, MS_STUDY_SHININESS);
    for (int k = 0; k < 3; ++k) {
        double a = fmin(1, fmax(0, srgb[k]));
        im->rgb[3 * p + k] = job->options->albedo ? (uint8_t)lround(255 * a)
                                                  : ms_study_srgb8(ms_study_srgb_decode(a) * lit + highlight);
    }
}

static void render_block(void *ctx, size_t block)
{
    const render_job *job = ctx;
    const ms_camera *c = job->camera;
    ms_study_image *im = job->image;
    uint32_t w = im->width, h = im->height;
    uint32_t j_end = (uint32_t)((block + 1) * ROWS_PER_BLOCK < h ? (block + 1) * ROWS_PER_BLOCK : h);
    for (uint32_t j = (uint32_t)(block * ROWS_PER_BLOCK); j < j_end; ++j)
        for (uint32_t i = 0; i < w; ++i) {
            double x = (2.0 * (i + 0.5) / w - 1) * job->tan_x, y = (1 - 2.0 * (j + 0.5) / h) * job->tan_y;
            double dir[3];
            for (int k = 0; k < 3; ++k)
                dir[k] = c->forward[k] + x * c->right[k] + y * c->up[k];
            struct RTCRayHit rh;
            memset(&rh, 0, sizeof rh);
            rh.ray.org_x = job->origin[0];
            rh.ray.org_y = job->origin[1];
            rh.ray.org_z = job->origin[2];
            rh.ray.dir_x = (float)dir[0];
            rh.ray.dir_y = (float)dir[1];
            rh.ray.dir_z = (float)dir[2];
            rh.ray.tnear = (float)c->near_distance;
            rh.ray.tfar = (float)c->far_distance;
            rh.ray.mask = UINT32_MAX;
            rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
            rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
            struct RTCIntersectContext ictx;
            rtcInitIntersectContext(&ictx);
            rtcIntersect1(job->scene->rtc, &ictx, &rh);
            if (rh.hit.geomID != RTC_INVALID_GEOMETRY_ID)
                shade_pixel(job, (size_t)j * w + i, rh.hit.primID, rh.ray.tfar, rh.hit.u, rh.hit.v, dir);
        }
}

ms_status ms_study_render(const ms_study_scene *scene, const ms_camera *camera,
                          const ms_study_render_options *options, ms_study_image *image, ms_error *err)
{
    static const ms_study_render_options defaults = {0};
    if (!options)
        options = &defaults;
    if (options->apo && !options->triangle_cell)
        return ms_error_set(err, MS_ERR_ARG, "study render: APO normals need the triangles' cells");
    double w = camera->width, h = camera->height;
    if (!(w >= 1 && w <= 65535 && h >= 1 && h <= 65535) || w != floor(w) || h != floor(h))
        return ms_error_set(err, MS_ERR_RANGE, "study render: a %g x %g viewport (whole pixels, 1 to 65535)", w, h);
    if (image->width != (uint32_t)w || image->height != (uint32_t)h) {
        ms_study_image_free(image);
        ms_status st = ms_study_image_alloc(image, (uint32_t)w, (uint32_t)h, err);
        if (st != MS_OK)
            return st;
    } else {
        ms_study_image_clear(image);
    }
    render_job job = {.scene = scene, .camera = camera, .options = options, .image = image};
    job.tan_y = tan(camera->fovy / 2);
    job.tan_x = job.tan_y * w / h;
    job.footprint_per_depth = 2 * job.tan_y / h;
    for (int k = 0; k < 3; ++k)
        job.origin[k] = (float)(camera->position[k] - scene->origin[k]);
    size_t blocks = (image->height + ROWS_PER_BLOCK - 1) / ROWS_PER_BLOCK;
    return ms_parallel_for(options->threads, blocks, render_block, &job, err);
}

ms_status ms_study_image_write_png(const ms_study_image *im, const char *path, ms_error *err)
{
    return ms_png_write(path, im->rgb, im->width, im->height, 3, err);
}

ms_status ms_study_image_write_normals_png(const ms_study_image *im, const char *path, ms_error *err)
{
    size_t n = (size_t)im->width * im->height;
    uint8_t *rgb = malloc(3 * n);
    if (!rgb)
        return ms_error_set(err, MS_ERR_NOMEM, "study image: out of memory for %zu pixels", n);
    for (size_t p = 0; p < 3 * n; ++p)
        rgb[p] = ms_study_image_covered(im, p / 3) ? (uint8_t)lround(255 * (im->normal[p] + 1) / 2) : 0;
    ms_status st = ms_png_write(path, rgb, im->width, im->height, 3, err);
    free(rgb);
    return st;
}

ms_status ms_study_key_camera(const ms_camera_path *path, size_t key, double width, double height,
                              double near_distance, double far_distance, const double lo[3], const double hi[3],
                              ms_camera *camera, ms_error *err)
{
    if (key >= path->count)
        return ms_error_set(err, MS_ERR_RANGE, "camera path: keyframe %zu of %zu", key, path->count);
    const ms_camera_key *k = &path->keys[key];
    if (!(far_distance > 0)) { /* just past the box's farthest corner */
        double unused;
        ms_camera_depth_range(k->position, lo, hi, &unused, &far_distance);
    }
    if (!(near_distance > 0))
        near_distance = far_distance * 1e-5;
    return ms_camera_look_at(k->position, k->target, k->up, k->fovy_degrees, width, height, near_distance,
                             far_distance, camera, err);
}
