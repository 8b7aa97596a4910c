/* Wavefront OBJ parser for ms_mesh_read: `v` and `f` statements; everything else
 * (vt, vn, g, o, s, usemtl, mtllib, l, p, comments, ...) is ignored. Faces may
 * use v, v/vt, v//vn or v/vt/vn corners, negative (relative) indices, and any
 * number of corners (fan-triangulated). A line ending in '\' continues. Vertex
 * colour: `v x y z r g b [a]`, 0..1, on every vertex or on none (the first one
 * decides). */
#include "ms_mesh_colour.h"
#include "ms_mesh_reader_internal.h"
#include "ms_parse_number.h"

#include <string.h>

static ms_status obj_vertex(ms_reader *r, char *p)
{
    double value[7];
    int count = 0;
    for (;;) {
        p = ms_skip_blanks(p);
        if (*p == '\0' || *p == '#')
            break;
        if (count == 7)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "too many values in v statement");
        const char *end = ms_parse_double(p, &value[count]);
        if (!end)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "non-numeric value in v statement");
        ++count;
        p = (char *)end;
    }
    if (count < 3 || count == 5)
        return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                   "v statement with %d values (x y z [w], or x y z r g b [a])",
                                   count);
    const unsigned long long vertex = (unsigned long long)r->vertex_total + 1;
    if (!isfinite(value[0]) || !isfinite(value[1]) || !isfinite(value[2]))
        return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex %llu has a non-finite coordinate",
                                   vertex);
    if (r->vertex_total >= UINT32_MAX)
        return ms_reader_fail_line(r, MS_ERR_RANGE, "more than %u vertices are not supported",
                                   (unsigned)UINT32_MAX);
    const int channels = count >= 6 ? count - 3 : 0; /* a 4th value alone is w */
    ms_status st;
    if (r->vertex_total == 0 && channels > 0 &&
        (st = ms_reader_enable_colour(r, channels == 4)) != MS_OK)
        return st;
    const int expected = r->colour ? (r->colour_alpha ? 4 : 3) : 0;
    if (channels != expected)
        return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                   "vertex %llu has %d colour values, vertex 1 has %d (colour "
                                   "must be on every vertex or on none)",
                                   vertex, channels, expected);
    if (!channels)
        return ms_reader_add_vertex(r, value[0], value[1], value[2]);
    uint8_t rgba[4] = {0, 0, 0, 255};
    for (int c = 0; c < channels; ++c)
        if (!ms_colour_from_unit(value[3 + c], &rgba[c]))
            return ms_reader_fail_line(r, MS_ERR_RANGE,
                                       "vertex %llu: colour value %.9g is not in 0..1", vertex,
                                       value[3 + c]);
    return ms_reader_add_coloured_vertex(r, value[0], value[1], value[2], rgba);
}

/* Parses one face corner (v, v/vt, v//vn, v/vt/vn) and resolves its vertex. */
static ms_status obj_corner(ms_reader *r, char **cursor, uint32_t *vertex)
{
    char *p = *cursor;
    int64_t index;
    const char *end = ms_parse_int64(p, &index);
    if (!end)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad face corner");
    if (*end == '/') {
        int64_t ignored;
        ++end;
        if (*end != '/') {
            end = ms_parse_int64(end, &ignored); /* texture coordinate */
            if (!end)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad face corner");
        }
        if (*end == '/') {
            end = ms_parse_int64(end + 1, &ignored); /* normal */
            if (!end)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad face corner");
        }
    }
    if (!ms_is_token_end(*end) && *end != '#')
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad face corner");
    int64_t resolved;
    if (index > 0)
        resolved = index - 1;
    else if (index < 0)
        resolved = (int64_t)r->vertex_total + index;
    else
        return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex index 0 (OBJ counts from 1)");
    if (resolved < 0 || (uint64_t)resolved >= r->vertex_total)
        return ms_reader_fail_line(r, MS_ERR_RANGE,
                                   "vertex index %lld out of range (%llu vertices so far)",
                                   (long long)index, (unsigned long long)r->vertex_total);
    *vertex = (uint32_t)resolved;
    *cursor = (char *)end;
    return MS_OK;
}

static ms_status obj_face(ms_reader *r, char *p)
{
    ms_fan fan = {0};
    for (;;) {
        p = ms_skip_blanks(p);
        if (*p == '\0' || *p == '#')
            break;
        uint32_t v = 0;
        ms_status st = obj_corner(r, &p, &v);
        if (st != MS_OK || (st = ms_fan_add(r, &fan, v)) != MS_OK)
            return st;
    }
    if (fan.corners < 3)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "face with %llu vertices",
                                   (unsigned long long)fan.corners);
    ++r->input_faces;
    return MS_OK;
}

ms_status ms_read_obj(ms_reader *r)
{
    for (;;) {
        char *line;
        ms_status st = ms_reader_next_line(r, &line);
        if (st != MS_OK)
            return st;
        if (!line)
            return MS_OK;
        char *p = ms_skip_blanks(line);
        if (p[0] == 'v' && (p[1] == ' ' || p[1] == '\t'))
            st = obj_vertex(r, p + 2);
        else if (p[0] == 'f' && (p[1] == ' ' || p[1] == '\t'))
            st = obj_face(r, p + 2);
        else if (*p == '\0' || *p == '#')
            continue;
        else if ((*p >= 'a' && *p <= 'z') || (*p >= 'A' && *p <= 'Z') || *p == '_')
            continue; /* another statement (vt, vn, g, usemtl, ...): not geometry we use */
        else
            st = ms_reader_fail_line(r, MS_ERR_FORMAT, "not an OBJ statement");
        if (st != MS_OK)
            return st;
    }
}
