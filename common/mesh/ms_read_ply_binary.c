/* Binary PLY bodies (either byte order). Fast paths for the usual layouts
 * (all-scalar vertex records, decoded at fixed offsets; faces as a uchar count
 * with 32-bit indices, decoded in batches); everything else goes through the
 * general per-property path, which streams lists of any length. */
#include "ms_read_ply_internal.h"

#include <string.h>

static inline uint16_t bswap16_if(uint16_t v, bool swap)
{
    return swap ? (uint16_t)((v >> 8) | (v << 8)) : v;
}
static inline uint32_t bswap32_if(uint32_t v, bool swap)
{
    return swap ? __builtin_bswap32(v) : v;
}
static inline uint64_t bswap64_if(uint64_t v, bool swap)
{
    return swap ? __builtin_bswap64(v) : v;
}

static inline double read_binary_double(const char *p, ply_type t, bool swap)
{
    switch (t) {
    case PLY_INT8: return (double)(int8_t)p[0];
    case PLY_UINT8: return (double)(uint8_t)p[0];
    case PLY_INT16: { uint16_t v; memcpy(&v, p, 2); return (double)(int16_t)bswap16_if(v, swap); }
    case PLY_UINT16: { uint16_t v; memcpy(&v, p, 2); return (double)bswap16_if(v, swap); }
    case PLY_INT32: { uint32_t v; memcpy(&v, p, 4); return (double)(int32_t)bswap32_if(v, swap); }
    case PLY_UINT32: { uint32_t v; memcpy(&v, p, 4); return (double)bswap32_if(v, swap); }
    case PLY_FLOAT32: {
        uint32_t v; memcpy(&v, p, 4); v = bswap32_if(v, swap);
        float f; memcpy(&f, &v, 4); return (double)f;
    }
    case PLY_FLOAT64: {
        uint64_t v; memcpy(&v, p, 8); v = bswap64_if(v, swap);
        double d; memcpy(&d, &v, 8); return d;
    }
    }
    return 0.0;
}

/* Integer types only (checked in the header). */
static inline int64_t read_binary_int(const char *p, ply_type t, bool swap)
{
    switch (t) {
    case PLY_INT8: return (int8_t)p[0];
    case PLY_UINT8: return (uint8_t)p[0];
    case PLY_INT16: { uint16_t v; memcpy(&v, p, 2); return (int16_t)bswap16_if(v, swap); }
    case PLY_UINT16: { uint16_t v; memcpy(&v, p, 2); return bswap16_if(v, swap); }
    case PLY_INT32: { uint32_t v; memcpy(&v, p, 4); return (int32_t)bswap32_if(v, swap); }
    case PLY_UINT32: { uint32_t v; memcpy(&v, p, 4); return bswap32_if(v, swap); }
    case PLY_FLOAT32: case PLY_FLOAT64: break;
    }
    return 0;
}

static ms_status binary_skip(ms_reader *r, uint64_t bytes, const char *what)
{
    while (bytes > 0) {
        size_t have = ms_byte_source_available(&r->src);
        if (have == 0) {
            ms_status st = ms_reader_need(r, 1, what);
            if (st != MS_OK)
                return st;
            have = ms_byte_source_available(&r->src);
        }
        size_t step = bytes < have ? (size_t)bytes : have;
        r->src.pos += step;
        bytes -= step;
    }
    return MS_OK;
}

/* Reads a list count at the current position and advances past it. */
static ms_status binary_list_count(ms_reader *r, const ply_property *p, bool swap,
                                   uint64_t *count, const char *what)
{
    size_t size = ply_type_size(p->count_type);
    ms_status st = ms_reader_need(r, size, what);
    if (st != MS_OK)
        return st;
    int64_t n = read_binary_int(r->src.buf + r->src.pos, p->count_type, swap);
    if (n < 0)
        return ms_reader_fail_offset(r, MS_ERR_FORMAT, ms_byte_source_offset(&r->src),
                                     "negative list count %lld", (long long)n);
    r->src.pos += size;
    *count = (uint64_t)n;
    return MS_OK;
}

static ms_status binary_skip_property(ms_reader *r, const ply_property *p, bool swap,
                                      const char *what)
{
    if (!p->is_list)
        return binary_skip(r, ply_type_size(p->type), what);
    uint64_t n;
    ms_status st = binary_list_count(r, p, swap, &n, what);
    if (st != MS_OK)
        return st;
    return binary_skip(r, n * ply_type_size(p->type), what);
}

/* The colour of a vertex from its channel values (as doubles) or a complaint
 * naming the vertex, at the byte offset of its record. */
