/* APO texel format: normal quantisation bound, encode/decode round trip, the
 * validating loader (corrupted offsets, masks, tables, prefixes) and the stored
 * blob (zlib, CRCs). */
#include <stdarg.h>
#include <stdio.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <math.h>
#include <cmocka.h>

#include "ms_apo_blob.h"
#include "ms_apo_chunk.h"
#include "ms_apo_format.h"
#include "ms_apo_testtree.h"
#include "ms_apo_traverse.h"

static double angle_between(const float a[3], const float b[3])
{
    double c = (double)a[0] * b[0] + (double)a[1] * b[1] + (double)a[2] * b[2];
    double x[3] = {(double)a[1] * b[2] - (double)a[2] * b[1], (double)a[2] * b[0] - (double)a[0] * b[2],
                   (double)a[0] * b[1] - (double)a[1] * b[0]};
    return atan2(sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]), c);
}

/* The quantisation error bound, over random directions and the awkward ones
 * (axes, octahedron edges and the folded lower hemisphere). */
static void test_normal_quantisation_bound(void **state)
{
    (void)state;
    uint64_t rng = 7;
    double worst = 0.0;
    for (int i = 0; i < 1000000; ++i) {
        float n[3], d[3];
        double v[3], l2;
        do {
            l2 = 0;
            for (int a = 0; a < 3; ++a) {
                v[a] = 2.0 * ms_test_randf(&rng) - 1.0;
                l2 += v[a] * v[a];
            }
        } while (l2 > 1.0 || l2 < 1e-6);
        for (int a = 0; a < 3; ++a)
            n[a] = (float)(v[a] / sqrt(l2));
        uint32_t code = ms_apo_normal_encode(n);
        assert_true(ms_apo_normal_code_valid(code));
        ms_apo_normal_decode(code, d);
        double e = angle_between(n, d);
        if (e > worst)
            worst = e;
    }
    /* Special directions: exact on the axes. */
    const float axes[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    for (int i = 0; i < 6; ++i) {
        float d[3];
        ms_apo_normal_decode(ms_apo_normal_encode(axes[i]), d);
        for (int a = 0; a < 3; ++a)
            assert_true(fabsf(d[a] - axes[i][a]) < 1e-6f);
    }
    /* Directions on the octahedron's edges and the equator. */
    for (int i = 0; i < 20000; ++i) {
        double t = 2.0 * M_PI * i / 20000.0;
        float n[3] = {(float)cos(t), (float)sin(t), 0.0f}, d[3];
        ms_apo_normal_decode(ms_apo_normal_encode(n), d);
        double e = angle_between(n, d);
        if (e > worst)
            worst = e;
    }
    print_message("normal code: worst angular error %.6f rad\n", worst);
    assert_true(worst <= MS_APO_NORMAL_MAX_ERROR_RAD);
    assert_true(worst < 0.001); /* what we measure; the promise is 0.002 */
    /* Zero, NaN and infinite vectors encode +z. */
    float zero[3] = {0, 0, 0}, bad[3] = {NAN, 1, 0}, inf[3] = {INFINITY, 0, 0};
    uint32_t up = ms_apo_normal_encode(axes[4]);
    assert_int_equal(ms_apo_normal_encode(zero), up);
    assert_int_equal(ms_apo_normal_encode(bad), up);
    assert_int_equal(ms_apo_normal_encode(inf), up);
    assert_false(ms_apo_normal_code_valid(0xFFFu));
    assert_false(ms_apo_normal_code_valid(0x1000000u));
}

static void assert_same_structure(const ms_apo_tree *a, const ms_apo_tree *b)
{
    assert_int_equal(a->node_count, b->node_count);
    assert_int_equal(a->level_count, b->level_count);
    for (uint32_t d = 0; d <= a->level_count; ++d)
        assert_int_equal(a->level_start[d], b->level_start[d]);
    for (size_t i = 0; i < a->node_count; ++i) {
        const ms_apo_node *x = &a->nodes[i], *y = &b->nodes[i];
        assert_int_equal(x->child_mask, y->child_mask);
        assert_int_equal(x->depth, y->depth);
        assert_memory_equal(x->cell, y->cell, sizeof x->cell);
        if (x->child_mask)
            assert_int_equal(x->first_child, y->first_child);
        assert_int_equal(ms_apo_normal_encode(x->normal), ms_apo_normal_encode(y->normal));
    }
}

/* Re-encoding a decoded normal gives its code back (seam codes: their canonical
 * twin), over every 7th code and one that used to flip to a neighbour: adjacent
 * codes are ~1e-7 apart in cosine, within float rounding. */
static void test_reencoding_decoded_normals(void **state)
{
    (void)state;
    uint64_t checked = 0;
    for (uint32_t code = 0; code < (1u << 24); code += 7) {
        uint32_t qu = code & 0xFFFu, qv = code >> 12;
        if (qu > MS_APO_NORMAL_MAX_CODE || qv > MS_APO_NORMAL_MAX_CODE)
            continue;
        if (qu == 0 || qu == MS_APO_NORMAL_MAX_CODE)
            qv = qv < MS_APO_NORMAL_MAX_CODE - qv ? MS_APO_NORMAL_MAX_CODE - qv : qv;
        if (qv == 0 || qv == MS_APO_NORMAL_MAX_CODE)
            qu = qu < MS_APO_NORMAL_MAX_CODE - qu ? MS_APO_NORMAL_MAX_CODE - qu : qu;
        float d[3];
        ms_apo_normal_decode(code, d);
        assert_int_equal(ms_apo_normal_encode(d), qu | qv << 12);
        checked++;
    }
    assert_int_equal(checked, 2395575);
    float d[3];
    ms_apo_normal_decode(20u | 1615u << 12, d);
    assert_int_equal(ms_apo_normal_encode(d), 20u | 1615u << 12);
}

static void test_round_trip(void **state)
{
    (void)state;
    for (uint64_t seed = 1; seed <= 12; ++seed) {
        ms_apo_tree tree, back;
        ms_test_random_tree(seed, 2 + (uint32_t)(seed % 9), 0.45, &tree);
        ms_apo_chunk chunk, again;
        assert_int_equal(ms_apo_chunk_encode(&tree, &chunk, NULL), MS_OK);
        size_t in, leaves;
        ms_apo_tree_counts(&tree, &in, &leaves);
        assert_int_equal(chunk.texel_count, leaves + 2 * in);
        ms_apo_view view;
        assert_int_equal(ms_apo_view_of_chunk(&view, &chunk, NULL), MS_OK);
        assert_int_equal(view.complete_levels, tree.level_count);
        assert_int_equal(ms_apo_view_decode(&view, &back, NULL), MS_OK);
        assert_same_structure(&tree, &back);
        /* Decoding then encoding again gives the very same words. */
        assert_int_equal(ms_apo_chunk_encode(&back, &again, NULL), MS_OK);
        assert_int_equal(again.texel_count, chunk.texel_count);
        assert_memory_equal(again.texels, chunk.texels, chunk.texel_count * 4);
        assert_memory_equal(again.level_texels, chunk.level_texels, sizeof chunk.level_texels);
        /* Stored form. */
        uint8_t *blob;
        size_t size;
        ms_apo_chunk loaded;
        assert_int_equal(ms_apo_blob_write(&chunk, 6, &blob, &size, NULL), MS_OK);
        assert_int_equal(ms_apo_blob_read(blob, size, &loaded, NULL), MS_OK);
        assert_int_equal(loaded.texel_count, chunk.texel_count);
        assert_memory_equal(loaded.texels, chunk.texels, chunk.texel_count * 4);
        free(blob);
        ms_apo_chunk_free(&loaded);
        ms_apo_chunk_free(&again);
        ms_apo_chunk_free(&chunk);
        ms_apo_tree_free(&back);
        ms_apo_tree_free(&tree);
    }
}

/* A small fixed tree: root internal with children 0 (internal: children 1, 6)
 * and 5 (leaf). Words: [0,1] root, [2,3] child 0, [4] child 5, [5] leaf 1, [6]
 * leaf 6. */
static void small_chunk(ms_apo_chunk *chunk)
{
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    tree.nodes = calloc(5, sizeof *tree.nodes);
    assert_non_null(tree.nodes);
    tree.node_count = 5;
    tree.level_count = 3;
    tree.level_start[0] = 0;
    tree.level_start[1] = 1;
    tree.level_start[2] = 3;
    tree.level_start[3] = 5;
    ms_apo_node *n = tree.nodes;
    n[0] = (ms_apo_node){.first_child = 1, .child_mask = 0x21, .depth = 0, .normal = {0, 0, 1}};
    n[1] = (ms_apo_node){.first_child = 3, .child_mask = 0x42, .depth = 1, .normal = {1, 0, 0}};
    n[2] = (ms_apo_node){.cell = {1, 0, 1}, .depth = 1, .normal = {0, 1, 0}};
    n[3] = (ms_apo_node){.cell = {0, 0, 1}, .depth = 2, .normal = {0, -1, 0}};
    n[4] = (ms_apo_node){.cell = {1, 1, 0}, .depth = 2, .normal = {-1, 0, 0}};
    assert_int_equal(ms_apo_chunk_encode(&tree, chunk, NULL), MS_OK);
    ms_apo_tree_free(&tree);
    assert_int_equal(chunk->texel_count, 7);
    assert_int_equal(chunk->level_count, 3);
    assert_int_equal(chunk->level_texels[0], 2);
    assert_int_equal(chunk->level_texels[1], 3);
    assert_int_equal(chunk->level_texels[2], 2);
}

static ms_status load_words(const ms_apo_chunk *c, const uint32_t *words, size_t received)
{
    ms_apo_view v;
    ms_error err;
    ms_error_clear(&err);
    ms_status st = ms_apo_view_init(&v, c->level_texels, c->level_count, words, received, &err);
    if (st != MS_OK)
        print_message("  rejected as expected: %s\n", err.text);
    return st;
}

static void test_exact_words(void **state)
{
    (void)state;
    ms_apo_chunk c;
    small_chunk(&c);
    /* Root: offset 2 (children start at word 2), masks 0x21 and kind 0x01. */
    assert_int_equal(c.texels[0], (2u << 8) | 0x21u);
    assert_int_equal(ms_apo_mean_kind(c.texels[1]), 0x01u);
    /* Child 0: words 2-3, its children at word 5: offset 3. */
    assert_int_equal(c.texels[2], (3u << 8) | 0x42u);
    assert_int_equal(ms_apo_mean_kind(c.texels[3]), 0u);
    /* Leaves have a zero high byte. */
    assert_int_equal(c.texels[4] >> 24, 0);
    assert_int_equal(c.texels[5] >> 24, 0);
    ms_apo_chunk_free(&c);
}

/* A mean word may say "smooth" (MS_APO_NORMAL_SMOOTH: no correction there); it
 * encodes, loads and decodes back as such. Pruning keeps the chosen nodes in
 * breadth-first order, renumbers the children and turns a kept internal node
 * without kept children into a leaf. */
static void test_smooth_and_prune(void **state)
{
    (void)state;
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    tree.nodes = calloc(5, sizeof *tree.nodes);
    assert_non_null(tree.nodes);
    tree.node_count = 5, tree.level_count = 3;
    tree.level_start[1] = 1, tree.level_start[2] = 3, tree.level_start[3] = 5;
    ms_apo_node *n = tree.nodes;
    n[0] = (ms_apo_node){.first_child = 1, .child_mask = 0x21, .smooth = 1, .normal = {0, 0, 1}};
    n[1] = (ms_apo_node){.first_child = 3, .child_mask = 0x42, .depth = 1, .normal = {1, 0, 0}};
    n[2] = (ms_apo_node){.cell = {1, 0, 1}, .depth = 1, .normal = {0, 1, 0}};
    n[3] = (ms_apo_node){.cell = {0, 0, 1}, .depth = 2, .normal = {0, -1, 0}};
    n[4] = (ms_apo_node){.cell = {1, 1, 0}, .depth = 2, .normal = {-1, 0, 0}};
    ms_apo_chunk c;
    assert_int_equal(ms_apo_chunk_encode(&tree, &c, NULL), MS_OK);
    assert_int_equal(ms_apo_word_normal(c.texels[1]), MS_APO_NORMAL_SMOOTH);
    assert_int_equal(ms_apo_word_normal(c.texels[3]), ms_apo_normal_encode(n[1].normal));
    ms_apo_view v;
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, NULL), MS_OK);
    ms_apo_tree back;
    assert_int_equal(ms_apo_view_decode(&v, &back, NULL), MS_OK);
    assert_int_equal(back.node_count, 5);
    assert_int_equal(back.nodes[0].smooth, 1);
    assert_int_equal(back.nodes[1].smooth, 0);
    ms_apo_tree_free(&back);
    ms_apo_chunk_free(&c);
    /* keep the root, node 1 and its second child: node 2 and 3 go */
    uint8_t keep[5] = {1, 1, 0, 0, 1};
    assert_int_equal(ms_apo_tree_prune(&tree, keep, NULL), MS_OK);
    assert_int_equal(ms_apo_tree_check(&tree, NULL), MS_OK);
    assert_int_equal(tree.node_count, 3);
    assert_int_equal(tree.level_count, 3);
    assert_int_equal(tree.nodes[0].child_mask, 0x01);
    assert_int_equal(tree.nodes[1].child_mask, 0x40);
    assert_int_equal(tree.nodes[1].first_child, 2);
    assert_int_equal(tree.nodes[2].cell[0], 1);
    assert_true(tree.nodes[2].normal[0] == -1.0f);
    /* a kept node under a dropped parent is refused, the tree unchanged */
    uint8_t orphan[3] = {1, 0, 1};
    ms_error err;
    ms_error_clear(&err);
    assert_int_equal(ms_apo_tree_prune(&tree, orphan, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "apo prune: node 2 kept under a dropped parent");
    assert_int_equal(tree.node_count, 3);
    /* the internal node 1 kept without its child: a leaf */
    uint8_t top[3] = {1, 1, 0};
    assert_int_equal(ms_apo_tree_prune(&tree, top, NULL), MS_OK);
    assert_int_equal(ms_apo_tree_check(&tree, NULL), MS_OK);
    assert_int_equal(tree.node_count, 2);
    assert_int_equal(tree.level_count, 2);
    assert_int_equal(tree.nodes[1].child_mask, 0);
    /* nothing kept: an empty tree */
    uint8_t none[2] = {0, 0};
    assert_int_equal(ms_apo_tree_prune(&tree, none, NULL), MS_OK);
    assert_int_equal(tree.node_count, 0);
    assert_int_equal(tree.level_count, 0);
    assert_null(tree.nodes);
}

