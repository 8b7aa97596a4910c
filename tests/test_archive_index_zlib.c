/* Archive format version 2: the index stored as one zlib stream. What the
 * writer stores, that version 1 is still read (a fixture written by the
 * version-1 writer), that the index blob does not depend on the version, and
 * that every way a stored index can lie ends in its own one-line error. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_test.h"
#include "ms_test_archive.h"

#define CELLS MS_TEST_ARCHIVE_CELLS
/* ms_test_write_archive(path, 0) as the version-1 writer (commit 919e13d)
 * wrote it: 47,264 bytes, gzip'd. */
#define V1_FIXTURE "tests/data/archive-v1-synthetic.msa.gz"
#define V1_FIXTURE_SIZE 47264u

typedef struct fixture {
    char dir[512];
    char v2[600];  /* written by this build's writer */
    char v1[600];  /* the fixture, gunzipped */
    char bad[600]; /* scratch */
    uint8_t *file; /* the version-2 file */
    size_t size;
    uint8_t *raw; /* its raw index */
    size_t raw_size;
} fixture;

static uint64_t get_le(const uint8_t *p, int bytes)
{
    uint64_t v = 0;
    for (int i = 0; i < bytes; ++i)
        v |= (uint64_t)p[i] << (8 * i);
    return v;
}

static void put_le(uint8_t *p, uint64_t v, int bytes)
{
    for (int i = 0; i < bytes; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint8_t *read_gz(const char *path, size_t *size)
{
    gzFile gz = gzopen(path, "rb");
    if (!gz)
        fail_msg("cannot open %s (tests run from the repository root)", path);
    size_t cap = 1 << 16, n = 0;
    uint8_t *buf = malloc(cap);
    assert_non_null(buf);
    for (;;) {
        if (n == cap) {
            buf = realloc(buf, cap *= 2);
            assert_non_null(buf);
        }
        int got = gzread(gz, buf + n, (unsigned)(cap - n));
        assert_true(got >= 0);
        if (got == 0)
            break;
        n += (size_t)got;
    }
    gzclose(gz);
    *size = n;
    return buf;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->v2, sizeof f->v2, "%s/v2.msa", f->dir);
    snprintf(f->v1, sizeof f->v1, "%s/v1.msa", f->dir);
    snprintf(f->bad, sizeof f->bad, "%s/bad.msa", f->dir);
    ms_test_write_archive_version(f->v2, 0, MS_ARCHIVE_VERSION_ZLIB_INDEX);
    f->file = ms_test_read_file(f->v2, &f->size);
    f->raw = ms_test_archive_raw_index(f->file, f->size, &f->raw_size);
    size_t v1_size;
    uint8_t *v1 = read_gz(V1_FIXTURE, &v1_size);
    assert_int_equal(v1_size, V1_FIXTURE_SIZE);
    ms_test_write_file(f->v1, v1, v1_size);
    free(v1);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f->raw);
    free(f->file);
    free(f);
    return 0;
}

/* Writes an image to the scratch path and checks that opening it fails with
 * exactly `code`, an error naming the file and saying `text`. */
static void expect_image_fails(const fixture *f, const uint8_t *image, size_t size, ms_status code,
                               const char *text)
{
    ms_test_write_file(f->bad, image, size);
    ms_archive *a = (ms_archive *)1;
    ms_error err;
    ms_status st = ms_archive_open(f->bad, &a, &err);
    if (st == MS_OK)
        fail_msg("archive accepted; expected '%s'", text);
    assert_null(a);
    if (st != code)
        fail_msg("status %d, expected %d ('%s')", (int)st, (int)code, err.text);
    if (!strstr(err.text, text))
        fail_msg("error '%s' does not say '%s'", err.text, text);
    assert_non_null(strstr(err.text, f->bad));
    assert_null(strchr(err.text, '\n'));
}

/* Composes an image with `stored` as the stored index and checks the error. */
static void expect_stored_fails(const fixture *f, const uint8_t *stored, size_t stored_size,
                                uint64_t raw_size, uint32_t crc, ms_status code, const char *text)
{
    size_t size;
    uint8_t *image = ms_test_archive_compose(f->file, f->size, stored, stored_size, raw_size, crc,
                                             &size);
    expect_image_fails(f, image, size, code, text);
    free(image);
}

