/* Archive reader (file version 3, index blobs) and the record codec shared
 * with the writer. See ms_archive.h and docs/ARCHIVE.md. */
#include "ms_archive.h"
#include "ms_input_file.h"
#include "ms_archive_internal.h"
#include "ms_codec.h"
#include "ms_subtree.h"

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

static const uint8_t archive_magic[8] = {'M', 'S', 'A', 'R', 'C', 'H', '\r', '\n'};

/* --- Little-endian field access ------------------------------------------- */

static double get_f64(const uint8_t *p)
{
    uint64_t bits = ms_get_u64(p);
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

static void put_f64(uint8_t *p, double d)
{
    uint64_t bits;
    memcpy(&bits, &d, sizeof bits);
    ms_put_u64(p, bits);
}

static bool all_zero(const uint8_t *p, size_t n)
{
    for (size_t i = 0; i < n; ++i)
        if (p[i])
            return false;
    return true;
}

static unsigned log2_exact(unsigned n)
{
    unsigned k = 0;
    while ((1u << k) < n)
        ++k;
    return k;
}

/* --- Encoding (used by the writer) ---------------------------------------- */

/* The fields every header shares (docs/ARCHIVE.md), bytes 112..121 zero and
 * no header CRC yet. */
static void encode_common(const ms_archive_header *h, uint32_t version, uint64_t index_size,
                          uint64_t payload_size, uint64_t file_size, uint32_t index_crc,
                          uint8_t out[MS_ARCHIVE_HEADER_SIZE])
{
    memset(out, 0, MS_ARCHIVE_HEADER_SIZE);
    memcpy(out, archive_magic, 8);
    ms_put_u32(out + 8, version);
    ms_put_u32(out + 12, MS_ARCHIVE_HEADER_SIZE);
    for (int a = 0; a < 3; ++a)
        put_f64(out + 16 + 8 * a, h->box_origin[a]);
    put_f64(out + 40, h->box_side);
    out[48] = h->bits;
    out[49] = h->n;
    out[50] = h->root_bits;
    out[51] = (uint8_t)((h->has_apo ? 1 : 0) | (h->has_colour ? 2 : 0));
    ms_put_u32(out + 52, h->cell_count);
    ms_put_u64(out + 56, h->vertex_count);
    ms_put_u64(out + 64, h->triangle_count);
    ms_put_u32(out + 72, h->table_words);
    ms_put_u32(out + 76, h->min_triangles);
    ms_put_u64(out + 80, index_size);
    ms_put_u64(out + 88, payload_size);
    ms_put_u64(out + 96, file_size);
    out[104] = h->apo_lead;
    out[105] = h->apo_max_depth;
    out[106] = h->has_colour ? h->colour_bits : 0;
    out[107] = h->has_colour && h->colour_alpha ? 1 : 0;
    ms_put_u32(out + 108, index_crc);
    out[122] = h->smooth_rounds, out[123] = h->smooth_rounds ? h->smooth_bits : 0;
}

void ms_archive_encode_blob_header(const ms_archive_header *h, uint64_t index_size,
                                   uint64_t payload_size, uint32_t index_crc,
                                   uint8_t out[MS_ARCHIVE_HEADER_SIZE])
{
    encode_common(h, MS_ARCHIVE_BLOB_VERSION, index_size, payload_size,
                  MS_ARCHIVE_HEADER_SIZE + index_size + payload_size, index_crc, out);
    ms_put_u32(out + 124, (uint32_t)crc32(0L, out, 124));
}

void ms_archive_encode_header(const ms_archive_header *h, uint64_t index_size,
                              uint32_t stored_size, uint64_t payload_size, uint64_t file_size,
                              uint32_t index_crc, unsigned subtree_levels,
                              uint32_t subtree_count, uint8_t out[MS_ARCHIVE_HEADER_SIZE])
{
    encode_common(h, MS_ARCHIVE_VERSION, index_size, payload_size, file_size, index_crc, out);
    ms_put_u32(out + 112, stored_size);
    ms_put_u32(out + 116, subtree_count);
    out[120] = MS_ARCHIVE_INDEX_SUBTREES;
    out[121] = (uint8_t)subtree_levels;
    ms_put_u32(out + 124, (uint32_t)crc32(0L, out, 124));
}

void ms_archive_encode_cell(const ms_archive_cell *c, uint8_t out[MS_ARCHIVE_RECORD_SIZE])
{
    memset(out, 0, MS_ARCHIVE_RECORD_SIZE);
    ms_put_u32(out, c->parent);
    ms_put_u32(out + 4, c->first_child);
    out[8] = c->level;
    out[9] = c->bits_min;
    out[10] = c->bits_max;
    for (int a = 0; a < 3; ++a)
        ms_put_u32(out + 12 + 4 * a, c->position[a]);
    ms_put_u32(out + 24, c->vertex_count);
    ms_put_u32(out + 28, c->triangle_count);
    ms_put_u64(out + 32, c->geometry_offset);
    ms_put_u32(out + 40, c->geometry_length);
    ms_put_u32(out + 44, c->geometry_crc);
    ms_put_u64(out + 48, c->apo_offset);
    ms_put_u32(out + 56, c->apo_length);
    ms_put_u32(out + 60, c->apo_crc);
    ms_put_u32(out + 64, c->apo_raw_length);
    ms_put_u32(out + 68, c->table_first);
    out[72] = c->apo_levels;
}

void ms_archive_cell_window(const ms_archive_header *h, unsigned level, bool leaf,
                            uint8_t *bits_min, uint8_t *bits_max)
{
    unsigned step = log2_exact(h->n);
    unsigned lo = level == 0 ? 0 : h->root_bits + (level - 1) * step;
    unsigned hi = level == 0 ? h->root_bits : lo + step;
    if (lo > h->bits)
        lo = h->bits;
    if (hi > h->bits || leaf)
        hi = h->bits;
    *bits_min = (uint8_t)lo;
    *bits_max = (uint8_t)hi;
}

/* --- Validation ----------------------------------------------------------- */

/* The sections a header declares against the bytes it heads. */
static ms_status check_sections(const char *path, size_t size, ms_header_kind kind,
                                const ms_archive_header *h, const ms_archive_sections *sec,
                                ms_error *err)
{
    if (kind != MS_HEADER_FILE) {
        /* A blob or a head: the file size is the one of the model's raw index
         * and payloads (128 + raw index + payloads), whatever follows here. */
        uint64_t follows = kind == MS_HEADER_BLOB ? sec->index_size : sec->stored_size;
        if (size != MS_ARCHIVE_HEADER_SIZE + follows)
            return ms_error_set(err, MS_ERR_FORMAT, "%s: index %s is %zu bytes, expected %llu",
                                path, kind == MS_HEADER_BLOB ? "blob" : "head", size,
                                (unsigned long long)(MS_ARCHIVE_HEADER_SIZE + follows));
        if (sec->payload_size > UINT64_MAX / 2 ||
            h->file_size != MS_ARCHIVE_HEADER_SIZE + sec->index_size + sec->payload_size)
            return ms_error_set(err, MS_ERR_FORMAT, "%s: section sizes do not add up", path);
        return MS_OK;
    }
    if (h->file_size != size)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: file is %zu bytes but its header says %llu (truncated?)", path,
                            size, (unsigned long long)h->file_size);
    if (sec->payload_size > size ||
        MS_ARCHIVE_HEADER_SIZE + sec->stored_size > size - sec->payload_size ||
        MS_ARCHIVE_HEADER_SIZE + sec->stored_size + sec->payload_size != size)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: section sizes do not add up to the file size",
                            path);
    return MS_OK;
}

