/* PLY parser (ascii, binary_little_endian, binary_big_endian) for ms_mesh_read.
 *
 * Vertex element: x, y, z of any scalar type, other properties skipped. Face
 * element: the vertex_indices (or vertex_index) list, fan-triangulated. A
 * tristrips element: its index list, unrolled with -1 restarts. Other elements
 * are skipped. Binary input has fast paths for the usual layouts (float x y z
 * first; uchar count with int indices); everything else goes through the
 * general per-property path. */
#include "ms_mesh_reader_internal.h"
#include "ms_parse_number.h"

#include <stdlib.h>
#include <string.h>

#define PLY_MAX_ELEMENTS 64
#define PLY_MAX_PROPERTIES 256
#define PLY_MAX_NAME 64
#define PLY_MAX_HEADER_LINES 100000

typedef enum ply_type {
    PLY_INT8, PLY_UINT8, PLY_INT16, PLY_UINT16, PLY_INT32, PLY_UINT32, PLY_FLOAT32, PLY_FLOAT64
} ply_type;

static const size_t ply_type_size[] = {1, 1, 2, 2, 4, 4, 4, 8};

typedef struct ply_property {
    char name[PLY_MAX_NAME];
    bool is_list;
    ply_type type;       /* the item type for lists */
    ply_type count_type; /* lists only */
} ply_property;

typedef enum ply_role { PLY_ROLE_OTHER, PLY_ROLE_VERTEX, PLY_ROLE_FACE, PLY_ROLE_STRIPS } ply_role;

typedef struct ply_element {
    char name[PLY_MAX_NAME];
    uint64_t count;
    ply_role role;
    ply_property props[PLY_MAX_PROPERTIES];
    size_t prop_count;
    int coord[3];       /* vertex: property index of x, y, z */
    int index_list;     /* face/strips: property index of the index list */
    bool all_scalar;
    size_t stride;      /* record size when all_scalar */
} ply_element;

typedef struct ply_header {
    ply_element elements[PLY_MAX_ELEMENTS];
    size_t element_count;
    bool binary;
    bool swap; /* binary byte order differs from the host's */
} ply_header;

typedef struct ply_state {
    ms_reader *r;
    ply_header *h;
    uint64_t vertex_count; /* declared by the vertex element */
} ply_state;

static bool host_is_little_endian(void)
{
    const uint16_t probe = 1;
    return *(const uint8_t *)&probe == 1;
}

static bool parse_type(const char *word, ply_type *type)
{
    static const struct { const char *name; ply_type type; } names[] = {
        {"char", PLY_INT8},     {"int8", PLY_INT8},       {"uchar", PLY_UINT8},
        {"uint8", PLY_UINT8},   {"short", PLY_INT16},     {"int16", PLY_INT16},
        {"ushort", PLY_UINT16}, {"uint16", PLY_UINT16},   {"int", PLY_INT32},
        {"int32", PLY_INT32},   {"uint", PLY_UINT32},     {"uint32", PLY_UINT32},
        {"float", PLY_FLOAT32}, {"float32", PLY_FLOAT32}, {"double", PLY_FLOAT64},
        {"float64", PLY_FLOAT64},
    };
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i)
        if (strcmp(word, names[i].name) == 0) {
            *type = names[i].type;
            return true;
        }
    return false;
}

static bool is_integer_type(ply_type t)
{
    return t != PLY_FLOAT32 && t != PLY_FLOAT64;
}

/* Splits the next blank-separated word off *cursor, NUL-terminating it. */
static char *next_word(char **cursor)
{
    char *p = ms_skip_blanks(*cursor);
    if (*p == '\0')
        return NULL;
    char *w = p;
    while (*p && *p != ' ' && *p != '\t' && *p != '\r')
        ++p;
    if (*p)
        *p++ = '\0';
    *cursor = p;
    return w;
}

