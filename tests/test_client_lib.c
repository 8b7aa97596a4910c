/* libmeshstream-client's facade (client/lib/meshstream-client.h) in process,
 * under the sanitizers: its argument checks and one-line errors, a local
 * archive streamed at full precision (exactly the archive's leaves, triangles
 * and vertices; the cells' figures equal their records), a degenerate camera
 * refused while the stream goes on, a missing archive reported in progress,
 * and the version helpers. test_install runs the installed shared object. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "meshstream-client.h"
#include "ms_archive.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_version.h"

static void test_options_and_arguments(void **state)
{
    (void)state;
    msc_error e;
    msc_options *o = msc_options_new();
    assert_non_null(o);
    assert_int_equal(msc_options_set_server(o, "127.0.0.1", 0, &e), MSC_ERR_ARG);
    assert_string_equal(e.text, "server: the port must be in [1, 65535]");
    assert_int_equal(msc_options_set_server(o, "", 7800, &e), MSC_ERR_ARG);
    assert_int_equal(msc_options_set_tolerance(o, 0, &e), MSC_ERR_ARG);
    assert_int_equal(msc_options_set_tolerance(o, 1.0 / 0.0, &e), MSC_ERR_ARG);
    assert_int_equal(msc_options_set_bandwidth(o, -1, &e), MSC_ERR_ARG);
    assert_int_equal(msc_options_set_archive(o, NULL, &e), MSC_ERR_ARG);
    assert_int_equal(msc_options_set_model(o, "", &e), MSC_ERR_ARG);

    msc_stream *s = (msc_stream *)o; /* must be overwritten with NULL */
    assert_int_equal(msc_stream_new(o, &s, &e), MSC_ERR_ARG);
    assert_null(s);
    assert_string_equal(e.text, "stream: give a server or an archive");
    assert_int_equal(msc_options_set_server(o, "127.0.0.1", 7800, &e), MSC_OK);
    assert_int_equal(e.code, MSC_OK);
    assert_int_equal(msc_stream_new(o, &s, &e), MSC_ERR_ARG);
    assert_string_equal(e.text, "stream: a server needs a model name");
    assert_int_equal(msc_options_set_token(o, "secret", &e), MSC_OK);
    assert_int_equal(msc_options_set_token(o, NULL, &e), MSC_OK);
    msc_options_free(o);

    /* NULL handles: no-ops and argument errors, never a crash */
    msc_options_free(NULL);
    msc_stream_free(NULL);
    msc_frame_free(NULL);
    assert_null(msc_stream_take_frame(NULL));
    assert_int_equal(msc_frame_triangle_count(NULL), 0);
    assert_int_equal(msc_frame_cell(NULL, 0, NULL), MSC_ERR_ARG);
    assert_string_equal(msc_status_name(MSC_ERR_ARG), ms_status_name(MS_ERR_ARG));
    assert_string_equal(msc_version(), ms_version());
}

static void test_version_helpers(void **state)
{
    (void)state;
    char *a[] = {"prog", "--json", "--version", NULL};
    char *b[] = {"prog", "--", "--version", NULL};
    char *c[] = {"prog", "--versions", NULL};
    assert_true(ms_version_asked(3, a));
    assert_false(ms_version_asked(3, b)); /* after "--" it is an operand */
    assert_false(ms_version_asked(2, c));
    assert_false(ms_version_asked(1, a));
}

