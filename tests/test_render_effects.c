/* Composed shader programs (ms_render.h, "Composed programs"; docs/SCENES.md):
 *  - the assembled fragment source holds an effect's code exactly when the
 *    effect is in the set, for every set and both variants, and no effect
 *    directive is left for the driver (the markers are identifiers only the
 *    effect's code uses);
 *  - a program's variant (ms_render_program_variant) holds the vertex colours,
 *    the sections and the light loop's kinds exactly as the draw's options
 *    and cells call for them;
 *  - every set of the implemented effects compiles and links;
 *  - for each effect, a program without it renders the same picture (RGBA32F,
 *    every channel within 2e-6) as a program with it whose input does not call
 *    for it (no APO, specular 0, one-sided, haze 0), and the effect called for
 *    changes the picture (so the comparison can fail);
 *  - the draw reports which effects were compiled and which ran;
 *  - a placed model draws where its placement puts it;
 *  - displacement: tessellation levels follow projected size (the primitives
 *    a floor of patches generates fall as the camera backs away, about with the
 *    square of the distance; a floor wholly outside the view generates one
 *    triangle per patch), the relief changes the picture, and without the
 *    effect the same options draw the flat floor;
 *  - impostors: a far object drawn as its impostor agrees with its geometry
 *    (from the capture's direction, and 4 degrees away from it), the
 *    dissolve pattern of the geometry and the impostor's coverage are
 *    complementary. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_render.h"
#include "ms_render_impostor.h"
#include "ms_render_internal.h"
#include "ms_test.h"
#include "ms_test_render.h"

#define SIZE 64
#define SAME_TOLERANCE 2e-6 /* per channel, linear float output */
/* Impostor against geometry (mean over pixels of the largest channel
 * difference, and the share of pixels differing by more than 0.1). */
#define MEAN_AT_CAPTURE 0.05 /* measured 0.028 */
#define SHARE_AT_CAPTURE 0.12 /* measured 0.067 */
#define MEAN_TURNED 0.05 /* 4 degrees away: measured 0.025 */
#define SHARE_TURNED 0.15 /* measured 0.076 */
#define assert_near_angle(a, b) assert_true(fabs((a) - (b)) < 1e-9)

/* Identifiers only an effect's code declares or calls. */
static const struct {
    unsigned effect;
    const char *markers[3];
} effect_markers[] = {
    {MS_EFFECT_DETAIL_NORMALS, {"apo_lookup", "apo_words", "apo_on"}},
    {MS_EFFECT_SPECULAR, {"specular_strength", "shininess", "highlight"}},
    {MS_EFFECT_TWO_SIDED, {"two_sided", NULL, NULL}},
    {MS_EFFECT_HAZE, {"haze_density", "haze_colour", "exp("}},
    {MS_EFFECT_IMPOSTORS, {"dissolve", "bayer", NULL}},
};

/* Whether a preprocessor line of src still names an MS_EFFECT_ macro. */
static bool effect_directive_left(const char *src)
{
    for (const char *line = src; line && *line; line = strchr(line, '\n') ? strchr(line, '\n') + 1 : NULL) {
        const char *p = line;
        while (*p == ' ')
            p++;
        const char *end = strchr(p, '\n');
        size_t n = end ? (size_t)(end - p) : strlen(p);
        char buf[512];
        snprintf(buf, sizeof buf, "%.*s", (int)(n < sizeof buf ? n : sizeof buf - 1), p);
        if (*p == '#' && strstr(buf, "MS_EFFECT_"))
            return true;
    }
    return false;
}

static void test_source_composition(void **state)
{
    (void)state;
    for (unsigned effects = 0; effects <= MS_EFFECTS_ALL; ++effects)
        for (int wire = 0; wire < 2; ++wire) {
            char *src;
            ms_error err;
            if (ms_render_program_source(effects, wire, &src, &err) != MS_OK)
                fail_msg("effects 0x%x: %s", effects, err.text);
            assert_true(strncmp(src, "#version 410 core\n", 18) == 0);
            assert_true((strstr(src, "#define MS_WIREFRAME 1\n") != NULL) == (wire != 0));
            if (effect_directive_left(src)) {
                free(src);
                fail_msg("effects 0x%x wire %d: an MS_EFFECT_ directive is left", effects, wire);
            }
            for (size_t e = 0; e < sizeof effect_markers / sizeof effect_markers[0]; ++e)
                for (int m = 0; m < 3 && effect_markers[e].markers[m]; ++m) {
                    bool in_set = (effects & effect_markers[e].effect) != 0;
                    bool found = strstr(src, effect_markers[e].markers[m]) != NULL;
                    if (found != in_set) {
                        free(src);
                        fail_msg("effects 0x%x wire %d: '%s' %s", effects, wire, effect_markers[e].markers[m],
                                 found ? "present" : "missing");
                    }
                }
            free(src);
        }
    char *src = (char *)1;
    ms_error err;
    assert_int_equal(ms_render_program_source(MS_EFFECTS_ALL + 1, false, &src, &err), MS_ERR_ARG);
    assert_null(src);
    assert_string_equal(err.text, "render: effects 0x40 outside 0x3f");
    assert_string_equal(ms_effect_name(MS_EFFECT_HAZE), "haze");
    assert_null(ms_effect_name(3));
    assert_null(ms_effect_name(1u << MS_EFFECT_COUNT));
}

