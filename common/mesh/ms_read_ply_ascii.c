/* Ascii PLY bodies: one element record per line, values separated by blanks. */
#include "ms_read_ply_internal.h"
#include "ms_parse_number.h"

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
        double colour[4] = {0, 0, 0, 255};
        for (size_t k = first_other; k < e->prop_count; ++k) {
            int axis = (int)k == e->coord[0] ? 0 : (int)k == e->coord[1] ? 1
                       : (int)k == e->coord[2] ? 2 : -1;
            int channel = e->has_colour ? ply_colour_channel(e, k) : -1;
            if (axis >= 0)
                st = ascii_number(r, &p, &xyz[axis], e->props[k].name);
            else if (channel >= 0)
                st = ascii_number(r, &p, &colour[channel], e->props[k].name);
            else
                st = ascii_skip_property(r, &p, &e->props[k]);
            if (st != MS_OK)
                return st;
        }
        if ((st = ascii_end_of_record(r, p, e)) != MS_OK)
            return st;
        if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
            return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex %llu has a non-finite coordinate",
                                       (unsigned long long)r->vertex_total);
        if (!e->has_colour) {
            if ((st = ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2])) != MS_OK)
                return st;
            continue;
        }
        uint8_t rgba[4] = {0, 0, 0, 255};
        for (int c = 0; c < 4; ++c)
            if (e->colour[c] >= 0 && !ms_ply_colour_value(colour[c], e->props[e->colour[c]].type,
                                                          &rgba[c])) {
                char complaint[160];
                ms_ply_colour_complaint(complaint, sizeof complaint, r->vertex_total, e, c,
                                        colour[c]);
                return ms_reader_fail_line(r, MS_ERR_RANGE, "%s", complaint);
            }
        if ((st = ms_reader_add_coloured_vertex(r, xyz[0], xyz[1], xyz[2], rgba)) != MS_OK)
            return st;
    }
    return MS_OK;
}

/* index as a vertex of the model: MS_ERR_RANGE unless it is one. */
static ms_status ascii_check_index(ply_state *s, int64_t index)
{
    if (index < 0 || (uint64_t)index >= s->vertex_count)
        return ms_reader_fail_line(s->r, MS_ERR_RANGE,
                                   "vertex index %lld out of range (%llu vertices)",
                                   (long long)index, (unsigned long long)s->vertex_count);
    return MS_OK;
}

/* A face's index list: the count, then a polygon of at least 3 vertices. */
static ms_status ascii_face_list(ply_state *s, char **p)
{
    ms_reader *r = s->r;
    int64_t n;
    ms_status st = ascii_integer(r, p, &n, "the face vertex count");
    if (st != MS_OK)
        return st;
    if (n < 3)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "face with %lld vertices", (long long)n);
    ms_fan fan = {0};
    for (int64_t j = 0; j < n; ++j) {
        int64_t index;
        if ((st = ascii_integer(r, p, &index, "vertex_indices")) != MS_OK ||
            (st = ascii_check_index(s, index)) != MS_OK ||
            (st = ms_fan_add(r, &fan, (uint32_t)index)) != MS_OK)
            return st;
    }
    ++r->input_faces;
    return MS_OK;
}

/* A strip's index list: the length, then vertices, -1 restarting the strip. */
static ms_status ascii_strip_list(ply_state *s, char **p)
{
    ms_reader *r = s->r;
    int64_t n;
    ms_status st = ascii_integer(r, p, &n, "the strip length");
    if (st != MS_OK)
        return st;
    if (n < 0)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "negative strip length");
    ms_strip strip = {0};
    for (int64_t j = 0; j < n; ++j) {
        int64_t index;
        if ((st = ascii_integer(r, p, &index, "vertex_indices")) != MS_OK)
            return st;
        if (index == -1) {
            strip.length = 0;
            continue;
        }
        if ((st = ascii_check_index(s, index)) != MS_OK ||
            (st = ms_strip_add(r, &strip, (uint32_t)index)) != MS_OK)
            return st;
    }
    return MS_OK;
}

/* Reads the records of e: read_list reads the index list (when e has one and
 * read_list is not NULL), every other property is skipped. */
static ms_status ascii_records(ply_state *s, const ply_element *e, ms_status (*read_list)(ply_state *, char **))
{
    for (uint64_t i = 0; i < e->count; ++i) {
        char *p;
        ms_status st = ascii_record(s->r, e, &p);
        if (st != MS_OK)
            return st;
        for (size_t k = 0; k < e->prop_count; ++k) {
            st = read_list && (int)k == e->index_list ? read_list(s, &p)
                                                       : ascii_skip_property(s->r, &p, &e->props[k]);
            if (st != MS_OK)
                return st;
        }
        if ((st = ascii_end_of_record(s->r, p, e)) != MS_OK)
            return st;
    }
    return MS_OK;
}

ms_status ms_ply_ascii_element(ply_state *s, const ply_element *e)
{
    switch (e->role) {
    case PLY_ROLE_VERTEX: return ascii_vertices(s, e);
    case PLY_ROLE_FACE: return ascii_records(s, e, ascii_face_list);
    case PLY_ROLE_STRIPS: return ascii_records(s, e, ascii_strip_list);
    case PLY_ROLE_OTHER: break;
    }
    return ascii_records(s, e, NULL);
}

/* Only blank lines may follow the last element. */
ms_status ms_ply_ascii_check_end(ply_state *s)
{
    ms_reader *r = s->r;
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
