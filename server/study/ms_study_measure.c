/* Error measures of the accuracy study (ms_study_measure.h). */
#include "ms_study_measure.h"

#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_parallel.h"
#include "ms_study_scene_internal.h"

/* Fixed work split: results never depend on the thread count. */
#define TRIANGLES_PER_BLOCK 1024u
#define VERTICES_PER_BLOCK 4096u

/* ---- geometric distance ------------------------------------------------- */

typedef struct partial {
    double max_d, sum_wd2, sum_w;
    double max_px, sum_wpx2, sum_wpx;
    uint64_t samples, samples_px;
} partial;

typedef struct distance_job {
    const ms_study_scene *from, *to;
    double spacing;
    const ms_camera *camera;
    ms_frustum frustum;
    double pixels_per_unit;
    const uint8_t *referenced; /* per vertex of `from` */
    size_t triangle_blocks;
    partial *parts;            /* triangle blocks, then vertex blocks */
} distance_job;

static void add_sample(const distance_job *job, const double world[3], double weight, partial *p)
{
    double d = ms_study_scene_closest(job->to, world, NULL);
    p->samples++;
    if (d > p->max_d)
        p->max_d = d;
    p->sum_wd2 += weight * d * d;
    p->sum_w += weight;
    if (!job->camera || !ms_frustum_keeps_box(&job->frustum, world, world, 0))
        return;
    double rel[3], depth = 0;
    for (int k = 0; k < 3; ++k) {
        rel[k] = world[k] - job->camera->position[k];
        depth += rel[k] * job->camera->forward[k];
    }
    if (!(depth > 0))
        return;
    double px = d * job->pixels_per_unit / depth;
    p->samples_px++;
    if (px > p->max_px)
        p->max_px = px;
    p->sum_wpx2 += weight * px * px;
    p->sum_wpx += weight;
}

static void distance_block(void *ctx, size_t block)
{
    const distance_job *job = ctx;
    const ms_study_scene *s = job->from;
    partial *p = &job->parts[block];
    memset(p, 0, sizeof *p);
    if (block >= job->triangle_blocks) {
        size_t first = (block - job->triangle_blocks) * VERTICES_PER_BLOCK;
        size_t end = first + VERTICES_PER_BLOCK < s->vertex_count ? first + VERTICES_PER_BLOCK : s->vertex_count;
        for (size_t v = first; v < end; ++v) {
            if (!job->referenced[v])
                continue;
            double x[3];
            for (int k = 0; k < 3; ++k)
                x[k] = s->origin[k] + s->local[3 * v + k];
            add_sample(job, x, 0, p);
        }
        return;
    }
    size_t first = block * TRIANGLES_PER_BLOCK;
    size_t end = first + TRIANGLES_PER_BLOCK < s->triangle_count ? first + TRIANGLES_PER_BLOCK : s->triangle_count;
    for (size_t t = first; t < end; ++t) {
        const uint32_t *tv = &s->triangles[3 * t];
        const double *a = &s->local[3 * tv[0]], *b = &s->local[3 * tv[1]], *c = &s->local[3 * tv[2]];
        double ab[3], ac[3], bc[3];
        for (int k = 0; k < 3; ++k) {
            ab[k] = b[k] - a[k];
            ac[k] = c[k] - a[k];
            bc[k] = c[k] - b[k];
        }
        double cr[3] = {ab[1] * ac[2] - ab[2] * ac[1], ab[2] * ac[0] - ab[0] * ac[2], ab[0] * ac[1] - ab[1] * ac[0]};
        double area = 0.5 * sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
        double longest = sqrt(fmax(ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2],
                                   fmax(ac[0] * ac[0] + ac[1] * ac[1] + ac[2] * ac[2],
                                        bc[0] * bc[0] + bc[1] * bc[1] + bc[2] * bc[2])));
        double steps = ceil(longest / job->spacing);
        unsigned k_steps = steps < 1 ? 1 : steps > MS_STUDY_MAX_SUBDIVISION ? MS_STUDY_MAX_SUBDIVISION : (unsigned)steps;
        double weight = area / ((double)k_steps * k_steps), inv = 1.0 / (3.0 * k_steps);
        for (unsigned i = 0; i < k_steps; ++i)
            for (unsigned j = 0; i + j < k_steps; ++j)
                for (int down = 0; down < 2; ++down) {
                    if (down && i + j + 2 > k_steps)
                        break;
                    /* up: corners (i,j) (i+1,j) (i,j+1); down: (i+1,j) (i,j+1) (i+1,j+1) */
                    double u = (3.0 * i + 1 + down) * inv, v = (3.0 * j + 1 + down) * inv, x[3];
                    for (int k = 0; k < 3; ++k)
                        x[k] = s->origin[k] + a[k] + u * ab[k] + v * ac[k];
                    add_sample(job, x, weight, p);
                }
    }
}

