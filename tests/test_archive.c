/* Archive container: write, read back, and reject every kind of damage. */
#include <math.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_archive_writer.h"
#include "ms_codec.h"
#include "ms_test.h"
#include "ms_test_archive.h"

#define CELLS MS_TEST_ARCHIVE_CELLS

typedef struct fixture {
    char dir[512];
    char path[600];
} fixture;


static void test_topology(uint32_t *first_child)
{
    for (uint32_t i = 0; i < CELLS; ++i)
        first_child[i] = MS_ARCHIVE_NONE;
    first_child[0] = 1;
    first_child[5] = 65;
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->path, sizeof f->path, "%s/model.msa", f->dir);
    ms_test_write_archive(f->path, 0);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static void test_roundtrip(void **state)
{
    fixture *f = *state;
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    assert_true(h->box_origin[2] == 1e7 && h->box_side == 0.25);
    assert_int_equal(h->cell_count, CELLS);
    assert_int_equal(h->bits, 12);
    assert_int_equal(h->vertex_count, 1234);
    assert_null(ms_archive_get_cell(a, CELLS));
    uint8_t expect[1024];
    for (uint32_t id = 0; id < CELLS; ++id) {
        const ms_archive_cell *c = ms_archive_get_cell(a, id);
        assert_int_equal(c->vertex_count, id * 3);
        assert_int_equal(c->triangle_count, id * 5);
        size_t len;
        const uint8_t *g = ms_archive_geometry(a, id, &len);
        assert_int_equal(len, ms_test_archive_geometry_length(id));
        ms_test_archive_fill(expect, (uint32_t)len, id);
        assert_memory_equal(g, expect, len);
        const uint8_t *apo = ms_archive_apo(a, id, &len);
        assert_int_equal(len, 40 * ms_test_archive_apo_levels(id));
        if (len) {
            ms_test_archive_fill(expect, (uint32_t)len, id + 1000);
            assert_memory_equal(apo, expect, len);
        }
        assert_int_equal(ms_archive_verify_payload(a, id, &err), MS_OK);
        /* Prefix look-ups clamp to the window and end at the payload length. */
        assert_int_equal(ms_archive_geometry_prefix(a, id, 0), 8);
        assert_int_equal(ms_archive_geometry_prefix(a, id, 99), ms_test_archive_geometry_length(id));
        uint32_t texels;
        if (ms_test_archive_apo_levels(id)) {
            assert_int_equal(ms_archive_apo_prefix(a, id, 0, &texels), 40);
            assert_int_equal(texels, 10);
            assert_int_equal(ms_archive_apo_prefix(a, id, 99, &texels), 40 * ms_test_archive_apo_levels(id));
        } else {
            assert_int_equal(ms_archive_apo_prefix(a, id, 0, &texels), 0);
            assert_int_equal(texels, 0);
        }
    }
    /* Tree and windows follow docs/ARCHIVE.md. */
    const ms_archive_cell *root = ms_archive_get_cell(a, 0), *c5 = ms_archive_get_cell(a, 5),
                          *c6 = ms_archive_get_cell(a, 6), *c70 = ms_archive_get_cell(a, 70);
    assert_int_equal(root->bits_min, 0);
    assert_int_equal(root->bits_max, 7);
    assert_int_equal(c5->bits_min, 7);
    assert_int_equal(c5->bits_max, 9);
    assert_int_equal(c6->bits_max, 12);
    assert_int_equal(c70->parent, 5);
    assert_int_equal(c70->level, 2);
    assert_int_equal(c70->bits_min, 9);
    assert_int_equal(c70->bits_max, 12);
    /* cell 5 is child 4 of the root: position (0, 1, 0); cell 70 is child 5 of it. */
    assert_int_equal(c5->position[0], 0);
    assert_int_equal(c5->position[1], 1);
    assert_int_equal(c70->position[0], 1);
    assert_int_equal(c70->position[1], 5);
    assert_int_equal(c70->position[2], 0);
    /* Payloads are placed in cell order. */
    assert_true(ms_archive_get_cell(a, 1)->geometry_offset < ms_archive_get_cell(a, 2)->geometry_offset);
    ms_archive_close(a);
}