static ms_status binary_colour(ms_reader *r, const ply_element *e, const double value[4],
                               uint64_t offset, uint8_t rgba[4])
{
    rgba[3] = 255;
    for (int c = 0; c < 4; ++c)
        if (e->colour[c] >= 0 &&
            !ms_ply_colour_value(value[c], e->props[e->colour[c]].type, &rgba[c])) {
            char complaint[160];
            ms_ply_colour_complaint(complaint, sizeof complaint, r->vertex_total, e, c, value[c]);
            return ms_reader_fail_offset(r, MS_ERR_RANGE, offset, "%s", complaint);
        }
    return MS_OK;
}

static ms_status binary_vertices(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    const bool swap = s->h->swap;
    const ply_type tx = e->props[e->coord[0]].type, ty = e->props[e->coord[1]].type,
                   tz = e->props[e->coord[2]].type;
    uint64_t remaining = e->count;
    if (e->all_scalar) {
        size_t off[3];
        for (int a = 0; a < 3; ++a) {
            off[a] = 0;
            for (int i = 0; i < e->coord[a]; ++i)
                off[a] += ply_type_size(e->props[i].type);
        }
        const bool plain_floats = !swap && tx == PLY_FLOAT32 && ty == PLY_FLOAT32 &&
                                  tz == PLY_FLOAT32;
        size_t coff[4] = {0, 0, 0, 0};
        bool byte_colour = true; /* every channel uchar: no conversion, no check */
        for (int c = 0; e->has_colour && c < 4; ++c) {
            if (e->colour[c] < 0)
                continue;
            for (int i = 0; i < e->colour[c]; ++i)
                coff[c] += ply_type_size(e->props[i].type);
            byte_colour = byte_colour && e->props[e->colour[c]].type == PLY_UINT8;
        }
        const size_t stride = e->stride;
        while (remaining > 0) {
            ms_status st = ms_reader_need(r, stride, "the vertex list");
            if (st != MS_OK)
                return st;
            uint64_t fit = ms_byte_source_available(&r->src) / stride;
            size_t n = (size_t)(fit < remaining ? fit : remaining);
            if (n > MS_MESH_READ_CHUNK_VERTICES) /* keeps the position current for */
                n = MS_MESH_READ_CHUNK_VERTICES; /* progress and page release */
            const char *p = r->src.buf + r->src.pos;
            for (size_t i = 0; i < n; ++i, p += stride) {
                double x, y, z;
                if (plain_floats) {
                    float f[3];
                    memcpy(&f[0], p + off[0], 4);
                    memcpy(&f[1], p + off[1], 4);
                    memcpy(&f[2], p + off[2], 4);
                    x = f[0], y = f[1], z = f[2];
                } else {
                    x = read_binary_double(p + off[0], tx, swap);
                    y = read_binary_double(p + off[1], ty, swap);
                    z = read_binary_double(p + off[2], tz, swap);
                }
                if (!isfinite(x) || !isfinite(y) || !isfinite(z))
                    return ms_reader_fail_offset(
                        r, MS_ERR_RANGE, r->src.base + (uint64_t)(p - r->src.buf),
                        "vertex %llu has a non-finite coordinate",
                        (unsigned long long)r->vertex_total);
                if (!e->has_colour) {
                    st = ms_reader_add_vertex(r, x, y, z);
                } else {
                    uint8_t rgba[4] = {0, 0, 0, 255};
                    if (byte_colour) {
                        for (int c = 0; c < 4; ++c)
                            if (e->colour[c] >= 0)
                                rgba[c] = (uint8_t)p[coff[c]];
                    } else {
                        double value[4] = {0, 0, 0, 0};
                        for (int c = 0; c < 4; ++c)
                            if (e->colour[c] >= 0)
                                value[c] = read_binary_double(p + coff[c],
                                                              e->props[e->colour[c]].type, swap);
                        st = binary_colour(r, e, value, r->src.base + (uint64_t)(p - r->src.buf),
                                           rgba);
                        if (st != MS_OK)
                            return st;
                    }
                    st = ms_reader_add_coloured_vertex(r, x, y, z, rgba);
                }
                if (st != MS_OK)
                    return st;
            }
            r->src.pos += n * stride;
            remaining -= n;
        }
        return MS_OK;
    }
    /* General layout: some vertex property is a list. */
    for (; remaining > 0; --remaining) {
        double xyz[3] = {0, 0, 0}, value[4] = {0, 0, 0, 0};
        uint64_t start = ms_byte_source_offset(&r->src);
        for (size_t i = 0; i < e->prop_count; ++i) {
            const ply_property *p = &e->props[i];
            int axis = (int)i == e->coord[0] ? 0 : (int)i == e->coord[1] ? 1
                       : (int)i == e->coord[2] ? 2 : -1;
            int channel = e->has_colour ? ply_colour_channel(e, i) : -1;
            ms_status st;
            if (axis >= 0 || channel >= 0) {
                st = ms_reader_need(r, ply_type_size(p->type), "the vertex list");
                if (st != MS_OK)
                    return st;
                double v = read_binary_double(r->src.buf + r->src.pos, p->type, swap);
                *(axis >= 0 ? &xyz[axis] : &value[channel]) = v;
                r->src.pos += ply_type_size(p->type);
            } else if ((st = binary_skip_property(r, p, swap, "the vertex list")) != MS_OK) {
                return st;
            }
        }
        if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
            return ms_reader_fail_offset(r, MS_ERR_RANGE, start,
                                         "vertex %llu has a non-finite coordinate",
                                         (unsigned long long)r->vertex_total);
        ms_status st;
        uint8_t rgba[4];
        if (!e->has_colour)
            st = ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2]);
        else if ((st = binary_colour(r, e, value, start, rgba)) == MS_OK)
            st = ms_reader_add_coloured_vertex(r, xyz[0], xyz[1], xyz[2], rgba);
        if (st != MS_OK)
            return st;
    }
    return MS_OK;
}

