/* Shared machinery of the format parsers behind ms_mesh_read: the input buffer,
 * line splitting, error messages with positions, and the chunked hand-over of
 * vertices and triangles through the cleaning policy. Internal to common/. */
#ifndef MS_MESH_READER_INTERNAL_H
#define MS_MESH_READER_INTERNAL_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <string.h>

#include "ms_byte_source.h"
#include "ms_mesh_clean.h"
#include "ms_mesh_reader.h"

/* Text lines longer than this are an error (guards against binary garbage and
 * unbounded buffering). */
#define MS_READER_MAX_LINE (1u << 20)
#define MS_READER_BUFFER (4u << 20)

typedef struct ms_reader {
    ms_byte_source src;
    const char *path;
    const ms_mesh_sink *sink;
    ms_error *err;
    ms_mesh_cleaner cleaner;
    ms_mesh_format format;
    bool join_continued_lines; /* OBJ: a line ending in '\' continues */
    uint64_t line;             /* number of the last line returned (1-based) */
    uint64_t vertex_total;     /* vertices read so far (delivered + pending) */
    uint64_t input_faces;
    double *vertex_chunk;      /* MS_MESH_READ_CHUNK_VERTICES * 3 */
    uint8_t *colour_chunk;     /* MS_MESH_READ_CHUNK_VERTICES * 4 when colour, else NULL */
    bool colour, colour_alpha; /* the file's vertices have colour (with alpha) */
    size_t vertex_pending;
    uint32_t *triangle_chunk;  /* MS_MESH_READ_CHUNK_TRIANGLES * 3 */
    size_t triangle_pending;
    double bbox_min[3], bbox_max[3];
} ms_reader;

/* Error with "PATH: line N: " prefix (the last line returned). Returns code. */
ms_status ms_reader_fail_line(ms_reader *r, ms_status code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
/* Error with "PATH: byte offset N: " prefix. Returns code. */
ms_status ms_reader_fail_offset(ms_reader *r, ms_status code, uint64_t offset, const char *fmt,
                                ...) __attribute__((format(printf, 4, 5)));

/* Refills the input so at least `want` bytes are available. Running out of input is not an error here (check the available count). */
ms_status ms_reader_fill(ms_reader *r, size_t want);

/* Makes `want` bytes available or fails with a truncation error naming `what`. */
static inline ms_status ms_reader_need(ms_reader *r, size_t want, const char *what)
{
    if (r->src.end - r->src.pos >= want)
        return MS_OK;
    ms_status st = ms_reader_fill(r, want);
    if (st != MS_OK)
        return st;
    if (r->src.end - r->src.pos < want)
        return ms_reader_fail_offset(r, MS_ERR_FORMAT, ms_byte_source_offset(&r->src),
                                     "file ends inside %s (truncated?)", what);
    return MS_OK;
}

/* Next text line, NUL-terminated in place without its line ending; *line is NULL
 * at the end of the input. Counts lines in r->line. */
ms_status ms_reader_next_line(ms_reader *r, char **line);

/* Skips spaces and tabs. */
static inline char *ms_skip_blanks(char *p)
{
    while (*p == ' ' || *p == '\t' || *p == '\r' || *p == '\v' || *p == '\f')
        ++p;
    return p;
}

ms_status ms_reader_flush_vertices(ms_reader *r);
ms_status ms_reader_flush_triangles(ms_reader *r);

/* Appends one vertex; the parser has checked that the coordinates are finite. */
static inline ms_status ms_reader_add_vertex(ms_reader *r, double x, double y, double z)
{
    if (r->vertex_pending == MS_MESH_READ_CHUNK_VERTICES) {
        ms_status st = ms_reader_flush_vertices(r);
        if (st != MS_OK)
            return st;
    }
    double *v = r->vertex_chunk + 3 * r->vertex_pending++;
    v[0] = x;
    v[1] = y;
    v[2] = z;
    ++r->vertex_total;
    return MS_OK;
}

/* Declares that every vertex of the file has a colour (with alpha or not);
 * called by a parser before its first vertex. MS_ERR_NOMEM. */
ms_status ms_reader_enable_colour(ms_reader *r, bool alpha);

/* Appends one vertex with its colour (r g b a; the reader has colour). */
static inline ms_status ms_reader_add_coloured_vertex(ms_reader *r, double x, double y, double z,
                                                      const uint8_t rgba[4])
{
    ms_status st = ms_reader_add_vertex(r, x, y, z);
    if (st == MS_OK)
        memcpy(r->colour_chunk + 4 * (r->vertex_pending - 1), rgba, 4);
    return st;
}

/* Appends one triangle whose indices the parser has checked against
 * r->vertex_total; applies the cleaning policy. The triangle may use vertices
 * still pending: flush_triangles hands pending vertices over first, which keeps
 * the order guarantee without cutting chunks short for interleaved OBJ. */
static inline ms_status ms_reader_add_triangle(ms_reader *r, uint32_t a, uint32_t b, uint32_t c)
{
    uint64_t announced = r->cleaner.vertex_count;
    if (a >= announced || b >= announced || c >= announced) {
        ms_status st = ms_mesh_cleaner_set_vertex_count(&r->cleaner, r->vertex_total, r->err);
        if (st != MS_OK)
            return st;
    }
    if (!ms_mesh_cleaner_keep(&r->cleaner, a, b, c))
        return MS_OK;
    if (r->triangle_pending == MS_MESH_READ_CHUNK_TRIANGLES) {
        ms_status st = ms_reader_flush_triangles(r);
        if (st != MS_OK)
            return st;
    }
    uint32_t *t = r->triangle_chunk + 3 * r->triangle_pending++;
    t[0] = a;
    t[1] = b;
    t[2] = c;
    return MS_OK;
}

/* A polygon read corner by corner, triangulated as a fan from its first corner. */
typedef struct ms_fan {
    uint32_t first, previous;
    uint64_t corners;
} ms_fan;

/* Adds corner v (checked) to the fan: from the third corner on, the triangle
 * (first, previous, v). */
static inline ms_status ms_fan_add(ms_reader *r, ms_fan *fan, uint32_t v)
{
    ms_status st = MS_OK;
    if (fan->corners == 0)
        fan->first = v;
    else if (fan->corners >= 2)
        st = ms_reader_add_triangle(r, fan->first, fan->previous, v);
    fan->previous = v;
    ++fan->corners;
    return st;
}

/* A triangle strip read vertex by vertex; a restart index sets length to 0. */
typedef struct ms_strip {
    uint32_t a, b; /* the last two vertices */
    uint64_t length;
} ms_strip;

/* Adds vertex v (checked) to the strip: a new strip counts as one input face;
 * from the third vertex on, a triangle, odd ones flipped to keep orientation. */
static inline ms_status ms_strip_add(ms_reader *r, ms_strip *strip, uint32_t v)
{
    ms_status st = MS_OK;
    if (strip->length == 0)
        ++r->input_faces;
    if (strip->length >= 2)
        st = (strip->length & 1) ? ms_reader_add_triangle(r, strip->b, strip->a, v)
                                 : ms_reader_add_triangle(r, strip->a, strip->b, v);
    strip->a = strip->b;
    strip->b = v;
    ++strip->length;
    return st;
}

/* Format parsers: the input is positioned at the start of the file. */
ms_status ms_read_ply(ms_reader *r);
ms_status ms_read_obj(ms_reader *r);
ms_status ms_read_off(ms_reader *r);

#endif