static void expect_open_fails(const char *path, ms_status code, const char *text)
{
    ms_archive *a = (ms_archive *)1;
    ms_error err;
    ms_status st = ms_archive_open(path, &a, &err);
    if (st == MS_OK)
        fail_msg("archive accepted; expected '%s'", text ? text : "an error");
    assert_null(a);
    if (code != MS_OK)
        assert_int_equal(st, code);
    if (text && !strstr(err.text, text))
        fail_msg("error '%s' does not mention '%s'", err.text, text);
    assert_non_null(strstr(err.text, path));
}

/* The same for an index blob, opened with ms_archive_open_index. */
static void expect_blob_fails(const uint8_t *blob, size_t size, ms_status code, const char *text)
{
    ms_archive *a = (ms_archive *)1;
    ms_error err;
    ms_status st = ms_archive_open_index(blob, size, "tampered", &a, &err);
    if (st == MS_OK)
        fail_msg("blob accepted; expected '%s'", text ? text : "an error");
    assert_null(a);
    if (code != MS_OK)
        assert_int_equal(st, code);
    if (text && !strstr(err.text, text))
        fail_msg("error '%s' does not mention '%s'", err.text, text);
    assert_non_null(strstr(err.text, "tampered"));
}

static void test_every_header_byte_flip_rejected(void **state)
{
    fixture *f = *state;
    size_t size;
    uint8_t *data = ms_test_read_file(f->path, &size);
    char bad[700];
    snprintf(bad, sizeof bad, "%s/bad.msa", f->dir);
    for (size_t i = 0; i < MS_ARCHIVE_HEADER_SIZE; ++i) {
        data[i] ^= 0x10;
        ms_test_write_file(bad, data, size);
        expect_open_fails(bad, MS_OK, NULL);
        data[i] ^= 0x10;
    }
    free(data);
}

/* The archive with header bytes 122 (smoothing rounds) and 123 (below which
 * bit) set and its header CRC made right, written to DIR/smooth.msa. */
static const char *with_smoothing(const fixture *f, uint8_t rounds, uint8_t bits, char *path, size_t size)
{
    size_t n;
    uint8_t *data = ms_test_read_file(f->path, &n);
    data[122] = rounds, data[123] = bits;
    uint32_t crc = (uint32_t)crc32(0L, data, 124);
    for (int i = 0; i < 4; ++i)
        data[124 + i] = (uint8_t)(crc >> (8 * i));
    snprintf(path, size, "%s/smooth.msa", f->dir);
    ms_test_write_file(path, data, n);
    free(data);
    return path;
}

/* The smoothing fields (docs/ARCHIVE.md, header bytes 122 and 123): read as
 * written, none by default; more rounds than the codec's maximum, rounds
 * without a precision or the reverse, and a precision beyond p refused. */
static void test_smoothing_fields(void **state)
{
    fixture *f = *state;
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &a, &err), MS_OK);
    assert_int_equal(ms_archive_get_header(a)->smooth_rounds, 0);
    assert_int_equal(ms_archive_get_header(a)->smooth_bits, 0);
    ms_archive_close(a);
    char path[700];
    assert_int_equal(ms_archive_open(with_smoothing(f, 3, 10, path, sizeof path), &a, &err), MS_OK);
    assert_int_equal(ms_archive_get_header(a)->smooth_rounds, 3);
    assert_int_equal(ms_archive_get_header(a)->smooth_bits, 10);
    ms_archive_close(a);
    expect_open_fails(with_smoothing(f, MS_CODEC_SMOOTH_ROUNDS_MAX + 1, 10, path, sizeof path), MS_ERR_RANGE,
                      "smoothing 9 rounds below 10 bits");
    expect_open_fails(with_smoothing(f, 3, 0, path, sizeof path), MS_ERR_RANGE, "smoothing 3 rounds below 0");
    expect_open_fails(with_smoothing(f, 0, 5, path, sizeof path), MS_ERR_RANGE, "smoothing 0 rounds below 5");
    expect_open_fails(with_smoothing(f, 3, 13, path, sizeof path), MS_ERR_RANGE, "below 1..12");
}