static void test_loader_rejects_corruption(void **state)
{
    (void)state;
    ms_apo_chunk c;
    small_chunk(&c);
    uint32_t w[7];
    assert_int_equal(load_words(&c, c.texels, 7), MS_OK);
    /* An offset pointing outside the chunk. */
    memcpy(w, c.texels, sizeof w);
    w[2] = (0xFFFFFFu << 8) | 0x42u;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* An offset pointing inside the chunk but at the wrong place. */
    memcpy(w, c.texels, sizeof w);
    w[0] = (3u << 8) | 0x21u;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* Offset 0 (a loop). */
    memcpy(w, c.texels, sizeof w);
    w[0] = 0x21u;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* Empty existence mask. */
    memcpy(w, c.texels, sizeof w);
    w[2] = 3u << 8;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* Kind bit without the existence bit. */
    memcpy(w, c.texels, sizeof w);
    w[1] = ms_apo_mean_word(0x03u, ms_apo_word_normal(w[1]));
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* A leaf that claims to be more (high byte set) and a bad normal code. */
    memcpy(w, c.texels, sizeof w);
    w[4] |= 0x01000000u;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    memcpy(w, c.texels, sizeof w);
    w[6] = 0xFFFu;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* "Smooth" is a mean word's code only: a leaf always holds a normal. */
    memcpy(w, c.texels, sizeof w);
    w[6] = MS_APO_NORMAL_SMOOTH;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    memcpy(w, c.texels, sizeof w);
    w[1] = ms_apo_mean_word(ms_apo_mean_kind(w[1]), MS_APO_NORMAL_SMOOTH);
    w[3] = ms_apo_mean_word(ms_apo_mean_kind(w[3]), MS_APO_NORMAL_SMOOTH);
    assert_int_equal(load_words(&c, w, 7), MS_OK);
    /* ... and a mean word with another invalid code is refused */
    w[3] = ms_apo_mean_word(ms_apo_mean_kind(w[3]), 0xFFEFFFu);
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* More children than the next level holds (a mask with every bit set). */
    memcpy(w, c.texels, sizeof w);
    w[0] = (2u << 8) | 0xFFu;
    assert_int_equal(load_words(&c, w, 7), MS_ERR_CORRUPT);
    /* Tables that do not match the words. */
    ms_apo_view v;
    uint32_t table[3] = {2, 3, 2};
    table[1] = 4;
    assert_int_equal(ms_apo_view_init(&v, table, 3, c.texels, 7, NULL), MS_ERR_CORRUPT);
    table[1] = 3;
    table[0] = 3;
    assert_int_equal(ms_apo_view_init(&v, table, 3, c.texels, 7, NULL), MS_ERR_FORMAT);
    table[0] = 2;
    table[2] = 0;
    assert_int_equal(ms_apo_view_init(&v, table, 3, c.texels, 7, NULL), MS_ERR_FORMAT);
    table[2] = 2;
    assert_int_equal(ms_apo_view_init(&v, table, 2, c.texels, 5, NULL), MS_ERR_CORRUPT); /* children below the last level */
    assert_int_equal(ms_apo_view_init(&v, table, 3, c.texels, 8, NULL), MS_ERR_RANGE);
    assert_int_equal(ms_apo_view_init(&v, table, MS_APO_MAX_LEVELS + 1, c.texels, 7, NULL), MS_ERR_FORMAT);
    ms_apo_chunk_free(&c);
}