/* The variant's defines: colours and sections only where the draw uses them
 * (the wireframe program always: its geometry stage passes both on), the
 * lights' count and kinds as given; the general source keeps the uniforms. */
static void test_variant_source(void **state)
{
    (void)state;
    ms_render_options o;
    ms_render_options_default(&o);
    ms_error err;
    char *src;
    uint32_t v = ms_render_program_variant(&o, false, false, false);
    assert_int_equal(v & (MS_RENDER_VARIANT_COLOUR | MS_RENDER_VARIANT_SECTIONS), 0);
    assert_int_equal(ms_render_program_source_variant(MS_EFFECTS_VIEWER, v, false, &src, &err), MS_OK);
    assert_non_null(strstr(src, "#define MS_LIGHT_COUNT 1\n#define MS_LIGHT_KINDS float[](2.0)\n"));
    assert_null(strstr(src, "#define MS_VERTEX_COLOUR"));
    assert_null(strstr(src, "#define MS_SECTIONS"));
    free(src);
    assert_true(ms_render_program_variant(&o, true, false, false) & MS_RENDER_VARIANT_COLOUR);
    assert_int_equal(ms_render_program_variant(&o, false, true, false) & MS_RENDER_VARIANT_GENERAL,
                     MS_RENDER_VARIANT_GENERAL);
    assert_int_equal(ms_render_program_variant(&o, false, false, true) & MS_RENDER_VARIANT_GENERAL,
                     MS_RENDER_VARIANT_GENERAL);
    o.section_count = 1;
    o.light_count = 3;
    o.lights[0].kind = MS_RENDER_LIGHT_DIRECTIONAL;
    o.lights[1].kind = MS_RENDER_LIGHT_POINT;
    o.lights[2].kind = MS_RENDER_LIGHT_HEAD;
    v = ms_render_program_variant(&o, true, false, false);
    assert_int_equal(ms_render_program_source_variant(MS_EFFECTS_VIEWER, v, false, &src, &err), MS_OK);
    assert_non_null(strstr(src, "#define MS_VERTEX_COLOUR 1\n#define MS_SECTIONS 1\n"
                                "#define MS_LIGHT_COUNT 3\n#define MS_LIGHT_KINDS float[](0.0, 1.0, 2.0)\n"));
    free(src);
    o.light_count = 0; /* no light: the array still has a size */
    v = ms_render_program_variant(&o, false, false, false);
    assert_int_equal(ms_render_program_source_variant(0, v, false, &src, &err), MS_OK);
    assert_non_null(strstr(src, "#define MS_LIGHT_COUNT 0\n#define MS_LIGHT_KINDS float[](0.0)\n"));
    free(src);
    assert_int_equal(ms_render_program_source(MS_EFFECTS_VIEWER, false, &src, &err), MS_OK);
    assert_non_null(strstr(src, "#define MS_VERTEX_COLOUR 1\n#define MS_SECTIONS 1\n"));
    assert_null(strstr(src, "MS_LIGHT_KINDS float"));
    free(src);
}

/* ---- pictures -------------------------------------------------------------- */

typedef struct fixture {
    char dir[512];
    ms_archive *archive;
    ms_render *render;   /* the demo model with APO, fully held */
    ms_camera camera;
    ms_render *plane;    /* one back-facing triangle across the view */
    ms_camera plane_camera;
} fixture;

static fixture fx;

static void expect(ms_status st, const ms_error *err)
{
    if (st != MS_OK)
        fail_msg("%s", err->text);
}