static void test_writer_stores_zlib_index(void **state)
{
    fixture *f = *state;
    const uint8_t *p = f->file;
    uint64_t raw = get_le(p + 80, 8), payload = get_le(p + 88, 8), stored = get_le(p + 112, 8);
    uint32_t table_words = (uint32_t)get_le(p + 72, 4);
    assert_int_equal(get_le(p + 8, 4), 2);
    assert_int_equal(p[120], 1); /* zlib */
    assert_int_equal(get_le(p + 121, 3), 0);
    assert_int_equal(raw, CELLS * 80u + 4u * table_words);
    assert_int_equal(raw, 14964); /* as in the version-1 fixture */
    assert_int_equal(raw, f->raw_size);
    assert_int_equal(get_le(p + 96, 8), f->size);
    assert_int_equal(f->size, 128 + stored + payload);
    assert_true(stored < raw / 3);
    /* An RFC 1950 header announcing the best compression (level 9). */
    assert_int_equal(p[128], 0x78);
    assert_int_equal(p[129], 0xDA);
    /* The index CRC is that of the raw index. */
    assert_int_equal(get_le(p + 108, 4), (uint32_t)crc32_z(0L, f->raw, f->raw_size));

    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->v2, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    assert_int_equal(h->version, 2);
    assert_int_equal(h->index_stored_size, stored);
    assert_int_equal(h->file_size, f->size);
    /* Offsets count from the end of the stored index. */
    for (uint32_t id = 0; id < CELLS; ++id) {
        const ms_archive_cell *c = ms_archive_get_cell(a, id);
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, id, &len);
        assert_non_null(g);
        assert_int_equal(len, ms_test_archive_geometry_length(id));
        assert_memory_equal(g, p + 128 + stored + c->geometry_offset, len);
        assert_int_equal(ms_archive_verify_payload(a, id, &err), MS_OK);
    }
    /* The blob: a version-1 header and the raw index. */
    size_t blob_size;
    const uint8_t *blob = ms_archive_index_bytes(a, &blob_size);
    assert_int_equal(blob_size, 128 + raw);
    assert_int_equal(get_le(blob + 8, 4), 1);
    assert_int_equal(get_le(blob + 96, 8), 128 + raw + payload);
    assert_memory_equal(blob + 128, f->raw, raw);
    ms_archive *idx;
    assert_int_equal(ms_archive_open_index(blob, blob_size, "net:v2", &idx, &err), MS_OK);
    assert_int_equal(ms_archive_get_header(idx)->version, 1);
    assert_int_equal(ms_archive_get_header(idx)->cell_count, CELLS);
    ms_archive_close(idx);
    /* A version-2 file is not a blob. */
    idx = (ms_archive *)1;
    assert_int_equal(ms_archive_open_index(p, 128 + stored, "net:v2", &idx, &err),
                     MS_ERR_UNSUPPORTED);
    assert_string_equal(err.text, "net:v2: index blob version 2, this build reads version 1");
    assert_null(idx);
    ms_archive_close(a);

    /* Deterministic: the same input writes the same bytes. */
    char again[700];
    snprintf(again, sizeof again, "%s/again.msa", f->dir);
    ms_test_write_archive_version(again, 0, MS_ARCHIVE_VERSION_ZLIB_INDEX);
    size_t again_size;
    uint8_t *again_data = ms_test_read_file(again, &again_size);
    assert_int_equal(again_size, f->size);
    assert_memory_equal(again_data, f->file, f->size);
    free(again_data);
}

/* The fixture was written by the version-1 writer from the same input as the
 * version-2 file: same records, same payloads, same index blob. */
