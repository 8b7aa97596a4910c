/* The colour stream's header (docs/COLOUR.md, "Layout"): written by the
 * encoder, read and validated field by field by the decoder. */
#include "ms_colour_internal.h"

#include <string.h>
#include <zlib.h>

enum { FLAG_ALPHA = 1, FLAG_BASE_GIVEN = 2 };

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static size_t header_size(unsigned nchunks)
{
    return MS_COLOUR_LEAD + MS_COLOUR_BASE_ENTRY + (size_t)MS_COLOUR_CHUNK_ENTRY * nchunks + 4;
}

size_t cc_write_header(uint8_t *p, const ms_colour_header *h)
{
    unsigned nchunks = h->p_max - h->p_min;
    size_t size = header_size(nchunks);
    if (!p)
        return size;
    memset(p, 0, size);
    memcpy(p, MS_COLOUR_MAGIC, 4);
    p[4] = (uint8_t)h->version;
    p[5] = (uint8_t)h->p_max;
    p[6] = (uint8_t)h->p_min;
    p[7] = (uint8_t)((h->alpha ? FLAG_ALPHA : 0) | (h->base_given ? FLAG_BASE_GIVEN : 0));
    p[8] = (uint8_t)h->colour_bits;
    put32(p + 12, h->start_cells);
    put32(p + 16, h->end_cells);
    put32(p + 20, h->chunk_end[0]);
    put32(p + 24, h->chunk_crc[0]);
    for (unsigned i = 1; i <= nchunks; ++i) {
        uint8_t *e = p + MS_COLOUR_LEAD + MS_COLOUR_BASE_ENTRY + MS_COLOUR_CHUNK_ENTRY * (i - 1);
        put32(e, h->chunk_end[i]);
        put32(e + 4, h->chunk_crc[i]);
        put32(e + 8, h->chunk_cells[i]);
    }
    put32(p + size - 4, (uint32_t)crc32(0L, p, (uInt)(size - 4)));
    return size;
}

static ms_status bad(ms_error *err, const char *what)
{
    return ms_error_set(err, MS_ERR_FORMAT, "colour stream: %s", what);
}

static ms_status read_header(const uint8_t *data, size_t size, ms_colour_header *h,
                             bool check_crc, ms_error *err)
{
    memset(h, 0, sizeof *h);
    if (size < MS_COLOUR_LEAD)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: truncated header (%zu bytes)",
                            size);
    if (memcmp(data, MS_COLOUR_MAGIC, 4) != 0)
        return bad(err, "bad magic (not a colour stream)");
    h->version = data[4];
    if (h->version != MS_COLOUR_VERSION)
        return ms_error_set(err, MS_ERR_UNSUPPORTED,
                            "colour stream version %u, this build reads version %u", h->version,
                            MS_COLOUR_VERSION);
    h->p_max = data[5];
    h->p_min = data[6];
    if (h->p_max < 1 || h->p_max > MS_CODEC_MAX_BITS)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: precision %u outside 1..%d",
                            h->p_max, MS_CODEC_MAX_BITS);
    if (h->p_min > h->p_max)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: window [%u, %u] is empty",
                            h->p_min, h->p_max);
    if (data[7] & ~(FLAG_ALPHA | FLAG_BASE_GIVEN))
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: unknown flags 0x%02x", data[7]);
    h->alpha = data[7] & FLAG_ALPHA;
    h->base_given = (data[7] & FLAG_BASE_GIVEN) != 0;
    h->colour_bits = data[8];
    if (h->colour_bits < 1 || h->colour_bits > MS_COLOUR_MAX_BITS)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: colour precision %u outside 1..%d",
                            h->colour_bits, MS_COLOUR_MAX_BITS);
    if (data[9] || data[10] || data[11])
        return bad(err, "reserved header bytes are not zero");
    h->start_cells = get32(data + 12);
    h->end_cells = get32(data + 16);
    if (h->start_cells < 1 || h->end_cells > MS_CODEC_MAX_VERTICES ||
        h->start_cells > h->end_cells)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "colour stream: cell counts %u -> %u outside 1..%u or decreasing",
                            h->start_cells, h->end_cells, (unsigned)MS_CODEC_MAX_VERTICES);
    if (h->p_min == 0 && h->start_cells != 1)
        return bad(err, "a window from precision 0 must start from one cell");
    unsigned nchunks = h->p_max - h->p_min;
    h->header_size = header_size(nchunks);
    if (size < h->header_size)
        return ms_error_set(err, MS_ERR_FORMAT, "colour stream: truncated header (%zu of %zu "
                            "bytes)", size, h->header_size);
    if (check_crc && crc32(0L, data, (uInt)(h->header_size - 4)) !=
                         get32(data + h->header_size - 4))
        return ms_error_set(err, MS_ERR_CORRUPT, "colour stream: header CRC mismatch");
    h->chunk_end[0] = get32(data + 20);
    h->chunk_crc[0] = get32(data + 24);
    h->chunk_cells[0] = h->start_cells;
    /* a chunk is at least the range coder's 4 flushed bytes; a kd-level at most
     * doubles the cells, a chunk (three levels) at most multiplies them by 8 */
    if (h->chunk_end[0] < 4)
        return bad(err, "base chunk shorter than 4 bytes");
    for (unsigned i = 1; i <= nchunks; ++i) {
        const uint8_t *e =
            data + MS_COLOUR_LEAD + MS_COLOUR_BASE_ENTRY + MS_COLOUR_CHUNK_ENTRY * (i - 1);
        h->chunk_end[i] = get32(e);
        h->chunk_crc[i] = get32(e + 4);
        h->chunk_cells[i] = get32(e + 8);
        if (h->chunk_end[i] < h->chunk_end[i - 1] || h->chunk_end[i] - h->chunk_end[i - 1] < 4)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "colour stream: chunk %u shorter than 4 bytes", i);
        uint64_t before = h->chunk_cells[i - 1];
        if (h->chunk_cells[i] < before || h->chunk_cells[i] > 8 * before)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "colour stream: chunk %u cell count %u impossible after %u", i,
                                h->chunk_cells[i], (unsigned)before);
    }
    if (h->chunk_cells[nchunks] != h->end_cells)
        return bad(err, "last chunk's cell count differs from the final count");
    h->body_size = h->chunk_end[nchunks];
    return MS_OK;
}

ms_status ms_colour_read_header(const uint8_t *data, size_t size, ms_colour_header *h,
                                ms_error *err)
{
    return read_header(data, size, h, true, err);
}

ms_status cc_read_header(const uint8_t *data, size_t size, ms_colour_header *h, bool check_crc,
                         ms_error *err)
{
    return read_header(data, size, h, check_crc, err);
}
