/* The browser client's colour, natively (client/web/ms_web_view.h, "Colour";
 * docs/BROWSER.md, "Colour"): the colour trefoil fixture (tests/data) baked
 * with its colour, streamed through the web view's plans, the geometry and
 * colour prefixes each handed over in two overlapping pieces. The view
 * settles only once the colour is held; its stitched colours are then
 * exactly those of a view given every byte of the archive (the same cut:
 * ms_study_cut), with no vertex left in the pending grey. A damaged colour
 * stream fails the stitch with one line naming it; bytes with a gap, past
 * the stream or for a model without colour are refused, and a model without
 * colour plans none and stitches no colours. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_camera.h"
#include "ms_nsp_check.h"
#include "ms_study_cut.h"
#include "ms_test.h"
#include "ms_view_decoder.h"
#include "ms_web_view.h"

/* in the repository, not fetched: tests run from its root */
#define FIXTURE "tests/data/trefoil_color.ply.gz"

typedef struct fixture {
    char dir[512];
    ms_archive *colour, *plain; /* the trefoil with its colour, and without */
} fixture;

static ms_archive *bake_trefoil(const char *dir, const char *name, bool no_colour)
{
    char path[700];
    ms_bake_options o;
    ms_nsp_test_bake_options(FIXTURE, dir, name, &o);
    o.min_triangles = 2000; /* several levels of cells: children's colour starts from their parent's */
    o.no_colour = no_colour;
    o.apo.enabled = false;
    ms_bake_report report;
    ms_error err;
    if (ms_bake(&o, &report, &err) != MS_OK) {
        fprintf(stderr, "bake: %s\n", err.text);
        return NULL;
    }
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_archive *a = NULL;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fprintf(stderr, "%s\n", err.text);
    return a;
}

static int group_setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f)
        return -1;
    ms_test_tmpdir(f->dir, sizeof f->dir);
    f->colour = bake_trefoil(f->dir, "trefoil", false);
    f->plain = bake_trefoil(f->dir, "grey", true);
    *state = f;
    return f->colour && f->plain ? 0 : -1;
}