static inline ms_status check_index(ply_state *s, int64_t index, uint64_t offset)
{
    if (index < 0 || (uint64_t)index >= s->vertex_count)
        return ms_reader_fail_offset(s->r, MS_ERR_RANGE, offset,
                                     "vertex index %lld out of range (%llu vertices)",
                                     (long long)index, (unsigned long long)s->vertex_count);
    return MS_OK;
}

/* One face's index list read item by item (any size, any types). */
static ms_status binary_face_list(ply_state *s, const ply_property *p)
{
    ms_reader *r = s->r;
    const bool swap = s->h->swap;
    uint64_t start = ms_byte_source_offset(&r->src);
    uint64_t n;
    ms_status st = binary_list_count(r, p, swap, &n, "the face list");
    if (st != MS_OK)
        return st;
    if (n < 3)
        return ms_reader_fail_offset(r, MS_ERR_FORMAT, start, "face with %llu vertices",
                                     (unsigned long long)n);
    const size_t size = ply_type_size(p->type);
    ms_fan fan = {0};
    for (uint64_t k = 0; k < n; ++k) {
        if ((st = ms_reader_need(r, size, "the face list")) != MS_OK)
            return st;
        int64_t index = read_binary_int(r->src.buf + r->src.pos, p->type, swap);
        if ((st = check_index(s, index, ms_byte_source_offset(&r->src))) != MS_OK)
            return st;
        r->src.pos += size;
        if ((st = ms_fan_add(r, &fan, (uint32_t)index)) != MS_OK)
            return st;
    }
    ++r->input_faces;
    return MS_OK;
}

static ms_status binary_faces(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    const bool swap = s->h->swap;
    const ply_property *list = &e->props[e->index_list];
    const bool only_list = e->prop_count == 1;
    const size_t index_size = ply_type_size(list->type);
    const bool fast = only_list && list->count_type == PLY_UINT8 && index_size == 4;
    uint64_t remaining = e->count;
    while (remaining > 0) {
        if (fast) {
            /* Common layout: uchar count then 32-bit indices, nothing else. Take
             * the triangles that are whole in the buffer in one tight loop. */
            ms_status st = ms_reader_fill(r, 1 + 3 * 4);
            if (st != MS_OK)
                return st;
            const char *p = r->src.buf + r->src.pos;
            const char *end = r->src.buf + r->src.end;
            const bool is_signed = list->type == PLY_INT32;
            const int64_t limit = (int64_t)s->vertex_count;
            /* Decode straight into the triangle chunk, then clean the batch. The
             * vertex element is complete, so every valid index is announced. */
            while (remaining > 0 && end - p >= 13 && (uint8_t)p[0] == 3) {
                /* the position is current for the progress report (and the
                 * release of parsed pages) of the hand-over */
                r->src.pos = (size_t)(p - r->src.buf);
                if (r->triangle_pending == MS_MESH_READ_CHUNK_TRIANGLES &&
                    (st = ms_reader_flush_triangles(r)) != MS_OK)
                    return st;
                uint32_t *out = r->triangle_chunk + 3 * r->triangle_pending;
                size_t room = MS_MESH_READ_CHUNK_TRIANGLES - r->triangle_pending;
                size_t n = 0;
                while (n < room && n < remaining && end - p >= 13 && (uint8_t)p[0] == 3) {
                    uint32_t ua, ub, uc;
                    memcpy(&ua, p + 1, 4);
                    memcpy(&ub, p + 5, 4);
                    memcpy(&uc, p + 9, 4);
                    ua = bswap32_if(ua, swap);
                    ub = bswap32_if(ub, swap);
                    uc = bswap32_if(uc, swap);
                    int64_t a = is_signed ? (int32_t)ua : (int64_t)ua;
                    int64_t b = is_signed ? (int32_t)ub : (int64_t)ub;
                    int64_t c = is_signed ? (int32_t)uc : (int64_t)uc;
                    if (a < 0 || a >= limit || b < 0 || b >= limit || c < 0 || c >= limit)
                        break; /* the general path below reports it with its offset */
                    out[3 * n] = (uint32_t)a;
                    out[3 * n + 1] = (uint32_t)b;
                    out[3 * n + 2] = (uint32_t)c;
                    ++n;
                    p += 13;
                }
                r->triangle_pending += ms_mesh_cleaner_filter(&r->cleaner, out, n);
                r->input_faces += n;
                remaining -= n;
                if (n < room)
                    break;
            }
            r->src.pos = (size_t)(p - r->src.buf);
            if (remaining == 0)
                break;
        }
        /* General path for one record, also for whatever stopped the fast loop. */
        for (size_t i = 0; i < e->prop_count; ++i) {
            ms_status st = (int)i == e->index_list
                               ? binary_face_list(s, list)
                               : binary_skip_property(r, &e->props[i], swap, "the face list");
            if (st != MS_OK)
                return st;
        }
        --remaining;
    }
    return MS_OK;
}

