/* Codec stream headers (docs/CODEC.md section 5): the full layout of a stream
 * on its own, and the compact one of a stream inside an archive (flags bit 1),
 * which leaves the box to the archive and writes counts and chunk ends as
 * LEB128 varints. Both are read into one ms_codec_header and validated alike. */
#include "ms_codec.h"
#include "ms_codec_internal.h"

#include <math.h>
#include <string.h>
#include <zlib.h>

enum { FLAG_REGION = 1, FLAG_COMPACT = 2, AHEAD_SHIFT = 2, AHEAD_MASK = 7 << AHEAD_SHIFT, UNTIL_SHIFT = 5,
       UNTIL_MASK = 7 << UNTIL_SHIFT };

static void put32(uint8_t *p, uint32_t v)
{
    for (int i = 0; i < 4; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static void put64(uint8_t *p, uint64_t v)
{
    for (int i = 0; i < 8; ++i)
        p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static uint64_t get64(const uint8_t *p)
{
    return (uint64_t)get32(p) | (uint64_t)get32(p + 4) << 32;
}

static uint64_t dbits(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    return u;
}

static double bitsd(uint64_t u)
{
    double d;
    memcpy(&d, &u, sizeof d);
    return d;
}

/* ---- writing: a cursor that only counts when p is NULL ---- */

typedef struct wcur {
    uint8_t *p;
    size_t n;
} wcur;

static void w_bytes(wcur *w, const uint8_t *b, size_t n)
{
    if (w->p)
        memcpy(w->p + w->n, b, n);
    w->n += n;
}

static void w_u32(wcur *w, uint32_t v)
{
    uint8_t b[4];
    put32(b, v);
    w_bytes(w, b, 4);
}

static void w_u64(wcur *w, uint64_t v)
{
    uint8_t b[8];
    put64(b, v);
    w_bytes(w, b, 8);
}

static void w_var(wcur *w, uint32_t v)
{
    uint8_t b[5];
    size_t n = 0;
    do {
        b[n] = (uint8_t)(v & 0x7F);
        v >>= 7;
        if (v)
            b[n] |= 0x80;
        n++;
    } while (v);
    w_bytes(w, b, n);
}

size_t ms_codec_write_header(uint8_t *p, const ms_codec_header *h)
{
    unsigned nchunks = h->p_max - h->p_min;
    wcur w = {p, 0};
    uint8_t lead[8];
    memcpy(lead, MS_CODEC_MAGIC, 4);
    lead[4] = (uint8_t)h->version;
    lead[5] = (uint8_t)h->p_max;
    lead[6] = (uint8_t)h->p_min;
    lead[7] = (uint8_t)((h->has_region ? FLAG_REGION : 0) | (h->compact ? FLAG_COMPACT : 0) |
                        h->ahead << AHEAD_SHIFT | h->ahead_until << UNTIL_SHIFT);
    w_bytes(&w, lead, 8);
    if (h->compact) {
        w_var(&w, h->start_vertices);
        w_var(&w, h->start_tris);
        w_var(&w, h->start_edges);
        w_u64(&w, h->start_checksum);
        w_var(&w, h->end_vertices);
        w_var(&w, h->end_tris);
        w_var(&w, h->end_edges);
        if (h->has_region) {
            for (int a = 0; a < 3; ++a)
                w_var(&w, h->region.min[a] >> h->region.log2_side);
            uint8_t l = (uint8_t)h->region.log2_side;
            w_bytes(&w, &l, 1);
        }
        for (unsigned i = 0; i < nchunks; ++i) {
            w_var(&w, h->chunk_end[i] - (i ? h->chunk_end[i - 1] : 0));
            w_u32(&w, h->chunk_crc[i]);
        }
    } else {
        for (int a = 0; a < 3; ++a)
            w_u64(&w, dbits(h->box.origin[a]));
        w_u64(&w, dbits(h->box.size));
        w_u32(&w, h->start_vertices);
        w_u32(&w, h->start_tris);
        w_u32(&w, h->start_edges);
        w_u64(&w, h->start_checksum);
        w_u32(&w, h->end_vertices);
        w_u32(&w, h->end_tris);
        w_u32(&w, h->end_edges);
        if (h->has_region) {
            uint8_t q[MS_CODEC_REGION_BYTES] = {0};
            for (int a = 0; a < 3; ++a)
                put32(q + 4 * a, h->region.min[a]);
            q[12] = (uint8_t)h->region.log2_side;
            w_bytes(&w, q, sizeof q);
        }
        for (unsigned i = 0; i < nchunks; ++i) {
            w_u32(&w, h->chunk_end[i]);
            w_u32(&w, h->chunk_crc[i]);
        }
    }
    if (p)
        put32(p + w.n, (uint32_t)crc32(0L, p, (uInt)w.n));
    return w.n + 4;
}

/* ---- reading ---- */

ms_status ms_codec_region_check(const ms_codec_region *r, unsigned p_min, unsigned p_max,
                                ms_error *err)
{
    if (r->log2_side > p_max || p_max - r->log2_side > p_min)
        return ms_error_set(err, MS_ERR_FORMAT, "codec region of side 2^%u does not fit the "
                            "window [%u, %u]", r->log2_side, p_min, p_max);
    uint64_t side = 1ull << r->log2_side, grid = 1ull << p_max;
    for (int a = 0; a < 3; ++a)
        if (r->min[a] % side != 0 || r->min[a] + side > grid)
            return ms_error_set(err, MS_ERR_FORMAT, "codec region not aligned inside the grid");
    return MS_OK;
}

typedef struct rcur {
    const uint8_t *p;
    size_t n, at;
    bool short_read, bad_varint;
} rcur;

static const uint8_t *r_bytes(rcur *r, size_t n)
{
    if (r->n - r->at < n) {
        r->short_read = true;
        r->at = r->n;
        return NULL;
    }
    const uint8_t *b = r->p + r->at;
    r->at += n;
    return b;
}

static uint32_t r_u32(rcur *r)
{
    const uint8_t *b = r_bytes(r, 4);
    return b ? get32(b) : 0;
}

static uint64_t r_u64(rcur *r)
{
    const uint8_t *b = r_bytes(r, 8);
    return b ? get64(b) : 0;
}

/* LEB128, at most 5 bytes, at most 32 bits, shortest form only (one spelling
 * per value keeps headers comparable byte for byte). */
static uint32_t r_var(rcur *r)
{
    uint64_t v = 0;
    for (unsigned i = 0; i < 5; ++i) {
        const uint8_t *b = r_bytes(r, 1);
        if (!b)
            return 0;
        v |= (uint64_t)(*b & 0x7F) << (7 * i);
        if (!(*b & 0x80)) {
            if ((i > 0 && *b == 0) || v > UINT32_MAX)
                r->bad_varint = true;
            return (uint32_t)v;
        }
    }
    r->bad_varint = true;
    return 0;
}

ms_status ms_codec_read_header(const uint8_t *data, size_t size, ms_codec_header *h,
                               ms_error *err)
{
    return ms_codec_parse_header(data, size, h, true, err);
}

/* Reads the fields after the 8 lead bytes, in either layout; *reserved is set
 * when the full layout's region has non-zero reserved bytes. */
static void read_fields(rcur *r, ms_codec_header *h, unsigned nchunks, bool *reserved)
{
    *reserved = false;
    if (h->compact) {
        h->start_vertices = r_var(r);
        h->start_tris = r_var(r);
        h->start_edges = r_var(r);
        h->start_checksum = r_u64(r);
        h->end_vertices = r_var(r);
        h->end_tris = r_var(r);
        h->end_edges = r_var(r);
        if (h->has_region) {
            uint32_t pos[3];
            for (int a = 0; a < 3; ++a)
                pos[a] = r_var(r);
            const uint8_t *l = r_bytes(r, 1);
            h->region.log2_side = l ? *l : 0;
            for (int a = 0; a < 3; ++a) {
                /* a corner off the grid becomes 1: refused as unaligned */
                uint64_t m = h->region.log2_side <= 32 ? (uint64_t)pos[a] << h->region.log2_side
                                                       : UINT64_MAX;
                h->region.min[a] = m > UINT32_MAX ? 1u : (uint32_t)m;
            }
        }
        uint64_t end = 0;
        for (unsigned i = 0; i < nchunks; ++i) {
            end += r_var(r);
            h->chunk_end[i] = end > UINT32_MAX ? UINT32_MAX : (uint32_t)end;
            h->chunk_crc[i] = r_u32(r);
        }
        return;
    }
    for (int a = 0; a < 3; ++a)
        h->box.origin[a] = bitsd(r_u64(r));
    h->box.size = bitsd(r_u64(r));
    h->start_vertices = r_u32(r);
    h->start_tris = r_u32(r);
    h->start_edges = r_u32(r);
    h->start_checksum = r_u64(r);
    h->end_vertices = r_u32(r);
    h->end_tris = r_u32(r);
    h->end_edges = r_u32(r);
    if (h->has_region) {
        const uint8_t *q = r_bytes(r, MS_CODEC_REGION_BYTES);
        if (q) {
            for (int a = 0; a < 3; ++a)
                h->region.min[a] = get32(q + 4 * a);
            h->region.log2_side = q[12];
            *reserved = q[13] || q[14] || q[15];
        }
    }
    for (unsigned i = 0; i < nchunks; ++i) {
        h->chunk_end[i] = r_u32(r);
        h->chunk_crc[i] = r_u32(r);
    }
}

ms_status ms_codec_parse_header(const uint8_t *data, size_t size, ms_codec_header *h,
                                bool verify_crc, ms_error *err)
{
    memset(h, 0, sizeof *h);
    if (size < 8)
        return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated in its header (%zu bytes)",
                            size);
    if (memcmp(data, MS_CODEC_MAGIC, 4) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "not a meshstream codec stream (bad magic)");
    h->version = data[4];
    if (h->version != MS_CODEC_VERSION)
        return ms_error_set(err, MS_ERR_UNSUPPORTED,
                            "codec stream version %u, this build reads version %u", h->version,
                            MS_CODEC_VERSION);
    h->p_max = data[5];
    h->p_min = data[6];
    /* every bit of the flags byte has a meaning (0, 1, 2-4, 5-7): each field is
     * checked below */
    if (h->p_max < 1 || h->p_max > MS_CODEC_MAX_BITS || h->p_min > h->p_max)
        return ms_error_set(err, MS_ERR_FORMAT, "bad precision window [%u, %u]", h->p_min, h->p_max);
    h->ahead = (data[7] & AHEAD_MASK) >> AHEAD_SHIFT;
    if (h->ahead > MS_CODEC_MAX_AHEAD)
        return ms_error_set(err, MS_ERR_FORMAT, "geometry ahead by %u kd-levels (at most %u)",
                            h->ahead, MS_CODEC_MAX_AHEAD);
    h->ahead_until = (data[7] & UNTIL_MASK) >> UNTIL_SHIFT;
    /* the encoder writes a stop only where it falls inside the window */
    if (h->ahead_until && (h->ahead == 0 || h->ahead_until <= h->p_min || h->ahead_until >= h->p_max))
        return ms_error_set(err, MS_ERR_FORMAT, "geometry ahead by %u kd-levels stopping at %u bits, in a "
                            "window [%u, %u]", h->ahead, h->ahead_until, h->p_min, h->p_max);
    h->has_region = data[7] & FLAG_REGION;
    h->compact = data[7] & FLAG_COMPACT;
    unsigned nchunks = h->p_max - h->p_min;
    rcur r = {data, size, 8, false, false};
    bool reserved;
    read_fields(&r, h, nchunks, &reserved);
    size_t hs = r.at + 4;
    if (r.short_read || size < hs)
        return ms_error_set(err, MS_ERR_FORMAT, "codec stream truncated in its header (%zu "
                            "bytes)", size);
    if (verify_crc && get32(data + hs - 4) != (uint32_t)crc32(0L, data, (uInt)(hs - 4)))
        return ms_error_set(err, MS_ERR_CORRUPT, "codec header checksum mismatch");
    if (r.bad_varint)
        return ms_error_set(err, MS_ERR_FORMAT, "codec header: malformed number");
    if (!h->compact) {
        for (int a = 0; a < 3; ++a)
            if (!isfinite(h->box.origin[a]))
                return ms_error_set(err, MS_ERR_FORMAT, "box origin is not finite");
        if (!isfinite(h->box.size) || !(h->box.size > 0))
            return ms_error_set(err, MS_ERR_FORMAT, "box size is not a positive number");
    }
    if (h->end_vertices < 1 || h->end_vertices > MS_CODEC_MAX_VERTICES ||
        h->end_tris > MS_CODEC_MAX_TRIANGLES || h->end_edges > MS_CODEC_MAX_EDGES)
        return ms_error_set(err, MS_ERR_NOMEM, "declared complex too large or empty (%u vertices, "
                            "%u triangles, %u edges)", h->end_vertices, h->end_tris, h->end_edges);
    if (h->p_max < 9 && h->end_vertices > (1u << (3 * h->p_max)))
        return ms_error_set(err, MS_ERR_FORMAT, "more vertices (%u) than grid cells",
                            h->end_vertices);
    if (h->start_vertices < 1 || h->start_vertices > h->end_vertices ||
        h->start_tris > h->end_tris ||
        (uint64_t)h->start_edges > (uint64_t)h->end_edges + h->end_tris)
        return ms_error_set(err, MS_ERR_FORMAT, "start state larger than the final complex");
    if (h->p_min == 0 && (h->start_vertices != 1 || h->start_tris || h->start_edges))
        return ms_error_set(err, MS_ERR_FORMAT, "a stream from precision 0 starts at one vertex");
    if (reserved)
        return ms_error_set(err, MS_ERR_FORMAT, "codec region: reserved bytes not zero");
    if (h->has_region) {
        ms_status rs = ms_codec_region_check(&h->region, h->p_min, h->p_max, err);
        if (rs != MS_OK)
            return rs;
    }
    uint32_t prev = 0;
    for (unsigned i = 0; i < nchunks; ++i) {
        if (h->chunk_end[i] < prev + 4 || h->chunk_end[i] > (1u << 31))
            return ms_error_set(err, MS_ERR_FORMAT, "bad chunk offset table (entry %u)", i);
        prev = h->chunk_end[i];
    }
    /* Plausibility: even a perfectly regular complex costs more than 1/32 bit
     * per new vertex; this bounds what a short hostile stream can make the
     * decoder allocate. */
    uint64_t room = 256ull * ((uint64_t)prev + 16);
    if ((uint64_t)h->end_vertices > h->start_vertices + room ||
        (uint64_t)h->end_tris > h->start_tris + 2 * room ||
        (uint64_t)h->end_edges > (uint64_t)h->start_edges + 2 * room)
        return ms_error_set(err, MS_ERR_FORMAT, "declared complex (%u vertices, %u triangles) "
                            "implausibly large for a %u-byte body", h->end_vertices,
                            h->end_tris, prev);
    h->header_size = hs;
    h->body_size = prev;
    return MS_OK;
}