ms_status ms_archive_parse_header(const char *path, const uint8_t *p, size_t size,
                                 ms_header_kind kind, ms_archive_header *h,
                                 ms_archive_sections *sec, ms_error *err)
{
    if (size < MS_ARCHIVE_HEADER_SIZE)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %zu bytes is too short for an archive header",
                            path, size);
    if (memcmp(p, archive_magic, 8) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: not a meshstream archive (bad magic)", path);
    uint32_t version = ms_get_u32(p + 8);
    /* One format: a file or a head is version 3, a blob has its own version 1.
     * An older file (1 or 2, never released) is refused in one line. */
    uint32_t expected = kind == MS_HEADER_BLOB ? MS_ARCHIVE_BLOB_VERSION : MS_ARCHIVE_VERSION;
    if (version != expected)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "%s: %s version %u, this build reads version %u",
                            path, kind == MS_HEADER_FILE   ? "archive"
                                  : kind == MS_HEADER_BLOB ? "index blob"
                                                           : "index head",
                            version, expected);
    bool subtrees = kind != MS_HEADER_BLOB;
    if ((uint32_t)crc32(0L, p, 124) != ms_get_u32(p + 124))
        return ms_error_set(err, MS_ERR_CORRUPT, "%s: header checksum mismatch", path);
    /* A blob reserves bytes 112..121; a file or head stores there the index's
     * stored size (112..115), the subtree count (116..119), the encoding (120)
     * and S (121). Bytes 122 and 123: the smoothing, in every kind. */
    const uint8_t *reserved_tail = p + 112;
    size_t reserved_tail_size = subtrees ? 0 : 10;
    if (ms_get_u32(p + 12) != MS_ARCHIVE_HEADER_SIZE ||
        !all_zero(reserved_tail, reserved_tail_size) || (p[51] & ~3u))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: bad header size or reserved bytes", path);
    if (subtrees && p[120] != MS_ARCHIVE_INDEX_SUBTREES)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: index encoding %u, version %u stores subtrees (%u)", path,
                            p[120], version, MS_ARCHIVE_INDEX_SUBTREES);
    memset(h, 0, sizeof *h);
    memset(sec, 0, sizeof *sec);
    for (int a = 0; a < 3; ++a)
        h->box_origin[a] = get_f64(p + 16 + 8 * a);
    h->box_side = get_f64(p + 40);
    h->bits = p[48];
    h->n = p[49];
    h->root_bits = p[50];
    h->has_apo = p[51] & 1;
    h->cell_count = ms_get_u32(p + 52);
    h->vertex_count = ms_get_u64(p + 56);
    h->triangle_count = ms_get_u64(p + 64);
    h->table_words = ms_get_u32(p + 72);
    h->min_triangles = ms_get_u32(p + 76);
    sec->index_size = ms_get_u64(p + 80);
    sec->payload_size = ms_get_u64(p + 88);
    h->file_size = ms_get_u64(p + 96);
    h->apo_lead = p[104];
    h->apo_max_depth = p[105];
    h->smooth_rounds = p[122], h->smooth_bits = p[123];
    ms_status colour = ms_archive_check_colour_header(path, p, h, err);
    if (colour != MS_OK)
        return colour;
    sec->index_crc = ms_get_u32(p + 108);
    sec->stored_size = subtrees ? ms_get_u32(p + 112) : sec->index_size;
    if (subtrees) {
        sec->subtree_count = ms_get_u32(p + 116);
        sec->subtree_levels = p[121];
    }
    h->version = version;
    h->index_stored_size = sec->stored_size;
    for (int a = 0; a < 3; ++a)
        if (!isfinite(h->box_origin[a]))
            return ms_error_set(err, MS_ERR_RANGE, "%s: box origin is not finite", path);
    if (!isfinite(h->box_side) || !(h->box_side > 0))
        return ms_error_set(err, MS_ERR_RANGE, "%s: box side %g is not a positive number", path,
                            h->box_side);
    if (h->bits < 8 || h->bits > 20)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %u bits per coordinate outside 8..20", path,
                            h->bits);
    if (h->n != 2 && h->n != 4 && h->n != 8)
        return ms_error_set(err, MS_ERR_RANGE, "%s: n = %u is not 2, 4 or 8", path, h->n);
    if (h->root_bits < 1 || h->root_bits > h->bits)
        return ms_error_set(err, MS_ERR_RANGE, "%s: root bits %u outside 1..%u", path,
                            h->root_bits, h->bits);
    if (h->smooth_rounds > MS_CODEC_SMOOTH_ROUNDS_MAX || (h->smooth_rounds == 0) != (h->smooth_bits == 0) ||
        h->smooth_bits > h->bits)
        return ms_error_set(err, MS_ERR_RANGE, "%s: smoothing %u rounds below %u bits (1..%u below 1..%u, "
                            "or none)", path, h->smooth_rounds, h->smooth_bits, MS_CODEC_SMOOTH_ROUNDS_MAX, h->bits);
    if (h->cell_count < 1 || h->cell_count > MS_ARCHIVE_MAX_CELLS)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %u cells outside 1..%u", path, h->cell_count,
                            MS_ARCHIVE_MAX_CELLS);
    if (h->table_words > MS_ARCHIVE_MAX_TABLE_WORDS || h->vertex_count > (1ull << 32) ||
        h->triangle_count > (1ull << 34) || h->apo_lead > 16 || h->apo_max_depth > 24)
        return ms_error_set(err, MS_ERR_RANGE, "%s: header count out of range", path);
    if (subtrees && (sec->subtree_levels < MS_SUBTREE_MIN_LEVELS ||
                     sec->subtree_levels > MS_SUBTREE_MAX_LEVELS))
        return ms_error_set(err, MS_ERR_RANGE, "%s: subtree depth %u outside %u..%u", path,
                            sec->subtree_levels, MS_SUBTREE_MIN_LEVELS, MS_SUBTREE_MAX_LEVELS);
    if (subtrees && (sec->subtree_count < 1 || sec->subtree_count > h->cell_count))
        return ms_error_set(err, MS_ERR_RANGE, "%s: %u subtrees outside 1..%u", path,
                            sec->subtree_count, h->cell_count);
    /* The raw size follows from two counts capped above: never trust it alone. */
    uint64_t expect_index = (uint64_t)h->cell_count * MS_ARCHIVE_RECORD_SIZE +
                            4ull * h->table_words;
    if (sec->index_size != expect_index)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: index size %llu, expected %llu (%u cells, %u table words)", path,
                            (unsigned long long)sec->index_size, (unsigned long long)expect_index,
                            h->cell_count, h->table_words);
    return check_sections(path, size, kind, h, sec, err);
}

