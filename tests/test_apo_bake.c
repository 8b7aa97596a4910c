/* Per-cell APO chunks baked by meshbake (docs/APO.md "Per-cell chunks",
 * docs/ARCHIVE.md): every chunk of a baked archive passes its CRC, inflates, has
 * the level table the index says, loads, and decodes into a tree that encodes
 * back to the very same words (the baker also compared it with the tree it built:
 * verify on); chunk depths follow the depth rule exactly; the archive is
 * byte-identical for 1 and 2 threads; a prefix of L levels inflates to exactly
 * the first L levels' words; damaged chunks and tables are rejected with errors;
 * the CLI reports APO figures. MESHSTREAM_BIG=1 adds the 871k-triangle dragon. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <sys/stat.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <jansson.h>
#include <zlib.h>

#include "ms_apo_chunk.h"
#include "ms_apo_sample.h"
#include "ms_apo_stream.h"
#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_nsp_check.h"
#include "ms_quant.h"
#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_view_decoder.h"

static void bake_report(const char *model, const char *dir, const char *name, unsigned threads,
                        const ms_bake_apo_params *apo, unsigned bits, unsigned n, unsigned root_bits,
                        uint32_t min_tris, ms_bake_report *r)
{
    ms_bake_options o;
    ms_bake_options_default(&o);
    o.input = model;
    o.archive_dir = dir;
    o.name = name;
    o.threads = threads;
    o.min_triangles = min_tris;
    o.bits = bits, o.n = n, o.root_bits = root_bits;
    o.apo = *apo;
    ms_error err;
    ms_error_clear(&err);
    if (ms_bake(&o, r, &err) != MS_OK)
        fail_msg("bake of %s failed: %s", model, err.text);
}

static void bake(const char *model, const char *dir, const char *name, unsigned threads,
                 const ms_bake_apo_params *apo, unsigned bits, unsigned n, unsigned root_bits,
                 uint32_t min_tris)
{
    ms_bake_report r;
    bake_report(model, dir, name, threads, apo, bits, n, root_bits, min_tris, &r);
}

static unsigned log2_of(unsigned n) { return n == 2 ? 1 : n == 4 ? 2 : 3; }

/* The depth rule, written out independently of the baker's function. */
static uint32_t expected_depth(const ms_archive_header *h, const ms_archive_cell *c)
{
    int finest = (int)c->bits_max - (int)(log2_of(h->n) * c->level);
    int d = (finest > 0 ? finest : 0) + h->apo_lead;
    return d < h->apo_max_depth ? (uint32_t)d : h->apo_max_depth;
}

typedef struct archive_check {
    uint32_t chunks, at_rule_depth;  /* cells with a chunk; of them, as deep as the rule allows */
    uint32_t multi_level;            /* chunks with at least 2 levels */
    uint32_t internal_with_chunk;    /* internal cells (M gathered from several leaves) */
    uint32_t smooth_cells;           /* cells that could have a chunk, left without: no texel needed */
} archive_check;

/* Everything a client may rely on, for every cell of the archive at path.
 * every_cell: the archive was baked with apo.every_cell (a chunk exactly where m
 * has triangles); otherwise leaf cells, whose geometry renders M, have none. */
static archive_check check_archive(const char *path, bool every_cell)
{
    archive_check k = {0};
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    const ms_archive_header *h = ms_archive_get_header(a);
    assert_true(h->has_apo);
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(a, i);
        /* a chunk only where m has triangles, leaf cells aside by default; of
         * those, none where m's smooth normal gives every texel */
        bool leaf = c->first_child == MS_ARCHIVE_NONE;
        if (c->apo_levels > 0)
            assert_true(c->triangle_count > 0 && (every_cell || !leaf));
        k.smooth_cells += c->apo_levels == 0 && c->triangle_count > 0 && (every_cell || !leaf);
        if (c->apo_levels == 0) {
            assert_int_equal(c->apo_length, 0);
            continue;
        }
        k.chunks++;
        k.multi_level += c->apo_levels >= 2;
        k.internal_with_chunk += c->first_child != MS_ARCHIVE_NONE;
        assert_int_equal(ms_archive_verify_payload(a, i, &err), MS_OK);
        size_t length;
        const uint8_t *data = ms_archive_apo(a, i, &length);
        assert_int_equal(length, c->apo_length);
        uint32_t table[2 * MS_APO_MAX_LEVELS];
        for (uint32_t l = 0; l < c->apo_levels; ++l)
            table[2 * l] = ms_archive_apo_prefix(a, i, l, &table[2 * l + 1]);
        assert_int_equal(table[2 * (c->apo_levels - 1)], c->apo_length);
        assert_int_equal(table[2 * (c->apo_levels - 1) + 1], c->apo_raw_length / 4);
        ms_apo_chunk chunk;
        if (ms_apo_stream_inflate(data, length, table, c->apo_levels, &chunk, &err) != MS_OK)
            fail_msg("cell %u: %s", i, err.text);
        assert_int_equal(chunk.texel_count, c->apo_raw_length / 4);
        assert_int_equal(chunk.level_count, c->apo_levels);
        uint32_t sum = 0;
        for (uint32_t l = 0; l < chunk.level_count; ++l) {
            sum += chunk.level_texels[l];
            assert_int_equal(sum, table[2 * l + 1]);
        }
        ms_apo_view view;
        if (ms_apo_view_of_chunk(&view, &chunk, &err) != MS_OK)
            fail_msg("cell %u: %s", i, err.text);
        assert_int_equal(view.complete_levels, c->apo_levels);
        /* decode, encode again: the same words */
        ms_apo_tree tree = {0};
        assert_int_equal(ms_apo_view_decode(&view, &tree, &err), MS_OK);
        ms_apo_chunk again = {0};
        assert_int_equal(ms_apo_chunk_encode(&tree, &again, &err), MS_OK);
        assert_int_equal(again.texel_count, chunk.texel_count);
        assert_memory_equal(again.level_texels, chunk.level_texels, chunk.level_count * 4);
        assert_memory_equal(again.texels, chunk.texels, chunk.texel_count * 4);
        /* the depth rule */
        uint32_t depth = c->apo_levels - 1, rule = expected_depth(h, c);
        assert_true(depth <= rule);
        k.at_rule_depth += depth == rule;
        /* every prefix of whole levels inflates to exactly those levels' words;
         * one byte short of a boundary gives one level less */
        for (uint32_t l = 1; l <= c->apo_levels; ++l) {
            size_t bytes = table[2 * (l - 1)];
            ms_apo_chunk part;
            assert_int_equal(ms_apo_stream_inflate(data, bytes, table, c->apo_levels, &part, &err), MS_OK);
            assert_int_equal(part.texel_count, table[2 * (l - 1) + 1]);
            assert_memory_equal(part.texels, chunk.texels, part.texel_count * 4);
            ms_apo_view pv;
            assert_int_equal(ms_apo_view_init(&pv, part.level_texels, part.level_count, part.texels,
                                              part.texel_count, &err), MS_OK);
            assert_int_equal(pv.complete_levels, l);
            ms_apo_chunk_free(&part);
            assert_int_equal(ms_apo_stream_inflate(data, bytes - 1, table, c->apo_levels, &part, &err), MS_OK);
            assert_int_equal(part.texel_count, l >= 2 ? table[2 * (l - 2) + 1] : 0);
            ms_apo_chunk_free(&part);
        }
        ms_apo_chunk_free(&again);
        ms_apo_tree_free(&tree);
        ms_apo_chunk_free(&chunk);
    }
    ms_archive_close(a);
    return k;
}

