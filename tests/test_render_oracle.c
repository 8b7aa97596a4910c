/* APO shader = CPU oracle (issue 17, docs/RENDERER.md "Tests"): the dragon at
 * resolution 3 and the demo model are baked, decoded for fixed cameras and drawn
 * with the renderer in NORMALS mode into a float colour + 32F depth framebuffer,
 * and in CELL_ID mode. For every covered pixel the surface point is recomputed
 * from the depth (ms_render_unproject), taken to the drawing cell's local
 * coordinates, and ms_apo_lookup_filtered (the renderer's default filter) or
 * ms_apo_lookup (--apo-filter none) is evaluated there on the chunk prefix
 * inflated independently (ms_apo_stream_inflate with the archive's level
 * table), with the same depth cap, missing-child rule and, with the filter, the
 * footprint depth of the pixel (ms_render_apo_footprint_scale times its eye
 * depth; near a power of two the depth on either side is accepted, as a node
 * face is). The angle between the two normals must
 * be within 1 degree at >= 99.5 % of covered pixels and within 5 degrees
 * everywhere except on borders: a pixel whose 3x3 neighbourhood holds another
 * cell id or background (silhouettes and cell borders), which is counted and
 * printed. A truncated prefix (fewer levels, and half of the next level's bytes
 * in transit) must match the oracle of that prefix, and visibly differ from the
 * full chunk's. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "ms_apo_stream.h"
#include "ms_apo_filter.h"
#include "ms_apo_traverse.h"
#include "ms_render.h"
#include "ms_render_internal.h"
#include "ms_test.h"
#include "ms_test_render.h"

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

#define WIDTH 200
#define HEIGHT 150

typedef struct figures {
    size_t covered, within_1, border, border_over_5, ambiguous, inner_over_5, disagree_full;
    size_t filter_changed;   /* the filtered normal > 1 degree from the nearest leaf's */
    size_t footprint_bound;  /* the footprint depth stopped above the nearest leaf */
    size_t smooth;           /* the oracle gives the base (flat) normal: no texel around */
    size_t no_chunk;         /* drawn by a cell without a chunk */
    double worst_inner, worst_border, worst_face;
} figures;

/* Per cell: the oracle's view of the prefix the renderer was given. */
typedef struct oracle {
    ms_apo_chunk *chunks;
    ms_apo_view *views;
    bool *have;
    uint32_t cell_count;
} oracle;

static void oracle_build(oracle *o, const ms_archive *a, const ms_core_apo_chunk *apo, size_t apo_count)
{
    o->cell_count = ms_archive_get_header(a)->cell_count;
    o->chunks = calloc(o->cell_count, sizeof *o->chunks);
    o->views = calloc(o->cell_count, sizeof *o->views);
    o->have = calloc(o->cell_count, sizeof *o->have);
    assert_true(o->chunks && o->views && o->have);
    for (size_t i = 0; i < apo_count; ++i) {
        uint32_t c = apo[i].cell;
        const ms_archive_cell *rec = ms_archive_get_cell(a, c);
        uint32_t table[2 * MS_APO_MAX_LEVELS];
        for (unsigned l = 0; l < rec->apo_levels; ++l)
            table[2 * l] = ms_archive_apo_prefix(a, c, l, &table[2 * l + 1]);
        ms_error err;
        if (ms_apo_stream_inflate(apo[i].data, apo[i].length, table, rec->apo_levels, &o->chunks[c], &err) != MS_OK)
            fail_msg("cell %u: %s", c, err.text);
        if (ms_apo_view_of_chunk(&o->views[c], &o->chunks[c], &err) != MS_OK)
            fail_msg("cell %u: %s", c, err.text);
        assert_int_equal(o->views[c].complete_levels, apo[i].levels);
        o->have[c] = true;
    }
}

static void oracle_free(oracle *o)
{
    for (uint32_t c = 0; c < o->cell_count; ++c)
        ms_apo_chunk_free(&o->chunks[c]);
    free(o->chunks);
    free(o->views);
    free(o->have);
    memset(o, 0, sizeof *o);
}