void ms_archive_decode_cell(const uint8_t *p, ms_archive_cell *c)
{
    c->parent = ms_get_u32(p);
    c->first_child = ms_get_u32(p + 4);
    c->level = p[8];
    c->bits_min = p[9];
    c->bits_max = p[10];
    for (int a = 0; a < 3; ++a)
        c->position[a] = ms_get_u32(p + 12 + 4 * a);
    c->vertex_count = ms_get_u32(p + 24);
    c->triangle_count = ms_get_u32(p + 28);
    c->geometry_offset = ms_get_u64(p + 32);
    c->geometry_length = ms_get_u32(p + 40);
    c->geometry_crc = ms_get_u32(p + 44);
    c->apo_offset = ms_get_u64(p + 48);
    c->apo_length = ms_get_u32(p + 56);
    c->apo_crc = ms_get_u32(p + 60);
    c->apo_raw_length = ms_get_u32(p + 64);
    c->table_first = ms_get_u32(p + 68);
    c->apo_levels = p[72];
}

static uint32_t table_word(const uint8_t *tables, uint64_t index)
{
    return ms_get_u32(tables + 4 * index);
}

ms_status ms_archive_check_record(const char *path, const ms_archive_header *h,
                                  uint64_t payload_size, uint32_t id, const uint8_t *raw,
                                  ms_archive_cell *c, const ms_archive_cell *parent,
                                  const uint8_t *tables, uint64_t table_words,
                                  uint64_t *next_table, ms_error *err)
{
    uint32_t children = (uint32_t)h->n * h->n * h->n;
#define CELL_FAIL(...) ms_error_set(err, MS_ERR_FORMAT, __VA_ARGS__)
    if (raw[11] != 0 || !all_zero(raw + 73, 7))
        return CELL_FAIL("%s: cell %u: reserved bytes are not zero", path, id);
    bool leaf = c->first_child == MS_ARCHIVE_NONE;
    if (id == 0) {
        if (c->parent != MS_ARCHIVE_NONE || c->level != 0 || c->position[0] || c->position[1] ||
            c->position[2])
            return CELL_FAIL("%s: cell 0 is not a root", path);
    } else {
        if (c->parent >= id)
            return CELL_FAIL("%s: cell %u: parent %u does not precede it", path, id, c->parent);
        if (!parent)
            return CELL_FAIL("%s: cell %u: its parent %u is not held", path, id, c->parent);
        if (parent->first_child == MS_ARCHIVE_NONE || id < parent->first_child ||
            id - parent->first_child >= children)
            return CELL_FAIL("%s: cell %u: not among the children of its parent %u", path, id,
                             c->parent);
        uint32_t k = id - parent->first_child, n = h->n;
        uint32_t offset[3] = {k % n, (k / n) % n, k / (n * n)};
        if (c->level != parent->level + 1)
            return CELL_FAIL("%s: cell %u: level %u under a level-%u parent", path, id, c->level,
                             parent->level);
        for (int ax = 0; ax < 3; ++ax)
            if (c->position[ax] != parent->position[ax] * n + offset[ax])
                return CELL_FAIL("%s: cell %u: position does not match its place in the parent",
                                 path, id);
    }
    uint8_t lo, hi;
    ms_archive_cell_window(h, c->level, leaf, &lo, &hi);
    if (c->bits_min != lo || c->bits_max != hi || (!leaf && hi >= h->bits) || lo > hi)
        return CELL_FAIL("%s: cell %u: precision window [%u, %u] breaks the tree rules", path, id,
                         c->bits_min, c->bits_max);
    if (!leaf) {
        if (c->first_child <= id || c->first_child > h->cell_count ||
            h->cell_count - c->first_child < children)
            return CELL_FAIL("%s: cell %u: children out of range", path, id);
    }
    if (c->geometry_offset > payload_size ||
        c->geometry_length > payload_size - c->geometry_offset || c->apo_offset > payload_size ||
        c->apo_length > payload_size - c->apo_offset)
        return CELL_FAIL("%s: cell %u: payload outside the payload area", path, id);
    if (c->apo_levels > MS_ARCHIVE_MAX_APO_LEVELS || (c->apo_raw_length & 3) ||
        ((c->apo_levels == 0) != (c->apo_length == 0)) || (!h->has_apo && c->apo_levels))
        return CELL_FAIL("%s: cell %u: bad APO chunk description", path, id);
    /* Tables: inside the table words, monotone, ending at the lengths. */
    uint64_t geometry_words = (uint64_t)c->bits_max - c->bits_min + 1;
    uint64_t words = ms_archive_cell_table_words(h, c);
    /* Tables are laid out in cell order with no gaps, so no two cells share one. */
    if (c->table_first != *next_table)
        return CELL_FAIL("%s: cell %u: tables out of order", path, id);
    *next_table += words;
    if (c->table_first > table_words || words > table_words - c->table_first)
        return CELL_FAIL("%s: cell %u: tables outside the table area", path, id);
    uint32_t previous = 0;
    for (uint64_t k = 0; k < geometry_words; ++k) {
        uint32_t v = table_word(tables, c->table_first + k);
        if (v < previous || v > c->geometry_length)
            return CELL_FAIL("%s: cell %u: geometry prefix table is not monotone", path, id);
        previous = v;
    }
    if (previous != c->geometry_length)
        return CELL_FAIL("%s: cell %u: geometry prefix table does not end at the payload length",
                         path, id);
    /* the error table: within the kd-cell's diagonal, never growing with the
     * bits in world units (the half-diagonal halves each bit), nothing after
     * its last byte */
    const uint8_t *error = tables + 4 * ms_archive_error_table_first(h, c);
    for (uint64_t k = 0; k < (geometry_words + 3) / 4 * 4; ++k) {
        unsigned e = error[k];
        if (k >= geometry_words ? e != 0
                                : e > MS_ARCHIVE_ERROR_MAX || (k > 0 && e > 2u * c->error[k - 1]))
            return CELL_FAIL("%s: cell %u: surface error table out of range or growing", path, id);
        if (k < geometry_words)
            c->error[k] = (uint8_t)e;
    }
    uint32_t prev_bytes = 0, prev_texels = 0;
    for (uint32_t l = 0; l < c->apo_levels; ++l) {
        uint32_t bytes = table_word(tables, c->table_first + geometry_words + 2 * l);
        uint32_t texels = table_word(tables, c->table_first + geometry_words + 2 * l + 1);
        if (bytes < prev_bytes || texels < prev_texels || bytes > c->apo_length)
            return CELL_FAIL("%s: cell %u: APO level table is not monotone", path, id);
        prev_bytes = bytes, prev_texels = texels;
    }
    if (c->apo_levels && (prev_bytes != c->apo_length || prev_texels != c->apo_raw_length / 4))
        return CELL_FAIL("%s: cell %u: APO level table does not end at the chunk size", path, id);
#undef CELL_FAIL
    return ms_archive_check_colour_tables(path, h, payload_size, id, c, tables, err);
}