static float *draw(ms_render *r, const ms_camera *cam, const ms_render_options *o, ms_render_draw_stats *stats)
{
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, SIZE, SIZE);
    ms_error err;
    ms_render_draw_stats local;
    expect(ms_render_draw(r, cam, o, stats ? stats : &local, &err), &err);
    float *px = malloc((size_t)SIZE * SIZE * 4 * sizeof *px);
    assert_non_null(px);
    ms_test_fbo_read(&fbo, px, NULL);
    ms_test_fbo_free(&fbo);
    return px;
}

/* Largest channel difference, and how many pixels differ by more than 1e-3. */
static double compare(const float *a, const float *b, size_t *differing)
{
    double worst = 0;
    *differing = 0;
    for (size_t i = 0; i < (size_t)SIZE * SIZE; ++i) {
        double d = 0;
        for (int c = 0; c < 4; ++c)
            d = fmax(d, fabs((double)a[4 * i + c] - (double)b[4 * i + c]));
        worst = fmax(worst, d);
        *differing += d > 1e-3;
    }
    return worst;
}

/* The scene asks for nothing: diffuse, one-sided, no haze, no APO. */
static void plain_options(ms_render_options *o)
{
    ms_render_options_default(o);
    o->apo = false;
    o->specular = 0.0f;
    o->two_sided = false;
    o->haze_density = 0.0f;
    o->haze_colour[0] = 0.6f, o->haze_colour[1] = 0.3f, o->haze_colour[2] = 0.1f;
    o->effects = 0;
}

/* Turns on the input that calls for the effect. */
static void call_for(unsigned effect, ms_render_options *o)
{
    if (effect == MS_EFFECT_DETAIL_NORMALS)
        o->apo = true;
    if (effect == MS_EFFECT_SPECULAR)
        o->specular = 0.5f, o->shininess = 8.0f;
    if (effect == MS_EFFECT_TWO_SIDED)
        o->two_sided = true;
    if (effect == MS_EFFECT_HAZE)
        o->haze_density = 2.0f;
}

static void test_same_picture_without_effect(void **state)
{
    (void)state;
    const unsigned effects[] = {MS_EFFECT_DETAIL_NORMALS, MS_EFFECT_SPECULAR, MS_EFFECT_TWO_SIDED, MS_EFFECT_HAZE};
    for (size_t k = 0; k < 4; ++k) {
        unsigned e = effects[k];
        /* two-sided needs a back face in view: the plane; the others the model */
        ms_render *r = e == MS_EFFECT_TWO_SIDED ? fx.plane : fx.render;
        const ms_camera *cam = e == MS_EFFECT_TWO_SIDED ? &fx.plane_camera : &fx.camera;
        ms_render_options without, with;
        plain_options(&without);
        /* the program without the effect, even when asked for its input: the
         * input changes nothing */
        call_for(e, &without);
        with = without;
        plain_options(&with);
        with.effects = e;
        ms_render_draw_stats s_without, s_with;
        float *a = draw(r, cam, &without, &s_without);
        float *b = draw(r, cam, &with, &s_with);
        size_t differing;
        double worst = compare(a, b, &differing);
        print_message("%s: without vs not called for: worst %.2g\n", ms_effect_name(e), worst);
        if (worst > SAME_TOLERANCE)
            fail_msg("%s: pictures differ by %g (%zu pixels)", ms_effect_name(e), worst, differing);
        assert_int_equal(s_without.effects_compiled, 0);
        assert_int_equal(s_without.effects_ran, 0);
        /* detail normals not called for: the draw takes the program without
         * them (a software rasteriser pays for a compiled-in branch) */
        assert_int_equal(s_with.effects_compiled, e == MS_EFFECT_DETAIL_NORMALS ? 0 : e);
        assert_int_equal(s_with.effects_ran, 0);
        /* called for, the effect changes a good part of the picture */
        call_for(e, &with);
        ms_render_draw_stats s_on;
        float *c = draw(r, cam, &with, &s_on);
        compare(a, c, &differing);
        print_message("%s: called for: %zu of %d pixels change\n", ms_effect_name(e), differing, SIZE * SIZE);
        assert_true(differing > (size_t)SIZE * SIZE / 20);
        assert_int_equal(s_on.effects_ran, e);
        free(a);
        free(b);
        free(c);
    }
}

/* Every set of the implemented effects builds, with and without wireframe,
 * and draws the model. */