static void test_index_damage_and_truncation(void **state)
{
    fixture *f = *state;
    size_t size;
    uint8_t *data = ms_test_read_file(f->path, &size);
    char bad[700];
    snprintf(bad, sizeof bad, "%s/bad.msa", f->dir);
    /* A damaged raw index under the header's CRC: the CRC catches it. */
    size_t raw_size;
    uint8_t *raw = ms_test_archive_raw_index(data, size, &raw_size);
    uint32_t crc = (uint32_t)crc32_z(0L, raw, raw_size);
    for (size_t i = 0; i < CELLS * 80; i += 97) {
        raw[i] ^= 1;
        size_t bad_size;
        uint8_t *blob = ms_test_archive_blob(data, size, raw, raw_size, crc, &bad_size);
        expect_blob_fails(blob, bad_size, MS_ERR_CORRUPT, "index checksum mismatch");
        free(blob);
        raw[i] ^= 1;
    }
    free(raw);
    const size_t cuts[] = {0, 7, 127, 128, 129, 1000, size - 1};
    for (size_t k = 0; k < sizeof cuts / sizeof *cuts; ++k) {
        ms_test_write_file(bad, data, cuts[k]);
        expect_open_fails(bad, MS_ERR_FORMAT, NULL);
    }
    ms_test_write_file(bad, (const uint8_t *)"hello", 5);
    expect_open_fails(bad, MS_ERR_FORMAT, "too short");
    /* Version from the future, and the three versions before 4 (never
     * released, no longer read): one line naming the version, before anything
     * else. */
    static const struct { uint8_t version; const char *text; } versions[] = {
        {5, "archive version 5, this build reads version 4"},
        {3, "archive version 3, this build reads version 4"},
        {2, "archive version 2, this build reads version 4"},
        {1, "archive version 1, this build reads version 4"},
    };
    for (size_t k = 0; k < sizeof versions / sizeof *versions; ++k) {
        data[8] = versions[k].version;
        ms_test_archive_seal(data);
        ms_test_write_file(bad, data, size);
        ms_archive *a = (ms_archive *)1;
        ms_error err;
        assert_int_equal(ms_archive_open(bad, &a, &err), MS_ERR_UNSUPPORTED);
        assert_null(a);
        char expected[900];
        snprintf(expected, sizeof expected, "%s: %s", bad, versions[k].text);
        assert_string_equal(err.text, expected);
    }
    free(data);
    expect_open_fails("/nonexistent/x.msa", MS_ERR_IO, "cannot open");
}

static void test_payload_damage_found_by_verify(void **state)
{
    fixture *f = *state;
    size_t size;
    uint8_t *data = ms_test_read_file(f->path, &size);
    data[size - 1] ^= 0xff; /* last byte: the last cell's payload */
    char bad[700];
    snprintf(bad, sizeof bad, "%s/bad.msa", f->dir);
    ms_test_write_file(bad, data, size);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(bad, &a, &err), MS_OK);
    assert_int_equal(ms_archive_verify_payload(a, 0, &err), MS_OK);
    ms_status st = ms_archive_verify_payload(a, CELLS - 1, &err);
    assert_int_equal(st, MS_ERR_CORRUPT);
    assert_non_null(strstr(err.text, "cell 128"));
    assert_int_equal(ms_archive_verify_payload(a, CELLS, &err), MS_ERR_RANGE);
    ms_archive_close(a);
    free(data);
}

/* Rewrites one cell record field of the raw index and opens it as an index
 * blob with valid CRCs (the checks a file's assembled index goes through), so
 * only the structural checks can catch it. */
static void tamper(const fixture *f, uint32_t cell, size_t field, uint32_t value,
                   const char *expect)
{
    size_t size, raw_size, bad_size;
    uint8_t *data = ms_test_read_file(f->path, &size);
    uint8_t *raw = ms_test_archive_raw_index(data, size, &raw_size);
    uint8_t *p = raw + (size_t)cell * 80 + field;
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(value >> (8 * i));
    uint8_t *blob = ms_test_archive_blob_with_index(data, size, raw, raw_size, &bad_size);
    expect_blob_fails(blob, bad_size, MS_ERR_FORMAT, expect);
    free(blob);
    free(raw);
    free(data);
}