/* A prefix cut in the middle of a level: only the whole levels are used, and a
 * corruption in the partial level does not matter because it is never read. */
/* Random damage to the words of random chunks: the loader either rejects the
 * words or accepts words that are a consistent tree, which lookups then walk
 * safely (ASan watches every read). */
static void test_loader_random_damage(void **state)
{
    (void)state;
    uint64_t rng = 4242;
    size_t accepted = 0, rejected = 0;
    for (uint64_t seed = 0; seed < 20; ++seed) {
        ms_apo_tree tree;
        ms_test_random_tree(500 + seed, 7, 0.5, &tree);
        ms_apo_chunk c;
        assert_int_equal(ms_apo_chunk_encode(&tree, &c, NULL), MS_OK);
        uint32_t *w = malloc(c.texel_count * sizeof *w);
        assert_non_null(w);
        for (int k = 0; k < 200; ++k) {
            memcpy(w, c.texels, c.texel_count * sizeof *w);
            size_t at = (size_t)(ms_test_rand(&rng) % c.texel_count);
            w[at] ^= 1u << (ms_test_rand(&rng) % 32);
            ms_apo_view v;
            size_t received = (k & 3) ? c.texel_count : (size_t)(ms_test_rand(&rng) % (c.texel_count + 1));
            if (ms_apo_view_init(&v, c.level_texels, c.level_count, w, received, NULL) != MS_OK) {
                ++rejected;
                continue;
            }
            ++accepted;
            for (int i = 0; i < 200; ++i) {
                float p[3] = {ms_test_randf(&rng), ms_test_randf(&rng), ms_test_randf(&rng)};
                ms_apo_lookup_result r;
                ms_apo_lookup(&v, p, 30, (i & 1) ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP, &r);
                if (r.stop != MS_APO_STOP_EMPTY)
                    assert_true(r.word + (r.stop == MS_APO_STOP_LEAF ? 0u : 1u) < v.texel_count);
            }
        }
        free(w);
        ms_apo_chunk_free(&c);
        ms_apo_tree_free(&tree);
    }
    print_message("random damage: %zu rejected, %zu accepted (normal bits only, or beyond the prefix)\n", rejected,
                  accepted);
    assert_true(rejected > 1000);
}

