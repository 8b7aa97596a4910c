/* Colour streams in an archive (docs/ARCHIVE.md, "Colour streams"): the
 * header's colour fields, each cell's colour tables and the accessors of
 * ms_archive.h. */
#include "ms_archive.h"
#include "ms_archive_internal.h"

#include <zlib.h>

ms_status ms_archive_check_colour_header(const char *where, const uint8_t *p,
                                         ms_archive_header *h, ms_error *err)
{
    h->has_colour = (p[51] & 2) != 0;
    h->colour_bits = p[106];
    h->colour_alpha = (p[107] & 1) != 0;
    if (!h->has_colour && (p[106] || p[107]))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: bad header size or reserved bytes", where);
    if (h->has_colour && (p[106] < 1 || p[106] > 8 || (p[107] & ~1u)))
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: colour precision %u outside 1..8 or colour flags %u", where,
                            p[106], p[107]);
    return MS_OK;
}

static uint32_t word(const uint8_t *tables, uint64_t index)
{
    return ms_get_u32(tables + 4 * index);
}

ms_status ms_archive_check_colour_tables(const char *where, const ms_archive_header *h,
                                         uint64_t payload_size, uint32_t id,
                                         const ms_archive_cell *c, const uint8_t *tables,
                                         ms_error *err)
{
    if (!h->has_colour)
        return MS_OK;
    /* ms_archive_check_record has checked that the cell's words lie inside
     * the table area. */
    uint64_t first = ms_archive_colour_table_first(c);
    uint64_t words = (uint64_t)c->bits_max - c->bits_min + 1;
    uint32_t previous = 0;
    for (uint64_t k = 0; k < words; ++k) {
        uint32_t v = word(tables, first + k);
        if (v < previous)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "%s: cell %u: colour prefix table is not monotone", where, id);
        previous = v;
    }
    uint64_t start = c->geometry_offset + c->geometry_length; /* <= payload_size, checked */
    if (previous > payload_size - start)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u: colour stream outside the payload area",
                            where, id);
    if ((c->vertex_count == 0) != (previous == 0) ||
        (c->apo_length && c->apo_offset < start + previous))
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: cell %u: colour stream of %u bytes for %u vertices, or "
                            "overlapping the APO chunk", where, id, previous, c->vertex_count);
    if (previous == 0 && word(tables, first + words) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: cell %u: colour CRC without a colour stream",
                            where, id);
    return MS_OK;
}

uint32_t ms_archive_colour_length(const ms_archive *a, uint32_t cell)
{
    const ms_archive_cell *c;
    const uint8_t *tables;
    if (!a->header.has_colour || !ms_archive_cell_tables(a, cell, &c, &tables))
        return 0;
    return word(tables, ms_archive_colour_table_first(c) + (c->bits_max - c->bits_min));
}

const uint8_t *ms_archive_colour(const ms_archive *a, uint32_t cell, size_t *length)
{
    *length = ms_archive_colour_length(a, cell);
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    if (!c || !a->payload || !a->header.has_colour)
        return NULL;
    return a->payload + c->geometry_offset + c->geometry_length;
}

uint32_t ms_archive_colour_prefix(const ms_archive *a, uint32_t cell, unsigned bits)
{
    const ms_archive_cell *c;
    const uint8_t *tables;
    if (!a->header.has_colour || !ms_archive_cell_tables(a, cell, &c, &tables))
        return 0;
    if (bits < c->bits_min)
        bits = c->bits_min;
    if (bits > c->bits_max)
        bits = c->bits_max;
    return word(tables, ms_archive_colour_table_first(c) + (bits - c->bits_min));
}

ms_status ms_archive_check_colour(const ms_archive *a, uint32_t cell, const uint8_t *data,
                                  size_t length, ms_error *err)
{
    const ms_archive_cell *c;
    const uint8_t *tables;
    if (!ms_archive_cell_tables(a, cell, &c, &tables))
        return ms_error_set(err, MS_ERR_RANGE, "cell %u is not held (%u cells)", cell,
                            a->header.cell_count);
    uint32_t expect = ms_archive_colour_length(a, cell);
    if (length != expect)
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: colour stream is %zu bytes, expected %u",
                            cell, length, expect);
    if (expect == 0)
        return MS_OK;
    uint64_t first = ms_archive_colour_table_first(c);
    if (crc32_z(0L, data, length) != word(tables, first + (c->bits_max - c->bits_min) + 1))
        return ms_error_set(err, MS_ERR_CORRUPT, "cell %u: colour stream checksum mismatch", cell);
    return MS_OK;
}