static void test_structural_lies_rejected(void **state)
{
    fixture *f = *state;
    tamper(f, 0, 0, 3, "cell 0 is not a root");
    tamper(f, 7, 0, 9, "parent 9 does not precede it");
    tamper(f, 70, 0, 4, "not among the children");
    tamper(f, 5, 4, 200, "children out of range");
    tamper(f, 6, 4, 65, "precision window");         /* a leaf turned into a bogus parent */
    tamper(f, 9, 8, 0x00090703, "level 3 under a level-0 parent");
    tamper(f, 9, 12, 3, "position does not match");
    tamper(f, 9, 32, 0xfffffff0, "payload outside");
    tamper(f, 9, 64, 7, "bad APO chunk description");
    tamper(f, 9, 68, 0x0fffffff, "tables out of order");
    tamper(f, 10, 68, 0, "tables out of order");
    tamper(f, 12, 40, 5, "geometry prefix table");
}

/* The byte of c's error table at bit bits_min + k inside the raw index. */
static uint8_t *error_byte(uint8_t *raw, const ms_archive_cell *c, unsigned k)
{
    size_t window = (size_t)c->bits_max - c->bits_min + 1;
    size_t words = window + 2u * c->apo_levels + (window + 3) / 4; /* no colour */
    return raw + (size_t)CELLS * 80 + 4 * ((size_t)c->table_first + words - (window + 3) / 4) + k;
}

/* The surface error table: the writer keeps what it is given, or the
 * half-diagonal; the reader's error and need follow it; a table beyond the
 * diagonal, growing in world units, or with a byte after its last bit is
 * refused. */
static void test_surface_error_table(void **state)
{
    fixture *f = *state;
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &a, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(a);
    unsigned measured_cells = 0;
    for (uint32_t id = 0; id < CELLS; ++id) {
        const ms_archive_cell *c = ms_archive_get_cell(a, id);
        unsigned window = c->bits_max - c->bits_min + 1u;
        uint8_t want[MS_ARCHIVE_MAX_WINDOW];
        bool measured = ms_test_archive_error_table(id, window, want);
        measured_cells += measured;
        for (unsigned k = 0; k < window; ++k) {
            double half = 0.5 * sqrt(3.0) * ldexp(h->box_side, -(int)(c->bits_min + k));
            assert_int_equal(c->error[k], measured ? want[k] : 100);
            assert_float_equal(ms_archive_cell_error(h, c, c->bits_min + k),
                               (measured ? want[k] / 100.0 : 1.0) * half, 1e-12 * half);
        }
        assert_true(ms_archive_cell_error(h, c, c->bits_max + 3) == ms_archive_cell_error(h, c, c->bits_max));
        assert_true(ms_archive_cell_error(h, c, 0) == ms_archive_cell_error(h, c, c->bits_min));
    }
    assert_int_equal(measured_cells, 32);

    /* the default table (the root's) needs what the half-diagonal needs:
     * log2(sqrt(3) / 2 * side * px_per_unit / tolerance), below, inside and
     * above its window [0, 7] */
    const ms_archive_cell *root = ms_archive_get_cell(a, 0);
    const double needs[] = {-2.0, 0.0, 3.25, 7.0, 9.5};
    for (size_t i = 0; i < sizeof needs / sizeof *needs; ++i) {
        double ppu = 1.5 * exp2(needs[i]) / (0.5 * sqrt(3.0) * h->box_side);
        assert_float_equal(ms_archive_bits_needed(h, root, ppu, 1.5), needs[i], 1e-9);
    }
    assert_true(isinf(ms_archive_bits_needed(h, root, INFINITY, 1.0)));

    /* a measured leaf, window [7, 12]: geometric between two bits, doubling
     * per bit below, halving above; a bit that errs by nothing is needed whole */
    const ms_archive_cell *leaf = ms_archive_get_cell(a, 1);
    assert_true(leaf->first_child == MS_ARCHIVE_NONE && leaf->bits_min == 7 && leaf->bits_max == 12);
    double e0 = ms_archive_cell_error(h, leaf, 7), e3 = ms_archive_cell_error(h, leaf, 10),
           e4 = ms_archive_cell_error(h, leaf, 11), e5 = ms_archive_cell_error(h, leaf, 12);
    assert_true(ms_archive_cell_error(h, leaf, 9) > e3 && e3 > e4); /* this table's shape */
    assert_float_equal(ms_archive_bits_needed(h, leaf, 1.0 / sqrt(e3 * e4), 1.0), 10.5, 1e-9);
    assert_float_equal(ms_archive_bits_needed(h, leaf, 1.0 / (8 * e0), 1.0), 4.0, 1e-9);
    assert_float_equal(ms_archive_bits_needed(h, leaf, 4.0 / e5, 1.0), 14.0, 1e-9);
    ms_archive_cell exact = *leaf;
    exact.error[5] = 0;
    assert_float_equal(ms_archive_bits_needed(h, &exact, 1e9 / e5, 1.0), 12.0, 0);

    /* the reader's refusals, each with its CRCs right */
    size_t size, raw_size, blob_size;
    uint8_t *data = ms_test_read_file(f->path, &size);
    static const struct { unsigned k; uint8_t value; bool ok; } lies[] = {
        {5, 0, true},     /* exact at the last bit */
        {4, 0, false},    /* exact at a bit, then not */
        {0, 200, true},   /* the whole diagonal */
        {0, 201, false},  /* beyond it */
        {1, 255, false},  /* more than twice the bit before (57) */
        {6, 1, false},    /* a byte after the last bit's (6 bits, 8 bytes) */
        {7, 1, false},
    };
    for (size_t i = 0; i < sizeof lies / sizeof *lies; ++i) {
        uint8_t *raw = ms_test_archive_raw_index(data, size, &raw_size);
        *error_byte(raw, leaf, lies[i].k) = lies[i].value;
        uint8_t *blob = ms_test_archive_blob_with_index(data, size, raw, raw_size, &blob_size);
        if (lies[i].ok) {
            ms_archive *b;
            if (ms_archive_open_index(blob, blob_size, "tampered", &b, &err) != MS_OK)
                fail_msg("%s", err.text);
            assert_int_equal(ms_archive_get_cell(b, 1)->error[lies[i].k], lies[i].value);
            ms_archive_close(b);
        } else {
            expect_blob_fails(blob, blob_size, MS_ERR_FORMAT, "cell 1: surface error table");
        }
        free(blob);
        free(raw);
    }
    free(data);
    ms_archive_close(a);
}