static void test_version_1_still_read(void **state)
{
    fixture *f = *state;
    ms_archive *v1, *v2;
    ms_error err;
    assert_int_equal(ms_archive_open(f->v1, &v1, &err), MS_OK);
    assert_int_equal(ms_archive_open(f->v2, &v2, &err), MS_OK);
    const ms_archive_header *h1 = ms_archive_get_header(v1), *h2 = ms_archive_get_header(v2);
    assert_int_equal(h1->version, 1);
    assert_int_equal(h1->index_stored_size, f->raw_size);
    assert_int_equal(h1->file_size, V1_FIXTURE_SIZE);
    assert_int_equal(V1_FIXTURE_SIZE - f->size, f->raw_size - h2->index_stored_size);
    assert_int_equal(h1->cell_count, h2->cell_count);
    assert_int_equal(h1->table_words, h2->table_words);
    assert_true(h1->box_origin[2] == 1e7 && h1->box_side == 0.25);
    for (uint32_t id = 0; id < CELLS; ++id) {
        assert_memory_equal(ms_archive_get_cell(v1, id), ms_archive_get_cell(v2, id),
                            sizeof(ms_archive_cell));
        size_t l1, l2;
        const uint8_t *g1 = ms_archive_geometry(v1, id, &l1);
        const uint8_t *g2 = ms_archive_geometry(v2, id, &l2);
        assert_int_equal(l1, l2);
        assert_memory_equal(g1, g2, l1);
        g1 = ms_archive_apo(v1, id, &l1), g2 = ms_archive_apo(v2, id, &l2);
        assert_int_equal(l1, l2);
        if (l1)
            assert_memory_equal(g1, g2, l1);
        assert_int_equal(ms_archive_verify_payload(v1, id, &err), MS_OK);
        assert_int_equal(ms_archive_geometry_prefix(v1, id, 10),
                         ms_archive_geometry_prefix(v2, id, 10));
    }
    /* The blob is the version-1 file's first bytes, and the same for both. */
    size_t s1, s2, v1_size;
    const uint8_t *b1 = ms_archive_index_bytes(v1, &s1), *b2 = ms_archive_index_bytes(v2, &s2);
    uint8_t *v1_file = ms_test_read_file(f->v1, &v1_size);
    assert_int_equal(s1, 128 + f->raw_size);
    assert_int_equal(s2, s1);
    assert_memory_equal(b1, v1_file, s1);
    assert_memory_equal(b2, v1_file, s1);
    ms_archive_close(v1);
    ms_archive_close(v2);

    /* Version 1's own checks are unchanged. */
    v1_file[128 + 5 * 80 + 24] ^= 1;
    expect_image_fails(f, v1_file, v1_size, MS_ERR_CORRUPT, "index checksum mismatch");
    v1_file[128 + 5 * 80 + 24] ^= 1;
    v1_file[112] = 1; /* reserved in version 1 (the stored size in version 2) */
    ms_test_archive_seal(v1_file);
    expect_image_fails(f, v1_file, v1_size, MS_ERR_FORMAT, "reserved bytes");
    v1_file[112] = 0;
    ms_test_archive_seal(v1_file);
    expect_image_fails(f, v1_file, v1_size - 1, MS_ERR_FORMAT, "truncated?");
    free(v1_file);
}

