#include "ms_test_archive.h"

#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive_writer.h"
#include "ms_test.h"

ms_archive_header ms_test_archive_header(void)
{
    ms_archive_header h = {0};
    h.box_origin[0] = -1.5, h.box_origin[1] = 2.0, h.box_origin[2] = 1e7;
    h.box_side = 0.25;
    h.bits = 12, h.n = 4, h.root_bits = 7;
    h.has_apo = true, h.apo_lead = 3, h.apo_max_depth = 13;
    h.cell_count = MS_TEST_ARCHIVE_CELLS;
    h.min_triangles = 8000;
    h.vertex_count = 1234, h.triangle_count = 2468;
    return h;
}

void ms_test_archive_fill(uint8_t *buf, uint32_t length, uint32_t seed)
{
    for (uint32_t i = 0; i < length; ++i)
        buf[i] = (uint8_t)((i * 131u + seed * 7u) >> 1);
}

uint32_t ms_test_archive_geometry_length(uint32_t cell) { return 20 + (cell * 37) % 300; }
uint32_t ms_test_archive_apo_levels(uint32_t cell) { return cell % 3 == 0 ? 0 : 1 + cell % 5; }

bool ms_test_archive_error_table(uint32_t cell, unsigned window, uint8_t *table)
{
    for (unsigned k = 0; k < window; ++k) /* never more than twice the one before */
        table[k] = (uint8_t)(50 + (cell * 7 + k * 13) % 50);
    return cell % 4 == 1;
}

/* Writes a tree of h.cell_count cells with the synthetic payloads. */
static void write_tree(const char *path, const ms_archive_header *hp, const uint32_t *first_child,
                       uint32_t salt)
{
    ms_archive_header h = *hp;
    ms_archive_writer *w;
    ms_error err;
    if (ms_archive_writer_open(path, &h, first_child, &w, &err) != MS_OK)
        fail_msg("%s", err.text);
    uint8_t buf[1024];
    /* Reverse order, APO before geometry on odd cells: the writer must not care. */
    for (uint32_t k = 0; k < h.cell_count; ++k) {
        uint32_t cell = h.cell_count - 1 - k;
        uint8_t lo, hi;
        ms_archive_writer_window(w, cell, &lo, &hi);
        uint32_t levels = ms_test_archive_apo_levels(cell), apo_table[64];
        for (uint32_t l = 0; l < levels; ++l)
            apo_table[2 * l] = 40 * (l + 1), apo_table[2 * l + 1] = 10 * (l + 1);
        for (int pass = 0; pass < 2; ++pass) {
            bool apo_now = levels && (pass == 0) == (cell % 2 == 1);
            if (apo_now) {
                ms_test_archive_fill(buf, 40 * levels, cell + 1000 + salt);
                if (ms_archive_writer_put_apo(w, cell, buf, 40 * levels, 40 * levels, apo_table,
                                              (uint8_t)levels, &err) != MS_OK)
                    fail_msg("%s", err.text);
            }
            if (pass == 0) {
                uint32_t len = ms_test_archive_geometry_length(cell), table[32];
                uint32_t words = hi - lo + 1u;
                for (uint32_t b = 0; b < words; ++b)
                    table[b] = 8 + (len - 8) * b / (words - 1 ? words - 1 : 1);
                table[words - 1] = len;
                ms_test_archive_fill(buf, len, cell + salt);
                if (ms_archive_writer_put_geometry(w, cell, buf, len, table, cell * 3, cell * 5,
                                                   &err) != MS_OK)
                    fail_msg("%s", err.text);
                uint8_t error[MS_ARCHIVE_MAX_WINDOW];
                if (ms_test_archive_error_table(cell, words, error) &&
                    ms_archive_writer_put_error(w, cell, error, &err) != MS_OK)
                    fail_msg("%s", err.text);
            }
        }
    }
    if (ms_archive_writer_finish(w, &err) != MS_OK)
        fail_msg("%s", err.text);
}

void ms_test_write_archive(const char *path, uint32_t salt)
{
    ms_archive_header h = ms_test_archive_header();
    uint32_t first_child[MS_TEST_ARCHIVE_CELLS];
    for (uint32_t i = 0; i < MS_TEST_ARCHIVE_CELLS; ++i)
        first_child[i] = MS_ARCHIVE_NONE;
    first_child[0] = 1;
    first_child[5] = 65;
    write_tree(path, &h, first_child, salt);
}