/* Every cell's words on the GPU are the oracle's words of the prefix given. */
static void check_texels(const ms_render *r, const oracle *o, const ms_core_apo_chunk *apo, size_t count)
{
    glBindBuffer(GL_TEXTURE_BUFFER, ms_render_texel_buffer(r));
    for (size_t i = 0; i < count; ++i) {
        uint32_t c = apo[i].cell, start, words, levels;
        assert_true(ms_render_cell_texels(r, c, &start, &words, &levels));
        assert_int_equal(levels, o->views[c].complete_levels);
        assert_int_equal(words, o->views[c].level_start[levels]);
        uint32_t *back = malloc(words * sizeof *back);
        glGetBufferSubData(GL_TEXTURE_BUFFER, 4 * (GLintptr)start, 4 * (GLsizeiptr)words, back);
        assert_memory_equal(back, o->chunks[c].texels, words * sizeof *back);
        free(back);
    }
    glBindBuffer(GL_TEXTURE_BUFFER, 0);
}

static uint32_t pixel_id(const float *rgba, size_t p)
{
    uint32_t r = (uint32_t)lroundf(rgba[4 * p] * 255.0f), g = (uint32_t)lroundf(rgba[4 * p + 1] * 255.0f),
             b = (uint32_t)lroundf(rgba[4 * p + 2] * 255.0f);
    return r | g << 8 | b << 16;
}

static double angle_deg(const double a[3], const double b[3])
{
    double la = sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2]), lb = sqrt(b[0] * b[0] + b[1] * b[1] + b[2] * b[2]);
    double c = (a[0] * b[0] + a[1] * b[1] + a[2] * b[2]) / (la * lb);
    c = c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c);
    return acos(c) * 180.0 / M_PI;
}

/* How far apart, in cell-local units, the GPU's interpolated position and the
 * one recomputed from the 32F depth may be (both are float computations; the
 * depth alone is good to about 1e-7 of the box side here). */
#define POSITION_SLACK (1.0 / (1 << 18))

/* How the shader looked up: the options' cap, rule and filter, and the camera
 * for the footprint. */
typedef struct lookup_rule {
    uint32_t cap;
    ms_apo_missing_rule rule;
    bool filter, footprint;
    const ms_camera *camera;
} lookup_rule;

/* The footprint depth at a world point in a cube of side `side`, with the
 * footprint scaled by (1 + nudge) (the float rounding of the GPU's eye depth). */
static uint32_t footprint_depth(const lookup_rule *l, const double world[3], double side, double nudge)
{
    const ms_camera *c = l->camera;
    double z = 0;
    for (int k = 0; k < 3; ++k)
        z += (world[k] - c->position[k]) * c->forward[k];
    float f = (float)z * ms_render_apo_footprint_scale(c, side);
    return ms_apo_footprint_depth(f * (float)(1.0 + nudge));
}

/* The oracle's normal at a pixel of the drawing cell, the cell-local position
 * moved by offset[k] * POSITION_SLACK, with the footprint nudged (false: no
 * chunk). */
static bool oracle_normal_at(const oracle *o, const ms_archive *a, uint32_t cell, const double world[3],
                             const int offset[3], double nudge, const lookup_rule *l, const float base[3], double n[3])
{
    if (cell >= o->cell_count || !o->have[cell]) {
        for (int k = 0; k < 3; ++k) /* no chunk: the shader's own normal */
            n[k] = base[k];
        return false;
    }
    double origin[3], side;
    ms_render_cell_cube(ms_archive_get_header(a), ms_archive_get_cell(a, cell), origin, &side);
    float p[3];
    for (int k = 0; k < 3; ++k)
        p[k] = (float)((world[k] - origin[k]) / side + offset[k] * POSITION_SLACK);
    uint32_t cap = l->cap;
    if (l->footprint) {
        uint32_t d = footprint_depth(l, world, side, nudge);
        cap = d < cap ? d : cap;
    }
    if (l->filter) {
        ms_apo_filter_result res;
        ms_apo_lookup_filtered_smooth(&o->views[cell], p, cap, l->rule, base, &res);
        for (int k = 0; k < 3; ++k)
            n[k] = res.normal[k];
    } else {
        ms_apo_lookup_result res;
        ms_apo_lookup(&o->views[cell], p, cap, l->rule, &res);
        for (int k = 0; k < 3; ++k)
            n[k] = res.smooth ? base[k] : res.normal[k];
    }
    return true;
}