/* Every non-root cell must be claimed by exactly one parent, and the tables must
 * fill the table words exactly. */
static ms_status check_tree_cover(const char *path, const ms_archive *a, ms_error *err)
{
    const ms_archive_header *h = &a->header;
    uint64_t claimed = 0, table_used = 0;
    uint32_t children = (uint32_t)h->n * h->n * h->n;
    for (uint32_t id = 0; id < h->cell_count; ++id) {
        const ms_archive_cell *c = &a->cells[id];
        if (c->first_child != MS_ARCHIVE_NONE) {
            for (uint32_t k = 0; k < children; ++k)
                if (a->cells[c->first_child + k].parent != id)
                    return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u: child %u names another parent",
                                        path, id, c->first_child + k);
            claimed += children;
        }
        table_used += ms_archive_cell_table_words(h, c);
    }
    if (claimed != (uint64_t)h->cell_count - 1)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: the cell tree does not cover the index", path);
    if (table_used != h->table_words)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: table words do not match the cells' tables",
                            path);
    return MS_OK;
}

/* Validates header and index of a->map (a whole file, or header + index only). */
static ms_status archive_validate(const char *path, ms_archive *a, ms_error *err)
{
    ms_archive_sections sec = {0};
    ms_status status = ms_archive_parse_header(path, a->map, a->map_size,
                                               a->index_only ? MS_HEADER_BLOB : MS_HEADER_FILE,
                                               &a->header, &sec, err);
    if (status == MS_OK) {
        a->index_size = sec.index_size;
        a->payload_size = sec.payload_size;
        a->blob = a->map;
    }
    if (status == MS_OK && !a->index_only) {
        /* A file: the blob is a blob header and the index its subtrees assemble. */
        a->inflated_blob = malloc(MS_ARCHIVE_HEADER_SIZE + (size_t)sec.index_size);
        if (!a->inflated_blob)
            status = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for a %llu-byte index",
                                  path, (unsigned long long)sec.index_size);
        else
            status = ms_archive_v3_assemble(path, a, &sec,
                                            a->inflated_blob + MS_ARCHIVE_HEADER_SIZE, err);
        if (status == MS_OK) {
            ms_archive_encode_blob_header(&a->header, sec.index_size, sec.payload_size,
                                          sec.index_crc, a->inflated_blob);
            a->blob = a->inflated_blob;
        }
    }
    if (status == MS_OK) {
        const uint8_t *index = a->blob + MS_ARCHIVE_HEADER_SIZE;
        if (crc32_z(0L, index, (z_size_t)a->index_size) != sec.index_crc)
            status = ms_error_set(err, MS_ERR_CORRUPT, "%s: index checksum mismatch", path);
    }
    if (status == MS_OK) {
        a->cells = calloc(a->header.cell_count, sizeof *a->cells);
        if (!a->cells)
            status = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for %u cells", path,
                                  a->header.cell_count);
    }
    if (status == MS_OK) {
        const uint8_t *records = a->blob + MS_ARCHIVE_HEADER_SIZE;
        a->tables = records + (size_t)a->header.cell_count * MS_ARCHIVE_RECORD_SIZE;
        /* Payload offsets count from the end of the index as stored. */
        a->payload = a->index_only ? NULL : a->map + MS_ARCHIVE_HEADER_SIZE + sec.stored_size;
        for (uint32_t id = 0; id < a->header.cell_count; ++id)
            ms_archive_decode_cell(records + (size_t)id * MS_ARCHIVE_RECORD_SIZE, &a->cells[id]);
        uint64_t next_table = 0;
        for (uint32_t id = 0; status == MS_OK && id < a->header.cell_count; ++id) {
            ms_archive_cell *c = &a->cells[id];
            const ms_archive_cell *parent = id && c->parent < id ? &a->cells[c->parent] : NULL;
            status = ms_archive_check_record(path, &a->header, a->payload_size, id,
                                             records + (size_t)id * MS_ARCHIVE_RECORD_SIZE, c,
                                             parent, a->tables, a->header.table_words,
                                             &next_table, err);
        }
        if (status == MS_OK)
            status = check_tree_cover(path, a, err);
    }
    if (status == MS_OK) {
        bool file = !a->index_only;
        status = ms_archive_subtrees_init(
            a, file ? sec.subtree_levels : ms_subtree_default_levels(a->header.n), err);
        if (status == MS_OK && file)
            status = ms_archive_v3_check_directory(path, a, err);
    }
    return status;
}

