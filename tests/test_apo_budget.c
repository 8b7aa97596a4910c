/* The APO byte budget (docs/APO.md, "The byte budget"): levels go finest
 * first, the larger cell first on a tie, one at a time while over; a chunk cut
 * to k levels is the valid chunk of its first k levels with the last level's
 * smooth nodes gone (exact trees by hand); a bake over its budget stores at
 * most R times its geometry bytes, every chunk still valid, the same for 1 and
 * 2 threads, and reports what it dropped; a bake within its budget is
 * byte-identical to one without a budget; meshbake --json reports the ratio. */
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

#include <jansson.h>

#include "ms_apo_budget.h"
#include "ms_apo_chunk.h"
#include "ms_apo_stream.h"
#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_test.h"

/* ---- the order ------------------------------------------------------------- */

/* A: cell 0 at nSP depth 0, 3 levels (finest absolute level 2); B and C: cells
 * 1 and 2 one nSP level down with n = 4 (scale 2), 2 levels each (finest 3):
 * C and B lose their level 1 first (the larger cell first), then every chunk's
 * finest level is 2: C, B, then A three times; then none is left. */
static void test_order_finest_first(void **state)
{
    (void)state;
    ms_apo_budget_chunk c[3] = {
        {.cell = 0, .scale = 0, .levels = 3},
        {.cell = 1, .scale = 2, .levels = 2},
        {.cell = 2, .scale = 2, .levels = 2},
    };
    static const size_t expected[] = {2, 1, 2, 1, 0, 0, 0};
    for (size_t k = 0; k < sizeof expected / sizeof *expected; ++k) {
        size_t i = ms_apo_budget_next(c, 3);
        assert_int_equal(i, expected[k]);
        c[i].levels--;
    }
    assert_int_equal(ms_apo_budget_next(c, 3), 3);
    assert_int_equal(ms_apo_budget_next(NULL, 0), 0);
    /* ties on the cell number go to the later entry */
    ms_apo_budget_chunk same[2] = {{.cell = 5, .scale = 0, .levels = 1}, {.cell = 5, .scale = 0, .levels = 1}};
    assert_int_equal(ms_apo_budget_next(same, 2), 1);
}

/* ---- a cut by hand ----------------------------------------------------------- */

static ms_apo_node node_at(uint8_t depth, uint32_t x, uint32_t y, uint32_t z, uint8_t mask, uint32_t first,
                           bool smooth, float nx, float ny, float nz)
{
    float len = sqrtf(nx * nx + ny * ny + nz * nz);
    return (ms_apo_node){.first_child = first, .cell = {x, y, z}, .child_mask = mask, .depth = depth,
                         .smooth = smooth, .normal = {nx / len, ny / len, nz / len}};
}

/* Root (smooth) with three children: octant 0 internal with a correction of its
 * own and two leaves, octant 3 a leaf, octant 7 internal but smooth, one leaf. */
static void hand_tree(ms_apo_tree *t)
{
    memset(t, 0, sizeof *t);
    t->node_count = 7;
    t->nodes = calloc(7, sizeof *t->nodes);
    t->nodes[0] = node_at(0, 0, 0, 0, 0x89, 1, true, 0, 0, 1);
    t->nodes[1] = node_at(1, 0, 0, 0, 0x03, 4, false, 1, 0, 1);
    t->nodes[2] = node_at(1, 0, 1, 1, 0, 0, false, 0, 1, 1);
    t->nodes[3] = node_at(1, 1, 1, 1, 0x80, 6, true, 0, 0, 1);
    t->nodes[4] = node_at(2, 0, 0, 0, 0, 0, false, 1, 0, 2);
    t->nodes[5] = node_at(2, 0, 0, 1, 0, 0, false, 2, 0, 1);
    t->nodes[6] = node_at(2, 3, 3, 3, 0, 0, false, -1, 0, 1);
    t->level_count = 3;
    t->level_start[0] = 0, t->level_start[1] = 1, t->level_start[2] = 4, t->level_start[3] = 7;
}

static void stored(const ms_apo_tree *t, uint8_t **data, size_t *size, uint32_t table[2 * MS_APO_MAX_LEVELS])
{
    ms_apo_chunk c = {0};
    ms_error err;
    assert_int_equal(ms_apo_chunk_encode(t, &c, &err), MS_OK);
    assert_int_equal(ms_apo_stream_compress(&c, 6, data, size, table, &err), MS_OK);
    ms_apo_chunk_free(&c);
}

