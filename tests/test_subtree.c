/* The index in subtrees (ms_subtree.h, docs/ARCHIVE.md "Subtrees"): every
 * subtree of the synthetic archives and of the dragon encodes, deflates,
 * inflates and validates; the subtrees partition the index record for record;
 * a partial archive built from the head and the subtrees in tree order answers
 * get_cell and the prefix look-ups like the whole one; drop forgets a subtree
 * and everything below it; and every way a stored subtree can lie is refused
 * with a one-line error, leaving the partial archive as it was. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_nsp_check.h"
#include "ms_registry.h"
#include "ms_subtree.h"
#include "ms_test.h"
#include "ms_test_archive.h"

typedef struct fixture {
    char dir[512];
    char path[600];
    ms_archive *a;
} fixture;

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void le_put64(uint8_t *p, uint64_t v)
{
    put32(p, (uint32_t)v);
    put32(p + 4, (uint32_t)(v >> 32));
}

static ms_archive *open_or_fail(const char *path)
{
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    return a;
}

static int setup_synthetic(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->path, sizeof f->path, "%s/synthetic.msa", f->dir);
    ms_test_write_archive(f->path, 0);
    f->a = open_or_fail(f->path);
    *state = f;
    return 0;
}

static int setup_deep(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->path, sizeof f->path, "%s/deep.msa", f->dir);
    ms_test_write_deep_archive(f->path, 0);
    f->a = open_or_fail(f->path);
    *state = f;
    return 0;
}

static int setup_dragon(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    char input[512];
    ms_test_model_path(input, sizeof input, "stanford_dragon_vrip_res3.ply.gz");
    ms_bake_report report;
    ms_nsp_test_bake(input, f->dir, "dragon", 16, 2000, &report);
    snprintf(f->path, sizeof f->path, "%s/dragon.msa", f->dir);
    f->a = open_or_fail(f->path);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_archive_close(f->a);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* The stored bytes of a subtree at depth levels, through the public encoder. */
static uint8_t *stored_subtree(const ms_archive *a, unsigned levels, uint32_t id, size_t *size)
{
    uint8_t *raw, *stored;
    size_t raw_size;
    ms_error err;
    if (ms_subtree_encode(a, levels, id, &raw, &raw_size, &err) != MS_OK)
        fail_msg("%s", err.text);
    if (ms_subtree_deflate(raw, raw_size, &stored, size, &err) != MS_OK)
        fail_msg("%s", err.text);
    free(raw);
    return stored;
}

/* The head of a model at depth `levels` built from the public pieces, as a
 * version-3 header over the root subtree. */
static uint8_t *head_at(const ms_archive *a, unsigned levels, size_t *size)
{
    size_t root_size, count, blob_size;
    uint32_t *ids;
    ms_error err;
    if (ms_subtree_list(a, levels, &ids, &count, &err) != MS_OK)
        fail_msg("%s", err.text);
    free(ids);
    uint8_t *root = stored_subtree(a, levels, 0, &root_size);
    const uint8_t *blob = ms_archive_index_bytes(a, &blob_size);
    const ms_archive_header *h = ms_archive_get_header(a);
    uint8_t *head = malloc(MS_ARCHIVE_HEADER_SIZE + root_size);
    ms_archive_encode_header(h, blob_size - MS_ARCHIVE_HEADER_SIZE, (uint32_t)root_size,
                             get32(blob + 88), get32(blob + 96), get32(blob + 108), levels,
                             (uint32_t)count, head);
    memcpy(head + MS_ARCHIVE_HEADER_SIZE, root, root_size);
    free(root);
    *size = MS_ARCHIVE_HEADER_SIZE + root_size;
    return head;
}

/* Record equality but for table_first (a partial archive's is the subtree's),
 * and every prefix look-up equal. */
static void assert_same_cell(const ms_archive *whole, const ms_archive *part, uint32_t id)
{
    const ms_archive_cell *x = ms_archive_get_cell(whole, id);
    const ms_archive_cell *y = ms_archive_get_cell(part, id);
    if (!y)
        fail_msg("cell %u is not held", id);
    ms_archive_cell xc = *x, yc = *y;
    xc.table_first = yc.table_first = 0;
    uint8_t xr[MS_ARCHIVE_RECORD_SIZE], yr[MS_ARCHIVE_RECORD_SIZE];
    ms_archive_encode_cell(&xc, xr);
    ms_archive_encode_cell(&yc, yr);
    assert_memory_equal(xr, yr, sizeof xr);
    for (unsigned bits = 0; bits <= 21; ++bits)
        assert_int_equal(ms_archive_geometry_prefix(whole, id, bits),
                         ms_archive_geometry_prefix(part, id, bits));
    for (unsigned level = 0; level <= 33; ++level) {
        uint32_t tx, ty;
        assert_int_equal(ms_archive_apo_prefix(whole, id, level, &tx),
                         ms_archive_apo_prefix(part, id, level, &ty));
        assert_int_equal(tx, ty);
    }
}

/* Subtrees at `levels` partition the index, and a partial archive built from
 * the head and the subtrees in tree order equals the whole one. */
