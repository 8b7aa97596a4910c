/* OFF parser for ms_mesh_read: "OFF" (or COFF, NOFF, CNOFF, STOFF...) header,
 * a counts line "vertices faces [edges]" (also on the header line), one vertex
 * per line (x y z, then with N a normal, with C a colour r g b [a], with ST
 * texture coordinates; only the colour is kept), one face per line ("n i1 ... in",
 * trailing colour values ignored). '#' starts a comment. */
#include "ms_mesh_colour.h"
#include "ms_mesh_reader_internal.h"
#include "ms_parse_number.h"

#include <string.h>

/* Next line with content, with any comment cut off; NULL at the end. */
static ms_status off_line(ms_reader *r, char **out)
{
    for (;;) {
        char *line;
        ms_status st = ms_reader_next_line(r, &line);
        if (st != MS_OK || !line) {
            *out = NULL;
            return st;
        }
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *p = ms_skip_blanks(line);
        if (*p) {
            *out = p;
            return MS_OK;
        }
    }
}

/* The numbers after a vertex's x y z (at most `max` kept; *count says how many
 * there were), and whether each was written as an integer. */
static ms_status off_vertex_values(ms_reader *r, char *p, double *value, bool *integer,
                                   int max, int *count)
{
    *count = 0;
    for (p = ms_skip_blanks(p); *p; p = ms_skip_blanks(p)) {
        double v;
        const char *end = ms_parse_double(p, &v);
        if (!end)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "non-numeric vertex value");
        if (*count < max) {
            bool whole = true;
            for (const char *q = p; q < end; ++q)
                whole = whole && ((*q >= '0' && *q <= '9') || *q == '-' || *q == '+');
            value[*count] = v;
            integer[*count] = whole;
        }
        ++*count;
        p = (char *)end;
    }
    return MS_OK;
}

/* A COFF vertex colour: 3 or 4 values, integers 0..255 or (when any of them is
 * written with a fraction or an exponent) numbers 0..1. */
static ms_status off_colour(ms_reader *r, int64_t vertex, const double *value,
                            const bool *integer, int channels, uint8_t rgba[4])
{
    bool bytes = true;
    for (int c = 0; c < channels; ++c)
        bytes = bytes && integer[c];
    rgba[3] = 255;
    for (int c = 0; c < channels; ++c) {
        double v = value[c];
        bool ok = bytes ? v >= 0.0 && v <= 255.0 : ms_colour_from_unit(v, &rgba[c]);
        if (!ok)
            return ms_reader_fail_line(r, MS_ERR_RANGE,
                                       "vertex %lld: colour value %.9g is not in %s",
                                       (long long)vertex, v, bytes ? "0..255" : "0..1");
        if (bytes)
            rgba[c] = (uint8_t)v;
    }
    return MS_OK;
}

static ms_status off_count(ms_reader *r, char **p, int64_t *value, const char *what)
{
    *p = ms_skip_blanks(*p);
    const char *end = ms_parse_int64(*p, value);
    if (!end || !ms_is_token_end(*end) || *value < 0)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad %s", what);
    *p = (char *)end;
    return MS_OK;
}

/* What the OFF keyword's prefixes add to each vertex line after x y z. */
typedef struct off_layout {
    bool normal, colour, st; /* N: 3 numbers, C: r g b [a], ST: 2 numbers, in this order */
} off_layout;

/* Vertex i, its line p (with content). */
static ms_status off_vertex(ms_reader *r, char *p, int64_t i, const off_layout *layout)
{
    ms_status st;
    double xyz[3];
    for (int a = 0; a < 3; ++a) {
        p = ms_skip_blanks(p);
        const char *end = ms_parse_double(p, &xyz[a]);
        if (!end)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "%s vertex coordinate",
                                       *p ? "non-numeric" : "missing");
        p = (char *)end;
    }
    double value[9];
    bool integer[9];
    int count;
    if ((st = off_vertex_values(r, p, value, integer, 9, &count)) != MS_OK)
        return st;
    if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
        return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex %lld has a non-finite coordinate",
                                   (long long)i);
    if (!layout->colour)
        return ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2]);
    const int skip = layout->normal ? 3 : 0;
    const int channels = count - skip - (layout->st ? 2 : 0);
    if (channels != 3 && channels != 4)
        return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                   "vertex %lld: %d colour values (3 or 4 expected)",
                                   (long long)i, channels < 0 ? 0 : channels);
    if (i == 0 && (st = ms_reader_enable_colour(r, channels == 4)) != MS_OK)
        return st;
    if ((channels == 4) != r->colour_alpha)
        return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                   "vertex %lld: %d colour values, vertex 0 has %d",
                                   (long long)i, channels, r->colour_alpha ? 4 : 3);
    uint8_t rgba[4];
    if ((st = off_colour(r, i, value + skip, integer + skip, channels, rgba)) != MS_OK)
        return st;
    return ms_reader_add_coloured_vertex(r, xyz[0], xyz[1], xyz[2], rgba);
}