/* One direction: every sample of from against to, reduced in block order. */
static ms_status one_way(const ms_study_scene *from, const ms_study_scene *to, const ms_study_distance_params *params,
                         partial *total, ms_error *err)
{
    distance_job job = {.from = from, .to = to, .spacing = params->spacing, .camera = params->camera};
    if (params->camera) {
        ms_camera_frustum(params->camera, &job.frustum);
        job.pixels_per_unit = ms_camera_pixels_per_unit(params->camera);
    }
    uint8_t *referenced = calloc(from->vertex_count + 1, 1);
    job.triangle_blocks = (from->triangle_count + TRIANGLES_PER_BLOCK - 1) / TRIANGLES_PER_BLOCK;
    size_t blocks = job.triangle_blocks + (from->vertex_count + VERTICES_PER_BLOCK - 1) / VERTICES_PER_BLOCK;
    job.parts = calloc(blocks, sizeof *job.parts);
    if (!referenced || !job.parts) {
        free(referenced);
        free(job.parts);
        return ms_error_set(err, MS_ERR_NOMEM, "study distance: out of memory");
    }
    for (size_t i = 0; i < 3 * from->triangle_count; ++i)
        referenced[from->triangles[i]] = 1;
    job.referenced = referenced;
    ms_status st = ms_parallel_for(params->threads, blocks, distance_block, &job, err);
    memset(total, 0, sizeof *total);
    for (size_t b = 0; st == MS_OK && b < blocks; ++b) {
        const partial *p = &job.parts[b];
        total->max_d = fmax(total->max_d, p->max_d);
        total->sum_wd2 += p->sum_wd2;
        total->sum_w += p->sum_w;
        total->max_px = fmax(total->max_px, p->max_px);
        total->sum_wpx2 += p->sum_wpx2;
        total->sum_wpx += p->sum_wpx;
        total->samples += p->samples;
        total->samples_px += p->samples_px;
    }
    free(referenced);
    free(job.parts);
    return st;
}

static double rms_of(double sum_wd2, double sum_w)
{
    return sum_w > 0 ? sqrt(sum_wd2 / sum_w) : 0;
}

ms_status ms_study_distance_measure(const ms_study_scene *a, const ms_study_scene *b,
                                    const ms_study_distance_params *params, ms_study_distance *out,
                                    ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (!(params->spacing > 0) || !isfinite(params->spacing))
        return ms_error_set(err, MS_ERR_ARG, "study distance: sample spacing %g (must be positive)",
                            params->spacing);
    if (!a->triangle_count || !b->triangle_count)
        return ms_error_set(err, MS_ERR_EMPTY, "study distance: a mesh without triangles (%zu and %zu)",
                            a->triangle_count, b->triangle_count);
    partial ab, ba;
    ms_status st = one_way(a, b, params, &ab, err);
    if (st == MS_OK)
        st = one_way(b, a, params, &ba, err);
    if (st != MS_OK)
        return st;
    out->hausdorff_ab = ab.max_d;
    out->hausdorff_ba = ba.max_d;
    out->hausdorff = fmax(ab.max_d, ba.max_d);
    out->rms_ab = rms_of(ab.sum_wd2, ab.sum_w);
    out->rms_ba = rms_of(ba.sum_wd2, ba.sum_w);
    out->rms = rms_of(ab.sum_wd2 + ba.sum_wd2, ab.sum_w + ba.sum_w);
    out->samples_a = ab.samples;
    out->samples_b = ba.samples;
    out->hausdorff_px = fmax(ab.max_px, ba.max_px);
    out->rms_px = rms_of(ab.sum_wpx2 + ba.sum_wpx2, ab.sum_wpx + ba.sum_wpx);
    out->samples_px = ab.samples_px + ba.samples_px;
    return MS_OK;
}

