/* OFF parser for ms_mesh_read: "OFF" (or COFF, NOFF, CNOFF, STOFF...) header,
 * a counts line "vertices faces [edges]" (also on the header line), one vertex
 * per line (x y z, further values such as colours ignored), one face per line
 * ("n i1 ... in", trailing colour values ignored). '#' starts a comment. */
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

static ms_status off_count(ms_reader *r, char **p, int64_t *value, const char *what)
{
    *p = ms_skip_blanks(*p);
    const char *end = ms_parse_int64(*p, value);
    if (!end || !ms_is_token_end(*end) || *value < 0)
        return ms_reader_fail_line(r, MS_ERR_FORMAT, "bad %s", what);
    *p = (char *)end;
    return MS_OK;
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
    if (len - k > 3 && keyword[k] == 'S' && keyword[k + 1] == 'T')
        k += 2;
    if (len - k > 3 && keyword[k] == 'C')
        ++k;
    if (len - k > 3 && keyword[k] == 'N')
        ++k;
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
        double xyz[3];
        for (int a = 0; a < 3; ++a) {
            p = ms_skip_blanks(p);
            const char *end = ms_parse_double(p, &xyz[a]);
            if (!end)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "%s vertex coordinate",
                                           *p ? "non-numeric" : "missing");
            p = (char *)end;
        }
        for (p = ms_skip_blanks(p); *p; p = ms_skip_blanks(p)) {
            double ignored;
            const char *end = ms_parse_double(p, &ignored);
            if (!end)
                return ms_reader_fail_line(r, MS_ERR_FORMAT, "non-numeric vertex value");
            p = (char *)end;
        }
        if (!isfinite(xyz[0]) || !isfinite(xyz[1]) || !isfinite(xyz[2]))
            return ms_reader_fail_line(r, MS_ERR_RANGE, "vertex %lld has a non-finite coordinate",
                                       (long long)i);
        if ((st = ms_reader_add_vertex(r, xyz[0], xyz[1], xyz[2])) != MS_OK)
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
