/* Per-vertex colour through the archive (docs/ARCHIVE.md, "Colour streams"):
 * meshbake bakes the colour trefoil fixture's colour as each cell's own
 * section; the view decoder, fully refined, gives every stitched vertex
 * exactly its welded input colour; coarse cuts give each vertex its kd-cell's
 * colour by the rule of docs/COLOUR.md §1 (an independent implementation,
 * tests/support/ms_colour_check.c); every colour prefix decodes, a child's
 * colour waiting for its parent's whole stream; a model without colour, or a
 * bake with no_colour, stitches with colours NULL; damaged colour tables,
 * header fields and streams are refused with one line; a local client core's
 * frames carry the colours. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_colour.h"
#include "ms_colour_check.h"
#include "ms_mesh_io.h"
#include "ms_nsp_check.h"
#include "ms_quant.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_view_decoder.h"

#define FIXTURE "trefoil_color.ply.gz"

static void bake(const char *dir, const char *name, unsigned colour_bits, bool no_colour,
                 ms_bake_report *rep)
{
    char model[4096];
    ms_bake_options o;
    ms_nsp_test_bake_options(ms_test_model_path(model, sizeof model, FIXTURE), dir, name, &o);
    o.min_triangles = 2000; /* 64 leaves: foreign vertices, frozen ones too */
    o.colour_bits = colour_bits;
    o.no_colour = no_colour;
    ms_error err;
    if (ms_bake(&o, rep, &err) != MS_OK)
        fail_msg("bake: %s", err.text);
}

static ms_view *open_view(const char *path, ms_archive **a)
{
    ms_error err;
    if (ms_archive_open(path, a, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_view *v;
    if (ms_view_create_from_archive(*a, &v, &err) != MS_OK)
        fail_msg("%s", err.text);
    return v;
}

/* Full precision: exactly the welded input colours, every vertex; and a
 * coarse cut (the root alone at each of its precisions): the rule. */
/* A view decoder over every cell record of archive a (the caller's). */
static ms_view *view_of(const ms_archive *a)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_archive_cell *recs = malloc(h->cell_count * sizeof *recs);
    assert_non_null(recs);
    for (uint32_t i = 0; i < h->cell_count; ++i)
        recs[i] = *ms_archive_get_cell(a, i);
    ms_view *v;
    ms_error err;
    assert_int_equal(ms_view_create(h, recs, &v, &err), MS_OK);
    free(recs);
    return v;
}

static void test_trefoil_full_and_coarse(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    const unsigned precisions[2] = {8, 3};
    for (int pi = 0; pi < 2; ++pi) {
        unsigned c = precisions[pi];
        ms_bake_report rep;
        bake(dir, "trefoil", c, false, &rep);
        assert_true(rep.colour);
        assert_true(rep.colour_alpha);
        assert_int_equal(rep.colour_bits, c);
        assert_true(rep.colour_bytes > 0);
        ms_archive *a;
        ms_view *v = open_view(rep.archive_path, &a);
        const ms_archive_header *h = ms_archive_get_header(a);
        assert_true(h->has_colour);
        assert_int_equal(h->colour_bits, c);
        uint64_t sum = 0;
        for (uint32_t cell = 0; cell < h->cell_count; ++cell)
            sum += ms_archive_colour_length(a, cell);
        assert_int_equal(sum, rep.colour_bytes);
        ms_colour_test_welded w;
        ms_colour_test_weld(ms_test_model_path(model, sizeof model, FIXTURE), h, &w);
        ms_view_mesh m = {0};
        ms_error err;
        for (unsigned b = 0; b <= h->root_bits; ++b) {
            assert_int_equal(ms_view_set_bits(v, 0, b, &err), MS_OK);
            assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
            ms_colour_test_check(&m, &w, h->bits, c);
        }
        ms_nsp_test_decode_all(v);
        if (ms_view_stitch(v, NULL, &m, &err) != MS_OK)
            fail_msg("%s", err.text);
        assert_int_equal(m.vertex_count, w.n);
        assert_int_equal(m.vertex_count, rep.vertices);
        ms_colour_test_check(&m, &w, h->bits, c);
        if (c == 8) /* lossless: the input's own colours */
            for (size_t k = 0; k < m.vertex_count; ++k) {
                size_t i = 0;
                while (w.keys[i] != m.keys[k])
                    ++i;
                assert_memory_equal(&m.colours[4 * k], &w.rgba[4 * i], 4);
            }
        ms_view_mesh_free(&m);
        ms_view_destroy(v);
        ms_archive_close(a);
        ms_colour_test_welded_free(&w);
    }
    ms_test_rmdir(dir);
}

/* Colour bytes handed in prefixes (each precision's prefix of every cell, then
 * every 5th byte of the root's stream): every prefix stitches, with colours
 * once a base is held, and the whole streams give the exact colours. */
static void test_prefixes(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report rep;
    bake(dir, "trefoil", 8, false, &rep);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(rep.archive_path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_colour_test_welded w;
    ms_colour_test_weld(ms_test_model_path(model, sizeof model, FIXTURE), h, &w);
    ms_view *v = view_of(a);
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, i, &len);
        assert_int_equal(ms_view_set_bytes(v, i, g, len, &err), MS_OK);
    }
    ms_view_mesh m = {0};
    assert_int_equal(ms_view_set_bits(v, 0, h->root_bits, &err), MS_OK);
    size_t root_len;
    const uint8_t *root = ms_archive_colour(a, 0, &root_len);
    assert_true(root_len > 0);
    for (size_t len = 0; len <= root_len; len += len + 5 > root_len && len < root_len ? root_len - len : 5) {
        assert_int_equal(ms_view_set_colour_bytes(v, 0, root, len, &err), MS_OK);
        if (ms_view_stitch(v, NULL, &m, &err) != MS_OK)
            fail_msg("root prefix %zu: %s", len, err.text);
        assert_int_equal(m.colours != NULL, len >= ms_archive_colour_prefix(a, 0, 0));
    }
    ms_colour_test_check(&m, &w, h->bits, 8);
    ms_nsp_test_decode_all(v);
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    for (unsigned b = 0; b <= h->bits; ++b) {
        for (uint32_t i = 1; i < h->cell_count; ++i) {
            size_t len;
            const uint8_t *col = ms_archive_colour(a, i, &len);
            assert_int_equal(ms_view_set_colour_bytes(v, i, col, ms_archive_colour_prefix(a, i, b), &err),
                             MS_OK);
        }
        if (ms_view_stitch(v, NULL, &m, &err) != MS_OK)
            fail_msg("prefix at %u bits: %s", b, err.text);
        assert_non_null(m.colours);
    }
    ms_colour_test_check(&m, &w, h->bits, 8);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_colour_test_welded_free(&w);
    ms_test_rmdir(dir);
}