static void check_round_trip(const ms_archive *a, unsigned levels, size_t expect_count)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    uint32_t *ids;
    size_t count;
    ms_error err;
    assert_int_equal(ms_subtree_list(a, levels, &ids, &count, &err), MS_OK);
    if (expect_count)
        assert_int_equal(count, expect_count);
    assert_int_equal(ids[0], 0);
    /* The union, record for record: every cell in exactly one subtree. */
    uint8_t *seen = calloc(h->cell_count, 1);
    size_t raw_total = 0;
    uint64_t table_total = 0;
    for (size_t i = 0; i < count; ++i) {
        if (i)
            assert_true(ids[i] > ids[i - 1]);
        uint8_t *raw;
        size_t size;
        assert_int_equal(ms_subtree_encode(a, levels, ids[i], &raw, &size, &err), MS_OK);
        raw_total += size;
        assert_memory_equal(raw, MS_SUBTREE_MAGIC, 4);
        assert_int_equal(raw[6], levels);
        assert_int_equal(get32(raw + 8), ids[i]);
        uint32_t m = get32(raw + 12), t = get32(raw + 16);
        assert_int_equal(size, 24 + 84 * (size_t)m + 4 * (size_t)t);
        assert_int_equal(get32(raw + 20), (uint32_t)crc32(0, raw + 24, (uInt)(size - 24)));
        table_total += t;
        const uint8_t *records = raw + 24 + 4 * (size_t)m, *tables = records + 80 * (size_t)m;
        uint32_t next = 0;
        for (uint32_t k = 0; k < m; ++k) {
            uint32_t cell = get32(raw + 24 + 4 * k);
            assert_true(cell < h->cell_count);
            assert_int_equal(seen[cell], 0);
            seen[cell] = 1;
            const ms_archive_cell *c = ms_archive_get_cell(a, cell);
            ms_archive_cell rebased = *c;
            rebased.table_first = next;
            uint8_t rec[MS_ARCHIVE_RECORD_SIZE];
            ms_archive_encode_cell(&rebased, rec);
            assert_memory_equal(rec, records + 80 * (size_t)k, sizeof rec);
            uint32_t window = c->bits_max - c->bits_min + 1u;
            uint32_t words = window + 2u * c->apo_levels + (window + 3) / 4; /* no colour */
            size_t blob_size;
            const uint8_t *blob = ms_archive_index_bytes(a, &blob_size);
            const uint8_t *whole_tables = blob + MS_ARCHIVE_HEADER_SIZE +
                                          80 * (size_t)h->cell_count;
            assert_memory_equal(tables + 4 * (size_t)next,
                                whole_tables + 4 * (size_t)c->table_first, 4 * (size_t)words);
            next += words;
        }
        assert_int_equal(next, t);
        free(raw);
    }
    for (uint32_t c = 0; c < h->cell_count; ++c)
        assert_int_equal(seen[c], 1);
    assert_int_equal(table_total, h->table_words);
    free(seen);

    /* The partial archive, subtree by subtree in ascending id (tree order). */
    size_t head_size;
    uint8_t *head = head_at(a, levels, &head_size);
    ms_archive *p;
    if (ms_archive_open_head(head, head_size, "head", &p, &err) != MS_OK)
        fail_msg("%s", err.text);
    free(head);
    assert_true(ms_archive_is_partial(p));
    assert_int_equal(ms_archive_subtree_levels(p), levels);
    assert_int_equal(ms_archive_subtree_count(p), count);
    assert_int_equal(ms_archive_subtrees_held(p), 1);
    size_t index_bytes = 0;
    for (size_t i = 0; i < count; ++i) {
        uint32_t *members;
        size_t m;
        assert_int_equal(ms_subtree_members(a, levels, ids[i], &members, &m, &err), MS_OK);
        if (i) {
            for (size_t k = 0; k < m; ++k) {
                assert_null(ms_archive_get_cell(p, members[k]));
                assert_int_equal(ms_archive_geometry_prefix(p, members[k], 30), 0);
            }
            size_t size;
            uint8_t *stored = stored_subtree(a, levels, ids[i], &size);
            if (ms_archive_add_subtree(p, ids[i], stored, size, &err) != MS_OK)
                fail_msg("%s", err.text);
            /* Again: a no-op. */
            assert_int_equal(ms_archive_add_subtree(p, ids[i], stored, size, &err), MS_OK);
            free(stored);
        }
        assert_true(ms_archive_subtree_held(p, ids[i]));
        /* The held members and records, as the client's view learns them. */
        const uint32_t *held_ids;
        const ms_archive_cell *held_recs;
        size_t held;
        assert_true(ms_archive_held_subtree(p, ids[i], &held_ids, &held_recs, &held));
        assert_int_equal(held, m);
        assert_memory_equal(held_ids, members, m * sizeof *members);
        for (size_t k = 0; k < m; ++k)
            assert_memory_equal(&held_recs[k], ms_archive_get_cell(p, members[k]),
                                sizeof *held_recs);
        assert_false(ms_archive_held_subtree(a, ids[i], &held_ids, &held_recs, &held));
        assert_int_equal(held, 0);
        for (size_t k = 0; k < m; ++k) {
            assert_same_cell(a, p, members[k]);
            if (levels == ms_archive_subtree_levels(a)) {
                assert_int_equal(ms_archive_subtree_of(a, members[k]), ids[i]);
                assert_int_equal(ms_archive_children_subtree(a, members[k]),
                                 ms_archive_children_subtree(p, members[k]));
            }
            assert_int_equal(ms_archive_subtree_of(p, members[k]), ids[i]);
            const ms_archive_cell *c = ms_archive_get_cell(p, members[k]);
            uint32_t below = ms_archive_children_subtree(p, members[k]);
            if (c->first_child == MS_ARCHIVE_NONE)
                assert_int_equal(below, MS_ARCHIVE_NONE);
            else if ((c->level + 1u) % levels == 0)
                assert_int_equal(below, c->first_child);
            else
                assert_int_equal(below, ids[i]);
        }
        index_bytes += 24 + 84 * m;
        free(members);
        assert_int_equal(ms_archive_subtrees_held(p), i + 1);
    }
    assert_int_equal(ms_archive_index_bytes_held(p), index_bytes + 4ull * h->table_words);
    assert_int_equal(index_bytes + 4ull * h->table_words, raw_total);
    assert_null(ms_archive_get_cell(p, h->cell_count));
    assert_int_equal(ms_archive_subtree_of(p, h->cell_count), MS_ARCHIVE_NONE);
    size_t none;
    assert_null(ms_archive_index_bytes(p, &none));
    assert_int_equal(none, 0);
    ms_archive_close(p);
    free(ids);
}