ms_status ms_archive_open(const char *path, ms_archive **out, ms_error *err)
{
    *out = NULL;
    int fd;
    ms_status opened = ms_input_open(path, &fd, err);
    if (opened != MS_OK)
        return opened;
    struct stat st;
    if (fstat(fd, &st) != 0) {
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    }
    size_t size = (size_t)st.st_size;
    if (size < MS_ARCHIVE_HEADER_SIZE) {
        close(fd);
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %zu bytes is too short for an archive header",
                            path, size);
    }
    void *map = mmap(NULL, size, PROT_READ, MAP_SHARED, fd, 0);
    if (map == MAP_FAILED) {
        close(fd);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot map: %s", path, strerror(errno));
    }
    ms_archive *a = calloc(1, sizeof *a);
    if (!a) {
        munmap(map, size);
        close(fd);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    a->map = map;
    a->map_size = size;
    a->fd = fd;
    ms_status status = archive_validate(path, a, err);
    if (status != MS_OK) {
        ms_archive_close(a);
        return status;
    }
    *out = a;
    return MS_OK;
}

ms_status ms_archive_open_index(const uint8_t *blob, size_t size, const char *name,
                                ms_archive **out, ms_error *err)
{
    *out = NULL;
    if (size < MS_ARCHIVE_HEADER_SIZE)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: %zu bytes is too short for an archive header",
                            name, size);
    ms_archive *a = calloc(1, sizeof *a);
    uint8_t *copy = malloc(size);
    if (!a || !copy) {
        free(a);
        free(copy);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", name);
    }
    memcpy(copy, blob, size);
    a->map = copy;
    a->map_size = size;
    a->index_only = true;
    ms_status status = archive_validate(name, a, err);
    if (status != MS_OK) {
        ms_archive_close(a);
        return status;
    }
    *out = a;
    return MS_OK;
}