/* The whole model in view at a tiny tolerance: every leaf at full precision. */
static void test_local_archive_at_full_precision(void **state)
{
    (void)state;
    char dir[512], archives[600], file[700];
    assert_int_equal(ms_nsp_test_demo_archive(dir, sizeof dir, archives, sizeof archives), 0);
    snprintf(file, sizeof file, "%s/demo.msa", archives);
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(file, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    const ms_archive_header *h = ms_archive_get_header(a);

    msc_error e;
    msc_options *o = msc_options_new();
    assert_int_equal(msc_options_set_archive(o, file, &e), MSC_OK);
    /* From two box sides away a grid step is about 0.004 px, and a cell one bit
     * short of full precision may err by as little as the bake's floor (0.22 of
     * a step, ms_nsp_surface.h): 0.0001 px asks for every bit. */
    assert_int_equal(msc_options_set_tolerance(o, 0.0001, &e), MSC_OK);
    msc_stream *s;
    if (msc_stream_new(o, &s, &e) != MSC_OK)
        fail_msg("%s", e.text);
    msc_options_free(o);
    msc_model_info info;
    if (msc_stream_wait_open(s, 30.0, &info, &e) != MSC_OK)
        fail_msg("%s", e.text);
    assert_int_equal(info.cell_count, h->cell_count);
    assert_int_equal(info.triangle_count, h->triangle_count);
    assert_int_equal(info.vertex_count, h->vertex_count);
    assert_int_equal(info.bits, h->bits);
    assert_true(info.bounds_known);
    assert_true(info.box_side == h->box_side);

    double side = info.box_side, centre[3];
    for (int k = 0; k < 3; ++k)
        centre[k] = info.box_origin[k] + side / 2;
    msc_camera bad = {.position = {centre[0], centre[1], centre[2]},
                      .target = {centre[0], centre[1], centre[2]},
                      .up = {0, 1, 0}, .fovy_degrees = 60, .width = 800, .height = 600,
                      .near_distance = side / 100, .far_distance = side * 10};
    assert_int_equal(msc_stream_set_camera(s, &bad, &e), MSC_ERR_ARG);
    msc_camera cam = bad;
    cam.position[2] += 2 * side;
    assert_int_equal(msc_stream_set_camera(s, &cam, &e), MSC_OK);
    msc_progress p;
    if (msc_stream_wait_complete(s, 120.0, &p, &e) != MSC_OK)
        fail_msg("%s", e.text);
    assert_true(p.model_open && p.view_complete);
    assert_string_equal(p.error, "");

    msc_frame *f = msc_stream_take_frame(s);
    assert_non_null(f);
    assert_true(msc_frame_generation(f) > 0);
    assert_int_equal(msc_frame_triangle_count(f), h->triangle_count);
    assert_int_equal(msc_frame_vertex_count(f), h->vertex_count);
    size_t leaves = 0, cell_triangles = 0;
    for (uint32_t c = 0; c < h->cell_count; ++c)
        leaves += ms_archive_get_cell(a, c)->first_child == MS_ARCHIVE_NONE;
    assert_int_equal(msc_frame_cell_count(f), leaves);
    for (size_t i = 0; i < msc_frame_cell_count(f); ++i) {
        msc_cell cell;
        assert_int_equal(msc_frame_cell(f, i, &cell), MSC_OK);
        const ms_archive_cell *r = ms_archive_get_cell(a, cell.id);
        assert_true(cell.leaf);
        /* an empty leaf errs by nothing at any bit: it stays at its first */
        assert_int_equal(cell.bits, r->triangle_count ? cell.bits_max : r->bits_min);
        assert_int_equal(cell.bits_max, r->bits_max);
        assert_int_equal(cell.level, r->level);
        assert_int_equal(cell.triangle_count, r->triangle_count);
        cell_triangles += cell.triangle_count;
    }
    msc_cell cell;
    assert_int_equal(msc_frame_cell(f, leaves, &cell), MSC_ERR_ARG);
    /* every triangle's cell is a shown one, and its corners are vertices */
    const uint32_t *tri = msc_frame_triangles(f), *tri_cell = msc_frame_triangle_cells(f);
    for (size_t t = 0; t < msc_frame_triangle_count(f); ++t) {
        assert_true(ms_archive_get_cell(a, tri_cell[t])->first_child == MS_ARCHIVE_NONE);
        for (int k = 0; k < 3; ++k)
            assert_true(tri[3 * t + k] < msc_frame_vertex_count(f));
    }
    /* the leaves store the triangles cut by their boundaries more than once */
    assert_true(cell_triangles >= h->triangle_count);
    msc_frame_free(f);
    msc_stream_free(s);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* A missing archive: the stream starts, then says why it stopped. */
static void test_missing_archive(void **state)
{
    (void)state;
    msc_error e;
    msc_options *o = msc_options_new();
    assert_int_equal(msc_options_set_archive(o, "/nonexistent/demo.msa", &e), MSC_OK);
    msc_stream *s;
    assert_int_equal(msc_stream_new(o, &s, &e), MSC_OK);
    msc_options_free(o);
    msc_model_info info;
    assert_int_equal(msc_stream_wait_open(s, 20.0, &info, &e), MSC_ERR_IO);
    assert_non_null(strstr(e.text, "/nonexistent/demo.msa"));
    assert_null(strchr(e.text, '\n'));
    msc_progress p;
    msc_stream_get_progress(s, &p);
    assert_non_null(strstr(p.error, "/nonexistent/demo.msa"));
    msc_stream_free(s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_options_and_arguments),
        cmocka_unit_test(test_version_helpers),
        cmocka_unit_test(test_local_archive_at_full_precision),
        cmocka_unit_test(test_missing_archive),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
