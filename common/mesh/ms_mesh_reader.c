/* ms_mesh_read: format detection, buffering and the chunked hand-over shared by
 * the PLY, OBJ and OFF parsers. */
#include "ms_mesh_reader_internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *ms_mesh_format_name(ms_mesh_format format)
{
    switch (format) {
    case MS_MESH_FORMAT_PLY_ASCII: return "ply-ascii";
    case MS_MESH_FORMAT_PLY_BINARY_LE: return "ply-binary-le";
    case MS_MESH_FORMAT_PLY_BINARY_BE: return "ply-binary-be";
    case MS_MESH_FORMAT_OBJ: return "obj";
    case MS_MESH_FORMAT_OFF: return "off";
    case MS_MESH_FORMAT_UNKNOWN: break;
    }
    return "unknown";
}

ms_status ms_reader_fail_line(ms_reader *r, ms_status code, const char *fmt, ...)
{
    char message[MS_ERROR_TEXT_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    return ms_error_set(r->err, code, "%s: line %llu: %s", r->path, (unsigned long long)r->line,
                        message);
}

ms_status ms_reader_fail_offset(ms_reader *r, ms_status code, uint64_t offset, const char *fmt,
                                ...)
{
    char message[MS_ERROR_TEXT_MAX];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(message, sizeof message, fmt, ap);
    va_end(ap);
    return ms_error_set(r->err, code, "%s: byte offset %llu: %s", r->path,
                        (unsigned long long)offset, message);
}

ms_status ms_reader_fill(ms_reader *r, size_t want)
{
    return ms_byte_source_fill(&r->src, want, r->err);
}

/* Called once per chunk handed over, which is often enough for a progress bar
 * and works the same for buffered and memory-mapped input. */
static void report_progress(ms_reader *r)
{
    ms_byte_source_release_consumed(&r->src);
    if (r->sink->progress)
        r->sink->progress(r->sink->context, ms_byte_source_disk_offset(&r->src),
                          r->src.file_size);
}

ms_status ms_reader_next_line(ms_reader *r, char **line)
{
    ms_byte_source *s = &r->src;
    size_t scanned = 0; /* bytes after pos already known to hold no line end */
    uint64_t joined = 0;
    for (;;) {
        char *start = s->buf + s->pos;
        size_t have = s->end - s->pos;
        char *nl = scanned < have ? memchr(start + scanned, '\n', have - scanned) : NULL;
        if (nl && r->join_continued_lines) {
            char *q = nl;
            if (q > start && q[-1] == '\r')
                --q;
            if (q > start && q[-1] == '\\') {
                /* Join: blank out the backslash and the line end, keep looking. */
                memset(q - 1, ' ', (size_t)(nl - q) + 2);
                ++joined;
                scanned = (size_t)(nl - start) + 1;
                continue;
            }
        }
        if (nl) {
            if (nl > start && nl[-1] == '\r')
                nl[-1] = '\0';
            *nl = '\0';
            s->pos += (size_t)(nl - start) + 1;
            r->line += 1 + joined;
            *line = start;
            return MS_OK;
        }
        if (s->eof) {
            if (have == 0) {
                r->line += joined;
                *line = NULL;
                return MS_OK;
            }
            start[have] = '\0'; /* the buffer has one spare byte for this */
            if (have > 0 && start[have - 1] == '\r')
                start[have - 1] = '\0';
            s->pos = s->end;
            r->line += 1 + joined;
            *line = start;
            return MS_OK;
        }
        if (have >= MS_READER_MAX_LINE) {
            r->line += 1 + joined;
            return ms_reader_fail_line(r, MS_ERR_FORMAT, "line longer than %u bytes",
                                       MS_READER_MAX_LINE);
        }
        scanned = have;
        ms_status st = ms_reader_fill(r, have + 1);
        if (st != MS_OK)
            return st;
    }
}

ms_status ms_reader_flush_vertices(ms_reader *r)
{
    size_t n = r->vertex_pending;
    if (n == 0)
        return MS_OK;
    if (r->vertex_total > UINT32_MAX)
        return ms_error_set(r->err, MS_ERR_RANGE, "%s: more than %u vertices are not supported",
                            r->path, (unsigned)UINT32_MAX);
    const double *v = r->vertex_chunk;
    /* Six scalars rather than arrays, so they stay in registers. */
    double x0 = r->bbox_min[0], y0 = r->bbox_min[1], z0 = r->bbox_min[2];
    double x1 = r->bbox_max[0], y1 = r->bbox_max[1], z1 = r->bbox_max[2];
    for (size_t i = 0; i < n; ++i, v += 3) {
        x0 = v[0] < x0 ? v[0] : x0;
        x1 = v[0] > x1 ? v[0] : x1;
        y0 = v[1] < y0 ? v[1] : y0;
        y1 = v[1] > y1 ? v[1] : y1;
        z0 = v[2] < z0 ? v[2] : z0;
        z1 = v[2] > z1 ? v[2] : z1;
    }
    r->bbox_min[0] = x0, r->bbox_min[1] = y0, r->bbox_min[2] = z0;
    r->bbox_max[0] = x1, r->bbox_max[1] = y1, r->bbox_max[2] = z1;
    v = r->vertex_chunk;
    ms_status st = ms_mesh_cleaner_set_vertex_count(&r->cleaner, r->vertex_total, r->err);
    if (st != MS_OK)
        return st;
    r->vertex_pending = 0;
    report_progress(r);
    if (r->sink->vertices && (st = r->sink->vertices(r->sink->context, v, n, r->err)) != MS_OK)
        return st;
    if (r->colour && r->sink->colours)
        return r->sink->colours(r->sink->context, r->colour_chunk, n, r->err);
    return MS_OK;
}

ms_status ms_reader_enable_colour(ms_reader *r, bool alpha)
{
    if (!r->colour_chunk) {
        r->colour_chunk = malloc(4 * MS_MESH_READ_CHUNK_VERTICES);
        if (!r->colour_chunk)
            return ms_error_set(r->err, MS_ERR_NOMEM, "%s: out of memory for read buffers",
                                r->path);
    }
    r->colour = true;
    r->colour_alpha = alpha;
    return MS_OK;
}

ms_status ms_reader_flush_triangles(ms_reader *r)
{
    ms_status st = ms_reader_flush_vertices(r);
    if (st != MS_OK)
        return st;
    size_t n = r->triangle_pending;
    if (n == 0)
        return MS_OK;
    r->triangle_pending = 0;
    report_progress(r);
    if (r->sink->triangles)
        return r->sink->triangles(r->sink->context, r->triangle_chunk, n, r->err);
    return MS_OK;
}

static bool is_obj_keyword(const char *word, size_t len)
{
    static const char *const keywords[] = {
        "v", "vt", "vn", "vp", "f", "l", "p", "g", "o", "s", "usemtl", "mtllib", "cstype",
        "deg", "curv", "curv2", "surf", "mg", "lod", "maplib", "usemap",
    };
    for (size_t i = 0; i < sizeof keywords / sizeof keywords[0]; ++i)
        if (strlen(keywords[i]) == len && memcmp(keywords[i], word, len) == 0)
            return true;
    return false;
}

/* Looks at the first bytes: "ply" line, an OFF keyword, or OBJ statements. */
static ms_mesh_format detect_format(const char *data, size_t size)
{
    if (size >= 4 && memcmp(data, "ply", 3) == 0 &&
        (data[3] == '\n' || (data[3] == '\r' && size >= 5 && data[4] == '\n')))
        return MS_MESH_FORMAT_PLY_ASCII; /* the header tells which PLY variant */
    size_t i = 0;
    /* Skip blank and comment lines, then judge the first statement. */
    while (i < size) {
        while (i < size && (data[i] == ' ' || data[i] == '\t' || data[i] == '\r' ||
                            data[i] == '\n'))
            ++i;
        if (i < size && data[i] == '#') {
            while (i < size && data[i] != '\n')
                ++i;
            continue;
        }
        break;
    }
    if (i == size && size > 0)
        return MS_MESH_FORMAT_OBJ; /* only comments so far: OBJ's syntax */
    size_t word = i;
    while (i < size && data[i] > ' ' && data[i] < 127 && data[i] != '#')
        ++i;
    size_t len = i - word;
    if (len == 0)
        return MS_MESH_FORMAT_UNKNOWN;
    if (len >= 3 && len <= 6 && memcmp(data + i - 3, "OFF", 3) == 0)
        return MS_MESH_FORMAT_OFF;
    bool word_ends = i == size || data[i] == ' ' || data[i] == '\t' || data[i] == '\r' ||
                     data[i] == '\n' || data[i] == '#';
    if (word_ends && is_obj_keyword(data + word, len))
        return MS_MESH_FORMAT_OBJ;
    return MS_MESH_FORMAT_UNKNOWN;
}

ms_status ms_mesh_read(const char *path, const ms_mesh_sink *sink, ms_mesh_read_report *report,
                       ms_error *err)
{
    ms_reader r;
    memset(&r, 0, sizeof r);
    r.path = path;
    r.sink = sink;
    r.err = err;
    ms_mesh_cleaner_init(&r.cleaner);
    for (int a = 0; a < 3; ++a) {
        r.bbox_min[a] = HUGE_VAL;
        r.bbox_max[a] = -HUGE_VAL;
    }
    if (report)
        memset(report, 0, sizeof *report);
    ms_status st = MS_ERR_ARG;
    if (!path || !sink) {
        st = ms_error_set(err, MS_ERR_ARG, "ms_mesh_read: path and sink are required");
        goto done;
    }
    st = ms_byte_source_open(&r.src, path, MS_READER_BUFFER, err);
    if (st != MS_OK)
        goto done;
    r.vertex_chunk = malloc(sizeof(double) * 3 * MS_MESH_READ_CHUNK_VERTICES);
    r.triangle_chunk = malloc(sizeof(uint32_t) * 3 * MS_MESH_READ_CHUNK_TRIANGLES);
    if (!r.vertex_chunk || !r.triangle_chunk) {
        st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for read buffers", path);
        goto done;
    }
    st = ms_reader_fill(&r, 64 * 1024);
    if (st != MS_OK)
        goto done;
    if (ms_byte_source_available(&r.src) == 0) {
        st = ms_error_set(err, MS_ERR_EMPTY, "%s: file is empty", path);
        goto done;
    }
    r.format = detect_format(r.src.buf + r.src.pos, ms_byte_source_available(&r.src));
    switch (r.format) {
    case MS_MESH_FORMAT_PLY_ASCII:
    case MS_MESH_FORMAT_PLY_BINARY_LE:
    case MS_MESH_FORMAT_PLY_BINARY_BE:
        st = ms_read_ply(&r);
        break;
    case MS_MESH_FORMAT_OBJ:
        r.join_continued_lines = true;
        st = ms_read_obj(&r);
        break;
    case MS_MESH_FORMAT_OFF:
        st = ms_read_off(&r);
        break;
    case MS_MESH_FORMAT_UNKNOWN:
        st = ms_error_set(err, MS_ERR_UNSUPPORTED,
                          "%s: byte offset 0: unknown format (not PLY, OBJ or OFF)", path);
        break;
    }
    if (st == MS_OK)
        st = ms_reader_flush_triangles(&r);
    if (st == MS_OK && r.cleaner.kept_triangles == 0)
        st = ms_error_set(err, MS_ERR_EMPTY, "%s: no triangles (%llu faces read, %llu dropped)",
                          path, (unsigned long long)r.input_faces,
                          (unsigned long long)r.cleaner.dropped_faces);
done:
    if (report) {
        ms_mesh_clean_stats stats;
        ms_mesh_cleaner_stats(&r.cleaner, &stats);
        report->format = r.format;
        report->gzip = r.src.gzip;
        report->input_bytes = ms_byte_source_offset(&r.src);
        report->vertices = r.vertex_total - r.vertex_pending;
        report->triangles = stats.kept_triangles - r.triangle_pending;
        report->input_faces = r.input_faces;
        report->dropped_faces = stats.dropped_faces;
        report->isolated_vertices = stats.isolated_vertices;
        report->colour = r.colour;
        report->colour_alpha = r.colour_alpha;
        for (int a = 0; a < 3; ++a) {
            report->bbox_min[a] = report->vertices ? r.bbox_min[a] : 0.0;
            report->bbox_max[a] = report->vertices ? r.bbox_max[a] : 0.0;
        }
    }
    free(r.vertex_chunk);
    free(r.triangle_chunk);
    free(r.colour_chunk);
    ms_mesh_cleaner_free(&r.cleaner);
    if (r.src.buf)
        ms_byte_source_close(&r.src);
    return st;
}