static void test_header_lies(void **state)
{
    fixture *f = *state;
    uint8_t *d = malloc(f->size);
    memcpy(d, f->file, f->size);
    uint64_t stored = get_le(d + 112, 8);

    /* Header CRC: any header byte changed without it, the stored size included. */
    d[112] ^= 1;
    expect_image_fails(f, d, f->size, MS_ERR_CORRUPT, "header checksum mismatch");
    d[112] ^= 1;
    d[100] ^= 0x40;
    expect_image_fails(f, d, f->size, MS_ERR_CORRUPT, "header checksum mismatch");
    d[100] ^= 0x40;

    /* Compressed size past the end of the file. */
    put_le(d + 112, f->size - 127, 8);
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "runs past the end of the");
    put_le(d + 112, UINT64_MAX, 8);
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "runs past the end of the");
    /* ... or inside it but leaving the sections inconsistent. */
    put_le(d + 112, stored + 1, 8);
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "section sizes do not add up");
    put_le(d + 112, stored, 8);

    /* Raw size inconsistent with the cell count and table words. */
    put_le(d + 80, f->raw_size + 4, 8);
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT,
                       "index size 14968, expected 14964 (129 cells, 1161 table words)");
    put_le(d + 80, f->raw_size, 8);
    put_le(d + 72, get_le(d + 72, 4) + 1, 4); /* table words */
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT,
                       "index size 14964, expected 14968 (129 cells, 1162 table words)");
    put_le(d + 72, get_le(d + 72, 4) - 1, 4);
    put_le(d + 52, CELLS - 1, 4); /* cells */
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT,
                       "index size 14964, expected 14884 (128 cells, 1161 table words)");
    put_le(d + 52, CELLS, 4);
    /* A raw size over the cap is out of range before any size is believed. */
    put_le(d + 52, MS_ARCHIVE_MAX_CELLS + 1, 4);
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_RANGE, "cells outside");
    put_le(d + 52, CELLS, 4);

    /* The encoding byte and the reserved bytes after it. */
    d[120] = 0;
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "index encoding 0, version 2 stores zlib (1)");
    d[120] = 2;
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "index encoding 2");
    d[120] = 1;
    d[122] = 1;
    ms_test_archive_seal(d);
    expect_image_fails(f, d, f->size, MS_ERR_FORMAT, "reserved bytes");
    d[122] = 0;
    ms_test_archive_seal(d);
    assert_memory_equal(d, f->file, f->size);
    free(d);

    /* A stored index too short to inflate to the raw size, whatever it holds:
     * refused before the raw size is allocated. */
    static const uint8_t tiny[8] = {0x78, 0xDA, 0, 0, 0, 0, 0, 0};
    expect_stored_fails(f, tiny, sizeof tiny, f->raw_size, 0, MS_ERR_FORMAT,
                        "a compressed index of 8 bytes cannot inflate to 14964");
    expect_stored_fails(f, tiny, 0, f->raw_size, 0, MS_ERR_FORMAT,
                        "a compressed index of 0 bytes cannot inflate to 14964");
}