static int group_teardown(void **state)
{
    fixture *f = *state;
    ms_archive_close(f->colour);
    ms_archive_close(f->plain);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static ms_web_view *open_view(const ms_archive *a, const char *name)
{
    size_t size;
    const uint8_t *blob = ms_archive_index_bytes(a, &size);
    ms_web_view *v = NULL;
    ms_error err;
    assert_int_equal(ms_web_view_new(blob, size, name, &v, &err), MS_OK);
    return v;
}

static const double POSITION[3] = {0.4, 0.3, 1.4}, TARGET[3] = {0, 0, 0}, UP[3] = {0, 1, 0};
#define WIDTH 320
#define HEIGHT 240

/* Bytes [held, want) of a stream handed over in two pieces, the second
 * overlapping the first by a byte. */
static void give_in_two(ms_web_view *v, uint32_t cell, const uint8_t *stream, uint32_t held, uint32_t want,
                        bool colour)
{
    uint32_t half = held + (want - held) / 2, from = half > held ? half - 1 : held;
    if (colour) {
        assert_int_equal(ms_web_view_give_colour(v, cell, held, stream + held, half - held), MS_OK);
        assert_int_equal(ms_web_view_give_colour(v, cell, from, stream + from, want - from), MS_OK);
        assert_int_equal(ms_web_view_colour_held(v, cell), want);
    } else {
        assert_int_equal(ms_web_view_give(v, cell, held, stream + held, half - held), MS_OK);
        assert_int_equal(ms_web_view_give(v, cell, from, stream + from, want - from), MS_OK);
        assert_int_equal(ms_web_view_held(v, cell), want);
    }
}

/* Plans and hands over what each plan asks for until settled; the colour
 * bytes handed over are added to *colour_bytes. */
static unsigned stream(const ms_archive *a, ms_web_view *v, uint64_t *colour_bytes)
{
    unsigned rounds = 0;
    for (;;) {
        int settled = -1;
        assert_int_equal(ms_web_view_plan(v, 0, &settled), MS_OK);
        uint32_t cells = ms_web_view_plan_count(v), colours = ms_web_view_plan_colour_count(v);
        if (settled) {
            assert_int_equal(cells, 0);
            assert_int_equal(colours, 0);
            return rounds;
        }
        assert_true(cells + colours > 0);
        for (uint32_t k = 0; k < cells; ++k) {
            uint32_t cell = ms_web_view_plan_cell(v, k);
            size_t total;
            const uint8_t *payload = ms_archive_geometry(a, cell, &total);
            give_in_two(v, cell, payload, ms_web_view_held(v, cell), ms_web_view_plan_bytes(v, k), false);
        }
        for (uint32_t k = 0; k < colours; ++k) {
            uint32_t cell = ms_web_view_plan_colour_cell(v, k), want = ms_web_view_plan_colour_bytes(v, k);
            uint32_t held = ms_web_view_colour_held(v, cell);
            assert_int_equal(want, ms_archive_colour_prefix(a, cell, ms_web_view_plan_colour_bits(v, k)));
            assert_int_equal(want, ms_web_view_colour_prefix(v, cell, ms_web_view_plan_colour_bits(v, k)));
            assert_true(want > held);
            size_t total;
            const uint8_t *stream_bytes = ms_archive_colour(a, cell, &total);
            give_in_two(v, cell, stream_bytes, held, want, true);
            *colour_bytes += want - held;
        }
        assert_true(++rounds < 100);
    }
}

/* The cut of a view given every byte of the archive, for the same camera. */
static void reference_cut(const ms_archive *a, double tolerance, ms_view_mesh *mesh, ms_view **full)
{
    ms_error err;
    assert_int_equal(ms_view_create_from_archive(a, full, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    double lo[3], hi[3], near, far;
    for (int k = 0; k < 3; ++k) {
        lo[k] = h->box_origin[k];
        hi[k] = lo[k] + h->box_side;
    }
    ms_camera_depth_range(POSITION, lo, hi, &near, &far);
    ms_camera camera;
    assert_int_equal(ms_camera_look_at(POSITION, TARGET, UP, 40, WIDTH, HEIGHT, far * 1e-5, far, &camera, &err),
                     MS_OK);
    ms_view_select_params params;
    ms_view_select_params_default(&params);
    params.tolerance_px = tolerance;
    ms_study_cut_report report;
    assert_int_equal(ms_study_cut(a, *full, &camera, &params, NULL, mesh, &report, &err), MS_OK);
}

static void test_colour_streams_to_the_cut_of_every_byte(void **state)
{
    fixture *f = *state;
    static const double tolerances[] = {8.0, 1.0, 0.25};
    for (size_t t = 0; t < sizeof tolerances / sizeof *tolerances; ++t) {
        ms_web_view *v = open_view(f->colour, "trefoil");
        assert_true(ms_web_view_has_colour(v));
        assert_int_equal(ms_web_view_camera(v, POSITION, TARGET, UP, 40, WIDTH, HEIGHT, 0, 0, tolerances[t]),
                         MS_OK);
        uint64_t colour_bytes = 0;
        unsigned rounds = stream(f->colour, v, &colour_bytes);
        assert_int_equal(ms_web_view_stitch(v), MS_OK);
        ms_view *full;
        ms_view_mesh mesh = {0};
        reference_cut(f->colour, tolerances[t], &mesh, &full);
        uint32_t nv = ms_web_view_vertex_count(v);
        const uint8_t *colours = ms_web_view_colours(v);
        printf("%.2f px: %u rounds, %u cells, %u vertices, %u triangles, %llu colour bytes\n", tolerances[t],
               rounds, ms_web_view_shown_cells(v), nv, ms_web_view_triangle_count(v),
               (unsigned long long)colour_bytes);
        assert_non_null(colours);
        assert_non_null(mesh.colours);
        assert_true(colour_bytes > 0);
        assert_int_equal(nv, mesh.vertex_count);
        assert_int_equal(ms_web_view_triangle_count(v), mesh.triangle_count);
        assert_memory_equal(colours, mesh.colours, 4 * (size_t)nv);
        if (tolerances[t] < 1.0) /* a cut of several cells, some split: their children's colour too */
            assert_true(ms_web_view_shown_cells(v) > 1);
        /* every vertex in its scanned colour: none in the pending grey */
        static const uint8_t pending[4] = {221, 216, 209, 255};
        for (uint32_t i = 0; i < nv; ++i)
            assert_memory_not_equal(colours + 4 * (size_t)i, pending, 4);
        ms_view_mesh_free(&mesh);
        ms_view_destroy(full);
        ms_web_view_free(v);
    }
}

static void test_damaged_colour_fails_the_stitch(void **state)
{
    fixture *f = *state;
    ms_web_view *v = open_view(f->colour, "trefoil");
    assert_int_equal(ms_web_view_camera(v, POSITION, TARGET, UP, 40, WIDTH, HEIGHT, 0, 0, 8.0), MS_OK);
    int settled = -1;
    assert_int_equal(ms_web_view_plan(v, 0, &settled), MS_OK);
    assert_false(settled);
    assert_true(ms_web_view_plan_colour_count(v) > 0);
    /* the root's geometry as planned, its colour damaged in its last byte */
    for (uint32_t k = 0; k < ms_web_view_plan_count(v); ++k) {
        uint32_t cell = ms_web_view_plan_cell(v, k);
        size_t total;
        const uint8_t *payload = ms_archive_geometry(f->colour, cell, &total);
        assert_int_equal(ms_web_view_give(v, cell, 0, payload, ms_web_view_plan_bytes(v, k)), MS_OK);
    }
    uint32_t cell = ms_web_view_plan_colour_cell(v, 0), want = ms_web_view_plan_colour_bytes(v, 0);
    size_t total;
    const uint8_t *stream_bytes = ms_archive_colour(f->colour, cell, &total);
    uint8_t *damaged = malloc(want);
    assert_non_null(damaged);
    memcpy(damaged, stream_bytes, want);
    for (uint32_t i = want / 2; i < want; ++i)
        damaged[i] ^= 0x5A;
    assert_int_equal(ms_web_view_give_colour(v, cell, 0, damaged, want), MS_OK);
    free(damaged);
    assert_int_equal(ms_web_view_plan(v, 0, &settled), MS_OK);
    ms_status st = ms_web_view_stitch(v);
    printf("damaged: %s\n", ms_web_view_error(v));
    assert_int_not_equal(st, MS_OK);
    assert_non_null(strstr(ms_web_view_error(v), "colour"));
    assert_null(strchr(ms_web_view_error(v), '\n'));
    ms_web_view_free(v);
}

static void test_colour_bytes_refused(void **state)
{
    fixture *f = *state;
    ms_web_view *v = open_view(f->colour, "trefoil");
    size_t total;
    const uint8_t *stream_bytes = ms_archive_colour(f->colour, 0, &total);
    assert_true(total > 4);
    /* a gap after nothing held */
    assert_int_equal(ms_web_view_give_colour(v, 0, 2, stream_bytes + 2, 2), MS_ERR_ARG);
    printf("%s\n", ms_web_view_error(v));
    assert_non_null(strstr(ms_web_view_error(v), "gap"));
    /* past the stream's end */
    uint8_t *longer = calloc(total + 1, 1);
    assert_non_null(longer);
    memcpy(longer, stream_bytes, total);
    assert_int_equal(ms_web_view_give_colour(v, 0, 0, longer, (uint32_t)total + 1), MS_ERR_RANGE);
    printf("%s\n", ms_web_view_error(v));
    free(longer);
    assert_int_equal(ms_web_view_colour_held(v, 0), 0);
    /* an unknown cell */
    assert_int_equal(ms_web_view_give_colour(v, ms_web_view_cell_count(v), 0, stream_bytes, 1), MS_ERR_ARG);
    /* the whole stream, then again (nothing new) */
    assert_int_equal(ms_web_view_give_colour(v, 0, 0, stream_bytes, (uint32_t)total), MS_OK);
    assert_int_equal(ms_web_view_give_colour(v, 0, 0, stream_bytes, (uint32_t)total), MS_OK);
    assert_int_equal(ms_web_view_colour_held(v, 0), total);
    ms_web_view_free(v);

    /* a model without colour: nothing planned, nothing taken, no colours */
    v = open_view(f->plain, "grey");
    assert_false(ms_web_view_has_colour(v));
    assert_int_equal(ms_web_view_colour_prefix(v, 0, 8), 0);
    assert_int_equal(ms_web_view_give_colour(v, 0, 0, stream_bytes, 1), MS_ERR_ARG);
    assert_non_null(strstr(ms_web_view_error(v), "no colour"));
    assert_int_equal(ms_web_view_camera(v, POSITION, TARGET, UP, 40, WIDTH, HEIGHT, 0, 0, 4.0), MS_OK);
    uint64_t colour_bytes = 0;
    stream(f->plain, v, &colour_bytes);
    assert_int_equal(colour_bytes, 0);
    assert_int_equal(ms_web_view_stitch(v), MS_OK);
    assert_true(ms_web_view_triangle_count(v) > 0);
    assert_null(ms_web_view_colours(v));
    ms_web_view_free(v);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_colour_streams_to_the_cut_of_every_byte),
        cmocka_unit_test(test_damaged_colour_fails_the_stitch),
        cmocka_unit_test(test_colour_bytes_refused),
    };
    return cmocka_run_group_tests(tests, group_setup, group_teardown);
}