/* ---- image error -------------------------------------------------------- */

double ms_study_psnr(const uint8_t *a, const uint8_t *b, size_t count, double *mse_out)
{
    uint64_t sum = 0; /* exact: at most 255^2 per value */
    for (size_t i = 0; i < count; ++i) {
        int d = (int)a[i] - (int)b[i];
        sum += (uint64_t)(d * d);
    }
    double mse = count ? (double)sum / (double)count : 0;
    if (mse_out)
        *mse_out = mse;
    return sum ? 10 * log10(255.0 * 255.0 / mse) : INFINITY;
}

#define SSIM_RADIUS 5
#define SSIM_SIGMA 1.5

/* Separable Gaussian blur of src (w x h) over the valid window positions: out is
 * (w - 10) x (h - 10). tmp holds (w - 10) x h. */
static void blur_valid(const double *src, uint32_t w, uint32_t h, const double *kernel, double *tmp, double *out)
{
    uint32_t ow = w - 2 * SSIM_RADIUS, oh = h - 2 * SSIM_RADIUS;
    for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < ow; ++x) {
            double s = 0;
            for (int k = 0; k <= 2 * SSIM_RADIUS; ++k)
                s += kernel[k] * src[(size_t)y * w + x + k];
            tmp[(size_t)y * ow + x] = s;
        }
    for (uint32_t y = 0; y < oh; ++y)
        for (uint32_t x = 0; x < ow; ++x) {
            double s = 0;
            for (int k = 0; k <= 2 * SSIM_RADIUS; ++k)
                s += kernel[k] * tmp[(size_t)(y + k) * ow + x];
            out[(size_t)y * ow + x] = s;
        }
}

static double ssim_of(double mx, double my, double sxx, double syy, double sxy)
{
    const double c1 = (0.01 * 255) * (0.01 * 255), c2 = (0.03 * 255) * (0.03 * 255);
    return ((2 * mx * my + c1) * (2 * sxy + c2)) / ((mx * mx + my * my + c1) * (sxx + syy + c2));
}