/* A child's stream takes its base from its parent's whole stream: with the
 * root's colour one precision short, the children (all shown) have no colour
 * yet; once it is whole they have exactly theirs, and the version of every
 * run that draws triangles changed (the renderer uploads the new colours). */
static void test_child_waits_for_parent(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report rep;
    bake(dir, "trefoil", 8, false, &rep);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(rep.archive_path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_colour_test_welded w;
    ms_colour_test_weld(ms_test_model_path(model, sizeof model, FIXTURE), h, &w);
    ms_view *v = view_of(a);
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, i, &len);
        assert_int_equal(ms_view_set_bytes(v, i, g, len, &err), MS_OK);
        const uint8_t *col = ms_archive_colour(a, i, &len);
        if (i == 0)
            len = ms_archive_colour_prefix(a, 0, ms_archive_get_cell(a, 0)->bits_max - 1);
        if (len)
            assert_int_equal(ms_view_set_colour_bytes(v, i, col, len, &err), MS_OK);
    }
    ms_nsp_test_decode_all(v);
    ms_view_mesh m = {0};
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    assert_null(m.colours);
    size_t runs = m.run_count;
    assert_true(runs > 1);
    uint64_t *before = malloc(runs * sizeof *before);
    memcpy(before, m.run_version, runs * sizeof *before);
    size_t len;
    const uint8_t *root = ms_archive_colour(a, 0, &len);
    assert_int_equal(ms_view_set_colour_bytes(v, 0, root, len, &err), MS_OK);
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    ms_colour_test_check(&m, &w, h->bits, 8);
    assert_int_equal(m.run_count, runs);
    size_t drawn = 0;
    for (size_t k = 0; k < runs; ++k) /* a cell that draws nothing keeps its version */
        if (m.run_first[k + 1] > m.run_first[k]) {
            assert_true(m.run_version[k] != before[k]);
            ++drawn;
        }
    assert_true(drawn > 1);
    free(before);
    uint32_t withheld = 0; /* the child cell that draws the most triangles */
    size_t most = 0;
    for (size_t k = 0; k < m.run_count; ++k)
        if (m.run_cell[k] != 0 && m.run_first[k + 1] - m.run_first[k] > most)
            most = m.run_first[k + 1] - m.run_first[k], withheld = m.run_cell[k];
    assert_true(withheld != 0);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);

    /* Every cell's colour but one shown cell's: that cell draws in the
     * renderers' default grey until its colour arrives, never white. */
    v = view_of(a);
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        const uint8_t *g = ms_archive_geometry(a, i, &len);
        assert_int_equal(ms_view_set_bytes(v, i, g, len, &err), MS_OK);
        const uint8_t *col = ms_archive_colour(a, i, &len);
        if (len && i != withheld)
            assert_int_equal(ms_view_set_colour_bytes(v, i, col, len, &err), MS_OK);
    }
    ms_nsp_test_decode_all(v);
    m = (ms_view_mesh){0};
    assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    assert_non_null(m.colours);
    static const uint8_t pending[4] = {221, 216, 209, 255}, white[4] = {255, 255, 255, 255};
    size_t own_pending = 0, own_corners = 0;
    for (size_t t = 0; t < m.triangle_count; ++t)
        for (int k = 0; k < 3 && m.triangle_cell[t] == withheld; ++k, ++own_corners)
            own_pending += !memcmp(&m.colours[4 * (size_t)m.triangles[3 * t + k]], pending, 4);
    for (size_t i = 0; i < m.vertex_count; ++i)
        assert_memory_not_equal(&m.colours[4 * i], white, 4);
    print_message("the withheld cell's corners: %zu, %zu of them pending\n", own_corners, own_pending);
    assert_true(own_corners > 0);
    assert_true(own_pending * 2 > own_corners);
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_colour_test_welded_free(&w);
    ms_test_rmdir(dir);
}