static ms_status finish_element(ms_reader *r, ply_element *e)
{
    e->all_scalar = true;
    e->stride = 0;
    for (size_t i = 0; i < e->prop_count; ++i) {
        if (e->props[i].is_list)
            e->all_scalar = false;
        else
            e->stride += ply_type_size[e->props[i].type];
    }
    if (e->role == PLY_ROLE_VERTEX) {
        static const char *const axis[3] = {"x", "y", "z"};
        for (int a = 0; a < 3; ++a) {
            e->coord[a] = -1;
            for (size_t i = 0; i < e->prop_count; ++i)
                if (strcmp(e->props[i].name, axis[a]) == 0)
                    e->coord[a] = (int)i;
            if (e->coord[a] < 0)
                return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                           "element vertex has no property %s", axis[a]);
            if (e->props[e->coord[a]].is_list)
                return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                           "vertex property %s is a list", axis[a]);
        }
    } else if (e->role == PLY_ROLE_FACE || e->role == PLY_ROLE_STRIPS) {
        e->index_list = -1;
        for (size_t i = 0; i < e->prop_count; ++i)
            if (e->props[i].is_list && (strcmp(e->props[i].name, "vertex_indices") == 0 ||
                                        strcmp(e->props[i].name, "vertex_index") == 0))
                e->index_list = (int)i;
        if (e->index_list < 0)
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "element %s has no vertex_indices list", e->name);
        const ply_property *p = &e->props[e->index_list];
        if (!is_integer_type(p->type) || !is_integer_type(p->count_type))
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "element %s: vertex_indices must have integer types",
                                       e->name);
    }
    return MS_OK;
}