static void test_truncated_mid_level(void **state)
{
    (void)state;
    ms_apo_chunk c;
    small_chunk(&c);
    ms_apo_view v;
    uint32_t w[7];
    memcpy(w, c.texels, sizeof w);
    w[6] = 0xFFFFFFFFu; /* garbage in the level still in transit */
    assert_int_equal(ms_apo_view_init(&v, c.level_texels, 3, w, 6, NULL), MS_OK);
    assert_int_equal(v.complete_levels, 2);
    /* The point (0.1, 0.1, 0.3) lies in octant 1 of child 0, a leaf of level 2
     * not usable yet: the traversal stops on child 0's mean normal. */
    ms_apo_lookup_result r;
    float p[3] = {0.1f, 0.1f, 0.3f};
    assert_int_equal(ms_apo_lookup(&v, p, 30, MS_APO_MISSING_STOP, &r), MS_APO_STOP_PREFIX);
    assert_int_equal(r.word, 2);
    assert_int_equal(r.depth, 1);
    assert_int_equal(r.code, ms_apo_word_normal(c.texels[3]));
    /* The same words in full reach the leaf. */
    ms_apo_view full;
    assert_int_equal(ms_apo_view_of_chunk(&full, &c, NULL), MS_OK);
    assert_int_equal(ms_apo_lookup(&full, p, 30, MS_APO_MISSING_STOP, &r), MS_APO_STOP_LEAF);
    assert_int_equal(r.word, 5);
    assert_int_equal(r.depth, 2);
    /* Cut inside level 0 (1 of its 2 words): nothing usable. */
    assert_int_equal(ms_apo_view_init(&v, c.level_texels, 3, c.texels, 1, NULL), MS_OK);
    assert_int_equal(v.complete_levels, 0);
    assert_int_equal(ms_apo_lookup(&v, p, 30, MS_APO_MISSING_STOP, &r), MS_APO_STOP_EMPTY);
    /* Decoding a prefix gives the shallower tree. */
    ms_apo_tree t;
    assert_int_equal(ms_apo_view_init(&v, c.level_texels, 3, c.texels, 6, NULL), MS_OK);
    assert_int_equal(ms_apo_view_decode(&v, &t, NULL), MS_OK);
    assert_int_equal(t.level_count, 2);
    assert_int_equal(t.node_count, 3);
    assert_int_equal(t.nodes[1].child_mask, 0);
    ms_apo_tree_free(&t);
    ms_apo_chunk_free(&c);
}