static void decoded(const ms_bake_apo_result *r, ms_apo_tree *t)
{
    ms_apo_chunk c = {0};
    ms_apo_view v;
    ms_error err;
    memset(t, 0, sizeof *t);
    assert_int_equal(ms_apo_stream_inflate(r->data, r->size, r->level_table, r->levels, &c, &err), MS_OK);
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, &err), MS_OK);
    assert_int_equal(v.complete_levels, r->levels);
    assert_int_equal(ms_apo_view_decode(&v, t, &err), MS_OK);
    ms_apo_chunk_free(&c);
}

static void test_cut_by_hand(void **state)
{
    (void)state;
    ms_apo_tree t;
    hand_tree(&t);
    ms_error err;
    assert_int_equal(ms_apo_tree_check(&t, &err), MS_OK);
    uint8_t *data;
    size_t size;
    uint32_t table[2 * MS_APO_MAX_LEVELS];
    stored(&t, &data, &size, table);
    ms_bake_apo_result r;
    /* all levels kept: the same bytes */
    assert_int_equal(ms_apo_budget_cut(data, size, table, 3, 3, 6, &r, &err), MS_OK);
    assert_int_equal(r.size, size);
    assert_memory_equal(r.data, data, size);
    assert_int_equal(r.levels, 3);
    assert_int_equal(r.internal_nodes, 3);
    assert_int_equal(r.leaves, 4);
    ms_bake_apo_result_free(&r);
    /* two levels: octant 0 becomes a leaf with its own correction, octant 3
     * stays, octant 7 (smooth, its correction was below) goes */
    assert_int_equal(ms_apo_budget_cut(data, size, table, 3, 2, 6, &r, &err), MS_OK);
    assert_int_equal(r.levels, 2);
    assert_int_equal(r.level_texels[0], 2);
    assert_int_equal(r.level_texels[1], 2);
    assert_int_equal(r.texels, 4);
    assert_int_equal(r.internal_nodes, 1);
    assert_int_equal(r.leaves, 2);
    assert_int_equal(r.level_table[2], r.size);
    ms_apo_tree back;
    decoded(&r, &back);
    assert_int_equal(back.node_count, 3);
    assert_int_equal(back.nodes[0].child_mask, 0x09);
    assert_true(back.nodes[0].smooth);
    assert_int_equal(back.nodes[1].child_mask, 0);
    assert_int_equal(ms_apo_normal_encode(back.nodes[1].normal), ms_apo_normal_encode(t.nodes[1].normal));
    assert_int_equal(ms_apo_normal_encode(back.nodes[2].normal), ms_apo_normal_encode(t.nodes[2].normal));
    assert_int_equal(back.nodes[2].cell[1], 1);
    ms_apo_tree_free(&back);
    ms_bake_apo_result_free(&r);
    /* one level: the root alone would be smooth, so nothing is left */
    assert_int_equal(ms_apo_budget_cut(data, size, table, 3, 1, 6, &r, &err), MS_OK);
    assert_int_equal(r.levels, 0);
    assert_null(r.data);
    assert_int_equal(r.size, 0);
    /* out of range */
    assert_int_equal(ms_apo_budget_cut(data, size, table, 3, 0, 6, &r, &err), MS_ERR_ARG);
    assert_int_equal(ms_apo_budget_cut(data, size, table, 3, 4, 6, &r, &err), MS_ERR_ARG);
    /* a table beyond the bytes */
    assert_int_equal(ms_apo_budget_cut(data, table[2] - 1, table, 3, 2, 6, &r, &err), MS_ERR_FORMAT);
    free(data);
    ms_apo_tree_free(&t);
}

/* ---- bakes ----------------------------------------------------------------- */

/* The small bunny with a chunk in every cell (as test_apo_bake): far more APO
 * than geometry. */
static void bake_bunny(const char *dir, const char *name, unsigned threads, double budget, ms_bake_report *r)
{
    char model[4096];
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.input = model;
    o.archive_dir = dir;
    o.name = name;
    o.threads = threads;
    o.min_triangles = 200;
    o.no_thumbnail = true;
    ms_bake_apo_params_default(&o.apo);
    o.apo.max_depth = 8;
    o.apo.tolerance = 0.15;
    o.apo.verify = true;
    o.apo.every_cell = true;
    o.apo.budget = budget;
    ms_error err;
    ms_error_clear(&err);
    if (ms_bake(&o, r, &err) != MS_OK)
        fail_msg("bake failed: %s", err.text);
}