static void test_every_set_builds(void **state)
{
    (void)state;
    const unsigned implemented =
        MS_EFFECT_DETAIL_NORMALS | MS_EFFECT_SPECULAR | MS_EFFECT_TWO_SIDED | MS_EFFECT_HAZE;
    for (unsigned effects = 0; effects <= implemented; ++effects) {
        if (effects & ~implemented)
            continue;
        for (int wire = 0; wire < 2; ++wire) {
            ms_render_options o;
            ms_render_options_default(&o);
            o.effects = effects;
            o.wireframe = wire;
            o.haze_density = 0.5f;
            ms_render_draw_stats s;
            free(draw(fx.render, &fx.camera, &o, &s));
            assert_int_equal(s.effects_compiled, effects);
            assert_true(s.cells_drawn > 0);
            assert_int_equal(s.effects_ran, effects);
        }
    }
}

/* The programs built for light sets (the loop unrolled, the kinds resolved
 * when compiled) link and draw: none, each kind alone, eight of them; each
 * lit set draws a different picture from the unlit one. */
static void test_light_sets_build(void **state)
{
    (void)state;
    ms_render_options o;
    ms_render_options_default(&o);
    o.light_count = 0;
    ms_render_draw_stats s;
    float *dark = draw(fx.render, &fx.camera, &o, &s);
    assert_true(s.cells_drawn > 0);
    for (unsigned set = 0; set < 4; ++set) {
        ms_render_options_default(&o);
        o.light_count = set == 3 ? MS_RENDER_MAX_LIGHTS : 1;
        for (unsigned i = 0; i < o.light_count; ++i) {
            ms_render_light *l = &o.lights[i];
            l->kind = set == 3 ? (ms_render_light_kind)(i % 3) : (ms_render_light_kind)set;
            l->colour[0] = l->colour[1] = l->colour[2] = 1.0f / (float)o.light_count;
            l->vector[0] = 0.3, l->vector[1] = 0.4, l->vector[2] = 2.0;
            l->range = 5.0;
        }
        float *lit = draw(fx.render, &fx.camera, &o, &s);
        assert_true(s.cells_drawn > 0);
        size_t differing;
        compare(dark, lit, &differing);
        assert_true(differing > (size_t)SIZE * SIZE / 20);
        free(lit);
    }
    free(dark);
}

/* A model placed by a translation, seen by a camera translated alike, gives
 * the same picture; seen by the unmoved camera, it has left the view. */
static void test_placement(void **state)
{
    (void)state;
    ms_render_options o;
    ms_render_options_default(&o);
    float *a = draw(fx.render, &fx.camera, &o, NULL);
    const double offset[3] = {5.0, -2.0, 3.0};
    o.placed = true;
    for (int i = 0; i < 16; ++i)
        o.placement[i] = i % 5 == 0 ? 1.0 : 0.0;
    for (int r = 0; r < 3; ++r)
        o.placement[12 + r] = offset[r];
    ms_camera moved = fx.camera;
    for (int r = 0; r < 3; ++r)
        moved.position[r] += offset[r];
    float *b = draw(fx.render, &moved, &o, NULL);
    size_t differing;
    double worst = compare(a, b, &differing);
    print_message("placement: worst %.2g, %zu pixels over 1e-3\n", worst, differing);
    assert_true(differing <= 2); /* float rounding on a silhouette pixel or two */
    /* the model placed away from the unmoved camera: it is no longer in view */
    float *c = draw(fx.render, &fx.camera, &o, NULL);
    compare(a, c, &differing);
    assert_true(differing > (size_t)SIZE * SIZE / 10);
    free(a);
    free(b);
    free(c);
}

/* A floor of 8 x 8 quads (128 triangle patches) over the unit square at y = 0,
 * one cell. */
#define FLOOR_QUADS 8
static ms_render *make_floor(void)
{
    enum { N = FLOOR_QUADS + 1 };
    double positions[3 * N * N];
    uint32_t tris[6 * FLOOR_QUADS * FLOOR_QUADS];
    for (int j = 0; j < N; ++j)
        for (int i = 0; i < N; ++i) {
            double *p = &positions[3 * (j * N + i)];
            p[0] = (double)i / FLOOR_QUADS, p[1] = 0.0, p[2] = (double)j / FLOOR_QUADS;
        }
    size_t t = 0;
    for (int j = 0; j < FLOOR_QUADS; ++j)
        for (int i = 0; i < FLOOR_QUADS; ++i) {
            uint32_t a = (uint32_t)(j * N + i), b = a + 1, c = a + N, d = c + 1;
            /* counter-clockwise seen from +y */
            uint32_t quad[6] = {a, c, d, a, d, b};
            memcpy(&tris[6 * t++], quad, sizeof quad);
        }
    return ms_test_render_one_cell(2, positions, N * N, tris, 2 * FLOOR_QUADS * FLOOR_QUADS);
}