static void test_writer_refuses_bad_use(void **state)
{
    fixture *f = *state;
    ms_archive_header h = ms_test_archive_header();
    uint32_t first_child[CELLS];
    test_topology(first_child);
    ms_archive_writer *w;
    ms_error err;
    char path[700];
    snprintf(path, sizeof path, "%s/w.msa", f->dir);
    /* Children not in breadth-first place. */
    first_child[5] = 66;
    assert_int_equal(ms_archive_writer_open(path, &h, first_child, &w, &err), MS_ERR_ARG);
    test_topology(first_child);
    assert_int_equal(ms_archive_writer_open(path, &h, first_child, &w, &err), MS_OK);
    uint8_t data[16] = {0};
    uint32_t table[8] = {1, 2, 3, 4, 5, 6, 7, 16};
    uint32_t shrink[8] = {5, 2, 3, 4, 5, 6, 7, 16};
    assert_int_equal(ms_archive_writer_put_geometry(w, 0, data, 16, shrink, 0, 0, &err), MS_ERR_ARG);
    assert_int_equal(ms_archive_writer_put_geometry(w, 0, data, 16, table, 0, 0, &err), MS_OK);
    assert_int_equal(ms_archive_writer_put_geometry(w, 0, data, 16, table, 0, 0, &err), MS_ERR_ARG);
    assert_int_equal(ms_archive_writer_put_geometry(w, CELLS, data, 16, table, 0, 0, &err), MS_ERR_ARG);
    /* Error tables (the root's window is 8 bits): beyond the diagonal,
     * growing, out of range, twice. */
    uint8_t over[8] = {201, 100, 50, 25, 12, 6, 3, 0}, growing[8] = {50, 101, 50, 25, 12, 6, 3, 0};
    uint8_t error[8] = {200, 100, 50, 25, 12, 6, 3, 0};
    assert_int_equal(ms_archive_writer_put_error(w, 0, over, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "cell 0: surface errors out of range or growing"));
    assert_int_equal(ms_archive_writer_put_error(w, 0, growing, &err), MS_ERR_ARG);
    assert_int_equal(ms_archive_writer_put_error(w, CELLS, error, &err), MS_ERR_ARG);
    assert_int_equal(ms_archive_writer_put_error(w, 0, error, &err), MS_OK);
    assert_int_equal(ms_archive_writer_put_error(w, 0, error, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "given twice"));
    /* Missing geometry for the other cells: finish fails and leaves nothing. */
    assert_int_equal(ms_archive_writer_finish(w, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "cell 1 has no geometry"));
    assert_int_equal(access(path, F_OK), -1);
    char partial[720];
    snprintf(partial, sizeof partial, "%s.partial", path);
    assert_int_equal(access(partial, F_OK), -1);
}