static ms_status parse_header(ms_reader *r, ply_header *h)
{
    char *line;
    ms_status st = ms_reader_next_line(r, &line);
    if (st != MS_OK)
        return st;
    if (!line || strcmp(line, "ply") != 0)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "missing 'ply' magic");
    bool have_format = false;
    ply_element *current = NULL;
    for (unsigned lines = 0;; ++lines) {
        st = ms_reader_next_line(r, &line);
        if (st != MS_OK)
            return st;
        if (!line)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "file ends inside the PLY header");
        if (lines > PLY_MAX_HEADER_LINES)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "PLY header too long");
        char *cursor = line;
        char *keyword = next_word(&cursor);
        if (!keyword)
            continue;
        if (strcmp(keyword, "comment") == 0 || strcmp(keyword, "obj_info") == 0)
            continue;
        if (strcmp(keyword, "end_header") == 0)
            break;
        if (strcmp(keyword, "format") == 0) {
            char *kind = next_word(&cursor);
            char *version = next_word(&cursor);
            if (have_format || !kind || !version || next_word(&cursor))
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad format line");
            if (strcmp(version, "1.0") != 0 && strcmp(version, "1") != 0)
                return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "PLY version %s", version);
            if (strcmp(kind, "ascii") == 0) {
                r->format = MS_MESH_FORMAT_PLY_ASCII;
            } else if (strcmp(kind, "binary_little_endian") == 0) {
                r->format = MS_MESH_FORMAT_PLY_BINARY_LE;
                h->binary = true;
                h->swap = !host_is_little_endian();
            } else if (strcmp(kind, "binary_big_endian") == 0) {
                r->format = MS_MESH_FORMAT_PLY_BINARY_BE;
                h->binary = true;
                h->swap = host_is_little_endian();
            } else {
                return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "unknown PLY format '%s'", kind);
            }
            have_format = true;
            continue;
        }
        if (!have_format)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "'%s' before the format line", keyword);
        if (strcmp(keyword, "element") == 0) {
            char *name = next_word(&cursor);
            char *count = next_word(&cursor);
            int64_t n = 0;
            const char *after = count ? ms_parse_int64(count, &n) : NULL;
            if (!name || !after || *after || n < 0 || next_word(&cursor))
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad element line");
            if (strlen(name) >= PLY_MAX_NAME)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "element name too long");
            if (strcmp(name, "vertex") == 0 && n > (int64_t)UINT32_MAX)
                return ms_reader_fail_line(r, MS_ERR_RANGE,
                                           "%lld vertices declared; at most %u are supported",
                                           (long long)n, (unsigned)UINT32_MAX);
            if (current && (st = finish_element(r, current)) != MS_OK)
                return st;
            if (h->element_count == PLY_MAX_ELEMENTS)
                return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "more than %d elements",
                                           PLY_MAX_ELEMENTS);
            current = &h->elements[h->element_count++];
            strcpy(current->name, name);
            current->count = (uint64_t)n;
            current->role = strcmp(name, "vertex") == 0  ? PLY_ROLE_VERTEX
                            : strcmp(name, "face") == 0  ? PLY_ROLE_FACE
                            : strcmp(name, "tristrips") == 0 ? PLY_ROLE_STRIPS
                                                           : PLY_ROLE_OTHER;
            for (size_t i = 0; i + 1 < h->element_count; ++i)
                if (current->role != PLY_ROLE_OTHER && h->elements[i].role == current->role)
                    return ms_reader_fail_line(r, MS_ERR_FORMAT, "second element %s", name);
            continue;
        }
        if (strcmp(keyword, "property") == 0) {
            if (!current)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "property before any element");
            if (current->prop_count == PLY_MAX_PROPERTIES)
                return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "more than %d properties",
                                           PLY_MAX_PROPERTIES);
            ply_property *p = &current->props[current->prop_count];
            char *type = next_word(&cursor);
            if (type && strcmp(type, "list") == 0) {
                char *count_type = next_word(&cursor);
                char *item_type = next_word(&cursor);
                if (!count_type || !item_type || !parse_type(count_type, &p->count_type) ||
                    !parse_type(item_type, &p->type))
                    return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad list property types");
                if (!is_integer_type(p->count_type))
                    return ms_reader_fail_line(r, MS_ERR_FORMAT, "list count type must be an integer");
                p->is_list = true;
            } else if (!type || !parse_type(type, &p->type)) {
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "unknown property type '%s'",
                                           type ? type : "");
            }
            char *name = next_word(&cursor);
            if (!name || next_word(&cursor) || strlen(name) >= PLY_MAX_NAME)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad property line");
            strcpy(p->name, name);
            for (size_t i = 0; i < current->prop_count; ++i)
                if (strcmp(current->props[i].name, name) == 0)
                    return ms_reader_fail_line(r, MS_ERR_FORMAT, "duplicate property %s", name);
            ++current->prop_count;
            continue;
        }
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "unknown header keyword '%s'", keyword);
    }
    if (!have_format)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "PLY header has no format line");
    if (current && (st = finish_element(r, current)) != MS_OK)
        return st;
    bool seen_vertex = false;
    for (size_t i = 0; i < h->element_count; ++i) {
        if (h->elements[i].role == PLY_ROLE_VERTEX)
            seen_vertex = true;
        else if (h->elements[i].role != PLY_ROLE_OTHER && !seen_vertex)
            return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED,
                                       "element %s before element vertex is not supported",
                                       h->elements[i].name);
    }
    if (!seen_vertex)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "PLY header has no vertex element");
    return MS_OK;
}