static void test_empty_chunk(void **state)
{
    (void)state;
    ms_apo_tree empty;
    memset(&empty, 0, sizeof empty);
    ms_apo_chunk c;
    assert_int_equal(ms_apo_chunk_encode(&empty, &c, NULL), MS_OK);
    assert_int_equal(c.texel_count, 0);
    assert_int_equal(c.level_count, 0);
    ms_apo_view v;
    assert_int_equal(ms_apo_view_of_chunk(&v, &c, NULL), MS_OK);
    ms_apo_lookup_result r;
    float p[3] = {0.5f, 0.5f, 0.5f};
    assert_int_equal(ms_apo_lookup(&v, p, 30, MS_APO_MISSING_NEAREST, &r), MS_APO_STOP_EMPTY);
    assert_true(r.normal[0] == 0.0f && r.normal[1] == 0.0f && r.normal[2] == 0.0f);
    uint8_t *blob;
    size_t size;
    ms_apo_chunk back;
    assert_int_equal(ms_apo_blob_write(&c, 6, &blob, &size, NULL), MS_OK);
    assert_int_equal(ms_apo_blob_read(blob, size, &back, NULL), MS_OK);
    assert_int_equal(back.level_count, 0);
    assert_int_equal(back.texel_count, 0);
    free(blob);
    ms_apo_chunk_free(&back);
    ms_apo_chunk_free(&c);
}