static void test_synthetic_round_trip(void **state)
{
    fixture *f = *state;
    assert_int_equal(ms_subtree_default_levels(4), 1);
    assert_int_equal(ms_subtree_default_levels(8), 1);
    assert_int_equal(ms_subtree_default_levels(2), 2);
    /* 129 cells: {0}, {1..64}, {65..128} at S = 1; {0..64}, {65..128} at 2;
     * everything in the root at 3. */
    check_round_trip(f->a, 1, 3);
    check_round_trip(f->a, 2, 2);
    check_round_trip(f->a, 3, 1);
    uint32_t *members;
    size_t m;
    ms_error err;
    assert_int_equal(ms_subtree_members(f->a, 1, 65, &members, &m, &err), MS_OK);
    assert_int_equal(m, 64);
    assert_int_equal(members[0], 65);
    assert_int_equal(members[63], 128);
    free(members);
    assert_int_equal(ms_subtree_members(f->a, 1, 2, &members, &m, &err), MS_ERR_RANGE);
    assert_int_equal(ms_subtree_members(f->a, 2, 1, &members, &m, &err), MS_ERR_RANGE);
    assert_int_equal(ms_subtree_list(f->a, 0, &members, &m, &err), MS_ERR_ARG);
    assert_int_equal(ms_subtree_list(f->a, 9, &members, &m, &err), MS_ERR_ARG);
}

static void test_deep_round_trip(void **state)
{
    fixture *f = *state;
    /* n = 2: the default is 2 levels a subtree. Levels 0-1 are the root
     * subtree; 2 groups at level 2, 8 at level 4. */
    assert_int_equal(ms_archive_subtree_levels(f->a), 2);
    assert_int_equal(ms_archive_subtree_count(f->a), 11);
    for (unsigned levels = 1; levels <= 8; ++levels)
        check_round_trip(f->a, levels, 0);
    check_round_trip(f->a, 1, 1 + 1 + 2 + 4 + 8 + 16);
}

static void test_dragon_round_trip(void **state)
{
    fixture *f = *state;
    unsigned levels = ms_archive_subtree_levels(f->a);
    assert_int_equal(levels, ms_subtree_default_levels(ms_archive_get_header(f->a)->n));
    check_round_trip(f->a, levels, ms_archive_subtree_count(f->a));
    check_round_trip(f->a, levels + 1, 0);
}

/* The server side: stored bytes equal the encoder's, stable pointers, the
 * head, unknown ids. */
static void test_server_side(void **state)
{
    fixture *f = *state;
    size_t size, again_size, expect_size;
    for (uint32_t i = 0; i < ms_archive_subtree_count(f->a); ++i) {
        uint32_t *ids;
        size_t count;
        ms_error err;
        assert_int_equal(ms_subtree_list(f->a, ms_archive_subtree_levels(f->a), &ids, &count, &err),
                         MS_OK);
        const uint8_t *s = ms_archive_subtree(f->a, ids[i], &size);
        assert_non_null(s);
        uint8_t *expect = stored_subtree(f->a, ms_archive_subtree_levels(f->a), ids[i], &expect_size);
        assert_int_equal(size, expect_size);
        assert_memory_equal(s, expect, size);
        assert_ptr_equal(ms_archive_subtree(f->a, ids[i], &again_size), s);
        assert_int_equal(again_size, size);
        assert_true(ms_archive_subtree_held(f->a, ids[i]));
        free(expect);
        free(ids);
    }
    assert_null(ms_archive_subtree(f->a, 2, &size));
    assert_int_equal(size, 0);
    assert_false(ms_archive_subtree_held(f->a, 2));
    assert_null(ms_archive_subtree(f->a, 1u << 30, &size));
    assert_false(ms_archive_is_partial(f->a));
    assert_int_equal(ms_archive_subtrees_held(f->a), 3);

    size_t head_size, built_size;
    const uint8_t *head = ms_archive_index_head(f->a, &head_size);
    uint8_t *built = head_at(f->a, 1, &built_size);
    assert_int_equal(head_size, built_size);
    assert_memory_equal(head, built, head_size);
    assert_ptr_equal(ms_archive_index_head(f->a, &built_size), head);
    free(built);
    assert_int_equal(get32(head + 8), MS_ARCHIVE_VERSION);
    assert_int_equal(head[120], MS_ARCHIVE_INDEX_SUBTREES);
    assert_int_equal(head[121], 1);
    assert_int_equal(get32(head + 116), 3);
    assert_int_equal(get32(head + 112), head_size - MS_ARCHIVE_HEADER_SIZE);
    ms_archive *p;
    ms_error err;
    assert_int_equal(ms_archive_open_head(head, head_size, "h", &p, &err), MS_OK);
    assert_null(ms_archive_subtree(p, 0, &size));
    assert_null(ms_archive_index_head(p, &size));
    ms_archive_close(p);
}