ms_status ms_study_ssim_rgb(const uint8_t *a, const uint8_t *b, uint32_t w, uint32_t h, double *ssim, ms_error *err)
{
    size_t n = (size_t)w * h;
    *ssim = 1;
    if (!n)
        return MS_OK;
    double *x = malloc(n * sizeof *x), *y = malloc(n * sizeof *y);
    if (!x || !y) {
        free(x);
        free(y);
        return ms_error_set(err, MS_ERR_NOMEM, "ssim: out of memory for %u x %u pixels", w, h);
    }
    for (size_t p = 0; p < n; ++p) {
        x[p] = 0.299 * a[3 * p] + 0.587 * a[3 * p + 1] + 0.114 * a[3 * p + 2];
        y[p] = 0.299 * b[3 * p] + 0.587 * b[3 * p + 1] + 0.114 * b[3 * p + 2];
    }
    if (w < 2 * SSIM_RADIUS + 1 || h < 2 * SSIM_RADIUS + 1) {
        double mx = 0, my = 0, sxx = 0, syy = 0, sxy = 0;
        for (size_t p = 0; p < n; ++p) {
            mx += x[p];
            my += y[p];
        }
        mx /= (double)n;
        my /= (double)n;
        for (size_t p = 0; p < n; ++p) {
            sxx += (x[p] - mx) * (x[p] - mx);
            syy += (y[p] - my) * (y[p] - my);
            sxy += (x[p] - mx) * (y[p] - my);
        }
        *ssim = ssim_of(mx, my, sxx / (double)n, syy / (double)n, sxy / (double)n);
        free(x);
        free(y);
        return MS_OK;
    }
    double kernel[2 * SSIM_RADIUS + 1], ksum = 0;
    for (int k = -SSIM_RADIUS; k <= SSIM_RADIUS; ++k)
        ksum += kernel[k + SSIM_RADIUS] = exp(-(double)(k * k) / (2 * SSIM_SIGMA * SSIM_SIGMA));
    for (int k = 0; k <= 2 * SSIM_RADIUS; ++k)
        kernel[k] /= ksum;
    uint32_t ow = w - 2 * SSIM_RADIUS, oh = h - 2 * SSIM_RADIUS;
    size_t on = (size_t)ow * oh;
    double *prod = malloc(n * sizeof *prod), *tmp = malloc((size_t)ow * h * sizeof *tmp);
    double *maps[5] = {NULL};
    bool ok = prod && tmp;
    for (int m = 0; m < 5; ++m)
        ok &= (maps[m] = malloc(on * sizeof *maps[m])) != NULL;
    if (ok) {
        /* mu_x, mu_y, E[x^2], E[y^2], E[xy]: each by the same code, so identical
         * images give identical maps and an SSIM of exactly 1. */
        blur_valid(x, w, h, kernel, tmp, maps[0]);
        blur_valid(y, w, h, kernel, tmp, maps[1]);
        for (size_t p = 0; p < n; ++p)
            prod[p] = x[p] * x[p];
        blur_valid(prod, w, h, kernel, tmp, maps[2]);
        for (size_t p = 0; p < n; ++p)
            prod[p] = y[p] * y[p];
        blur_valid(prod, w, h, kernel, tmp, maps[3]);
        for (size_t p = 0; p < n; ++p)
            prod[p] = x[p] * y[p];
        blur_valid(prod, w, h, kernel, tmp, maps[4]);
        double sum = 0;
        for (size_t p = 0; p < on; ++p) {
            double mx = maps[0][p], my = maps[1][p];
            sum += ssim_of(mx, my, maps[2][p] - mx * mx, maps[3][p] - my * my, maps[4][p] - mx * my);
        }
        *ssim = sum / (double)on;
    }
    free(x);
    free(y);
    free(prod);
    free(tmp);
    for (int m = 0; m < 5; ++m)
        free(maps[m]);
    return ok ? MS_OK : ms_error_set(err, MS_ERR_NOMEM, "ssim: out of memory for %u x %u pixels", w, h);
}

static int compare_double(const void *pa, const void *pb)
{
    double a = *(const double *)pa, b = *(const double *)pb;
    return (a > b) - (a < b);
}

ms_status ms_study_image_compare(const ms_study_image *t, const ms_study_image *r, ms_study_image_error *out,
                                 ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (t->width != r->width || t->height != r->height)
        return ms_error_set(err, MS_ERR_ARG, "image compare: %u x %u against a %u x %u reference", t->width,
                            t->height, r->width, r->height);
    size_t n = (size_t)t->width * t->height;
    out->pixels = n;
    double *angles = malloc((n ? n : 1) * sizeof *angles);
    if (!angles)
        return ms_error_set(err, MS_ERR_NOMEM, "image compare: out of memory for %zu pixels", n);
    size_t both = 0;
    double sum = 0;
    for (size_t p = 0; p < n; ++p) {
        bool ct = ms_study_image_covered(t, p), cr = ms_study_image_covered(r, p);
        out->silhouette_mismatch += ct != cr;
        if (!ct || !cr)
            continue;
        const float *u = &t->normal[3 * p], *v = &r->normal[3 * p];
        double cx = (double)u[1] * v[2] - (double)u[2] * v[1], cy = (double)u[2] * v[0] - (double)u[0] * v[2],
               cz = (double)u[0] * v[1] - (double)u[1] * v[0];
        double dot = (double)u[0] * v[0] + (double)u[1] * v[1] + (double)u[2] * v[2];
        double a = atan2(sqrt(cx * cx + cy * cy + cz * cz), dot) * (180.0 / M_PI);
        angles[both++] = a;
        sum += a;
    }
    out->both_covered = both;
    if (both) {
        qsort(angles, both, sizeof *angles, compare_double);
        out->normal_mean_deg = sum / (double)both;
        out->normal_p95_deg = angles[(size_t)ceil(0.95 * (double)both) - 1];
        out->normal_max_deg = angles[both - 1];
    }
    free(angles);
    out->psnr_db = ms_study_psnr(t->rgb, r->rgb, 3 * n, &out->mse);
    return ms_study_ssim_rgb(t->rgb, r->rgb, t->width, t->height, &out->ssim, err);
}