static ms_status binary_strips(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    const bool swap = s->h->swap;
    const ply_property *list = &e->props[e->index_list];
    const size_t size = ply_type_size(list->type);
    for (uint64_t record = 0; record < e->count; ++record) {
        for (size_t i = 0; i < e->prop_count; ++i) {
            ms_status st;
            if ((int)i != e->index_list) {
                if ((st = binary_skip_property(r, &e->props[i], swap, "the strip list")) != MS_OK)
                    return st;
                continue;
            }
            uint64_t n;
            if ((st = binary_list_count(r, list, swap, &n, "the strip list")) != MS_OK)
                return st;
            ms_strip strip = {0};
            while (n > 0) {
                if ((st = ms_reader_need(r, size, "the strip list")) != MS_OK)
                    return st;
                size_t fit = ms_byte_source_available(&r->src) / size;
                size_t take = (size_t)(n < fit ? n : fit);
                const char *p = r->src.buf + r->src.pos;
                for (size_t k = 0; k < take; ++k, p += size) {
                    int64_t index = read_binary_int(p, list->type, swap);
                    if (index == -1) {
                        strip.length = 0;
                        continue;
                    }
                    uint64_t at = r->src.base + (uint64_t)(p - r->src.buf);
                    if ((st = check_index(s, index, at)) != MS_OK ||
                        (st = ms_strip_add(r, &strip, (uint32_t)index)) != MS_OK)
                        return st;
                }
                r->src.pos += take * size;
                n -= take;
            }
        }
    }
    return MS_OK;
}

static ms_status binary_skip_element(ply_state *s, const ply_element *e)
{
    if (e->all_scalar) {
        if (e->stride && e->count > UINT64_MAX / e->stride)
            return ms_reader_fail_offset(s->r, MS_ERR_FORMAT, ms_byte_source_offset(&s->r->src),
                                         "element %s is impossibly large", e->name);
        return binary_skip(s->r, e->count * e->stride, "a skipped element");
    }
    for (uint64_t i = 0; i < e->count; ++i)
        for (size_t k = 0; k < e->prop_count; ++k) {
            ms_status st = binary_skip_property(s->r, &e->props[k], s->h->swap,
                                                "a skipped element");
            if (st != MS_OK)
                return st;
        }
    return MS_OK;
}

ms_status ms_ply_binary_element(ply_state *s, const ply_element *e)
{
    switch (e->role) {
    case PLY_ROLE_VERTEX: return binary_vertices(s, e);
    case PLY_ROLE_FACE: return binary_faces(s, e);
    case PLY_ROLE_STRIPS: return binary_strips(s, e);
    case PLY_ROLE_OTHER: break;
    }
    return binary_skip_element(s, e);
}

/* Binary bodies must end exactly after the last element. */
ms_status ms_ply_binary_check_end(ply_state *s)
{
    ms_reader *r = s->r;
    ms_status st = ms_reader_fill(r, 1);
    if (st != MS_OK)
        return st;
    if (ms_byte_source_available(&r->src) > 0) {
        uint64_t at = ms_byte_source_offset(&r->src);
        uint64_t extra = 0;
        while (ms_byte_source_available(&r->src) > 0) {
            extra += ms_byte_source_available(&r->src);
            r->src.pos = r->src.end;
            if ((st = ms_reader_fill(r, 1)) != MS_OK)
                return st;
        }
        return ms_reader_fail_offset(r, MS_ERR_FORMAT, at,
                                     "%llu bytes after the last element (more elements "
                                     "than declared, or garbage)",
                                     (unsigned long long)extra);
    }
    return MS_OK;
}