typedef struct race {
    const ms_archive *a;
    const uint8_t *seen[3];
} race;

static void *race_thread(void *arg)
{
    race *r = arg;
    static const uint32_t ids[3] = {0, 1, 65};
    size_t size;
    for (int i = 0; i < 3; ++i)
        r->seen[i] = ms_archive_subtree(r->a, ids[i], &size);
    return NULL;
}

/* Threads asking for the same subtrees at once all get the one copy. */
static void test_concurrent_requests(void **state)
{
    fixture *f = *state;
    pthread_t t[4];
    race r[4];
    for (int i = 0; i < 4; ++i) {
        r[i].a = f->a;
        assert_int_equal(pthread_create(&t[i], NULL, race_thread, &r[i]), 0);
    }
    for (int i = 0; i < 4; ++i)
        pthread_join(t[i], NULL);
    for (int i = 0; i < 4; ++i)
        for (int k = 0; k < 3; ++k) {
            assert_non_null(r[i].seen[k]);
            assert_ptr_equal(r[i].seen[k], r[0].seen[k]);
        }
}

/* A partial archive of the synthetic model with everything held. */
static ms_archive *partial_all(const ms_archive *a)
{
    size_t head_size, size;
    const uint8_t *head = ms_archive_index_head(a, &head_size);
    ms_archive *p;
    ms_error err;
    if (ms_archive_open_head(head, head_size, "synthetic", &p, &err) != MS_OK)
        fail_msg("%s", err.text);
    static const uint32_t ids[2] = {1, 65};
    for (int i = 0; i < 2; ++i) {
        const uint8_t *s = ms_archive_subtree(a, ids[i], &size);
        if (ms_archive_add_subtree(p, ids[i], s, size, &err) != MS_OK)
            fail_msg("%s", err.text);
    }
    return p;
}

static void test_drop(void **state)
{
    fixture *f = *state;
    ms_archive *p = partial_all(f->a);
    size_t all_bytes = ms_archive_index_bytes_held(p);
    size_t root_size;
    uint8_t *root_raw;
    ms_error err;
    assert_int_equal(ms_subtree_encode(f->a, 1, 0, &root_raw, &root_size, &err), MS_OK);
    free(root_raw);
    ms_archive_drop_subtree(p, 0); /* never the root */
    ms_archive_drop_subtree(p, 7); /* not a subtree */
    assert_int_equal(ms_archive_subtrees_held(p), 3);
    /* Dropping 65 leaves 1. */
    ms_archive_drop_subtree(p, 65);
    assert_int_equal(ms_archive_subtrees_held(p), 2);
    assert_non_null(ms_archive_get_cell(p, 64));
    assert_null(ms_archive_get_cell(p, 65));
    assert_null(ms_archive_get_cell(p, 128));
    assert_int_equal(ms_archive_subtree_of(p, 65), MS_ARCHIVE_NONE);
    assert_int_equal(ms_archive_children_subtree(p, 5), 65); /* known, though not held */
    assert_int_equal(ms_archive_children_subtree(p, 6), MS_ARCHIVE_NONE); /* a leaf */
    assert_false(ms_archive_subtree_held(p, 65));
    const uint32_t *held_ids = NULL;
    const ms_archive_cell *held_recs = NULL;
    size_t held = 1;
    assert_false(ms_archive_held_subtree(p, 65, &held_ids, &held_recs, &held));
    assert_null(held_ids);
    assert_int_equal(held, 0);
    /* Dropping 1 takes 65 with it once re-added. */
    size_t size;
    const uint8_t *s = ms_archive_subtree(f->a, 65, &size);
    assert_int_equal(ms_archive_add_subtree(p, 65, s, size, &err), MS_OK);
    assert_int_equal(ms_archive_index_bytes_held(p), all_bytes);
    ms_archive_drop_subtree(p, 1);
    assert_int_equal(ms_archive_subtrees_held(p), 1);
    assert_int_equal(ms_archive_index_bytes_held(p), root_size);
    assert_non_null(ms_archive_get_cell(p, 0));
    for (uint32_t c = 1; c < MS_TEST_ARCHIVE_CELLS; ++c)
        assert_null(ms_archive_get_cell(p, c));
    /* 65 cannot come back before 1. */
    assert_int_equal(ms_archive_add_subtree(p, 65, s, size, &err), MS_ERR_RANGE);
    assert_null(strchr(err.text, '\n'));
    s = ms_archive_subtree(f->a, 1, &size);
    assert_int_equal(ms_archive_add_subtree(p, 1, s, size, &err), MS_OK);
    for (uint32_t c = 0; c < 65; ++c)
        assert_same_cell(f->a, p, c);
    ms_archive_close(p);
}

/* Expects add_subtree(id, stored) to fail with `code` and a one-line error
 * saying `text`, leaving p unchanged. */