/* No colour: a bake with no_colour, and an input without colour. */
static void test_without_colour(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report rep;
    bake(dir, "plain", 8, true, &rep);
    assert_false(rep.colour);
    assert_int_equal(rep.colour_bytes, 0);
    ms_bake_options o;
    ms_nsp_test_bake_options(ms_test_model_path(model, sizeof model, "torus_tristrips.ply.gz"),
                             dir, "torus", &o);
    ms_bake_report rep2;
    ms_error err;
    assert_int_equal(ms_bake(&o, &rep2, &err), MS_OK);
    assert_false(rep2.colour);
    const char *paths[2] = {rep.archive_path, rep2.archive_path};
    for (int i = 0; i < 2; ++i) {
        ms_archive *a;
        ms_view *v = open_view(paths[i], &a);
        assert_false(ms_archive_get_header(a)->has_colour);
        assert_int_equal(ms_archive_colour_length(a, 0), 0);
        ms_nsp_test_decode_all(v);
        ms_view_mesh m = {0};
        assert_int_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
        assert_true(m.vertex_count > 0);
        assert_null(m.colours);
        uint8_t byte = 0;
        assert_int_equal(ms_view_set_colour_bytes(v, 0, &byte, 1, &err), MS_ERR_ARG);
        ms_view_mesh_free(&m);
        ms_view_destroy(v);
        ms_archive_close(a);
    }
    ms_test_rmdir(dir);
}

/* An index blob with one byte changed and its CRCs made good again: what the
 * reader says of it. */
static ms_status open_damaged(const uint8_t *blob, size_t size, size_t at, uint8_t value,
                              ms_error *err)
{
    uint8_t *copy = malloc(size);
    memcpy(copy, blob, size);
    copy[at] = value;
    uint32_t crc = (uint32_t)crc32(0L, copy + MS_ARCHIVE_HEADER_SIZE,
                                   (uInt)(size - MS_ARCHIVE_HEADER_SIZE));
    for (int i = 0; i < 4; ++i)
        copy[108 + i] = (uint8_t)(crc >> (8 * i));
    crc = (uint32_t)crc32(0L, copy, 124);
    for (int i = 0; i < 4; ++i)
        copy[124 + i] = (uint8_t)(crc >> (8 * i));
    ms_archive *a = NULL;
    ms_status st = ms_archive_open_index(copy, size, "damaged", &a, err);
    ms_archive_close(a);
    free(copy);
    return st;
}