/* Every chunk of the archive passes its CRC and loads, decodes and encodes back
 * to its words; returns the sum of the chunks' bytes. */
static uint64_t stored_apo_bytes(const char *dir, const char *name, uint32_t *chunks)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    uint64_t sum = 0;
    *chunks = 0;
    for (uint32_t i = 0; i < ms_archive_get_header(a)->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(a, i);
        if (c->apo_levels == 0)
            continue;
        ++*chunks;
        sum += c->apo_length;
        assert_int_equal(ms_archive_verify_payload(a, i, &err), MS_OK);
        size_t length;
        const uint8_t *data = ms_archive_apo(a, i, &length);
        uint32_t table[2 * MS_APO_MAX_LEVELS];
        for (uint32_t l = 0; l < c->apo_levels; ++l)
            table[2 * l] = ms_archive_apo_prefix(a, i, l, &table[2 * l + 1]);
        ms_apo_chunk chunk = {0}, again = {0};
        ms_apo_view view;
        ms_apo_tree tree = {0};
        assert_int_equal(ms_apo_stream_inflate(data, length, table, c->apo_levels, &chunk, &err), MS_OK);
        assert_int_equal(chunk.texel_count, c->apo_raw_length / 4);
        assert_int_equal(ms_apo_view_of_chunk(&view, &chunk, &err), MS_OK);
        assert_int_equal(view.complete_levels, c->apo_levels);
        assert_int_equal(ms_apo_view_decode(&view, &tree, &err), MS_OK);
        assert_int_equal(ms_apo_chunk_encode(&tree, &again, &err), MS_OK);
        assert_int_equal(again.texel_count, chunk.texel_count);
        assert_memory_equal(again.texels, chunk.texels, chunk.texel_count * 4);
        ms_apo_chunk_free(&again);
        ms_apo_tree_free(&tree);
        ms_apo_chunk_free(&chunk);
    }
    ms_archive_close(a);
    return sum;
}

static void test_bake_over_budget(void **state)
{
    (void)state;
    char dir[512], cmd[2048], out[256];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report none, one, one1, quarter;
    bake_bunny(dir, "none", 2, 0.0, &none);
    uint32_t chunks_none, chunks;
    assert_int_equal(stored_apo_bytes(dir, "none", &chunks_none), none.apo_bytes);
    assert_true(none.apo_bytes > 2 * none.geometry_bytes); /* over budget without one */
    assert_int_equal(none.apo_budget.limit, 0);
    assert_int_equal(none.apo_budget.bytes_before, none.apo_bytes);
    assert_int_equal(none.apo_budget.levels_dropped, 0);

    bake_bunny(dir, "one", 2, 1.0, &one);
    assert_int_equal(one.geometry_bytes, none.geometry_bytes);
    assert_true(one.apo_bytes <= one.geometry_bytes);
    assert_int_equal(one.apo_budget.limit, one.geometry_bytes);
    assert_int_equal(one.apo_budget.bytes_before, none.apo_bytes);
    assert_int_equal(one.apo_budget.bytes_after, one.apo_bytes);
    assert_true(one.apo_budget.levels_dropped > 0 && one.apo_budget.chunks_cut > 0);
    assert_int_equal(stored_apo_bytes(dir, "one", &chunks), one.apo_bytes);
    assert_int_equal(chunks, none.apo_chunks - one.apo_budget.chunks_removed);
    assert_int_equal(one.apo_chunks, chunks);
    /* the report's counts are the stored chunks' */
    uint64_t texels = 0;
    for (uint32_t d = 0; d < one.apo_levels; ++d)
        texels += one.apo_level_texels[d];
    assert_int_equal(4 * texels, one.apo_raw_bytes);
    assert_int_equal(texels, one.apo_leaves + 2 * one.apo_internal_nodes);
    assert_int_equal(none.apo_raw_bytes - one.apo_raw_bytes, 4 * one.apo_budget.texels_dropped);
    assert_int_equal(none.apo_leaves - one.apo_leaves, one.apo_budget.leaves_dropped);
    assert_true(one.apo_levels <= none.apo_levels);
    /* the finest levels went first: the deepest level lost the most */
    assert_true(one.apo_budget.level_texels_dropped[none.apo_levels - 1] > 0);

    /* the same on one thread, byte for byte */
    bake_bunny(dir, "one1", 1, 1.0, &one1);
    snprintf(cmd, sizeof cmd, "cmp '%s/one.msa' '%s/one1.msa'", dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);

    bake_bunny(dir, "quarter", 2, 0.25, &quarter);
    assert_true(quarter.apo_bytes <= quarter.geometry_bytes / 4);
    assert_true(quarter.apo_bytes > 0);
    assert_int_equal(stored_apo_bytes(dir, "quarter", &chunks), quarter.apo_bytes);
    assert_true(quarter.apo_budget.levels_dropped > one.apo_budget.levels_dropped);
    ms_test_rmdir(dir);
}