ms_status ms_read_off(ms_reader *r)
{
    char *p;
    ms_status st = off_line(r, &p);
    if (st != MS_OK)
        return st;
    char *keyword = p;
    while (*p && *p != ' ' && *p != '\t')
        ++p;
    size_t len = (size_t)(p - keyword);
    /* Prefixes ST (texture), C (colour), N (normal) only add per-vertex values. */
    size_t k = 0;
    off_layout layout = {false, false, false};
    if (len - k > 3 && keyword[k] == 'S' && keyword[k + 1] == 'T')
        k += 2, layout.st = true;
    if (len - k > 3 && keyword[k] == 'C')
        ++k, layout.colour = true;
    if (len - k > 3 && keyword[k] == 'N')
        ++k, layout.normal = true;
    if (len - k != 3 || memcmp(keyword + k, "OFF", 3) != 0)
        return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "unsupported OFF variant '%.*s'",
                                   (int)len, keyword);
    p = ms_skip_blanks(p);
    if (strncmp(p, "BINARY", 6) == 0)
        return ms_reader_fail_line(r, MS_ERR_UNSUPPORTED, "binary OFF is not supported");
    if (*p == '\0' && (st = off_line(r, &p)) != MS_OK)
        return st;
    if (!p)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "file ends before the OFF counts");
    int64_t vertices, faces, edges = 0;
    if ((st = off_count(r, &p, &vertices, "vertex count")) != MS_OK ||
        (st = off_count(r, &p, &faces, "face count")) != MS_OK)
        return st;
    if (*ms_skip_blanks(p) && (st = off_count(r, &p, &edges, "edge count")) != MS_OK)
        return st;
    if (*ms_skip_blanks(p))
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "extra values on the OFF counts line");
    if ((uint64_t)vertices > UINT32_MAX)
        return ms_reader_fail_line(r, MS_ERR_RANGE,
                                   "%lld vertices declared; at most %u are supported",
                                   (long long)vertices, (unsigned)UINT32_MAX);
    for (int64_t i = 0; i < vertices; ++i) {
        if ((st = off_line(r, &p)) != MS_OK)
            return st;
        if (!p)
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "file ends after %lld of %lld vertices (truncated?)",
                                       (long long)i, (long long)vertices);
        if ((st = off_vertex(r, p, i, &layout)) != MS_OK)
            return st;
    }
    if ((st = ms_reader_flush_vertices(r)) != MS_OK)
        return st;
    for (int64_t i = 0; i < faces; ++i) {
        if ((st = off_line(r, &p)) != MS_OK)
            return st;
        if (!p)
            return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                       "file ends after %lld of %lld faces (truncated?)",
                                       (long long)i, (long long)faces);
        int64_t n;
        if ((st = off_count(r, &p, &n, "face vertex count")) != MS_OK)
            return st;
        if (n < 3)
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "face with %lld vertices", (long long)n);
        ms_fan fan = {0};
        for (int64_t j = 0; j < n; ++j) {
            int64_t index;
            p = ms_skip_blanks(p);
            const char *end = ms_parse_int64(p, &index);
            if (!end || !ms_is_token_end(*end))
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "%s vertex index",
                                           *p ? "bad" : "missing");
            if (index < 0 || index >= vertices)
                return ms_reader_fail_line(r, MS_ERR_RANGE,
                                           "vertex index %lld out of range (%lld vertices)",
                                           (long long)index, (long long)vertices);
            p = (char *)end;
            if ((st = ms_fan_add(r, &fan, (uint32_t)index)) != MS_OK)
                return st;
        }
        for (p = ms_skip_blanks(p); *p; p = ms_skip_blanks(p)) {
            double ignored; /* per-face colour */
            const char *end = ms_parse_double(p, &ignored);
            if (!end)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "non-numeric face value");
            p = (char *)end;
        }
        ++r->input_faces;
    }
    if ((st = off_line(r, &p)) != MS_OK)
        return st;
    if (p)
        return ms_reader_fail_line(r, MS_ERR_FORMAT,
                                   "data after the last face (more faces than declared?)");
    (void)edges;
    return MS_OK;
}