static void test_index_blob_and_payload_checks(void **state)
{
    fixture *f = *state;
    ms_archive *full, *idx;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &full, &err), MS_OK);
    size_t size;
    const uint8_t *blob = ms_archive_index_bytes(full, &size);
    assert_int_equal(ms_archive_open_index(blob, size, "net:bunny", &idx, &err), MS_OK);
    for (uint32_t id = 0; id < CELLS; ++id) {
        assert_memory_equal(ms_archive_get_cell(idx, id), ms_archive_get_cell(full, id),
                            sizeof(ms_archive_cell));
        assert_int_equal(ms_archive_geometry_prefix(idx, id, 10),
                         ms_archive_geometry_prefix(full, id, 10));
        size_t len, full_len;
        assert_null(ms_archive_geometry(idx, id, &len));
        const uint8_t *g = ms_archive_geometry(full, id, &full_len);
        assert_int_equal(len, full_len);
        assert_int_equal(ms_archive_check_payload(idx, id, false, g, full_len, &err), MS_OK);
        const uint8_t *apo = ms_archive_apo(full, id, &full_len);
        assert_int_equal(ms_archive_check_payload(idx, id, true, apo, full_len, &err), MS_OK);
    }
    size_t len;
    const uint8_t *g = ms_archive_geometry(full, 9, &len);
    uint8_t *copy = malloc(len);
    memcpy(copy, g, len);
    copy[len / 2] ^= 4;
    assert_int_equal(ms_archive_check_payload(idx, 9, false, copy, len, &err), MS_ERR_CORRUPT);
    assert_string_equal(err.text, "cell 9: geometry payload checksum mismatch");
    assert_int_equal(ms_archive_check_payload(idx, 9, false, copy, len - 1, &err), MS_ERR_CORRUPT);
    assert_int_equal(ms_archive_check_payload(idx, CELLS, false, copy, len, &err), MS_ERR_RANGE);
    assert_int_equal(ms_archive_verify_payload(idx, 0, &err), MS_ERR_ARG);
    free(copy);
    ms_archive_close(idx);
    /* The blob must be exactly header + index, intact. */
    uint8_t *bad = malloc(size + 1);
    memcpy(bad, blob, size);
    bad[size] = 0;
    assert_int_equal(ms_archive_open_index(bad, size + 1, "net:x", &idx, &err), MS_ERR_FORMAT);
    assert_int_equal(ms_archive_open_index(bad, size - 1, "net:x", &idx, &err), MS_ERR_FORMAT);
    assert_int_equal(ms_archive_open_index(bad, 100, "net:x", &idx, &err), MS_ERR_FORMAT);
    bad[MS_ARCHIVE_HEADER_SIZE + 5] ^= 1;
    assert_int_equal(ms_archive_open_index(bad, size, "net:x", &idx, &err), MS_ERR_CORRUPT);
    assert_null(idx);
    free(bad);
    ms_archive_close(full);
}