/* Within the budget the archive is the one baked without a budget. */
static void test_bake_within_budget_unchanged(void **state)
{
    (void)state;
    char dir[512], cmd[2048], out[256];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report none, wide;
    bake_bunny(dir, "none", 2, 0.0, &none);
    bake_bunny(dir, "wide", 2, 100.0, &wide);
    assert_true(none.apo_bytes <= 100 * none.geometry_bytes);
    assert_int_equal(wide.apo_bytes, none.apo_bytes);
    assert_int_equal(wide.apo_budget.bytes_before, wide.apo_bytes);
    assert_int_equal(wide.apo_budget.levels_dropped, 0);
    assert_int_equal(wide.apo_budget.chunks_cut, 0);
    snprintf(cmd, sizeof cmd, "cmp '%s/none.msa' '%s/wide.msa'", dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    ms_test_rmdir(dir);
}

/* meshbake --json on the dragon at resolution 3 (more APO than geometry before
 * the budget: docs/APO.md): the default budget brings it within 1x and says what
 * it dropped; --apo-budget 0 keeps the chunks as built; bad values are usage
 * errors. */
static void test_cli_budget(void **state)
{
    (void)state;
    char dir[512], bin[4096], model[4096], cmd[16384], out[16384];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip_res3.ply.gz");
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name d --no-thumbnail --apo-verify --json", bin, model, dir);
    json_t *j = ms_test_run_json(cmd, 0);
    json_t *apo = json_object_get(j, "apo"), *b = json_object_get(apo, "budget");
    json_int_t bytes = json_integer_value(json_object_get(apo, "bytes"));
    json_int_t geometry = json_integer_value(json_object_get(b, "geometry_bytes"));
    json_int_t before = json_integer_value(json_object_get(b, "bytes_before"));
    assert_true(json_real_value(json_object_get(b, "budget")) == 1.0);
    assert_int_equal(json_integer_value(json_object_get(b, "limit_bytes")), geometry);
    assert_true(before > geometry);
    assert_true(bytes > 0 && bytes <= geometry);
    assert_int_equal(json_integer_value(json_object_get(b, "bytes_dropped")), before - bytes);
    assert_float_equal(json_real_value(json_object_get(b, "ratio")), (double)bytes / (double)geometry, 1e-12);
    assert_true(json_integer_value(json_object_get(b, "levels_dropped")) >= 1);
    assert_true(json_integer_value(json_object_get(b, "texels_dropped")) > 0);
    json_decref(j);

    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name d0 --no-thumbnail --apo-budget 0 --json", bin, model, dir);
    j = ms_test_run_json(cmd, 0);
    apo = json_object_get(j, "apo"), b = json_object_get(apo, "budget");
    assert_int_equal(json_integer_value(json_object_get(apo, "bytes")), before);
    assert_int_equal(json_integer_value(json_object_get(b, "bytes_dropped")), 0);
    assert_int_equal(json_integer_value(json_object_get(b, "limit_bytes")), 0);
    json_decref(j);

    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name d --apo-budget -1 2>&1", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--apo-budget"));
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name d --apo-budget x 2>&1", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_order_finest_first),
        cmocka_unit_test(test_cut_by_hand),
        cmocka_unit_test(test_bake_over_budget),
        cmocka_unit_test(test_bake_within_budget_unchanged),
        cmocka_unit_test(test_cli_budget),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