void ms_archive_close(ms_archive *a)
{
    if (!a)
        return;
    if (a->index_only) {
        free((void *)a->map);
    } else {
        munmap((void *)a->map, a->map_size);
        close(a->fd);
    }
    free(a->inflated_blob);
    free(a->cells);
    ms_archive_subtrees_free(a);
    ms_partial_free(a->partial);
    free(a);
}

ms_status ms_archive_file_stat(const ms_archive *a, struct stat *st, ms_error *err)
{
    if (a->index_only)
        return ms_error_set(err, MS_ERR_ARG, "an index has no archive file");
    if (fstat(a->fd, st) != 0)
        return ms_error_set(err, MS_ERR_IO, "the archive file: %s", strerror(errno));
    return MS_OK;
}

const ms_archive_header *ms_archive_get_header(const ms_archive *a) { return &a->header; }

const ms_archive_cell *ms_archive_get_cell(const ms_archive *a, uint32_t cell)
{
    if (cell >= a->header.cell_count)
        return NULL;
    if (a->partial)
        return ms_partial_get_cell(a, cell, NULL);
    return &a->cells[cell];
}

bool ms_archive_cell_tables(const ms_archive *a, uint32_t cell, const ms_archive_cell **c,
                            const uint8_t **tables)
{
    *c = NULL;
    *tables = NULL;
    if (cell >= a->header.cell_count)
        return false;
    if (a->partial)
        *c = ms_partial_get_cell(a, cell, tables);
    else
        *c = &a->cells[cell], *tables = a->tables;
    return *c != NULL;
}