/* ---- binary ---------------------------------------------------------------- */

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
    size_t size = ply_type_size[p->count_type];
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
        return binary_skip(r, ply_type_size[p->type], what);
    uint64_t n;
    ms_status st = binary_list_count(r, p, swap, &n, what);
    if (st != MS_OK)
        return st;
    return binary_skip(r, n * ply_type_size[p->type], what);
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
                off[a] += ply_type_size[e->props[i].type];
        }
        const bool plain_floats = !swap && tx == PLY_FLOAT32 && ty == PLY_FLOAT32 &&
                                  tz == PLY_FLOAT32;
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
                st = ms_reader_add_vertex(r, x, y, z);
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
        double xyz[3] = {0, 0, 0};
        uint64_t start = ms_byte_source_offset(&r->src);
        for (size_t i = 0; i < e->prop_count; ++i) {
            const ply_property *p = &e->props[i];
            int axis = (int)i == e->coord[0] ? 0 : (int)i == e->coord[1] ? 1
                       : (int)i == e->coord[2] ? 2 : -1;
            ms_status st;
            if (axis >= 0) {
                st = ms_reader_need(r, ply_type_size[p->type], "the vertex list");
                if (st != MS_OK)
                    return st;
                xyz[axis] = read_binary_double(r->src.buf + r->src.pos, p->type, swap);
                r->src.pos += ply_type_size[p->type];
            } else if ((st = binary_skip_property(r, p, swap, "the vertex list")) != MS_OK) {
                return st;
            }
        }
        if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
            return ms_reader_fail_offset(r, MS_ERR_RANGE, start,
                                         "vertex %llu has a non-finite coordinate",
                                         (unsigned long long)r->vertex_total);
        ms_status st = ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2]);
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
    const size_t size = ply_type_size[p->type];
    uint32_t first = 0, previous = 0;
    for (uint64_t k = 0; k < n; ++k) {
        if ((st = ms_reader_need(r, size, "the face list")) != MS_OK)
            return st;
        int64_t index = read_binary_int(r->src.buf + r->src.pos, p->type, swap);
        if ((st = check_index(s, index, ms_byte_source_offset(&r->src))) != MS_OK)
            return st;
        r->src.pos += size;
        uint32_t v = (uint32_t)index;
        if (k == 0)
            first = v;
        else if (k >= 2 && (st = ms_reader_add_triangle(r, first, previous, v)) != MS_OK)
            return st;
        previous = v;
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
    const size_t index_size = ply_type_size[list->type];
    const bool fast = only_list && list->count_type == PLY_UINT8 && index_size == 4 && !swap;
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
    const size_t size = ply_type_size[list->type];
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
            uint32_t a = 0, b = 0;
            uint64_t in_strip = 0;
            while (n > 0) {
                if ((st = ms_reader_need(r, size, "the strip list")) != MS_OK)
                    return st;
                size_t fit = ms_byte_source_available(&r->src) / size;
                size_t take = (size_t)(n < fit ? n : fit);
                const char *p = r->src.buf + r->src.pos;
                for (size_t k = 0; k < take; ++k, p += size) {
                    int64_t index = read_binary_int(p, list->type, swap);
                    if (index == -1) {
                        in_strip = 0;
                        continue;
                    }
                    uint64_t at = r->src.base + (uint64_t)(p - r->src.buf);
                    if ((st = check_index(s, index, at)) != MS_OK)
                        return st;
                    uint32_t c = (uint32_t)index;
                    if (in_strip == 0)
                        ++r->input_faces;
                    if (in_strip >= 2) {
                        /* Odd triangles of a strip are flipped to keep orientation. */
                        st = (in_strip & 1) ? ms_reader_add_triangle(r, b, a, c)
                                            : ms_reader_add_triangle(r, a, b, c);
                        if (st != MS_OK)
                            return st;
                    }
                    a = b;
                    b = c;
                    ++in_strip;
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

/* ---- ascii ----------------------------------------------------------------- */

/* Next non-blank line of element data, or a truncation error. */
static ms_status ascii_record(ms_reader *r, const ply_element *e, char **line)
{
    for (;;) {
        ms_status st = ms_reader_next_line(r, line);
        if (st != MS_OK)
            return st;
        if (!*line)
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "file ends inside element %s (truncated, or fewer "
                                       "elements than declared)", e->name);
        char *p = ms_skip_blanks(*line);
        if (*p) {
            *line = p;
            return MS_OK;
        }
    }
}

static ms_status ascii_number(ms_reader *r, char **p, double *value, const char *what)
{
    char *s = ms_skip_blanks(*p);
    if (*s == '\0')
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "missing value for %s", what);
    const char *end = ms_parse_double(s, value);
    if (!end)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "non-numeric value for %s", what);
    *p = (char *)end;
    return MS_OK;
}

static ms_status ascii_integer(ms_reader *r, char **p, int64_t *value, const char *what)
{
    char *s = ms_skip_blanks(*p);
    if (*s == '\0')
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "missing value for %s", what);
    const char *end = ms_parse_int64(s, value);
    if (!end || !ms_is_token_end(*end))
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad integer for %s", what);
    *p = (char *)end;
    return MS_OK;
}

static ms_status ascii_end_of_record(ms_reader *r, char *p, const ply_element *e)
{
    if (*ms_skip_blanks(p) != '\0')
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "extra values in element %s record",
                                   e->name);
    return MS_OK;
}