/* A fresh dir and the path of the small bunny (stanford_bunny_res3). */
static void bunny_case(char dir[512], char model[4096])
{
    ms_test_tmpdir(dir, 512);
    ms_test_model_path(model, 4096, "stanford_bunny_res3.ply.gz");
}

/* check_archive on dir/name.msa. */
static archive_check check_baked(const char *dir, const char *name, bool every_cell)
{
    char path[700];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    return check_archive(path, every_cell);
}

static void test_chunks_round_trip_and_threads_agree(void **state)
{
    (void)state;
    char dir[512], model[4096], cmd[2048], out[256];
    bunny_case(dir, model);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.max_depth = 8;
    apo.tolerance = 0.15;
    apo.verify = true;
    apo.every_cell = true;
    apo.budget = 0; /* the chunks as built, at the rule's depth (the budget: test_apo_budget) */
    bake(model, dir, "t1", 1, &apo, 16, 4, 7, 200);
    bake(model, dir, "t2", 2, &apo, 16, 4, 7, 200);
    snprintf(cmd, sizeof cmd, "cmp '%s/t1.msa' '%s/t2.msa'", dir, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    archive_check k = check_baked(dir, "t2", true);
    assert_true(k.chunks > 10);
    assert_true(k.multi_level >= 10);
    assert_true(k.internal_with_chunk >= 2); /* the root and a level-1 cell that split */
    assert_true(k.at_rule_depth >= 1);
    ms_test_rmdir(dir);
}

/* The default rule: a leaf's geometry renders its input, so the baker skips
 * gathering a leaf's M to check it; --apo-verify gathers it and checks. Both
 * give the same archive, with no chunk on a leaf (check_archive). */
static void test_leaves_skip_the_renders_check(void **state)
{
    (void)state;
    char dir[512], model[4096], cmd[2048], out[256], plain[600], checked[600];
    bunny_case(dir, model);
    snprintf(plain, sizeof plain, "%s/plain", dir);
    snprintf(checked, sizeof checked, "%s/checked", dir);
    assert_int_equal(mkdir(plain, 0755), 0);
    assert_int_equal(mkdir(checked, 0755), 0);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    bake(model, plain, "b", 2, &apo, 16, 4, 7, 200);
    apo.verify = true;
    bake(model, checked, "b", 2, &apo, 16, 4, 7, 200);
    snprintf(cmd, sizeof cmd, "cmp '%s/b.msa' '%s/b.msa'", plain, checked);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    archive_check k = check_baked(plain, "b", false);
    assert_true(k.chunks >= 1); /* internal cells still carry theirs */
    ms_test_rmdir(dir);
}

/* Splitting unconditionally (init depth above every cap) takes every chunk to
 * exactly the rule's depth: once through the cap, once through the finest
 * precision (lead 0, n = 2, p = 8, so that it stays small). */
static void test_depth_rule_exact(void **state)
{
    (void)state;
    char dir[512], model[4096], path[700];
    bunny_case(dir, model);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.init_depth = 30;
    apo.max_depth = 4;
    apo.verify = true;
    apo.every_cell = true;
    apo.full_normals = true; /* the split's depth: no texel left to the smooth normal */
    apo.budget = 0;          /* nor cut by the byte budget */
    bake(model, dir, "cap", 2, &apo, 16, 4, 7, 800);
    archive_check k = check_baked(dir, "cap", true);
    assert_true(k.chunks > 10);
    assert_int_equal(k.smooth_cells, 0);
    assert_int_equal(k.at_rule_depth, k.chunks);

    apo.max_depth = 24;
    apo.lead = 0;
    bake(model, dir, "lead", 2, &apo, 8, 2, 1, 400);
    snprintf(path, sizeof path, "%s/lead.msa", dir);
    k = check_archive(path, true);
    assert_true(k.chunks > 10 && k.internal_with_chunk >= 3);
    assert_int_equal(k.at_rule_depth, k.chunks);
    /* and the depths differ between cells: the rule is per cell */
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    uint32_t seen = 0;
    for (uint32_t i = 0; i < ms_archive_get_header(a)->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(a, i);
        if (c->apo_levels)
            seen |= 1u << (c->apo_levels - 1);
    }
    ms_archive_close(a);
    assert_true(seen & (seen - 1)); /* at least two distinct depths */
    ms_test_rmdir(dir);
}

/* Damage: a flipped byte inside a chunk fails its CRC and its inflation; a
 * damaged level table fails the index CRC at open; a truncated file does not
 * open; an inconsistent table given to the inflater is a format error. */
static void test_damaged_chunks_are_rejected(void **state)
{
    (void)state;
    char dir[512], model[4096], path[700], bad[700];
    bunny_case(dir, model);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.max_depth = 7;
    apo.every_cell = true;
    bake(model, dir, "good", 2, &apo, 16, 4, 7, 8000);
    snprintf(path, sizeof path, "%s/good.msa", dir);
    snprintf(bad, sizeof bad, "%s/bad.msa", dir);
    size_t size;
    uint8_t *file = ms_test_read_file(path, &size);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    const ms_archive_cell root = *ms_archive_get_cell(a, 0);
    assert_true(root.apo_levels >= 3);
    uint32_t table[2 * MS_APO_MAX_LEVELS];
    for (uint32_t l = 0; l < root.apo_levels; ++l)
        table[2 * l] = ms_archive_apo_prefix(a, 0, l, &table[2 * l + 1]);
    /* Version 2: the payload area follows the zlib-stored index; the level
     * table lies in the raw (inflated) index. */
    assert_int_equal(h->version, MS_ARCHIVE_VERSION);
    uint64_t payload_start = MS_ARCHIVE_HEADER_SIZE + h->index_stored_size;
    uint64_t table_at = (uint64_t)MS_ARCHIVE_RECORD_SIZE * h->cell_count +
                        4ull * (root.table_first + root.bits_max - root.bits_min + 1u);
    ms_archive_close(a);

    /* a byte of the root's chunk, in the middle of its last level */
    uint64_t at = payload_start + root.apo_offset + (table[2 * (root.apo_levels - 2)] + root.apo_length) / 2;
    file[at] ^= 0x5A;
    ms_test_write_file(bad, file, size);
    assert_int_equal(ms_archive_open(bad, &a, &err), MS_OK); /* payloads are checked on demand */
    assert_int_equal(ms_archive_verify_payload(a, 0, &err), MS_ERR_CORRUPT);
    assert_non_null(strstr(err.text, "APO chunk checksum mismatch"));
    size_t length;
    const uint8_t *data = ms_archive_apo(a, 0, &length);
    ms_apo_chunk chunk;
    assert_int_equal(ms_apo_stream_inflate(data, length, table, root.apo_levels, &chunk, &err), MS_ERR_CORRUPT);
    assert_null(chunk.texels);
    /* the levels before the damage still inflate, as a prefix */
    assert_int_equal(ms_apo_stream_inflate(data, table[2 * (root.apo_levels - 2)], table, root.apo_levels,
                                           &chunk, &err), MS_OK);
    assert_int_equal(chunk.texel_count, table[2 * (root.apo_levels - 2) + 1]);
    ms_apo_chunk_free(&chunk);
    ms_archive_close(a);
    file[at] ^= 0x5A;

    /* the level table in the index (an index blob under the old CRC: the
     * index CRC, which covers the raw index, is what catches it) */
    size_t raw_size, bad_size;
    uint8_t *raw = ms_test_archive_raw_index(file, size, &raw_size);
    uint32_t raw_crc = (uint32_t)crc32_z(0L, raw, raw_size);
    raw[table_at + 4] ^= 1;
    uint8_t *image = ms_test_archive_blob(file, size, raw, raw_size, raw_crc, &bad_size);
    a = NULL;
    assert_int_equal(ms_archive_open_index(image, bad_size, bad, &a, &err), MS_ERR_CORRUPT);
    assert_non_null(strstr(err.text, "index checksum mismatch"));
    assert_null(a);
    free(image);
    free(raw);

    /* the file cut inside the last chunk */
    ms_test_write_file(bad, file, size - 3);
    assert_int_not_equal(ms_archive_open(bad, &a, &err), MS_OK);

    /* inconsistent tables handed to the inflater */
    const uint8_t *root_data = file + payload_start + root.apo_offset;
    uint32_t swapped[2 * MS_APO_MAX_LEVELS];
    memcpy(swapped, table, sizeof swapped);
    swapped[0] = table[2], swapped[2] = table[0];
    assert_int_equal(ms_apo_stream_inflate(root_data, root.apo_length, swapped, root.apo_levels, &chunk, &err),
                     MS_ERR_FORMAT);
    assert_int_equal(ms_apo_stream_inflate(root_data, root.apo_length + 1, table, root.apo_levels, &chunk, &err),
                     MS_ERR_FORMAT);
    assert_int_equal(ms_apo_stream_inflate(root_data, root.apo_length, table, MS_APO_MAX_LEVELS + 1, &chunk, &err),
                     MS_ERR_FORMAT);
    /* a table claiming one texel more than the stream holds */
    uint32_t more[2 * MS_APO_MAX_LEVELS];
    memcpy(more, table, sizeof more);
    more[2 * (root.apo_levels - 1) + 1] += 1;
    assert_int_equal(ms_apo_stream_inflate(root_data, root.apo_length, more, root.apo_levels, &chunk, &err),
                     MS_ERR_CORRUPT);
    free(file);
    ms_test_rmdir(dir);
}

static void test_cli_reports_apo(void **state)
{
    (void)state;
    char dir[512], bin[4096], model[4096], cmd[16384], out[16384];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name b --min-tris 1000 --apo-max-depth 6 --apo-verify --json",
             bin, model, dir);
    json_t *j = ms_test_run_json(cmd, 0);
    json_t *apo = json_object_get(j, "apo");
    assert_true(json_is_true(json_object_get(apo, "enabled")));
    assert_null(json_object_get(apo, "every_cell"));
    assert_int_equal(json_integer_value(json_object_get(apo, "max_depth")), 6);
    assert_int_equal(json_integer_value(json_object_get(apo, "lead")), 1);
    assert_true(json_real_value(json_object_get(apo, "correction")) == 0.2);
    json_int_t bytes = json_integer_value(json_object_get(apo, "bytes"));
    json_int_t raw = json_integer_value(json_object_get(apo, "raw_bytes"));
    json_int_t internal = json_integer_value(json_object_get(apo, "internal_nodes"));
    json_int_t leaves = json_integer_value(json_object_get(apo, "leaves"));
    json_t *levels = json_object_get(apo, "level_texels");
    assert_int_equal(json_array_size(levels), 7);
    json_int_t texels = 0;
    for (size_t l = 0; l < json_array_size(levels); ++l)
        texels += json_integer_value(json_array_get(levels, l));
    assert_true(bytes > 0 && internal > 0 && leaves > internal);
    assert_int_equal(raw, 4 * texels);
    assert_int_equal(texels, leaves + 2 * internal);
    json_t *seconds = json_object_get(j, "seconds");
    assert_true(json_is_number(json_object_get(seconds, "apo")));
    /* the APO build's share of the bake: its seconds over the total */
    double share = json_number_value(json_object_get(apo, "share_of_bake"));
    assert_true(share >= 0 && share <= 1);
    assert_float_equal(share, json_number_value(json_object_get(seconds, "apo")) /
                                  json_number_value(json_object_get(seconds, "total")), 1e-9);
    json_t *sampling = json_object_get(apo, "sampling");
    json_int_t rays = json_integer_value(json_object_get(sampling, "rays"));
    json_int_t smooth = json_integer_value(json_object_get(sampling, "smooth_leaves"));
    assert_true(smooth > 0); /* leaves whose texel m's smooth normal already gives */
    assert_true(rays > 0 && rays <= 2 * (json_int_t)MS_APO_SAMPLES_PER_LEAF * (leaves + smooth));
    assert_true(json_is_integer(json_object_get(sampling, "point_queries")));
    /* adaptive sampling: at most 8 samples a leaf, 2 rays a sample */
    json_int_t samples = json_integer_value(json_object_get(sampling, "samples"));
    json_int_t sampled = json_integer_value(json_object_get(sampling, "leaves"));
    json_int_t agreed = json_integer_value(json_object_get(sampling, "agreed_leaves"));
    assert_true(sampled >= leaves && samples >= sampled && samples <= 8 * sampled && rays <= 2 * samples);
    assert_true(agreed > 0 && agreed <= sampled);
    json_decref(j);
    /* the archive's chunks add up to the report */
    char path[700];
    snprintf(path, sizeof path, "%s/b.msa", dir);
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    json_int_t sum = 0, sum_raw = 0;
    for (uint32_t i = 0; i < ms_archive_get_header(a)->cell_count; ++i) {
        sum += ms_archive_get_cell(a, i)->apo_length;
        sum_raw += ms_archive_get_cell(a, i)->apo_raw_length;
    }
    assert_int_equal(ms_archive_get_header(a)->apo_max_depth, 6);
    ms_archive_close(a);
    assert_int_equal(sum, bytes);
    assert_int_equal(sum_raw, raw);
    /* text report */
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name t --min-tris 1000 --apo-max-depth 4", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "APO texels per level: "));
    assert_non_null(strstr(out, "(APO "));
    ms_test_rmdir(dir);
}