/* Primitives the draw generated (after tessellation), and the picture. */
static GLuint64 draw_counted(ms_render *r, const ms_camera *cam, const ms_render_options *o, float **picture)
{
    GLuint query;
    glGenQueries(1, &query);
    glBeginQuery(GL_PRIMITIVES_GENERATED, query);
    *picture = draw(r, cam, o, NULL);
    glEndQuery(GL_PRIMITIVES_GENERATED);
    GLuint64 count = 0;
    glGetQueryObjectui64v(query, GL_QUERY_RESULT, &count);
    glDeleteQueries(1, &query);
    return count;
}

static void floor_camera(double distance, bool away, ms_camera *cam)
{
    /* looking down at the floor's centre from 45 degrees, or away from it */
    const double centre[3] = {0.5, 0.0, 0.5}, upv[3] = {0, 1, 0};
    double eye[3] = {0.5, distance * M_SQRT1_2, 0.5 + distance * M_SQRT1_2};
    double target[3] = {centre[0], centre[1], centre[2]};
    if (away)
        target[2] = eye[2] + 1.0, target[1] = eye[1];
    assert_int_equal(ms_camera_look_at(eye, target, upv, 40.0, SIZE, SIZE, 0.01, 20.0, cam, NULL), MS_OK);
}

/* Sections clip every program: plain, wireframe, tessellated and both. The
 * floor seen from above (front faces) and from below (back faces), whole and
 * with the plane x = 0.5 cutting its half away: about half its pixels stay,
 * from above each as it was, from below each in the section colour. */