static void test_hostile(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report rep;
    bake(dir, "trefoil", 8, false, &rep);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(rep.archive_path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    size_t size;
    const uint8_t *blob = ms_archive_index_bytes(a, &size);
    /* the blob as it is opens */
    if (open_damaged(blob, size, 0, blob[0], &err) != MS_OK)
        fail_msg("%s", err.text);
    /* header: precision 0 and 9, unknown colour flags, colour fields without the flag */
    assert_int_equal(open_damaged(blob, size, 106, 0, &err), MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "colour precision 0 outside 1..8"));
    assert_int_equal(open_damaged(blob, size, 106, 9, &err), MS_ERR_FORMAT);
    assert_int_equal(open_damaged(blob, size, 107, 2, &err), MS_ERR_FORMAT);
    assert_int_equal(open_damaged(blob, size, 51, blob[51] & ~2u, &err), MS_ERR_FORMAT);
    /* the root's colour prefix table: not monotone, past the payload area */
    const ms_archive_cell *root = ms_archive_get_cell(a, 0);
    size_t window = (size_t)root->bits_max - root->bits_min + 1;
    size_t table = MS_ARCHIVE_HEADER_SIZE + (size_t)h->cell_count * MS_ARCHIVE_RECORD_SIZE +
                   4 * ((size_t)root->table_first + window + 2u * root->apo_levels);
    assert_int_equal(open_damaged(blob, size, table + 3, 0x7F, &err), MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "cell 0: colour prefix table is not monotone"));
    assert_int_equal(open_damaged(blob, size, table + 4 * (window - 1) + 3, 0x7F, &err),
                     MS_ERR_FORMAT);
    assert_non_null(strstr(err.text, "cell 0: colour stream outside the payload area"));
    assert_null(strchr(err.text, '\n'));
    /* a damaged stream: its CRC; without the CRC, the stitch says so in one line */
    size_t len;
    const uint8_t *col = ms_archive_colour(a, 0, &len);
    uint8_t *bad = malloc(len);
    memcpy(bad, col, len);
    bad[len - 3] ^= 0x5A;
    assert_int_equal(ms_archive_check_colour(a, 0, bad, len, &err), MS_ERR_CORRUPT);
    assert_string_equal(err.text, "cell 0: colour stream checksum mismatch");
    assert_int_equal(ms_archive_check_colour(a, 0, col, len - 1, &err), MS_ERR_CORRUPT);
    ms_view *v = view_of(a);
    size_t glen;
    const uint8_t *g = ms_archive_geometry(a, 0, &glen);
    assert_int_equal(ms_view_set_bytes(v, 0, g, glen, &err), MS_OK);
    assert_int_equal(ms_view_set_colour_bytes(v, 0, bad, len, &err), MS_OK);
    assert_int_equal(ms_view_set_bits(v, 0, root->bits_max, &err), MS_OK);
    ms_view_mesh m = {0};
    assert_int_not_equal(ms_view_stitch(v, NULL, &m, &err), MS_OK);
    assert_non_null(strstr(err.text, "cell 0: colour stream: "));
    assert_null(strchr(err.text, '\n'));
    ms_view_mesh_free(&m);
    ms_view_destroy(v);
    free(bad);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* The client core in local mode: its frames carry the colours, each vertex
 * its kd-cell's at the precision shown (docs/CLIENT.md). */
static void test_client_core_local(void **state)
{
    (void)state;
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report rep;
    bake(dir, "trefoil", 8, false, &rep);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(rep.archive_path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_colour_test_welded w;
    ms_colour_test_weld(ms_test_model_path(model, sizeof model, FIXTURE), h, &w);
    double centre[3], eye[3], up[3] = {0, 1, 0};
    for (int k = 0; k < 3; ++k)
        centre[k] = h->box_origin[k] + h->box_side / 2;
    memcpy(eye, centre, sizeof eye);
    eye[2] += 1.5 * h->box_side;
    ms_camera cam;
    assert_int_equal(ms_camera_look_at(eye, centre, up, 50, 640, 480, 1e-3 * h->box_side,
                                       10 * h->box_side, &cam, &err), MS_OK);
    const double tolerances[2] = {4.0, 0.02}; /* mixed precisions, then (near) full */
    for (int t = 0; t < 2; ++t) {
        ms_core_options o = {0};
        o.archive_path = rep.archive_path;
        o.tolerance_px = tolerances[t];
        o.hysteresis_bits = 0;
        o.export_frames = true;
        ms_core *core;
        assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
        ms_core_set_camera(core, &cam);
        ms_core_stats st;
        ms_core_frame *frame = NULL;
        if (!ms_test_core_wait_complete(core, 60, &st, &frame))
            fail_msg("view not complete: '%s'", st.error);
        assert_non_null(frame);
        assert_true(frame->mesh.vertex_count > 0);
        ms_colour_test_check(&frame->mesh, &w, h->bits, 8);
        ms_core_frame_free(frame);
        ms_core_stop(core);
    }
    ms_archive_close(a);
    ms_colour_test_welded_free(&w);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_trefoil_full_and_coarse),
        cmocka_unit_test(test_prefixes),
        cmocka_unit_test(test_child_waits_for_parent),
        cmocka_unit_test(test_without_colour),
        cmocka_unit_test(test_hostile),
        cmocka_unit_test(test_client_core_local),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