/* An index saved in a file opens like the blob; errors name the file. */
static void test_index_file(void **state)
{
    fixture *f = *state;
    ms_archive *full, *idx;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &full, &err), MS_OK);
    size_t size;
    const uint8_t *blob = ms_archive_index_bytes(full, &size);
    char path[700];
    snprintf(path, sizeof path, "%s/model.index", f->dir);
    ms_test_write_file(path, blob, size);
    assert_int_equal(ms_archive_open_index_file(path, "model", &idx, &err), MS_OK);
    assert_int_equal(ms_archive_get_header(idx)->cell_count, CELLS);
    assert_memory_equal(ms_archive_get_cell(idx, 3), ms_archive_get_cell(full, 3),
                        sizeof(ms_archive_cell));
    ms_archive_close(idx);
    ms_test_write_file(path, blob, size - 1);
    assert_int_equal(ms_archive_open_index_file(path, "model", &idx, &err), MS_ERR_FORMAT);
    assert_null(idx);
    assert_true(strncmp(err.text, path, strlen(path)) == 0);
    snprintf(path, sizeof path, "%s/missing.index", f->dir);
    assert_int_equal(ms_archive_open_index_file(path, "model", &idx, &err), MS_ERR_IO);
    assert_null(idx);
    char want[800];
    snprintf(want, sizeof want, "%s: cannot open: No such file or directory", path);
    assert_string_equal(err.text, want);
    ms_archive_close(full);
}

/* ms_archive_file_stat describes the file mapped: after the path is renamed
 * over by another file it still gives the first file's inode and size, and a
 * truncation of that file in place shows; an index has no file. */
static void test_file_stat_follows_the_mapped_file(void **state)
{
    fixture *f = *state;
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(f->path, &a, &err), MS_OK);
    struct stat by_path, mapped;
    assert_int_equal(stat(f->path, &by_path), 0);
    assert_int_equal(ms_archive_file_stat(a, &mapped, &err), MS_OK);
    assert_true(mapped.st_ino == by_path.st_ino && mapped.st_size == by_path.st_size);
    char moved[700], other[700];
    snprintf(moved, sizeof moved, "%s/moved.msa", f->dir);
    snprintf(other, sizeof other, "%s/other.msa", f->dir);
    assert_int_equal(rename(f->path, moved), 0);
    ms_test_write_file(other, (const uint8_t *)"x", 1);
    assert_int_equal(rename(other, f->path), 0);
    assert_int_equal(ms_archive_file_stat(a, &mapped, &err), MS_OK);
    assert_true(mapped.st_ino == by_path.st_ino && mapped.st_size == by_path.st_size);
    assert_int_equal(truncate(moved, 100), 0);
    assert_int_equal(ms_archive_file_stat(a, &mapped, &err), MS_OK);
    assert_int_equal(mapped.st_size, 100);
    size_t size;
    const uint8_t *blob = ms_archive_index_bytes(a, &size);
    ms_archive *idx;
    assert_int_equal(ms_archive_open_index(blob, size, "model", &idx, &err), MS_OK);
    assert_int_equal(ms_archive_file_stat(idx, &mapped, &err), MS_ERR_ARG);
    assert_string_equal(err.text, "an index has no archive file");
    ms_archive_close(idx);
    ms_archive_close(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_roundtrip, setup, teardown),
        cmocka_unit_test_setup_teardown(test_every_header_byte_flip_rejected, setup, teardown),
        cmocka_unit_test_setup_teardown(test_smoothing_fields, setup, teardown),
        cmocka_unit_test_setup_teardown(test_index_damage_and_truncation, setup, teardown),
        cmocka_unit_test_setup_teardown(test_payload_damage_found_by_verify, setup, teardown),
        cmocka_unit_test_setup_teardown(test_structural_lies_rejected, setup, teardown),
        cmocka_unit_test_setup_teardown(test_surface_error_table, setup, teardown),
        cmocka_unit_test_setup_teardown(test_writer_refuses_bad_use, setup, teardown),
        cmocka_unit_test_setup_teardown(test_index_blob_and_payload_checks, setup, teardown),
        cmocka_unit_test_setup_teardown(test_index_file, setup, teardown),
        cmocka_unit_test_setup_teardown(test_file_stat_follows_the_mapped_file, setup, teardown),
    };
    return cmocka_run_group_tests_name("archive", tests, NULL, NULL);
}