/* ms_bake_apo_union by hand, in the unit box at 2 bits (cells of 0.25): parts A
 * and B (cubes x < 0.5 and x >= 0.5) share three grid cells, each taking its
 * owner's copy whatever the part order; B's second triangle repeats A's (other
 * vertices, same cells, reversed) and goes; part C at 3 bits stays apart; an empty
 * part changes nothing. */
static void test_union_of_parts(void **state)
{
    (void)state;
    const ms_quant_box box = {{0, 0, 0}, 1.0};
    double pa[] = {0.1, 0.1, 0.1, 0.3, 0.1, 0.1, 0.6, 0.1, 0.1};
    uint32_t ta[] = {0, 1, 2}, wa[] = {1, 2, 3};
    double pb[] = {0.65, 0.15, 0.1, 0.9, 0.1, 0.1, 0.3, 0.2, 0.2, 0.1, 0.2, 0.1};
    uint32_t tb[] = {0, 1, 2, 2, 3, 0}, wb[] = {5, 1, 1, 1};
    double pc[] = {0.3, 0.1, 0.1, 0.2, 0.2, 0.1, 0.1, 0.3, 0.1};
    uint32_t tc[] = {0, 1, 2}, wc[] = {1, 1, 1};
    ms_bake_apo_part parts[4] = {
        {.mesh = {.positions = pa, .triangles = ta, .vertex_count = 3, .triangle_count = 1}, .weight = wa,
         .bits = 2, .origin = {0, 0, 0}, .size = 0.5},
        {.mesh = {.positions = pb, .triangles = tb, .vertex_count = 4, .triangle_count = 2}, .weight = wb,
         .bits = 2, .origin = {0.5, 0, 0}, .size = 0.5},
        {.bits = 2, .size = 0.5},
        {.mesh = {.positions = pc, .triangles = tc, .vertex_count = 3, .triangle_count = 1}, .weight = wc,
         .bits = 3, .origin = {0, 0, 0}, .size = 0.5},
    };
    ms_mesh u;
    uint32_t *owned;
    ms_error err;
    assert_int_equal(ms_bake_apo_union(parts, 4, &box, &u, &owned, &err), MS_OK);
    assert_int_equal(u.vertex_count, 7); /* 4 cells at 2 bits, 3 at 3 bits */
    assert_int_equal(u.triangle_count, 3);
    const double *want[3][3] = {{&pa[0], &pa[3], &pb[0]}, {&pb[0], &pb[3], &pa[3]}, {&pc[0], &pc[3], &pc[6]}};
    for (int t = 0; t < 3; ++t)
        for (int k = 0; k < 3; ++k)
            assert_memory_equal(&u.positions[3 * u.triangles[3 * t + k]], want[t][k], 24);
    /* ordered by (bits, cell): the 2-bit cells x = 0, 1, 2, 3 first */
    const uint32_t owned_want[7] = {1, 2, 5, 1, 1, 1, 1};
    assert_memory_equal(owned, owned_want, sizeof owned_want);
    assert_memory_equal(&u.positions[0], &pa[0], 24);
    assert_memory_equal(&u.positions[9], &pb[3], 24);
    ms_mesh_free(&u);
    free(owned);
    assert_int_equal(ms_bake_apo_union(parts, 0, &box, &u, &owned, &err), MS_OK);
    assert_int_equal(u.vertex_count + u.triangle_count, 0);
    ms_mesh_free(&u);
    free(owned);
}