static void test_stream_lies(void **state)
{
    fixture *f = *state;
    uint32_t crc = (uint32_t)crc32_z(0L, f->raw, f->raw_size);
    size_t z_size;
    uint8_t *z = ms_test_zlib(f->raw, f->raw_size, &z_size);
    uint8_t *buf = malloc(z_size + 64);
    char text[128];

    /* The reference: this stored index, composed again, is accepted. */
    size_t size;
    uint8_t *image = ms_test_archive_compose(f->file, f->size, z, z_size, f->raw_size, crc, &size);
    ms_test_write_file(f->bad, image, size);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->bad, &a, &err), MS_OK);
    ms_archive_close(a);
    free(image);

    /* Not zlib: a bad stream header, a bad Adler-32 trailer. */
    memcpy(buf, z, z_size);
    buf[0] = 0x79;
    expect_stored_fails(f, buf, z_size, f->raw_size, crc, MS_ERR_CORRUPT,
                        "index is not a valid zlib stream: incorrect header check");
    buf[0] = z[0];
    uint8_t flg = 0xE0; /* level 9, FDICT set; FCHECK makes the header valid */
    flg = (uint8_t)(flg + (31 - (0x78u * 256 + flg) % 31) % 31);
    buf[1] = flg;
    expect_stored_fails(f, buf, z_size, f->raw_size, crc, MS_ERR_CORRUPT,
                        "index is not a valid zlib stream: it needs a preset dictionary");
    buf[1] = z[1];
    buf[z_size - 1] ^= 1;
    expect_stored_fails(f, buf, z_size, f->raw_size, crc, MS_ERR_CORRUPT,
                        "index is not a valid zlib stream: incorrect data check");

    /* Inflates short: a complete stream of 80 bytes fewer. */
    size_t short_size;
    uint8_t *short_z = ms_test_zlib(f->raw, f->raw_size - 80, &short_size);
    snprintf(text, sizeof text, "index inflates to %zu bytes, the header says %zu",
             f->raw_size - 80, f->raw_size);
    expect_stored_fails(f, short_z, short_size, f->raw_size, crc, MS_ERR_FORMAT, text);
    free(short_z);

    /* Inflates long: a complete stream of 80 bytes more. */
    uint8_t *longer = calloc(f->raw_size + 80, 1);
    memcpy(longer, f->raw, f->raw_size);
    size_t long_size;
    uint8_t *long_z = ms_test_zlib(longer, f->raw_size + 80, &long_size);
    snprintf(text, sizeof text, "index inflates to more than the %zu bytes the header says",
             f->raw_size);
    expect_stored_fails(f, long_z, long_size, f->raw_size, crc, MS_ERR_FORMAT, text);
    free(long_z);
    free(longer);

    /* Trailing bytes after the stream's end. */
    memcpy(buf, z, z_size);
    memset(buf + z_size, 0, 3);
    expect_stored_fails(f, buf, z_size + 3, f->raw_size, crc, MS_ERR_FORMAT,
                        "3 bytes follow the end of the index's zlib stream");
    /* Cut short: the stream without its last 2 bytes (all the data, half its
     * trailer), and without half its bytes. */
    snprintf(text, sizeof text, "index's zlib stream is cut short (%zu of %zu bytes inflated)",
             f->raw_size, f->raw_size);
    expect_stored_fails(f, z, z_size - 2, f->raw_size, crc, MS_ERR_FORMAT, text);
    expect_stored_fails(f, z, z_size / 2, f->raw_size, crc, MS_ERR_FORMAT,
                        "index's zlib stream is cut short");

    /* The CRC covers the raw index: a wrong CRC, and a changed index stored as
     * a valid stream under the old CRC. */
    expect_stored_fails(f, z, z_size, f->raw_size, crc ^ 1, MS_ERR_CORRUPT,
                        "index checksum mismatch");
    uint8_t *changed = malloc(f->raw_size);
    memcpy(changed, f->raw, f->raw_size);
    changed[7 * 80 + 24] ^= 1; /* cell 7's vertex count */
    size_t changed_size;
    uint8_t *changed_z = ms_test_zlib(changed, f->raw_size, &changed_size);
    expect_stored_fails(f, changed_z, changed_size, f->raw_size, crc, MS_ERR_CORRUPT,
                        "index checksum mismatch");
    free(changed_z);
    free(changed);

    /* Single-bit changes of the stored stream, without a crash or a leak: each
     * is refused (by zlib, the sizes or a checksum), unless it hit one of
     * deflate's redundant bits (a code length of a symbol the data never uses,
     * say) and the stream still inflates to the very same index, which is then
     * what the reader holds. */
    memcpy(buf, z, z_size);
    unsigned refused = 0, harmless = 0;
    for (size_t i = 0; i < z_size; ++i) {
        for (int bit = 0; bit < 8; bit += 3) {
            buf[i] ^= (uint8_t)(1u << bit);
            size_t n;
            image = ms_test_archive_compose(f->file, f->size, buf, z_size, f->raw_size, crc, &n);
            ms_test_write_file(f->bad, image, n);
            a = (ms_archive *)1;
            ms_status st = ms_archive_open(f->bad, &a, &err);
            if (st == MS_OK) {
                size_t blob_size;
                const uint8_t *blob = ms_archive_index_bytes(a, &blob_size);
                assert_int_equal(blob_size, 128 + f->raw_size);
                if (memcmp(blob + 128, f->raw, f->raw_size) != 0)
                    fail_msg("byte %zu bit %d flipped: a different index accepted", i, bit);
                ms_archive_close(a);
                harmless++;
            } else {
                assert_null(a);
                assert_true(st == MS_ERR_CORRUPT || st == MS_ERR_FORMAT);
                refused++;
            }
            free(image);
            buf[i] ^= (uint8_t)(1u << bit);
        }
    }
    assert_true(refused > 100 * harmless);
    free(buf);
    free(z);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_writer_stores_zlib_index, setup, teardown),
        cmocka_unit_test_setup_teardown(test_version_1_still_read, setup, teardown),
        cmocka_unit_test_setup_teardown(test_header_lies, setup, teardown),
        cmocka_unit_test_setup_teardown(test_stream_lies, setup, teardown),
    };
    return cmocka_run_group_tests_name("archive_index_zlib", tests, NULL, NULL);
}