static void test_sections_clip_every_program(void **state)
{
    (void)state;
    ms_render *floor = make_floor();
    const float section[3] = {MS_SECTION_R / 255.0f, MS_SECTION_G / 255.0f, MS_SECTION_B / 255.0f};
    for (int variant = 0; variant < 8; ++variant) {
        bool tess = variant & 1, wire = variant & 2, below = variant & 4;
        ms_render_options o;
        ms_render_options_default(&o);
        o.effects = MS_EFFECT_TWO_SIDED | (tess ? MS_EFFECT_DISPLACEMENT : 0u);
        o.displace = tess;
        o.wireframe = wire;
        o.apo = false;
        const double eye[3] = {0.5, below ? -2.0 : 2.0, 1.2}, centre[3] = {0.5, 0.0, 0.5}, upv[3] = {0, 1, 0};
        ms_camera cam;
        assert_int_equal(ms_camera_look_at(eye, centre, upv, 40.0, SIZE, SIZE, 0.01, 20.0, &cam, NULL), MS_OK);
        float *whole = draw(floor, &cam, &o, NULL);
        o.section_count = 1;
        const double plane[4] = {1, 0, 0, -0.5};
        memcpy(o.sections[0], plane, sizeof plane);
        float *cut = draw(floor, &cam, &o, NULL);
        const float *bg = whole; /* the corner: background */
        size_t covered = 0, kept = 0, wrong = 0;
        for (size_t i = 0; i < (size_t)SIZE * SIZE; ++i) {
            const float *a = &whole[4 * i], *b = &cut[4 * i];
            bool in_whole = fabsf(a[0] - bg[0]) + fabsf(a[1] - bg[1]) + fabsf(a[2] - bg[2]) > 1e-3f;
            bool in_cut = fabsf(b[0] - bg[0]) + fabsf(b[1] - bg[1]) + fabsf(b[2] - bg[2]) > 1e-3f;
            covered += in_whole, kept += in_cut;
            if (!in_cut)
                continue;
            bool same = fabsf(a[0] - b[0]) + fabsf(a[1] - b[1]) + fabsf(a[2] - b[2]) <= 1e-3f;
            bool coloured = fabsf(b[0] - section[0]) + fabsf(b[1] - section[1]) + fabsf(b[2] - section[2]) <= 3e-3f;
            wrong += !in_whole || (below ? !coloured : !same);
        }
        print_message("sections: %s%s from %s: %zu of %zu pixels kept, %zu wrong\n", tess ? "tessellated" : "plain",
                      wire ? " wireframe" : "", below ? "below" : "above", kept, covered, wrong);
        assert_true(covered > 400);
        assert_true(kept > covered * 3 / 10 && kept < covered * 7 / 10);
        assert_int_equal(wrong, 0);
        free(whole);
        free(cut);
    }
    ms_render_options o;
    ms_render_options_default(&o);
    o.section_count = MS_SECTIONS_MAX + 1;
    ms_error err;
    assert_int_equal(ms_render_draw(floor, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    o.section_count = 1;
    memset(o.sections, 0, sizeof o.sections);
    assert_int_equal(ms_render_draw(floor, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    ms_render_free(floor);
}

static void test_displacement_levels(void **state)
{
    (void)state;
    ms_render *floor = make_floor();
    ms_render_options o;
    ms_render_options_default(&o);
    o.effects = MS_EFFECT_DISPLACEMENT;
    o.displace = true;
    o.smooth = false;
    o.displacement_amplitude = 0.02f;
    o.displacement_radius = 0.04f;
    o.displacement_density = 400.0f;
    o.tess_pixels_per_level = 2.0f;
    const GLuint64 patches = 2 * FLOOR_QUADS * FLOOR_QUADS;
    GLuint64 counts[3];
    const double distances[3] = {1.0, 2.0, 4.0};
    float *pictures[3];
    for (int k = 0; k < 3; ++k) {
        ms_camera cam;
        floor_camera(distances[k], false, &cam);
        counts[k] = draw_counted(floor, &cam, &o, &pictures[k]);
        print_message("floor at %.0f: %llu primitives from %llu patches\n", distances[k],
                      (unsigned long long)counts[k], (unsigned long long)patches);
    }
    /* levels about halve with each doubling of the distance: the primitives
     * fall by about 4, less where fractional odd spacing rounds a level up
     * to the next odd count or a level is clamped at 1 (measured 2.9 and
     * 2.6): between 2.2 and 5.5 */
    for (int k = 0; k < 2; ++k) {
        double ratio = (double)counts[k] / (double)counts[k + 1];
        if (ratio < 2.2 || ratio > 5.5)
            fail_msg("distance %.0f to %.0f: primitives fell by %.2f", distances[k], distances[k + 1], ratio);
    }
    assert_true(counts[2] > patches);
    /* outside the view: level 1, one triangle per patch */
    ms_camera away;
    floor_camera(1.0, true, &away);
    float *empty;
    assert_int_equal(draw_counted(floor, &away, &o, &empty), patches);
    /* the relief shows; without the effect, the same options draw the flat floor */
    ms_camera cam;
    floor_camera(1.0, false, &cam);
    ms_render_options flat = o;
    flat.effects = 0;
    float *plain;
    assert_int_equal(draw_counted(floor, &cam, &flat, &plain), patches);
    size_t differing;
    compare(pictures[0], plain, &differing);
    print_message("relief: %zu of %d pixels change\n", differing, SIZE * SIZE);
    assert_true(differing > (size_t)SIZE * SIZE / 10);
    ms_render_draw_stats s;
    free(draw(floor, &cam, &o, &s));
    assert_int_equal(s.effects_ran, MS_EFFECT_DISPLACEMENT);
    free(draw(floor, &cam, &flat, &s));
    assert_int_equal(s.effects_ran, 0);
    for (int k = 0; k < 3; ++k)
        free(pictures[k]);
    free(empty);
    free(plain);
    ms_render_free(floor);
}

/* The demo model's camera moved back to `distance` box sides from the box
 * centre and turned by `degrees` about the vertical through it. */
static void far_camera(double distance, double degrees, ms_camera *cam, double centre[3], double *radius)
{
    const ms_archive_header *h = ms_archive_get_header(fx.archive);
    for (int a = 0; a < 3; ++a)
        centre[a] = h->box_origin[a] + 0.5 * h->box_side;
    *radius = 0.5 * sqrt(3.0) * h->box_side;
    double t = degrees * M_PI / 180.0;
    double dir[3] = {1.0, 0.5, 0.7};
    double rotated[3] = {dir[0] * cos(t) + dir[2] * sin(t), dir[1], -dir[0] * sin(t) + dir[2] * cos(t)};
    ms_test_render_camera(h, rotated, distance, 40.0, SIZE, SIZE, cam);
}

/* Over the object's pixels (those of a that differ from its corner pixel, the
 * background, or of b likewise): the mean of the largest channel difference,
 * and the share differing by more than 0.1; *object their count. */
static void image_error(const float *a, const float *b, double *mean, double *share, size_t *object)
{
    double sum = 0;
    size_t big = 0, n = 0;
    for (size_t i = 0; i < (size_t)SIZE * SIZE; ++i) {
        double d = 0, fa = 0, fb = 0;
        for (int c = 0; c < 3; ++c) {
            d = fmax(d, fabs((double)a[4 * i + c] - (double)b[4 * i + c]));
            fa = fmax(fa, fabs((double)a[4 * i + c] - (double)a[c]));
            fb = fmax(fb, fabs((double)b[4 * i + c] - (double)a[c]));
        }
        if (fa <= 1e-3 && fb <= 1e-3)
            continue;
        n++;
        sum += d;
        big += d > 0.1;
    }
    *object = n;
    *mean = n ? sum / (double)n : 0;
    *share = n ? (double)big / (double)n : 0;
}

/* The impostor's picture: the background as the geometry's draw clears it
 * (the geometry wholly dissolved), then the impostor. */
static float *draw_impostor(ms_impostor *imp, const ms_camera *cam, float coverage, float dissolve)
{
    ms_render_options o;
    ms_render_options_default(&o);
    o.effects |= MS_EFFECT_IMPOSTORS;
    o.dissolve = dissolve;
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, SIZE, SIZE);
    ms_error err;
    expect(ms_render_draw(fx.render, cam, &o, NULL, &err), &err);
    expect(ms_impostor_draw(imp, cam, coverage, 0.0f, NULL, &err), &err);
    float *px = malloc((size_t)SIZE * SIZE * 4 * sizeof *px);
    assert_non_null(px);
    ms_test_fbo_read(&fbo, px, NULL);
    ms_test_fbo_free(&fbo);
    return px;
}

static void test_impostor_matches_geometry(void **state)
{
    (void)state;
    ms_impostor *imp;
    ms_error err;
    expect(ms_impostor_new(128, &imp, &err), &err);
    ms_camera cam;
    double centre[3], radius;
    far_camera(2.5, 0.0, &cam, centre, &radius);
    assert_near_angle(ms_impostor_angle(imp, &cam), 180.0);
    ms_render_options o;
    ms_render_options_default(&o);
    expect(ms_impostor_capture(imp, fx.render, &o, centre, radius, &cam, &err), &err);
    assert_true(ms_impostor_angle(imp, &cam) < 1e-3);
    const double turns[2] = {0.0, 4.0};
    const double mean_bound[2] = {MEAN_AT_CAPTURE, MEAN_TURNED}, share_bound[2] = {SHARE_AT_CAPTURE, SHARE_TURNED};
    for (int k = 0; k < 2; ++k) {
        far_camera(2.5, turns[k], &cam, centre, &radius);
        float *geometry = draw(fx.render, &cam, &o, NULL);
        float *stand_in = draw_impostor(imp, &cam, 1.0f, 0.0f);
        double mean, share;
        size_t object;
        image_error(geometry, stand_in, &mean, &share, &object);
        print_message("impostor %.0f degrees from its capture (%.1f): over the object's %zu pixels, mean error "
                      "%.4f, %.1f%% over 0.1\n",
                      turns[k], ms_impostor_angle(imp, &cam), object, mean, 100 * share);
        assert_true(object > (size_t)SIZE * SIZE / 20);
        if (mean > mean_bound[k] || share > share_bound[k])
            fail_msg("impostor at %.0f degrees: mean %.4f (at most %.4f), share %.3f (at most %.3f)", turns[k], mean,
                     mean_bound[k], share, share_bound[k]);
        free(geometry);
        free(stand_in);
    }
    /* half and half: the geometry dissolved where the impostor draws, and
     * the other way round, gives the same picture as each alone at the
     * capture's direction within the same bounds; nothing drawn twice or not
     * at all shows as background inside the object */
    far_camera(2.5, 0.0, &cam, centre, &radius);
    float *geometry = draw(fx.render, &cam, &o, NULL);
    ms_render_options half = o;
    half.effects |= MS_EFFECT_IMPOSTORS;
    half.dissolve = 0.5f;
    ms_test_fbo fbo;
    ms_test_fbo_new(&fbo, SIZE, SIZE);
    expect(ms_render_draw(fx.render, &cam, &half, NULL, &err), &err);
    expect(ms_impostor_draw(imp, &cam, 0.5f, 0.0f, NULL, &err), &err);
    float *mixed = malloc((size_t)SIZE * SIZE * 4 * sizeof *mixed);
    assert_non_null(mixed);
    ms_test_fbo_read(&fbo, mixed, NULL);
    ms_test_fbo_free(&fbo);
    double mean, share;
    size_t object;
    image_error(geometry, mixed, &mean, &share, &object);
    print_message("half dissolved: mean error %.4f, %.1f%% over 0.1\n", mean, 100 * share);
    assert_true(mean <= MEAN_AT_CAPTURE && share <= SHARE_AT_CAPTURE);
    /* the geometry alone, half dissolved, misses half its pixels */
    float *holes = draw(fx.render, &cam, &half, NULL);
    image_error(geometry, holes, &mean, &share, &object);
    print_message("geometry half dissolved alone: %.1f%% of the object's pixels missing\n", 100 * share);
    assert_true(share > 0.4 && share < 0.6);
    free(holes);
    free(geometry);
    free(mixed);
    ms_impostor_free(imp);
}

static void test_bad_options(void **state)
{
    (void)state;
    ms_render_options o;
    ms_render_options_default(&o);
    ms_error err;
    o.effects = 1u << 9;
    assert_int_equal(ms_render_draw(fx.render, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render: effects 0x200 unknown");
    ms_render_options_default(&o);
    o.light_count = 9;
    assert_int_equal(ms_render_draw(fx.render, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render: 9 lights, at most 8");
    ms_render_options_default(&o);
    o.lights[0].kind = MS_RENDER_LIGHT_POINT;
    assert_int_equal(ms_render_draw(fx.render, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render: point light 0 without a positive range");
    ms_render_options_default(&o);
    o.shininess = 0.5f;
    assert_int_equal(ms_render_draw(fx.render, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render: shininess, specular or haze density out of range");
    ms_render_options_default(&o);
    o.displace = true;
    o.displacement_radius = 0.0f;
    assert_int_equal(ms_render_draw(fx.render, &fx.camera, &o, NULL, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "render: displacement amplitude, radius, density or level size out of range");
}

/* One triangle of a one-cell unit-box model across the view, wound clockwise
 * as seen from the camera (a back face). */
static ms_render *make_plane(void)
{
    const double positions[9] = {-20, -20, 0.4, 0.5, 20, 0.6, 20, -20, 0.5};
    const uint32_t tri[3] = {0, 1, 2};
    ms_render *r = ms_test_render_one_cell(4, positions, 3, tri, 1);
    const double eye[3] = {0.5, 0.5, 3.0}, centre[3] = {0.5, 0.5, 0.5}, upv[3] = {0, 1, 0};
    assert_int_equal(ms_camera_look_at(eye, centre, upv, 40.0, SIZE, SIZE, 0.5, 10.0, &fx.plane_camera, NULL),
                     MS_OK);
    return r;
}

static int setup(void **state)
{
    assert_int_equal(ms_test_gl_group_setup(state), 0);
    memset(&fx, 0, sizeof fx);
    ms_test_tmpdir(fx.dir, sizeof fx.dir);
    fx.archive = ms_test_render_bake_demo(24, fx.dir, 14, 2000, 0);
    ms_view *view;
    ms_test_render_open(fx.archive, &fx.render, &view);
    const double dir[3] = {1.0, 0.5, 0.7};
    ms_view_mesh mesh = {0};
    ms_test_render_look(fx.archive, view, dir, SIZE, SIZE, 1.0, &fx.camera, &mesh);
    ms_core_apo_chunk *apo;
    size_t apo_count;
    ms_test_render_apo(fx.archive, &mesh, 0, false, &apo, &apo_count);
    ms_render_upload_stats up;
    ms_test_render_show(fx.render, &mesh, apo, apo_count, &up);
    assert_int_equal(up.cells_pending, 0);
    free(apo);
    ms_view_mesh_free(&mesh);
    ms_view_destroy(view);
    fx.plane = make_plane();
    return 0;
}

static int teardown(void **state)
{
    ms_render_free(fx.render);
    ms_render_free(fx.plane);
    ms_archive_close(fx.archive);
    ms_test_rmdir(fx.dir);
    return ms_test_gl_group_teardown(state);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_source_composition),
        cmocka_unit_test(test_variant_source),
        cmocka_unit_test(test_same_picture_without_effect),
        cmocka_unit_test(test_sections_clip_every_program),
        cmocka_unit_test(test_every_set_builds),
        cmocka_unit_test(test_light_sets_build),
        cmocka_unit_test(test_placement),
        cmocka_unit_test(test_bad_options),
        cmocka_unit_test(test_displacement_levels),
        cmocka_unit_test(test_impostor_matches_geometry),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