/* ms_bake_apo_smooth at 1 bit: a vertex moves to the weighted mean of the owned M
 * vertices in its cell, to the plain mean where M has only foreign ones, and keeps
 * its centre where M has none; the weights add up. */
static void test_smooth_to_means(void **state)
{
    (void)state;
    const ms_quant_box box = {{0, 0, 0}, 1.0};
    double mp[] = {0.25, 0.25, 0.25, 0.75, 0.25, 0.25, 0.75, 0.75, 0.75};
    uint32_t mt[] = {0, 1, 2};
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, 3, 1, &err), MS_OK);
    memcpy(m.positions, mp, sizeof mp);
    memcpy(m.triangles, mt, sizeof mt);
    m.vertex_count = 3, m.triangle_count = 1;
    double Mp[] = {0.1, 0.1, 0.1, 0.3, 0.2, 0.1, 0.6, 0.1, 0.1, 0.7, 0.3, 0.1};
    uint32_t Mt[] = {0, 1, 2, 1, 2, 3}, owned[] = {1, 3, 0, 0};
    const ms_mesh M = {.positions = Mp, .triangles = Mt, .vertex_count = 4, .triangle_count = 2};
    const double origin[3] = {0, 0, 0};
    ms_bake_apo_part part;
    assert_int_equal(ms_bake_apo_smooth(&m, 1, &box, origin, 1.0, &M, owned, &part, &err), MS_OK);
    assert_null(m.positions);
    assert_int_equal(part.mesh.vertex_count, 3);
    assert_int_equal(part.bits, 1);
    const double want[9] = {(1 * 0.1 + 3 * 0.3) / 4, (1 * 0.1 + 3 * 0.2) / 4, (1 * 0.1 + 3 * 0.1) / 4,
                            (0.6 + 0.7) / 2, (0.1 + 0.3) / 2, (0.1 + 0.1) / 2,
                            0.75, 0.75, 0.75};
    assert_memory_equal(part.mesh.positions, want, sizeof want);
    const uint32_t weight_want[3] = {4, 2, 1};
    assert_memory_equal(part.weight, weight_want, sizeof weight_want);
    assert_memory_equal(part.mesh.triangles, mt, sizeof mt);
    ms_bake_apo_part_free(&part);
}