/* Skips one property of a record, checking the values are numbers. */
static ms_status ascii_skip_property(ms_reader *r, char **p, const ply_property *prop)
{
    double ignored;
    if (!prop->is_list)
        return ascii_number(r, p, &ignored, prop->name);
    int64_t n;
    ms_status st = ascii_integer(r, p, &n, prop->name);
    if (st != MS_OK)
        return st;
    if (n < 0)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "negative list count for %s", prop->name);
    for (int64_t k = 0; k < n; ++k)
        if ((st = ascii_number(r, p, &ignored, prop->name)) != MS_OK)
            return st;
    return MS_OK;
}

static ms_status ascii_vertices(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    const bool xyz_first = e->coord[0] == 0 && e->coord[1] == 1 && e->coord[2] == 2;
    for (uint64_t i = 0; i < e->count; ++i) {
        char *p;
        ms_status st = ascii_record(r, e, &p);
        if (st != MS_OK)
            return st;
        double xyz[3];
        size_t first_other = 0;
        if (xyz_first) {
            if ((st = ascii_number(r, &p, &xyz[0], "x")) != MS_OK ||
                (st = ascii_number(r, &p, &xyz[1], "y")) != MS_OK ||
                (st = ascii_number(r, &p, &xyz[2], "z")) != MS_OK)
                return st;
            first_other = 3;
        }
        for (size_t k = first_other; k < e->prop_count; ++k) {
            int axis = (int)k == e->coord[0] ? 0 : (int)k == e->coord[1] ? 1
                       : (int)k == e->coord[2] ? 2 : -1;
            st = axis >= 0 ? ascii_number(r, &p, &xyz[axis], e->props[k].name)
                           : ascii_skip_property(r, &p, &e->props[k]);
            if (st != MS_OK)
                return st;
        }
        if ((st = ascii_end_of_record(r, p, e)) != MS_OK)
            return st;
        if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
            return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex %llu has a non-finite coordinate",
                                       (unsigned long long)r->vertex_total);
        if ((st = ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2])) != MS_OK)
            return st;
    }
    return MS_OK;
}

static ms_status ascii_index(ply_state *s, char **p, uint32_t *out)
{
    int64_t index;
    ms_status st = ascii_integer(s->r, p, &index, "vertex_indices");
    if (st != MS_OK)
        return st;
    if (index < 0 || (uint64_t)index >= s->vertex_count)
        return ms_reader_fail_line(s->r, MS_ERR_RANGE,
                                   "vertex index %lld out of range (%llu vertices)",
                                   (long long)index, (unsigned long long)s->vertex_count);
    *out = (uint32_t)index;
    return MS_OK;
}

static ms_status ascii_faces(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    for (uint64_t i = 0; i < e->count; ++i) {
        char *p;
        ms_status st = ascii_record(r, e, &p);
        if (st != MS_OK)
            return st;
        for (size_t k = 0; k < e->prop_count; ++k) {
            if ((int)k != e->index_list) {
                if ((st = ascii_skip_property(r, &p, &e->props[k])) != MS_OK)
                    return st;
                continue;
            }
            int64_t n;
            if ((st = ascii_integer(r, &p, &n, "the face vertex count")) != MS_OK)
                return st;
            if (n < 3)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "face with %lld vertices",
                                           (long long)n);
            uint32_t first = 0, previous = 0, v = 0;
            if ((st = ascii_index(s, &p, &first)) != MS_OK ||
                (st = ascii_index(s, &p, &previous)) != MS_OK)
                return st;
            for (int64_t j = 2; j < n; ++j) {
                if ((st = ascii_index(s, &p, &v)) != MS_OK ||
                    (st = ms_reader_add_triangle(r, first, previous, v)) != MS_OK)
                    return st;
                previous = v;
            }
            ++r->input_faces;
        }
        if ((st = ascii_end_of_record(r, p, e)) != MS_OK)
            return st;
    }
    return MS_OK;
}