static bool oracle_normal(const oracle *o, const ms_archive *a, uint32_t cell, const double world[3],
                          const lookup_rule *l, const float base[3], double n[3])
{
    static const int here[3] = {0, 0, 0};
    return oracle_normal_at(o, a, cell, world, here, 0.0, l, base, n);
}

/* True when the oracle gives got (within 1 degree) somewhere within the position
 * slack of the point (the pixel sits on an octree node's face), or with the
 * footprint 0.1 % larger or smaller (it sits where the footprint depth changes). */
static bool near_node_face(const oracle *o, const ms_archive *a, uint32_t cell, const double world[3],
                           const lookup_rule *l, const float base[3], const double got[3])
{
    static const double nudges[3] = {0.0, -1e-3, 1e-3};
    for (int j = 0; j < (l->footprint ? 3 : 1); ++j)
        for (int i = 0; i < 27; ++i) {
            int offset[3] = {i % 3 - 1, i / 3 % 3 - 1, i / 9 - 1};
            double n[3];
            if (oracle_normal_at(o, a, cell, world, offset, nudges[j], l, base, n) && angle_deg(n, got) <= 1.0)
                return true;
        }
    return false;
}

/* Draws the frame at the camera, compares every covered pixel with the oracle of
 * the given prefixes (and, when full is not NULL, counts pixels where the oracle
 * of the full chunks differs by more than 1 degree). */