static int cmp_triple(const void *x, const void *y)
{
    return memcmp(x, y, 3 * sizeof(uint64_t)); /* any total order groups equal triples */
}

static int cmp_u64(const void *a, const void *b)
{
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

/* A leaf's vertex as the model's vertex: a frozen foreign vertex (ms_codec.h,
 * regions) is given as the first key of its lone kd-cell, which holds exactly one
 * model vertex: the first model key at or after it. */
static uint64_t model_vertex(const uint64_t *keys, size_t n, uint64_t key)
{
    size_t lo = 0, hi = n;
    while (lo < hi) {
        size_t mid = lo + (hi - lo) / 2;
        if (keys[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    assert_true(lo < n);
    return keys[lo];
}

static size_t children_union(ms_view *v, const ms_archive_cell *cells, uint32_t cell, unsigned nc,
                             const uint64_t *keys, size_t nkeys)
{
    ms_error err;
    size_t nt = 0, cap = 0;
    uint64_t *tris = NULL; /* 3 ids per triangle, sorted */
    for (unsigned k = 0; k < nc; ++k) {
        uint32_t c = cells[cell].first_child + k;
        if (ms_view_set_bits(v, c, cells[c].bits_max, &err) != MS_OK)
            fail_msg("cell %u: %s", c, err.text);
        ms_codec_state st = {0};
        assert_int_equal(ms_view_cell_state_copy(v, c, &st, &err), MS_OK);
        if (st.vertex_count > 0)
            assert_int_equal(st.level, 3u * cells[c].bits_max);
        if (nt + st.tri_count > cap) {
            cap = 2 * (nt + st.tri_count);
            tris = realloc(tris, cap * 3 * sizeof *tris);
            assert_non_null(tris);
        }
        for (size_t t = 0; t < st.tri_count; ++t) {
            uint64_t x[3];
            bool leaf = cells[c].first_child == MS_ARCHIVE_NONE;
            for (int j = 0; j < 3; ++j) {
                uint64_t id = st.cells[st.tris[3 * t + (size_t)j]];
                x[j] = (uint64_t)cells[c].bits_max << 56 | (leaf ? model_vertex(keys, nkeys, id) : id);
            }
            for (int i = 0; i < 2; ++i)
                for (int j = 0; j < 2 - i; ++j)
                    if (x[j] > x[j + 1]) {
                        uint64_t y = x[j];
                        x[j] = x[j + 1], x[j + 1] = y;
                    }
            memcpy(&tris[3 * nt++], x, sizeof x);
        }
        ms_codec_state_free(&st);
    }
    qsort(tris, nt, 3 * sizeof *tris, cmp_triple);
    size_t distinct = 0;
    for (size_t t = 0; t < nt; ++t)
        distinct += t == 0 || memcmp(&tris[3 * t], &tris[3 * (t - 1)], 24) != 0;
    free(tris);
    return distinct;
}

/* An internal cell's APO sampling surface is exactly the union of its children's
 * decoded meshes: the triangles of all internal cells' M add up to the unions
 * computed here from the archive through the client's view, and the largest
 * matches too. */
static void test_internal_sampling_surface_is_children_union(void **state)
{
    (void)state;
    char dir[512], model[4096], path[700];
    bunny_case(dir, model);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.max_depth = 5;
    ms_bake_report r;
    bake_report(model, dir, "u", 2, &apo, 16, 2, 3, 200, &r); /* n = 2: a deep tree */
    snprintf(path, sizeof path, "%s/u.msa", dir);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    const unsigned nc = h->n * h->n * h->n;
    ms_view *v;
    assert_int_equal(ms_view_create_from_archive(a, &v, &err), MS_OK);
    const ms_archive_cell *cells = ms_archive_get_cell(a, 0);
    assert_int_equal(ms_view_set_bits(v, 0, cells[0].bits_max, &err), MS_OK);
    ms_qmesh q = {0};
    ms_nsp_test_reference(model, 16, &q);
    uint64_t *keys = malloc((q.vertex_count + 1) * sizeof *keys);
    assert_non_null(keys);
    for (size_t i = 0; i < q.vertex_count; ++i)
        keys[i] = ms_quant_key(q.coords[3 * i], q.coords[3 * i + 1], q.coords[3 * i + 2], 16);
    qsort(keys, q.vertex_count, sizeof *keys, cmp_u64);
    /* cells are numbered parents first: split each internal cell in turn */
    size_t sum = 0, largest = 0, internal = 0, deeper = 0;
    for (uint32_t c = 0; c < h->cell_count; ++c) {
        if (cells[c].first_child == MS_ARCHIVE_NONE)
            continue;
        assert_int_equal(ms_view_split(v, c, &err), MS_OK);
        size_t u = children_union(v, cells, c, nc, keys, q.vertex_count);
        internal++;
        deeper += cells[c].level > 0;
        sum += u;
        largest = u > largest ? u : largest;
    }
    assert_true(internal >= 3 && deeper >= 2); /* the root and level-1 cells */
    assert_int_equal(r.apo_sample_triangles, sum);
    assert_int_equal(r.apo_sample_triangles_max, largest);
    /* the root's M is coarser than the model: log2(n) bits above its window */
    assert_true(largest < r.triangles);
    free(keys);
    ms_qmesh_free(&q);
    ms_view_destroy(v);
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* An ascii PLY of nv vertices and nf triangles. */
static void write_ply(const char *path, const double *v, size_t nv, const uint32_t *f, size_t nf)
{
    size_t cap = 256 + 80 * (nv + nf), len = 0;
    char *text = malloc(cap);
    assert_non_null(text);
    len += (size_t)snprintf(text + len, cap - len,
                            "ply\nformat ascii 1.0\nelement vertex %zu\nproperty double x\nproperty double y\n"
                            "property double z\nelement face %zu\nproperty list uchar int vertex_indices\n"
                            "end_header\n", nv, nf);
    for (size_t i = 0; i < nv; ++i)
        len += (size_t)snprintf(text + len, cap - len, "%.17g %.17g %.17g\n", v[3 * i], v[3 * i + 1], v[3 * i + 2]);
    for (size_t i = 0; i < nf; ++i)
        len += (size_t)snprintf(text + len, cap - len, "3 %u %u %u\n", f[3 * i], f[3 * i + 1], f[3 * i + 2]);
    ms_test_write_file(path, text, len);
    free(text);
}

/* The 12-triangle cube (issue 18: 211 KB of APO before, 926 times its geometry):
 * its one cell is a leaf whose geometry renders every face and crease, so a
 * default bake stores no chunk (0 bytes, within the geometry + 2 KB);
 * apo.every_cell with apo.full_normals (a chunk on every cell with triangles,
 * every texel kept) refines its 12 creases to the cap. */
static void test_cube_costs_no_apo(void **state)
{
    (void)state;
    char dir[512], path[700];
    ms_test_tmpdir(dir, sizeof dir);
    static const double v[8][3] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}, {0, 1, 1},
                                   {1, 0, 0}, {1, 0, 1}, {1, 1, 0}, {1, 1, 1}};
    static const uint32_t f[12][3] = {{0, 1, 3}, {0, 3, 2}, {4, 6, 7}, {4, 7, 5}, {0, 4, 5}, {0, 5, 1},
                                      {2, 3, 7}, {2, 7, 6}, {0, 2, 6}, {0, 6, 4}, {1, 5, 7}, {1, 7, 3}};
    snprintf(path, sizeof path, "%s/cube.ply", dir);
    write_ply(path, &v[0][0], 8, &f[0][0], 12);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.verify = true;
    ms_bake_report r;
    bake_report(path, dir, "cube", 1, &apo, 16, 4, 7, 8000, &r);
    assert_int_equal(r.cells, 1);
    assert_int_equal(r.apo_chunks, 0);
    assert_int_equal(r.apo_bytes, 0);
    assert_true(r.apo_bytes <= r.geometry_bytes + 2048);
    apo.every_cell = true;
    apo.full_normals = true;
    apo.budget = 0; /* the former rule's cost, which the byte budget would cut */
    bake_report(path, dir, "cube_every", 1, &apo, 16, 4, 7, 8000, &r);
    assert_int_equal(r.apo_chunks, 1);
    assert_int_equal(r.apo_levels, apo.max_depth + 1); /* the creases go to the cap */
    assert_true(r.apo_bytes > r.geometry_bytes + 2048);
    ms_test_rmdir(dir);
}

/* ms_bake_apo_geometry_renders on a crease between two flat faces (a roof of
 * four triangles): m as the decoder gives it (other vertex order, other
 * numbering, a foreign triangle more) renders it, so no chunk: the crease stops
 * where the geometry already draws it; an M triangle m lacks (a detail) needs a
 * chunk; a degenerate M triangle needs nothing. The cell's chunk follows. */
static void test_crease_rendered_by_geometry(void **state)
{
    (void)state;
    static const double roof[6][3] = {{0.1, 0.1, 0.3}, {0.5, 0.1, 0.6}, {0.9, 0.1, 0.3},
                                      {0.1, 0.9, 0.3}, {0.5, 0.9, 0.6}, {0.9, 0.9, 0.3}};
    static const uint32_t big_tris[4][3] = {{0, 1, 4}, {0, 4, 3}, {1, 2, 5}, {1, 5, 4}};
    /* m: vertices renumbered (reversed), triangles rotated, one more (foreign) */
    static const uint32_t m_tris[5][3] = {{4, 1, 5}, {5, 1, 2}, {1, 4, 0}, {4, 0, 3}, {0, 1, 2}};
    ms_mesh M, m;
    memset(&M, 0, sizeof M);
    memset(&m, 0, sizeof m);
    assert_int_equal(ms_mesh_reserve(&M, 7, 5, NULL), MS_OK);
    assert_int_equal(ms_mesh_reserve(&m, 7, 5, NULL), MS_OK);
    for (int i = 0; i < 6; ++i) {
        memcpy(&M.positions[3 * i], roof[i], sizeof roof[i]);
        memcpy(&m.positions[3 * (5 - i)], roof[i], sizeof roof[i]);
    }
    M.vertex_count = m.vertex_count = 6;
    memcpy(M.triangles, big_tris, sizeof big_tris);
    M.triangle_count = 4;
    memcpy(m.triangles, m_tris, sizeof m_tris);
    m.triangle_count = 5;
    assert_true(ms_bake_apo_geometry_renders(&m, &M));
    /* a degenerate M triangle (two equal corners) asks for nothing */
    M.triangles[12] = 0, M.triangles[13] = 0, M.triangles[14] = 2;
    M.triangle_count = 5;
    assert_true(ms_bake_apo_geometry_renders(&m, &M));
    /* a detail: M's triangle over a vertex m does not have */
    M.positions[18] = 0.5, M.positions[19] = 0.5, M.positions[20] = 0.62;
    M.vertex_count = 7;
    M.triangles[12] = 1, M.triangles[13] = 6, M.triangles[14] = 4;
    assert_false(ms_bake_apo_geometry_renders(&m, &M));
    /* through the cell: no chunk where the geometry renders M, one otherwise */
    M.triangle_count = 4;
    ms_nsp_shape shape = {.n = 4, .log2n = 2};
    ms_quant_box box = {.origin = {0, 0, 0}, .size = 1.0};
    const uint32_t position[3] = {0, 0, 0};
    ms_bake_apo_params p;
    ms_bake_apo_params_default(&p);
    p.verify = true;
    ms_apo_builder *builder;
    ms_error err;
    assert_int_equal(ms_apo_builder_create(&builder, &err), MS_OK);
    ms_bake_apo_result out;
    assert_int_equal(ms_bake_apo_cell(builder, &p, &shape, &box, 0, position, 8, &m, &M, NULL, 1, &out, &err),
                     MS_OK);
    assert_int_equal(out.levels, 0);
    assert_null(out.data);
    p.every_cell = true;
    p.full_normals = true;
    assert_int_equal(ms_bake_apo_cell(builder, &p, &shape, &box, 0, position, 8, &m, &M, NULL, 1, &out, &err),
                     MS_OK);
    uint32_t rule = 8 + p.lead < p.max_depth ? 8 + p.lead : p.max_depth; /* the crease splits to the rule */
    assert_int_equal(out.levels, rule + 1);
    ms_bake_apo_result_free(&out);
    ms_apo_builder_destroy(builder);
    ms_mesh_free(&M);
    ms_mesh_free(&m);
}

/* Writes the fan of n triangles around a hub at the origin, rim
 * (cos a, sin a, wave sin 7a), to path (PLY). */
static void write_fan_ply(const char *path, uint32_t n, double wave)
{
    double *v = malloc(3 * (n + 1) * sizeof *v);
    uint32_t *f = malloc(3 * n * sizeof *f);
    assert_true(v && f);
    v[0] = v[1] = v[2] = 0.0;
    for (uint32_t i = 0; i < n; ++i) {
        double a = 2.0 * M_PI * i / n;
        v[3 * (i + 1)] = cos(a), v[3 * (i + 1) + 1] = sin(a);
        v[3 * (i + 1) + 2] = wave != 0.0 ? wave * sin(7.0 * a) : 0.0; /* flat: +0, never -0 */
        f[3 * i] = 0, f[3 * i + 1] = 1 + i, f[3 * i + 2] = 1 + (i + 1) % n;
    }
    write_ply(path, v, n + 1, f, n);
    free(v);
    free(f);
}

/* A flat fan of 20,000 triangles (issue 18: 100,000 took 182 s with APO): its
 * leaf cells get no chunk (their geometry renders M), its internal cells none
 * either (M flat: m's smooth normal gives it, APO as a correction); with every
 * texel kept (full_normals) one leaf each, and each leaf samples at most
 * MS_APO_SAMPLES_PER_LEAF triangles (test_apo_build.c counts the rays). */
static void test_flat_fan_bakes(void **state)
{
    (void)state;
    char dir[512], path[700];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/fan.ply", dir);
    write_fan_ply(path, 20000, 0.0);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.verify = true;
    ms_bake_report r;
    bake_report(path, dir, "fan", 2, &apo, 16, 4, 7, 8000, &r);
    assert_true(r.cells > r.leaves);
    assert_int_equal(r.apo_chunks, 0);
    assert_int_equal(r.apo_bytes, 0);
    assert_true(r.apo_smooth_leaves >= r.cells - r.leaves); /* each internal cell's one leaf, dropped */
    apo.full_normals = true;
    bake_report(path, dir, "fan_full", 2, &apo, 16, 4, 7, 8000, &r);
    assert_true(r.cells > r.leaves && r.apo_chunks > 0);
    assert_int_equal(r.apo_internal_nodes, 0);
    assert_int_equal(r.apo_leaves, r.apo_chunks); /* one texel per chunk */
    assert_int_equal(r.apo_levels, 1);
    /* each one-texel chunk: at most 8 samples, 2 Embree rays each, however many
     * of the fan's triangles it touches (the root's m alone has thousands); a
     * fan's M is crowded, so most are answered from the leaf's own list */
    assert_true(r.apo_rays <= 2 * MS_APO_SAMPLES_PER_LEAF * r.apo_leaves);
    assert_true(r.apo_point_queries <= r.apo_leaves);
    archive_check k = check_baked(dir, "fan_full", false);
    assert_int_equal(k.chunks, r.apo_chunks);
    assert_int_equal(k.multi_level, 0);
    ms_test_rmdir(dir);
}

/* The wavy fan of issue 31 (n slivers around a hub at the origin, rim
 * (cos a, sin a, 0.1 sin 7a)) baked with the defaults: the APO build's work,
 * counted without clocks (the triangles the builders look at one by one, plus
 * every Embree query charged as a visit of the whole fan, what one costs
 * there), grows linearly with n. Before the capped lists Embree answered
 * 1,628 rays at 25,000 triangles and 66,056 at 100,000, each visiting a good
 * part of the fan (docs/PERFORMANCE.md, "APO build on a high-valence fan"). */
static uint64_t wavy_fan_work(const char *dir, uint32_t n, ms_bake_report *r)
{
    char path[700], name[32];
    snprintf(name, sizeof name, "wavy%u", n);
    snprintf(path, sizeof path, "%s/%s.ply", dir, name);
    write_fan_ply(path, n, 0.1);
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.verify = true;
    bake_report(path, dir, name, 2, &apo, 16, 4, 7, 8000, r);
    return r->apo_triangle_visits + (r->apo_rays + r->apo_point_queries) * (uint64_t)n;
}

static void test_wavy_fan_bake_work_linear(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_bake_report small, large;
    uint64_t w_small = wavy_fan_work(dir, 20000, &small), w_large = wavy_fan_work(dir, 40000, &large);
    print_message("wavy fan bake: 20000 -> %llu (%u chunks), 40000 -> %llu (%u chunks)\n",
                  (unsigned long long)w_small, small.apo_chunks, (unsigned long long)w_large, large.apo_chunks);
    assert_true(small.apo_chunks > 0 && large.apo_chunks > 0);
    /* the fan's M is crowded: its leaves answer from their lists, Embree is
     * never asked */
    assert_int_equal(large.apo_rays + large.apo_point_queries, 0);
    assert_true(w_small > 0);
    assert_true(w_large * 10 <= 23 * w_small);       /* 1.51 measured */
    assert_true(w_large <= 256 * 40000ull);          /* 135 per triangle measured */
    ms_test_rmdir(dir);
}

/* MESHSTREAM_BIG=1: the 871k dragon with the default settings, verified by the
 * baker and then chunk by chunk here. */
static void test_big_dragon(void **state)
{
    (void)state;
    const char *big = getenv("MESHSTREAM_BIG");
    if (!big || strcmp(big, "1") != 0)
        skip();
    char dir[512], model[4096];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_model_path(model, sizeof model, "stanford_dragon_vrip.ply.gz");
    ms_bake_apo_params apo;
    ms_bake_apo_params_default(&apo);
    apo.verify = true;
    ms_bake_report r;
    bake_report(model, dir, "dragon", 2, &apo, 16, 4, 7, 8000, &r);
    archive_check k = check_baked(dir, "dragon", false);
    print_message("dragon: %u chunks, %u at the rule's depth, APO %llu bytes, geometry %llu\n", k.chunks,
                  k.at_rule_depth, (unsigned long long)r.apo_bytes, (unsigned long long)r.geometry_bytes);
    assert_true(k.chunks >= 10);
    assert_int_equal(k.chunks, k.internal_with_chunk);
    assert_true(r.apo_bytes <= r.geometry_bytes); /* issue 18: APO pays for itself */
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_chunks_round_trip_and_threads_agree),
        cmocka_unit_test(test_leaves_skip_the_renders_check),
        cmocka_unit_test(test_depth_rule_exact),
        cmocka_unit_test(test_damaged_chunks_are_rejected),
        cmocka_unit_test(test_cli_reports_apo),
        cmocka_unit_test(test_union_of_parts),
        cmocka_unit_test(test_smooth_to_means),
        cmocka_unit_test(test_internal_sampling_surface_is_children_union),
        cmocka_unit_test(test_cube_costs_no_apo),
        cmocka_unit_test(test_crease_rendered_by_geometry),
        cmocka_unit_test(test_flat_fan_bakes),
        cmocka_unit_test(test_wavy_fan_bake_work_linear),
        cmocka_unit_test(test_big_dragon),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