static ms_status ascii_strips(ply_state *s, const ply_element *e)
{
    ms_reader *r = s->r;
    for (uint64_t i = 0; i < e->count; ++i) {
        char *p;
        ms_status st = ascii_record(r, e, &p);
        if (st != MS_OK)
            return st;
        for (size_t k = 0; k < e->prop_count; ++k) {
            if ((int)k != e->index_list) {
                if ((st = ascii_skip_property(r, &p, &e->props[k])) != MS_OK)
                    return st;
                continue;
            }
            int64_t n;
            if ((st = ascii_integer(r, &p, &n, "the strip length")) != MS_OK)
                return st;
            if (n < 0)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "negative strip length");
            uint32_t a = 0, b = 0;
            uint64_t in_strip = 0;
            for (int64_t j = 0; j < n; ++j) {
                int64_t index;
                if ((st = ascii_integer(r, &p, &index, "vertex_indices")) != MS_OK)
                    return st;
                if (index == -1) {
                    in_strip = 0;
                    continue;
                }
                if (index < 0 || (uint64_t)index >= s->vertex_count)
                    return ms_reader_fail_line(r, MS_ERR_RANGE,
                                               "vertex index %lld out of range (%llu vertices)",
                                               (long long)index,
                                               (unsigned long long)s->vertex_count);
                uint32_t c = (uint32_t)index;
                if (in_strip == 0)
                    ++r->input_faces;
                if (in_strip >= 2) {
                    st = (in_strip & 1) ? ms_reader_add_triangle(r, b, a, c)
                                        : ms_reader_add_triangle(r, a, b, c);
                    if (st != MS_OK)
                        return st;
                }
                a = b;
                b = c;
                ++in_strip;
            }
        }
        if ((st = ascii_end_of_record(r, p, e)) != MS_OK)
            return st;
    }
    return MS_OK;
}

static ms_status ascii_skip_element(ply_state *s, const ply_element *e)
{
    for (uint64_t i = 0; i < e->count; ++i) {
        char *p;
        ms_status st = ascii_record(s->r, e, &p);
        if (st != MS_OK)
            return st;
        for (size_t k = 0; k < e->prop_count; ++k)
            if ((st = ascii_skip_property(s->r, &p, &e->props[k])) != MS_OK)
                return st;
        if ((st = ascii_end_of_record(s->r, p, e)) != MS_OK)
            return st;
    }
    return MS_OK;
}

/* ---- body ------------------------------------------------------------------ */

static ms_status check_nothing_follows(ply_state *s)
{
    ms_reader *r = s->r;
    if (s->h->binary) {
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
    for (;;) {
        char *line;
        ms_status st = ms_reader_next_line(r, &line);
        if (st != MS_OK)
            return st;
        if (!line)
            return MS_OK;
        if (*ms_skip_blanks(line) != '\0')
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "data after the last element (more elements than "
                                       "declared, or garbage)");
    }
}

ms_status ms_read_ply(ms_reader *r)
{
    ply_header *h = calloc(1, sizeof *h);
    if (!h)
        return ms_error_set(r->err, MS_ERR_NOMEM, "%s: out of memory", r->path);
    ms_status st = parse_header(r, h);
    if (st == MS_OK && h->binary)
        st = ms_byte_source_map_rest(&r->src, r->err);
    ply_state s = {.r = r, .h = h, .vertex_count = 0};
    for (size_t i = 0; st == MS_OK && i < h->element_count; ++i) {
        const ply_element *e = &h->elements[i];
        switch (e->role) {
        case PLY_ROLE_VERTEX:
            s.vertex_count = e->count;
            st = h->binary ? binary_vertices(&s, e) : ascii_vertices(&s, e);
            if (st == MS_OK)
                st = ms_reader_flush_vertices(r);
            break;
        case PLY_ROLE_FACE:
            st = h->binary ? binary_faces(&s, e) : ascii_faces(&s, e);
            break;
        case PLY_ROLE_STRIPS:
            st = h->binary ? binary_strips(&s, e) : ascii_strips(&s, e);
            break;
        case PLY_ROLE_OTHER:
            st = h->binary ? binary_skip_element(&s, e) : ascii_skip_element(&s, e);
            break;
        }
    }
    if (st == MS_OK)
        st = check_nothing_follows(&s);
    free(h);
    return st;
}