static void expect_refused(ms_archive *p, uint32_t id, const uint8_t *stored, size_t size,
                           ms_status code, const char *text)
{
    size_t held = ms_archive_subtrees_held(p), bytes = ms_archive_index_bytes_held(p);
    ms_error err;
    ms_status st = ms_archive_add_subtree(p, id, stored, size, &err);
    if (st == MS_OK)
        fail_msg("subtree accepted; expected '%s'", text);
    if (st != code)
        fail_msg("status %d, expected %d ('%s')", (int)st, (int)code, err.text);
    if (!strstr(err.text, text))
        fail_msg("error '%s' does not say '%s'", err.text, text);
    assert_null(strchr(err.text, '\n'));
    assert_int_equal(ms_archive_subtrees_held(p), held);
    assert_int_equal(ms_archive_index_bytes_held(p), bytes);
}

/* Deflates raw after optionally resealing its CRC, then expects refusal. */
static void expect_raw_refused(ms_archive *p, uint32_t id, uint8_t *raw, size_t size, bool seal,
                               ms_status code, const char *text)
{
    if (seal)
        put32(raw + 20, (uint32_t)crc32(0, raw + 24, (uInt)(size - 24)));
    uint8_t *stored;
    size_t stored_size;
    ms_error err;
    assert_int_equal(ms_subtree_deflate(raw, size, &stored, &stored_size, &err), MS_OK);
    expect_refused(p, id, stored, stored_size, code, text);
    free(stored);
}

static void test_hostile(void **state)
{
    fixture *f = *state;
    size_t head_size, size;
    const uint8_t *head = ms_archive_index_head(f->a, &head_size);
    ms_archive *p;
    ms_error err;
    assert_int_equal(ms_archive_open_head(head, head_size, "synthetic", &p, &err), MS_OK);
    const uint8_t *good = ms_archive_subtree(f->a, 1, &size);
    uint8_t *copy = malloc(size + 1);
    memcpy(copy, good, size);

    /* The stored bytes. */
    expect_refused(p, 1, good, 0, MS_ERR_FORMAT, "0 stored bytes");
    for (size_t cut = 1; cut < size; cut += 1 + cut / 4)
        expect_refused(p, 1, good, cut, MS_ERR_FORMAT, "subtree 1: ");
    copy[size] = 0;
    expect_refused(p, 1, copy, size + 1, MS_ERR_FORMAT, "follow the zlib stream");
    /* A damaged Adler-32. */
    copy[size - 1] ^= 0x55;
    expect_refused(p, 1, copy, size, MS_ERR_CORRUPT, "not a valid zlib stream");
    expect_refused(p, 1, (const uint8_t *)"not zlib at all", 15, MS_ERR_CORRUPT,
                   "not a valid zlib stream");

    /* The raw blob. */
    uint8_t *raw;
    size_t raw_size;
    assert_int_equal(ms_subtree_encode(f->a, 1, 1, &raw, &raw_size, &err), MS_OK);
    uint8_t *bad = malloc(raw_size + 8);
#define FRESH() memcpy(bad, raw, raw_size)
    FRESH();
    bad[raw_size - 1] ^= 1;
    expect_raw_refused(p, 1, bad, raw_size, false, MS_ERR_CORRUPT, "checksum mismatch");
    FRESH();
    expect_raw_refused(p, 1, bad, raw_size - 4, true, MS_ERR_FORMAT, "zlib stream ends before");
    FRESH();
    memset(bad + raw_size, 0, 4);
    expect_raw_refused(p, 1, bad, raw_size + 4, true, MS_ERR_FORMAT, "inflates to more than");
    FRESH();
    bad[0] = 'X';
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "bad magic");
    FRESH();
    bad[4] = 2;
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_UNSUPPORTED, "subtree version 2");
    FRESH();
    bad[6] = 2;
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT,
                       "subtree of depth 2 in an archive of depth 1");
    FRESH();
    put32(bad + 8, 65);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "the blob is subtree 65");
    /* Subtree 1's bytes offered as 65: its header says 1. */
    expect_refused(p, 65, good, size, MS_ERR_FORMAT, "subtree 65: the blob is subtree 1");
    /* Huge declared counts: refused before anything is allocated. */
    FRESH();
    put32(bad + 12, 1u << 24);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "members outside 1..64");
    FRESH();
    put32(bad + 12, 0);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "members outside");
    FRESH();
    put32(bad + 16, 0xFFFFFFFFu);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "table words, at most");
    /* Ids. */
    FRESH();
    put32(bad + 24, 2);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "ascending order");
    FRESH();
    put32(bad + 24 + 4 * 5, get32(bad + 24 + 4 * 4));
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "ascending order");
    FRESH();
    put32(bad + 24 + 4 * 63, MS_TEST_ARCHIVE_CELLS + 5);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "member cell 134 of 129");
    /* A non-member: the last member renamed into subtree 65's range. */
    FRESH();
    put32(bad + 24 + 4 * 63, 100);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "not in its first group");
    uint8_t *records = bad + 24 + 4 * 64;
    /* A record naming another parent. */
    FRESH();
    put32(records + 80 * 3, 2);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "not a sibling of cell 1");
    /* Tables that do not follow each other. */
    FRESH();
    put32(records + 80 * 10 + 68, get32(records + 80 * 10 + 68) + 1);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "tables out of order");
    /* Table out of range: the last cell's tables past the t words. */
    FRESH();
    put32(bad + 16, get32(bad + 16) - 1);
    expect_raw_refused(p, 1, bad, raw_size - 4, true, MS_ERR_FORMAT, "tables outside the table area");
    /* A prefix table that does not end at the payload length. */
    FRESH();
    uint8_t *tables = records + 80 * 64;
    put32(tables, 0xFFFFFF);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "geometry prefix table");
    /* A payload outside the payload area. */
    FRESH();
    put32(records + 80 * 7 + 36, 0x7FFFFFFF);
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "payload outside the payload area");
    /* Reserved bytes. */
    FRESH();
    records[80 * 2 + 75] = 1;
    expect_raw_refused(p, 1, bad, raw_size, true, MS_ERR_FORMAT, "reserved bytes are not zero");
    free(raw);

    /* Subtree 65 before 1, whose cell 5 is its parent. */
    size_t size65;
    const uint8_t *s65 = ms_archive_subtree(f->a, 65, &size65);
    expect_refused(p, 65, s65, size65, MS_ERR_RANGE, "not the children of a held cell");
    assert_int_equal(ms_archive_subtrees_held(p), 1);
    /* After all that, the true bytes are taken. */
    assert_int_equal(ms_archive_add_subtree(p, 1, good, size, &err), MS_OK);
    assert_int_equal(ms_archive_add_subtree(p, 65, s65, size65, &err), MS_OK);
    for (uint32_t c = 0; c < MS_TEST_ARCHIVE_CELLS; ++c)
        assert_same_cell(f->a, p, c);
    free(copy);
    free(bad);
    ms_archive_close(p);