static void test_blob_damage(void **state)
{
    (void)state;
    ms_apo_tree tree;
    ms_test_random_tree(99, 6, 0.5, &tree);
    ms_apo_chunk c, back;
    assert_int_equal(ms_apo_chunk_encode(&tree, &c, NULL), MS_OK);
    uint8_t *blob;
    size_t size;
    assert_int_equal(ms_apo_blob_write(&c, 9, &blob, &size, NULL), MS_OK);
    uint8_t *copy = malloc(size);
    assert_non_null(copy);
    size_t harmless = 0;
    /* Every single-byte flip is rejected, or (only in the unused padding bits of
     * the last deflate byte) yields exactly the original words; never a crash. */
    for (size_t i = 0; i < size; ++i) {
        memcpy(copy, blob, size);
        copy[i] ^= 0x5A;
        ms_status st = ms_apo_blob_read(copy, size, &back, NULL);
        if (st == MS_OK) {
            assert_int_equal(back.texel_count, c.texel_count);
            assert_memory_equal(back.texels, c.texels, 4 * c.texel_count);
            ms_apo_chunk_free(&back);
            ++harmless;
            continue;
        }
        assert_null(back.texels);
    }
    assert_true(harmless <= 1);
    /* Every truncation is rejected. */
    for (size_t n = 0; n < size; n += 1 + n / 8)
        assert_true(ms_apo_blob_read(blob, n, &back, NULL) != MS_OK);
    /* Version and magic: version 2 (chunks are corrections of the smooth
     * normal); 1, whose missing nodes meant the nearest texel, and 3 are
     * refused in one line naming the version. */
    assert_int_equal(blob[4] | blob[5] << 8, 2);
    for (int v = 1; v <= 3; v += 2) {
        memcpy(copy, blob, size);
        copy[4] = (uint8_t)v;
        ms_error verr;
        ms_error_clear(&verr);
        assert_int_equal(ms_apo_blob_read(copy, size, &back, &verr), MS_ERR_UNSUPPORTED);
        char want[80];
        snprintf(want, sizeof want, "apo blob: version %d (this reader knows only 2)", v);
        assert_string_equal(verr.text, want);
        assert_null(back.texels);
    }
    memcpy(copy, blob, size);
    copy[0] = 'X';
    assert_int_equal(ms_apo_blob_read(copy, size, &back, NULL), MS_ERR_FORMAT);
    /* A partial chunk cannot be stored. */
    uint8_t *none = NULL;
    size_t none_size = 0;
    c.texel_count--;
    assert_int_equal(ms_apo_blob_write(&c, 6, &none, &none_size, NULL), MS_ERR_ARG);
    assert_null(none);
    c.texel_count++;
    free(copy);
    free(blob);
    ms_apo_chunk_free(&c);
    ms_apo_tree_free(&tree);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_normal_quantisation_bound), cmocka_unit_test(test_reencoding_decoded_normals),
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_exact_words),               cmocka_unit_test(test_loader_rejects_corruption),
        cmocka_unit_test(test_loader_random_damage),      cmocka_unit_test(test_truncated_mid_level),       cmocka_unit_test(test_empty_chunk),
        cmocka_unit_test(test_blob_damage),               cmocka_unit_test(test_smooth_and_prune),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