const uint8_t *ms_archive_index_bytes(const ms_archive *a, size_t *size)
{
    *size = a->blob ? MS_ARCHIVE_HEADER_SIZE + (size_t)a->index_size : 0;
    return a->blob;
}

uint64_t ms_archive_content_id(const ms_archive *a)
{
    size_t size;
    const uint8_t *index = ms_archive_index_bytes(a, &size);
    uint64_t hash = 1469598103934665603ull;
    for (size_t i = 0; i < size; ++i)
        hash = (hash ^ index[i]) * 1099511628211ull;
    return hash;
}

uint8_t ms_archive_max_apo_levels(const ms_archive *a)
{
    uint8_t most = 0;
    for (uint32_t cell = 0; cell < a->header.cell_count; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        if (c->apo_levels > most)
            most = c->apo_levels;
    }
    return most;
}

const uint8_t *ms_archive_geometry(const ms_archive *a, uint32_t cell, size_t *length)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    *length = c ? c->geometry_length : 0;
    return c && a->payload ? a->payload + c->geometry_offset : NULL;
}

const uint8_t *ms_archive_apo(const ms_archive *a, uint32_t cell, size_t *length)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    *length = c ? c->apo_length : 0;
    return c && a->payload ? a->payload + c->apo_offset : NULL;
}

uint32_t ms_archive_geometry_prefix(const ms_archive *a, uint32_t cell, unsigned bits)
{
    const ms_archive_cell *c;
    const uint8_t *tables;
    if (!ms_archive_cell_tables(a, cell, &c, &tables))
        return 0;
    if (bits < c->bits_min)
        bits = c->bits_min;
    if (bits > c->bits_max)
        bits = c->bits_max;
    return table_word(tables, (uint64_t)c->table_first + (bits - c->bits_min));
}

/* Entry k of c's error table in world units: its share of the half-diagonal
 * at bit bits_min + k. */
static double error_at(const ms_archive_header *h, const ms_archive_cell *c, unsigned k)
{
    double half_diagonal = 0.5 * sqrt(3.0) * ldexp(h->box_side, -(int)(c->bits_min + k));
    return c->error[k] * half_diagonal / MS_ARCHIVE_ERROR_SCALE;
}