#undef FRESH
}

/* A head that lies. */
static void test_hostile_head(void **state)
{
    fixture *f = *state;
    size_t head_size;
    const uint8_t *head = ms_archive_index_head(f->a, &head_size);
    uint8_t *bad = malloc(head_size + 1);
    ms_archive *p = (ms_archive *)1;
    ms_error err;
    struct {
        size_t size;
        int at;
        uint8_t value;
        bool seal;
        ms_status code;
        const char *text;
    } cases[] = {
        {100, -1, 0, false, MS_ERR_FORMAT, "too short"},
        {0, -1, 0, false, MS_ERR_FORMAT, "head is"}, /* size - 1 */
        {1, -1, 0, false, MS_ERR_FORMAT, "head is"}, /* size + 1 */
        {2, 8, 1, true, MS_ERR_UNSUPPORTED, "index head version 5"}, /* 4 ^ 1 */
        {2, 100, 1, false, MS_ERR_CORRUPT, "header checksum mismatch"},
        {2, 121, 8, true, MS_ERR_RANGE, "subtree depth 9"},
        {2, 121, 3, true, MS_ERR_FORMAT, "depth 1 in an archive of depth 2"},
        {2, 120, 3, true, MS_ERR_FORMAT, "index encoding 1"},
        {2, 122, 1, true, MS_ERR_RANGE, "smoothing 1 rounds below 0 bits"}, /* rounds without a precision */
        {2, 118, 1, true, MS_ERR_RANGE, "subtrees outside"},
        {2, 140, 0x33, false, MS_ERR_CORRUPT, "head: subtree 0"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        memcpy(bad, head, head_size);
        size_t size = cases[i].size == 0 ? head_size - 1
                      : cases[i].size == 1 ? head_size + 1
                      : cases[i].size == 2 ? head_size
                                           : cases[i].size;
        bad[head_size] = 0;
        if (cases[i].at >= 0)
            bad[cases[i].at] ^= cases[i].value;
        if (cases[i].seal)
            put32(bad + 124, (uint32_t)crc32(0, bad, 124));
        ms_status st = ms_archive_open_head(bad, size, "head", &p, &err);
        if (st == MS_OK)
            fail_msg("case %zu accepted", i);
        assert_null(p);
        if (cases[i].code == MS_ERR_CORRUPT && cases[i].at == 140)
            assert_true(st == MS_ERR_CORRUPT || st == MS_ERR_FORMAT);
        else if (st != cases[i].code)
            fail_msg("case %zu: status %d, expected %d ('%s')", i, (int)st, (int)cases[i].code,
                     err.text);
        if (!strstr(err.text, cases[i].text))
            fail_msg("case %zu: error '%s' does not say '%s'", i, err.text, cases[i].text);
        assert_null(strchr(err.text, '\n'));
    }
    free(bad);
}

/* A file and the archive opened from its index blob: the same records, and the
 * same subtrees and head (the blob's deflated on request, the file's stored);
 * then the file's layout byte by byte. */
static void test_file_and_blob_agree(void **state)
{
    fixture *f = *state;
    size_t s3, s2;
    const uint8_t *blob3 = ms_archive_index_bytes(f->a, &s3);
    ms_archive *b;
    ms_error err;
    if (ms_archive_open_index(blob3, s3, "blob", &b, &err) != MS_OK)
        fail_msg("%s", err.text);
    const ms_archive_header *h3 = ms_archive_get_header(f->a), *h2 = ms_archive_get_header(b);
    assert_int_equal(h3->version, MS_ARCHIVE_VERSION);
    assert_int_equal(h2->version, MS_ARCHIVE_BLOB_VERSION);
    const uint8_t *blob2 = ms_archive_index_bytes(b, &s2);
    assert_int_equal(s3, s2);
    assert_memory_equal(blob3, blob2, s3);
    for (uint32_t c = 0; c < MS_TEST_ARCHIVE_CELLS; ++c) {
        assert_memory_equal(ms_archive_get_cell(f->a, c), ms_archive_get_cell(b, c),
                            sizeof(ms_archive_cell));
        assert_int_equal(ms_archive_verify_payload(f->a, c, NULL), MS_OK);
    }
    static const uint32_t ids[3] = {0, 1, 65};
    for (int i = 0; i < 3; ++i) {
        const uint8_t *p3 = ms_archive_subtree(f->a, ids[i], &s3);
        const uint8_t *p2 = ms_archive_subtree(b, ids[i], &s2);
        assert_int_equal(s3, s2);
        assert_memory_equal(p3, p2, s3);
    }
    const uint8_t *head3 = ms_archive_index_head(f->a, &s3), *head2 = ms_archive_index_head(b, &s2);
    assert_int_equal(s3, s2);
    assert_memory_equal(head3, head2, s3);
    /* The file: header, directory (3 entries of 12 bytes and a CRC), the
     * subtrees in ascending id, payloads. */
    size_t size;
    uint8_t *file = ms_test_read_file(f->path, &size);
    assert_int_equal(get32(file + 8), MS_ARCHIVE_VERSION);
    assert_int_equal(file[120], MS_ARCHIVE_INDEX_SUBTREES);
    assert_int_equal(file[121], 1);
    assert_int_equal(get32(file + 116), 3);
    uint32_t stored = get32(file + 112);
    assert_int_equal(h3->index_stored_size, stored);
    assert_int_equal(size, 128 + (size_t)stored + get32(file + 88));
    const uint8_t *dir = file + 128;
    assert_int_equal(get32(dir + 36), (uint32_t)crc32(0, dir, 36));
    uint32_t offset = 0;
    for (int i = 0; i < 3; ++i) {
        assert_int_equal(get32(dir + 12 * i), ids[i]);
        assert_int_equal(get32(dir + 12 * i + 4), offset);
        const uint8_t *p3 = ms_archive_subtree(f->a, ids[i], &s3);
        assert_int_equal(get32(dir + 12 * i + 8), s3);
        assert_memory_equal(file + 128 + 40 + offset, p3, s3);
        offset += (uint32_t)s3;
    }
    assert_int_equal(40 + offset, stored);
    free(file);
    ms_archive_close(b);
}

/* Writes the image and expects ms_archive_open to fail naming it and saying text. */
static void expect_file_fails(const fixture *f, const uint8_t *image, size_t size, ms_status code,
                              const char *text)
{
    char bad[700];
    snprintf(bad, sizeof bad, "%s/bad.msa", f->dir);
    ms_test_write_file(bad, image, size);
    ms_archive *a = (ms_archive *)1;
    ms_error err;
    ms_status st = ms_archive_open(bad, &a, &err);
    if (st == MS_OK)
        fail_msg("archive accepted; expected '%s'", text);
    assert_null(a);
    if (st != code)
        fail_msg("status %d, expected %d ('%s')", (int)st, (int)code, err.text);
    if (!strstr(err.text, text) || !strstr(err.text, bad))
        fail_msg("error '%s' does not say '%s' and name the file", err.text, text);
    assert_null(strchr(err.text, '\n'));
}

/* A version-3 file whose directory or subtrees lie. */
static void test_version_3_lies(void **state)
{
    fixture *f = *state;
    size_t size;
    uint8_t *file = ms_test_read_file(f->path, &size), *bad = malloc(size + 64);
    uint8_t *dir = bad + 128;
#define FRESH() memcpy(bad, file, size)
#define SEAL_DIR() put32(dir + 36, (uint32_t)crc32(0, dir, 36))
    FRESH();
    dir[5] ^= 1;
    expect_file_fails(f, bad, size, MS_ERR_CORRUPT, "subtree directory checksum mismatch");
    FRESH();
    put32(dir + 12, 2); /* second id */
    SEAL_DIR();
    expect_file_fails(f, bad, size, MS_ERR_FORMAT, "subtree 2: the blob is subtree 1");
    FRESH();
    put32(dir + 24, 1); /* third id below the second */
    SEAL_DIR();
    expect_file_fails(f, bad, size, MS_ERR_FORMAT, "id 1 out of order");
    FRESH();
    put32(dir + 16, get32(dir + 16) + 1); /* second offset */
    SEAL_DIR();
    expect_file_fails(f, bad, size, MS_ERR_FORMAT, "outside the index");
    FRESH();
    put32(dir + 32, get32(dir + 32) - 1); /* last length short */
    SEAL_DIR();
    expect_file_fails(f, bad, size, MS_ERR_FORMAT, "the subtrees fill");
    FRESH();
    put32(bad + 116, 2); /* two subtrees said: the directory shifts */
    ms_test_archive_seal(bad);
    expect_file_fails(f, bad, size, MS_ERR_CORRUPT, "subtree directory checksum mismatch");
    FRESH();
    put32(bad + 116, 1u << 23);
    ms_test_archive_seal(bad);
    expect_file_fails(f, bad, size, MS_ERR_RANGE, "subtrees outside 1..129");
    FRESH();
    bad[121] = 2; /* S = 2: the root subtree blob says 1 */
    ms_test_archive_seal(bad);
    expect_file_fails(f, bad, size, MS_ERR_FORMAT, "subtree 0: subtree of depth 1");
    FRESH();
    bad[122] = 1; /* smoothing rounds without a precision */
    ms_test_archive_seal(bad);
    expect_file_fails(f, bad, size, MS_ERR_RANGE, "smoothing 1 rounds below 0 bits");
    FRESH();
    bad[128 + 40 + 5] ^= 0x40; /* inside the root subtree's stream */
    ms_status st;
    {
        char path[700];
        snprintf(path, sizeof path, "%s/bad.msa", f->dir);
        ms_test_write_file(path, bad, size);
        ms_archive *a = (ms_archive *)1;
        ms_error err;
        st = ms_archive_open(path, &a, &err);
        assert_true(st == MS_ERR_CORRUPT || st == MS_ERR_FORMAT);
        assert_non_null(strstr(err.text, "subtree 0"));
    }
    /* Subtree 65 left out of the directory and the file: its cells are in no
     * subtree. */
    {
        uint32_t stored = get32(file + 112), len65 = get32(file + 128 + 32);
        size_t payload = size - 128 - stored, kept = stored - 40 - len65;
        uint8_t *cut = malloc(size);
        memcpy(cut, file, 128);
        memcpy(cut + 128, file + 128, 24);
        put32(cut + 128 + 24, (uint32_t)crc32(0, cut + 128, 24));
        memcpy(cut + 128 + 28, file + 128 + 40, kept);
        memcpy(cut + 128 + 28 + kept, file + 128 + stored, payload);
        size_t cut_size = 128 + 28 + kept + payload;
        put32(cut + 112, (uint32_t)(28 + kept));
        put32(cut + 116, 2);
        le_put64(cut + 96, cut_size);
        ms_test_archive_seal(cut);
        expect_file_fails(f, cut, cut_size, MS_ERR_FORMAT, "cell 65 is in no subtree");
        free(cut);
    }
#undef FRESH
#undef SEAL_DIR
    free(bad);
    free(file);
}

/* meshbake's --subtree-levels changes only how the index is cut: the bunny
 * at S = 1 (the default) and S = 2 has the same records, payloads, index blob
 * and content id (as the server's registry computes it); each round-trips its
 * subtrees, and the archive opened from the blob gives the default's head. */
static void test_meshbake_subtree_levels(void **state)
{
    fixture *f = *state;
    char input[512], bin[512], cmd[8192], out[4096];
    ms_test_model_path(input, sizeof input, "glmark2_bunny.obj.gz");
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s %s -o %s --name b3 --threads 2 >/dev/null && "
             "%s %s -o %s --name b3s2 --subtree-levels 2 --threads 2 >/dev/null",
             bin, input, f->dir, bin, input, f->dir);
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("%s", out);
    snprintf(cmd, sizeof cmd, "%s %s -o %s --subtree-levels 9", bin, input, f->dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--subtree-levels wants an integer in [1, 8]"));

    ms_registry *r;
    ms_error err;
    if (ms_registry_scan(f->dir, NULL, 16, &r, NULL, NULL, &err) != MS_OK)
        fail_msg("%s", err.text);
    ms_model *m3 = ms_registry_find(r, "b3"), *m2 = ms_registry_find(r, "b3s2");
    assert_non_null(m3);
    assert_non_null(m2);
    assert_int_equal(ms_archive_get_header(m3->archive)->version, MS_ARCHIVE_VERSION);
    assert_int_equal(ms_archive_subtree_levels(m3->archive), 1);
    assert_int_equal(ms_archive_subtree_levels(m2->archive), 2);
    assert_true(m3->content_id == m2->content_id);
    assert_int_equal(m3->index_crc32, m2->index_crc32);
    size_t s3, s2;
    const uint8_t *b3 = ms_archive_index_bytes(m3->archive, &s3);
    const uint8_t *b2 = ms_archive_index_bytes(m2->archive, &s2);
    assert_int_equal(s3, s2);
    assert_memory_equal(b3, b2, s3);
    size_t blob_size = s3;
    uint32_t cells = ms_archive_get_header(m3->archive)->cell_count;
    for (uint32_t c = 0; c < cells; ++c) {
        const uint8_t *p3 = ms_archive_geometry(m3->archive, c, &s3);
        const uint8_t *p2 = ms_archive_geometry(m2->archive, c, &s2);
        assert_int_equal(s3, s2);
        if (s3)
            assert_memory_equal(p3, p2, s3);
        p3 = ms_archive_apo(m3->archive, c, &s3);
        p2 = ms_archive_apo(m2->archive, c, &s2);
        assert_int_equal(s3, s2);
        if (s3)
            assert_memory_equal(p3, p2, s3);
    }
    ms_archive *from_blob;
    if (ms_archive_open_index(b3, blob_size, "b3", &from_blob, &err) != MS_OK)
        fail_msg("%s", err.text);
    const uint8_t *h3 = ms_archive_index_head(m3->archive, &s3);
    const uint8_t *h2 = ms_archive_index_head(from_blob, &s2);
    assert_int_equal(s3, s2);
    assert_memory_equal(h3, h2, s3);
    ms_archive_close(from_blob);
    check_round_trip(m3->archive, 1, ms_archive_subtree_count(m3->archive));
    check_round_trip(m2->archive, 2, ms_archive_subtree_count(m2->archive));
    ms_registry_free(r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_synthetic_round_trip, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_deep_round_trip, setup_deep, teardown),
        cmocka_unit_test_setup_teardown(test_server_side, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_concurrent_requests, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_drop, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_hostile, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_hostile_head, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_file_and_blob_agree, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_version_3_lies, setup_synthetic, teardown),
        cmocka_unit_test_setup_teardown(test_dragon_round_trip, setup_dragon, teardown),
        cmocka_unit_test_setup_teardown(test_meshbake_subtree_levels, setup_synthetic, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