void ms_test_write_deep_archive(const char *path, uint32_t salt)
{
    ms_archive_header h = ms_test_archive_header();
    h.n = 2, h.root_bits = 4;
    h.cell_count = MS_TEST_DEEP_ARCHIVE_CELLS;
    uint32_t first_child[MS_TEST_DEEP_ARCHIVE_CELLS], level[MS_TEST_DEEP_ARCHIVE_CELLS];
    uint32_t next = 1;
    level[0] = 0;
    /* Breadth-first: the root and the first and last child of every group
     * above level 5 split. */
    for (uint32_t id = 0; id < MS_TEST_DEEP_ARCHIVE_CELLS; ++id) {
        uint32_t place = id == 0 ? 0 : (id - 1) % 8;
        bool split = level[id] < 5 && (id == 0 || place == 0 || place == 7);
        first_child[id] = split ? next : MS_ARCHIVE_NONE;
        for (uint32_t k = 0; split && k < 8; ++k)
            level[next++] = level[id] + 1;
    }
    if (next != MS_TEST_DEEP_ARCHIVE_CELLS)
        fail_msg("deep synthetic archive: %u cells, expected %u", next, MS_TEST_DEEP_ARCHIVE_CELLS);
    write_tree(path, &h, first_child, salt);
}

static void le_put(uint8_t *p, uint64_t v, int bytes)
{
    for (int i = 0; i < bytes; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

/* Header fields of docs/ARCHIVE.md. */
#define AT_RAW_SIZE 80
#define AT_PAYLOAD_SIZE 88
#define AT_FILE_SIZE 96
#define AT_INDEX_CRC 108

/* A file image's index blob, through the reader (its subtrees are many
 * streams): written to a scratch file, opened, and the blob copied. */
static uint8_t *image_blob(const uint8_t *file, size_t size, size_t *blob_size)
{
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/image.msa", dir);
    ms_test_write_file(path, file, size);
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    const uint8_t *blob = ms_archive_index_bytes(a, blob_size);
    uint8_t *out = malloc(*blob_size);
    assert_non_null(out);
    memcpy(out, blob, *blob_size);
    ms_archive_close(a);
    ms_test_rmdir(dir);
    return out;
}

uint8_t *ms_test_archive_raw_index(const uint8_t *file, size_t size, size_t *raw_size)
{
    size_t blob_size;
    uint8_t *blob = image_blob(file, size, &blob_size);
    *raw_size = blob_size - 128;
    uint8_t *out = malloc(*raw_size ? *raw_size : 1);
    assert_non_null(out);
    memcpy(out, blob + 128, *raw_size);
    free(blob);
    return out;
}

void ms_test_archive_seal(uint8_t *file)
{
    le_put(file + 124, crc32(0L, file, 124), 4);
}

uint8_t *ms_test_archive_blob(const uint8_t *file, size_t size, const uint8_t *raw,
                              size_t raw_size, uint32_t index_crc, size_t *out_size)
{
    size_t blob_size;
    uint8_t *blob = image_blob(file, size, &blob_size);
    size_t n = 128 + raw_size;
    uint8_t *out = malloc(n);
    assert_non_null(out);
    memcpy(out, blob, 128);
    memcpy(out + 128, raw, raw_size);
    free(blob);
    uint64_t payload = 0;
    for (int i = 0; i < 8; ++i)
        payload |= (uint64_t)out[AT_PAYLOAD_SIZE + i] << (8 * i);
    le_put(out + AT_RAW_SIZE, raw_size, 8);
    le_put(out + AT_FILE_SIZE, 128 + raw_size + payload, 8);
    le_put(out + AT_INDEX_CRC, index_crc, 4);
    ms_test_archive_seal(out);
    *out_size = n;
    return out;
}

uint8_t *ms_test_archive_blob_with_index(const uint8_t *file, size_t size, const uint8_t *raw,
                                         size_t raw_size, size_t *out_size)
{
    return ms_test_archive_blob(file, size, raw, raw_size, (uint32_t)crc32_z(0L, raw, raw_size),
                                out_size);
}

void ms_test_add_model(const char *dir, const char *name, uint32_t salt, uint8_t public_max_bits)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_test_write_archive(path, salt);
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", name);
    e.source = (char *)"synthetic";
    ms_catalog_now(e.baked_at, sizeof e.baked_at);
    e.vertices = 1234, e.triangles = 2468, e.cells = MS_TEST_ARCHIVE_CELLS;
    e.bits = 12, e.n = 4, e.root_bits = 7, e.min_triangles = 8000;
    e.apo = true, e.apo_lead = 3, e.apo_max_depth = 13, e.apo_tolerance = 0.1;
    e.public_max_bits = public_max_bits;
    ms_error err;
    if (ms_catalog_entry_fill_listing(&e, path, &err) != MS_OK || ms_catalog_update(dir, &e, &err) != MS_OK)
        fail_msg("%s", err.text);
}
