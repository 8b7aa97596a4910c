/* PLY parser (ascii, binary_little_endian, binary_big_endian) for ms_mesh_read.
 *
 * Vertex element: x, y, z of any scalar type, other properties skipped. Face
 * element: the vertex_indices (or vertex_index) list, fan-triangulated. A
 * tristrips element: its index list, unrolled with -1 restarts. Other elements
 * are skipped. This file parses the header and runs the body readers. */
#include "ms_read_ply_internal.h"
#include "ms_mesh_colour.h"
#include "ms_parse_number.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

static const char *type_name(ply_type t)
{
    static const char *const names[] = {"char", "uchar", "short", "ushort",
                                        "int", "uint", "float", "double"};
    return names[t];
}

bool ms_ply_colour_value(double v, ply_type t, uint8_t *out)
{
    switch (t) {
    case PLY_UINT8:
        if (!(v >= 0.0 && v <= 255.0) || v != (double)(int)v)
            return false;
        *out = (uint8_t)v;
        return true;
    case PLY_UINT16:
        if (!(v >= 0.0 && v <= 65535.0) || v != (double)(int)v)
            return false;
        *out = ms_colour_from_u16((uint32_t)v);
        return true;
    case PLY_FLOAT32:
    case PLY_FLOAT64:
        return ms_colour_from_unit(v, out);
    default:
        return false; /* refused in the header */
    }
}

void ms_ply_colour_complaint(char *buf, size_t size, uint64_t vertex, const ply_element *e,
                             int channel, double v)
{
    ply_type t = e->props[e->colour[channel]].type;
    const char *range = t == PLY_UINT8 ? "an integer in 0..255"
                        : t == PLY_UINT16 ? "an integer in 0..65535" : "in 0..1";
    snprintf(buf, size, "vertex %llu: colour %s = %.9g is not %s (%s)",
             (unsigned long long)vertex, e->props[e->colour[channel]].name, v, range,
             type_name(t));
}

/* The colour properties of the vertex element: red green blue [alpha], or the
 * same with the prefix diffuse_; scalars of type uchar, ushort, float or double. */
static ms_status find_colour(ms_reader *r, ply_element *e)
{
    static const char *const channel[4] = {"red", "green", "blue", "alpha"};
    const char *prefix = "";
    for (size_t i = 0; i < e->prop_count; ++i)
        if (strcmp(e->props[i].name, "diffuse_red") == 0)
            prefix = "diffuse_";
    for (size_t i = 0; i < e->prop_count; ++i)
        if (strcmp(e->props[i].name, "red") == 0)
            prefix = "";
    int found = 0;
    for (int c = 0; c < 4; ++c) {
        char name[32];
        snprintf(name, sizeof name, "%s%s", prefix, channel[c]);
        e->colour[c] = -1;
        for (size_t i = 0; i < e->prop_count; ++i)
            if (strcmp(e->props[i].name, name) == 0)
                e->colour[c] = (int)i;
        found += c < 3 && e->colour[c] >= 0;
    }
    /* Without all three of red, green and blue there is no colour: the channels
     * there are skipped like any other property. */
    e->has_colour = found == 3;
    for (int c = 0; c < 4; ++c) {
        if (!e->has_colour)
            e->colour[c] = -1;
        if (e->colour[c] < 0)
            continue;
        const ply_property *p = &e->props[e->colour[c]];
        if (p->is_list)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "vertex property %s is a list", p->name);
        if (p->type != PLY_UINT8 && p->type != PLY_UINT16 && p->type != PLY_FLOAT32 &&
            p->type != PLY_FLOAT64)
            return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED,
                                       "colour property %s of type %s (uchar, ushort, float or "
                                       "double expected)", p->name, type_name(p->type));
    }
    return MS_OK;
}

static ms_status finish_element(ms_reader *r, ply_element *e)
{
    e->all_scalar = true;
    e->stride = 0;
    for (size_t i = 0; i < e->prop_count; ++i) {
        if (e->props[i].is_list)
            e->all_scalar = false;
        else
            e->stride += ply_type_size(e->props[i].type);
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
        ms_status st = find_colour(r, e);
        if (st != MS_OK)
            return st;
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

/* "format KIND VERSION". */
static ms_status header_format(ms_reader *r, ply_header *h, char *cursor)
{
    char *kind = next_word(&cursor);
    char *version = next_word(&cursor);
    if (!kind || !version || next_word(&cursor))
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
    return MS_OK;
}

/* "element NAME COUNT": closes the element before it, opens *current. */
static ms_status header_element(ms_reader *r, ply_header *h, char *cursor, ply_element **current_io)
{
    ply_element *current = *current_io;
    ms_status st;
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
    *current_io = current;
    return MS_OK;
}

/* "property TYPE NAME" or "property list COUNT_TYPE ITEM_TYPE NAME" of
 * element current (NULL before any element). */
static ms_status header_property(ms_reader *r, ply_element *current, char *cursor)
{
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
            if (have_format)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad format line");
            if ((st = header_format(r, h, cursor)) != MS_OK)
                return st;
            have_format = true;
            continue;
        }
        if (!have_format)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "'%s' before the format line", keyword);
        if (strcmp(keyword, "element") == 0) {
            if ((st = header_element(r, h, cursor, &current)) != MS_OK)
                return st;
            continue;
        }
        if (strcmp(keyword, "property") == 0) {
            if ((st = header_property(r, current, cursor)) != MS_OK)
                return st;
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
        if (e->role == PLY_ROLE_VERTEX) {
            s.vertex_count = e->count;
            if (e->has_colour)
                st = ms_reader_enable_colour(r, e->colour[3] >= 0);
            if (st != MS_OK)
                break;
        }
        st = h->binary ? ms_ply_binary_element(&s, e) : ms_ply_ascii_element(&s, e);
        /* Faces are checked against the complete vertex element; hand it over
         * so the cleaner knows every vertex. */
        if (st == MS_OK && e->role == PLY_ROLE_VERTEX)
            st = ms_reader_flush_vertices(r);
    }
    if (st == MS_OK)
        st = h->binary ? ms_ply_binary_check_end(&s) : ms_ply_ascii_check_end(&s);
    free(h);
    return st;
}