double ms_archive_cell_error(const ms_archive_header *h, const ms_archive_cell *c, unsigned bits)
{
    if (bits < c->bits_min)
        bits = c->bits_min;
    if (bits > c->bits_max)
        bits = c->bits_max;
    return error_at(h, c, bits - c->bits_min);
}

double ms_archive_bits_needed(const ms_archive_header *h, const ms_archive_cell *c, double px_per_unit,
                              double tolerance_px)
{
    if (!(px_per_unit < INFINITY))
        return INFINITY;
    unsigned window = (unsigned)c->bits_max - c->bits_min;
    double allowed = tolerance_px / px_per_unit; /* world units */
    double before = error_at(h, c, 0);
    if (before <= allowed) /* coarser than the window: doubling per bit */
        return before > 0 ? c->bits_min - log2(allowed / before) : c->bits_min - 64.0;
    for (unsigned k = 1; k <= window; ++k) {
        double e = error_at(h, c, k);
        if (e == 0) /* exact at this bit: it is needed whole */
            return c->bits_min + k;
        if (e <= allowed) /* geometric between k - 1 and k (before > allowed >= e) */
            return c->bits_min + (k - 1) + log2(before / allowed) / log2(before / e);
        before = e;
    }
    return c->bits_max + log2(before / allowed); /* before > allowed > 0 */
}

uint32_t ms_archive_apo_prefix(const ms_archive *a, uint32_t cell, unsigned level,
                               uint32_t *texels)
{
    const ms_archive_cell *c;
    const uint8_t *tables;
    if (texels)
        *texels = 0;
    if (!ms_archive_cell_tables(a, cell, &c, &tables) || c->apo_levels == 0)
        return 0;
    if (level >= c->apo_levels)
        level = c->apo_levels - 1u;
    uint64_t base = (uint64_t)c->table_first + (c->bits_max - c->bits_min + 1u) + 2u * level;
    if (texels)
        *texels = table_word(tables, base + 1);
    return table_word(tables, base);
}

ms_status ms_archive_verify_payload(const ms_archive *a, uint32_t cell, ms_error *err)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u does not exist (%u cells)", cell,
                            a->header.cell_count);
    if (a->index_only)
        return ms_error_set(err, MS_ERR_ARG, "cell %u: this archive holds no payloads", cell);
    if (crc32_z(0L, a->payload + c->geometry_offset, c->geometry_length) != c->geometry_crc)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: geometry payload checksum mismatch", cell);
    if (crc32_z(0L, a->payload + c->apo_offset, c->apo_length) != c->apo_crc)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: APO chunk checksum mismatch", cell);
    size_t colour_length;
    const uint8_t *colour = ms_archive_colour(a, cell, &colour_length);
    return ms_archive_check_colour(a, cell, colour, colour_length, err);
}

ms_status ms_archive_check_payload(const ms_archive *a, uint32_t cell, bool apo,
                                   const uint8_t *data, size_t length, ms_error *err)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    if (!c)
        return ms_error_set(err, MS_ERR_RANGE, "cell %u does not exist (%u cells)", cell,
                            a->header.cell_count);
    uint32_t expect_length = apo ? c->apo_length : c->geometry_length;
    uint32_t expect_crc = apo ? c->apo_crc : c->geometry_crc;
    const char *kind = apo ? "APO chunk" : "geometry payload";
    if (length != expect_length)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: %s is %zu bytes, expected %u", cell,
                            kind, length, expect_length);
    if (crc32_z(0L, data, length) != expect_crc)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: %s checksum mismatch", cell, kind);
    return MS_OK;
}

ms_status ms_archive_open_index_file(const char *path, const char *name, ms_archive **archive,
                                     ms_error *err)
{
    *archive = NULL;
    FILE *f;
    ms_status opened = ms_input_fopen(path, &f, err);
    if (opened != MS_OK)
        return opened;
    size_t capacity = 1 << 20, size = 0, n;
    uint8_t *blob = malloc(capacity);
    while (blob && (n = fread(blob + size, 1, capacity - size, f)) > 0) {
        size += n;
        if (size == capacity) {
            uint8_t *grown = capacity < (256u << 20) ? realloc(blob, capacity * 2) : NULL;
            if (!grown) {
                free(blob);
                blob = NULL;
                break;
            }
            blob = grown;
            capacity *= 2;
        }
    }
    fclose(f);
    if (!blob)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    ms_status st = ms_archive_open_index(blob, size, name, archive, err);
    free(blob);
    if (st != MS_OK && err) {
        ms_error inner = *err;
        ms_error_set(err, st, "%s: %s", path, inner.text);
    }
    return st;
}