static void compare(const ms_archive *a, ms_render *r, const ms_camera *cam, const ms_render_options *opt,
                    const oracle *given, const oracle *full, figures *f)
{
    memset(f, 0, sizeof *f);
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, WIDTH, HEIGHT);
    size_t np = (size_t)WIDTH * HEIGHT;
    float *normals = malloc(np * 4 * sizeof *normals), *ids = malloc(np * 4 * sizeof *ids),
          *depth = malloc(np * sizeof *depth);
    assert_true(normals && ids && depth);
    ms_render_options o = *opt;
    o.shading = MS_SHADING_NORMALS;
    ms_error err;
    if (ms_render_draw(r, cam, &o, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_test_fbo_read(&fbo, normals, depth);
    o.shading = MS_SHADING_CELL_ID;
    if (ms_render_draw(r, cam, &o, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_test_fbo_read(&fbo, ids, NULL);
    /* The normal the shader starts from (flat: smooth is off), which a chunk
     * corrects where it holds texels: the same picture without APO. */
    float *base_px = malloc(np * 4 * sizeof *base_px);
    assert_non_null(base_px);
    o.shading = MS_SHADING_NORMALS;
    o.apo = false;
    if (ms_render_draw(r, cam, &o, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_test_fbo_read(&fbo, base_px, NULL);
    ms_test_fbo_free(&fbo);
    lookup_rule l = {opt->apo_depth_cap ? opt->apo_depth_cap : UINT32_MAX,
                     opt->apo_nearest ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP, opt->apo_filter,
                     opt->apo_footprint, cam};
    for (int y = 0; y < HEIGHT; ++y)
        for (int x = 0; x < WIDTH; ++x) {
            size_t p = (size_t)y * WIDTH + (size_t)x;
            uint32_t id = pixel_id(ids, p);
            if (depth[p] >= 1.0f) {
                assert_int_equal(id, 0);
                continue;
            }
            assert_true(id > 0);
            f->covered++;
            bool border = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= WIDTH || yy >= HEIGHT ||
                        pixel_id(ids, (size_t)yy * WIDTH + (size_t)xx) != id)
                        border = true;
                }
            double world[3], want[3], got[3];
            assert_true(ms_render_unproject(cam, x + 0.5, y + 0.5, depth[p], world));
            float base[3];
            for (int k = 0; k < 3; ++k)
                base[k] = 2.0f * base_px[4 * p + (size_t)k] - 1.0f;
            f->no_chunk += !oracle_normal(given, a, id - 1, world, &l, base, want);
            {
                /* where the chunk has no texel around, the base normal itself */
                double b[3] = {base[0], base[1], base[2]};
                f->smooth += angle_deg(b, want) < 1e-3;
            }
            for (int k = 0; k < 3; ++k)
                got[k] = 2.0 * normals[4 * p + (size_t)k] - 1.0;
            double angle = angle_deg(got, want);
            if (angle <= 1.0)
                f->within_1++;
            if (border) {
                f->border++;
                f->border_over_5 += angle > 5.0;
                if (angle > f->worst_border)
                    f->worst_border = angle;
            } else if (angle > 1.0 && near_node_face(given, a, id - 1, world, &l, base, got)) {
                f->ambiguous++;
                if (angle > f->worst_face)
                    f->worst_face = angle;
            } else {
                f->inner_over_5 += angle > 5.0;
                if (angle > f->worst_inner)
                    f->worst_inner = angle;
            }
            double other[3];
            if (full && oracle_normal(full, a, id - 1, world, &l, base, other) && angle_deg(other, want) > 1.0)
                f->disagree_full++;
            if (l.filter || l.footprint) {
                lookup_rule plain = l;
                plain.filter = plain.footprint = false;
                oracle_normal(given, a, id - 1, world, &plain, base, other);
                f->filter_changed += angle_deg(other, want) > 1.0;
                double origin[3], side;
                ms_render_cell_cube(ms_archive_get_header(a), ms_archive_get_cell(a, id - 1), origin, &side);
                uint32_t fd = footprint_depth(&l, world, side, 0.0);
                float local[3];
                for (int k = 0; k < 3; ++k)
                    local[k] = (float)((world[k] - origin[k]) / side);
                ms_apo_lookup_result deep;
                ms_apo_lookup(&given->views[id - 1], local, l.cap, l.rule, &deep);
                f->footprint_bound += l.footprint && deep.depth > fd;
            }
        }
    free(normals);
    free(ids);
    free(depth);
    free(base_px);
}

static void print_figures(const char *what, const figures *f)
{
    print_message("%-44s %6zu px, %6.3f %% within 1 deg, worst inner %.3f deg; on a node face %zu px (worst %.2f); "
                  "border %zu px (%zu over 5 deg, worst %.2f); %zu px without a texel around (%zu without a chunk)\n",
                  what, f->covered, 100.0 * (double)f->within_1 / (double)f->covered, f->worst_inner, f->ambiguous,
                  f->worst_face, f->border, f->border_over_5, f->worst_border, f->smooth, f->no_chunk);
}

static void check_figures(const figures *f)
{
    assert_true(f->covered > WIDTH * HEIGHT / 10); /* the model fills a good part of the picture */
    assert_true((double)f->within_1 >= 0.995 * (double)f->covered);
    assert_int_equal(f->inner_over_5, 0);
}

/* Renders a model at a few cameras and prefixes, each compared with the oracle. */
static void run_model(ms_archive *a, const char *name, const double dirs[][3], size_t dir_count)
{
    ms_view *view;
    ms_render *r;
    ms_test_render_open(a, &r, &view);
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_view_mesh mesh = {0};
    for (size_t d = 0; d < dir_count; ++d) {
        ms_camera cam;
        /* 0.5 px: a kd-cell's whole diagonal within a pixel, the cut these
         * bounds were measured on (coarser geometry puts more pixels on node
         * faces, where the shader and the oracle may pick different texels) */
        ms_test_render_look(a, view, dirs[d], WIDTH, HEIGHT, 0.5, &cam, &mesh);
        uint32_t cells_drawing = 0;
        {
            bool *seen = calloc(h->cell_count, 1);
            for (size_t t = 0; t < mesh.triangle_count; ++t)
                if (!seen[mesh.triangle_cell[t]])
                    seen[mesh.triangle_cell[t]] = true, cells_drawing++;
            free(seen);
        }
        struct {
            unsigned levels;
            bool mid;
            bool nearest;
            uint32_t cap;
            bool unfiltered; /* --apo-filter none: the nearest leaf, no footprint */
        } cases[] = {{0, false, true, 0, false}, {0, false, false, 0, false}, {0, false, false, 4, false},
                     {3, true, true, 0, false},  {2, false, true, 0, false},  {0, false, true, 0, true}};
        for (size_t k = 0; k < sizeof cases / sizeof *cases; ++k) {
            ms_core_apo_chunk *apo, *apo_full;
            size_t count, count_full;
            ms_test_render_apo(a, &mesh, cases[k].levels, cases[k].mid, &apo, &count);
            ms_test_render_apo(a, &mesh, 0, false, &apo_full, &count_full);
            ms_render_upload_stats up;
            ms_test_render_show(r, &mesh, apo, count, &up);
            assert_int_equal(up.cells_pending, 0);
            oracle given = {0}, full = {0};
            oracle_build(&given, a, apo, count);
            oracle_build(&full, a, apo_full, count_full);
            check_texels(r, &given, apo, count);
            ms_render_options o;
            ms_render_options_default(&o);
            o.apo_nearest = cases[k].nearest;
            o.apo_depth_cap = cases[k].cap;
            o.apo_filter = o.apo_footprint = !cases[k].unfiltered;
            o.smooth = false; /* the oracle's fallback is the flat normal */
            figures f;
            compare(a, r, &cam, &o, &given, cases[k].levels ? &full : NULL, &f);
            char what[128];
            snprintf(what, sizeof what, "%s view %zu%s%s%s (%u cells)", name, d,
                     cases[k].levels ? (cases[k].mid ? ", 3 levels + half" : ", 2 levels") : "", !cases[k].nearest ? (cases[k].cap ? ", STOP, cap 4" : ", STOP") : "",
                     cases[k].unfiltered ? ", unfiltered" : "", cells_drawing);
            print_figures(what, &f);
            check_figures(&f);
            if (!cases[k].unfiltered) {
                /* the filter really is exercised: it moves the normal at many pixels */
                print_message("%-44s %6zu px moved > 1 deg by the filter, %zu px stopped by the footprint\n", "",
                              f.filter_changed, f.footprint_bound);
                assert_true(f.smooth == f.covered || f.filter_changed > (f.covered - f.smooth) / 10);
            }
            if (cases[k].levels) {
                /* the prefix really is read short: the full chunk would shade differently */
                print_message("%-44s %6zu px differ from the full chunk by > 1 deg\n", "", f.disagree_full);
                assert_true(f.smooth == f.covered || f.disagree_full > (f.covered - f.smooth) / 20);
            }
            oracle_free(&given);
            oracle_free(&full);
            free(apo);
            free(apo_full);
        }
    }
    ms_view_mesh_free(&mesh);
    ms_render_free(r);
    ms_view_destroy(view);
}

static void test_dragon(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    double t0 = now_seconds();
    /* chunks as the bake makes them: corrections of the smooth normal, so the
     * missing-neighbour rule is compared on real data (the demo below keeps
     * every texel) */
    ms_archive *a = ms_test_render_bake_apo(model, dir, "dragon", 16, 1500, 7, false);
    print_message("dragon baked in %.1f s (APO depth <= 7)\n", now_seconds() - t0);
    const double dirs[][3] = {{0.3, 0.2, 1.0}, {-1.0, 0.4, -0.2}};
    run_model(a, "dragon res3", dirs, 2);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

static void test_demo(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_archive *a = ms_test_render_bake_demo(40, dir, 14, 2000, 0);
    const double dirs[][3] = {{1.0, 0.5, 0.7}};
    run_model(a, "demo 40", dirs, 1);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dragon),
        cmocka_unit_test(test_demo),
    };
    return cmocka_run_group_tests(tests, ms_test_gl_group_setup, ms_test_gl_group_teardown);
}