/* ---- colour ------------------------------------------------------------- */

static double psnr_of(uint64_t sum, uint64_t count)
{
    return sum ? 10 * log10(255.0 * 255.0 * (double)count / (double)sum) : INFINITY;
}

ms_status ms_study_colour_psnr(const uint8_t *test, const uint8_t *reference, size_t pixels, const uint8_t *mask,
                               ms_study_colour_error *out, ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (!test || !reference)
        return ms_error_set(err, MS_ERR_ARG, "colour PSNR: no picture");
    uint64_t sum[3] = {0, 0, 0}, count = 0; /* exact: at most 255^2 per value */
    unsigned worst = 0;
    for (size_t p = 0; p < pixels; ++p) {
        if (mask && !mask[p])
            continue;
        count++;
        for (int c = 0; c < 3; ++c) {
            int d = (int)test[3 * p + (size_t)c] - (int)reference[3 * p + (size_t)c];
            sum[c] += (uint64_t)(d * d);
            worst = (unsigned)abs(d) > worst ? (unsigned)abs(d) : worst;
        }
    }
    if (count == 0)
        return ms_error_set(err, MS_ERR_ARG, "colour PSNR: no pixel to compare");
    out->pixels = count;
    out->mse = (double)(sum[0] + sum[1] + sum[2]) / (3.0 * (double)count);
    out->psnr_db = psnr_of(sum[0] + sum[1] + sum[2], 3 * count);
    for (int c = 0; c < 3; ++c)
        out->channel_psnr_db[c] = psnr_of(sum[c], count);
    out->max_difference = worst;
    return MS_OK;
}

size_t ms_study_colour_mask(const uint8_t *test, const uint8_t *reference, size_t pixels, const uint8_t background[3],
                            bool both, uint8_t *mask)
{
    size_t covered = 0;
    for (size_t p = 0; p < pixels; ++p) {
        bool t = memcmp(&test[3 * p], background, 3) != 0, r = memcmp(&reference[3 * p], background, 3) != 0;
        mask[p] = both ? t && r : t || r;
        covered += mask[p];
    }
    return covered;
}

ms_status ms_study_image_colour_psnr(const ms_study_image *t, const ms_study_image *r, ms_study_colour_error *out,
                                     ms_error *err)
{
    memset(out, 0, sizeof *out);
    if (t->width != r->width || t->height != r->height)
        return ms_error_set(err, MS_ERR_ARG, "colour PSNR: %u x %u against %u x %u pixels", t->width, t->height,
                            r->width, r->height);
    size_t n = (size_t)t->width * t->height;
    uint8_t *mask = malloc(n ? n : 1);
    if (!mask)
        return ms_error_set(err, MS_ERR_NOMEM, "colour PSNR: out of memory for %zu pixels", n);
    for (size_t p = 0; p < n; ++p)
        mask[p] = ms_study_image_covered(t, p) || ms_study_image_covered(r, p);
    ms_status st = ms_study_colour_psnr(t->rgb, r->rgb, n, mask, out, err);
    free(mask);
    return st;
}
