/* PLY writer (ascii and binary little-endian). See ms_mesh_io.h. */
#include "ms_mesh_io.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

struct ms_ply_writer {
    FILE *file;
    char *path;     /* final name */
    char *tmp_path; /* name written until finish */
    bool binary, use_double;
    int colour_channels; /* 0, 3 (red green blue) or 4 (and alpha) uchars per vertex */
    uint64_t vertices_left, triangles_left;
    uint64_t vertex_count; /* for index range checks */
};

static int host_is_little_endian(void)
{
    const uint16_t probe = 1;
    return *(const uint8_t *)&probe == 1;
}

/* Stores one value of `size` bytes little-endian at out. */
static void put_le(uint8_t *out, const void *value, size_t size)
{
    const uint8_t *v = value;
    if (host_is_little_endian())
        memcpy(out, v, size);
    else
        for (size_t i = 0; i < size; ++i)
            out[i] = v[size - 1 - i];
}

static void writer_free(ms_ply_writer *w)
{
    if (w->file)
        fclose(w->file);
    free(w->path);
    free(w->tmp_path);
    free(w);
}

void ms_ply_writer_abort(ms_ply_writer *w)
{
    if (!w)
        return;
    if (w->file) {
        fclose(w->file);
        w->file = NULL;
    }
    remove(w->tmp_path);
    writer_free(w);
}

/* Reports a write failure and aborts the writer. */
static ms_status writer_fail(ms_ply_writer *w, ms_error *err)
{
    ms_status st = ms_error_set(err, MS_ERR_IO, "%s: write failed: %s", w->path, strerror(errno));
    ms_ply_writer_abort(w);
    return st;
}

ms_status ms_ply_writer_open(const char *path, uint64_t vertex_count, uint64_t triangle_count,
                             bool binary, bool use_double, ms_ply_writer **writer, ms_error *err)
{
    return ms_ply_writer_open_colour(path, vertex_count, triangle_count, binary, use_double, 0,
                                     writer, err);
}

ms_status ms_ply_writer_open_colour(const char *path, uint64_t vertex_count,
                                    uint64_t triangle_count, bool binary, bool use_double,
                                    int colour_channels, ms_ply_writer **writer, ms_error *err)
{
    *writer = NULL;
    if (vertex_count > INT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %" PRIu64 " vertices exceed PLY int indices",
                            path, vertex_count);
    ms_ply_writer *w = calloc(1, sizeof *w);
    size_t len = strlen(path);
    if (w) {
        w->path = strdup(path);
        w->tmp_path = malloc(len + 16);
    }
    if (!w || !w->path || !w->tmp_path) {
        if (w)
            writer_free(w);
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    }
    snprintf(w->tmp_path, len + 16, "%s.partial", path);
    w->binary = binary;
    w->use_double = use_double;
    w->colour_channels = colour_channels == 3 || colour_channels == 4 ? colour_channels : 0;
    w->vertices_left = w->vertex_count = vertex_count;
    w->triangles_left = triangle_count;
    w->file = fopen(w->tmp_path, "wb");
    if (!w->file) {
        ms_status st =
            ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", w->tmp_path, strerror(errno));
        writer_free(w);
        return st;
    }
    setvbuf(w->file, NULL, _IOFBF, 1 << 20);
    const char *type = use_double ? "double" : "float";
    if (fprintf(w->file,
                "ply\nformat %s 1.0\ncomment written by meshstream\n"
                "element vertex %" PRIu64 "\nproperty %s x\nproperty %s y\nproperty %s z\n"
                "%s%s"
                "element face %" PRIu64 "\nproperty list uchar int vertex_indices\nend_header\n",
                binary ? "binary_little_endian" : "ascii", vertex_count, type, type, type,
                w->colour_channels ? "property uchar red\nproperty uchar green\n"
                                     "property uchar blue\n" : "",
                w->colour_channels == 4 ? "property uchar alpha\n" : "",
                triangle_count) < 0)
        return writer_fail(w, err);
    *writer = w;
    return MS_OK;
}

ms_status ms_ply_writer_vertex(ms_ply_writer *w, const double p[3], ms_error *err)
{
    static const uint8_t white[4] = {255, 255, 255, 255};
    return ms_ply_writer_coloured_vertex(w, p, white, err);
}

ms_status ms_ply_writer_coloured_vertex(ms_ply_writer *w, const double p[3], const uint8_t rgba[4],
                                        ms_error *err)
{
    if (w->vertices_left == 0) {
        ms_status st = ms_error_set(err, MS_ERR_ARG, "%s: more vertices than declared", w->path);
        ms_ply_writer_abort(w);
        return st;
    }
    w->vertices_left--;
    int failed;
    const int channels = w->colour_channels;
    if (w->binary) {
        uint8_t buf[28];
        size_t n = 0;
        for (int a = 0; a < 3; ++a) {
            if (w->use_double) {
                put_le(buf + n, &p[a], 8);
                n += 8;
            } else {
                float x = (float)p[a];
                put_le(buf + n, &x, 4);
                n += 4;
            }
        }
        memcpy(buf + n, rgba, (size_t)channels);
        n += (size_t)channels;
        failed = fwrite(buf, 1, n, w->file) != n;
    } else {
        if (w->use_double)
            failed = fprintf(w->file, "%.17g %.17g %.17g", p[0], p[1], p[2]) < 0;
        else
            failed = fprintf(w->file, "%.9g %.9g %.9g", (float)p[0], (float)p[1], (float)p[2]) < 0;
        for (int c = 0; c < channels && !failed; ++c)
            failed = fprintf(w->file, " %u", (unsigned)rgba[c]) < 0;
        failed = failed || fputc('\n', w->file) == EOF;
    }
    return failed ? writer_fail(w, err) : MS_OK;
}

ms_status ms_ply_writer_triangle(ms_ply_writer *w, const uint32_t tri[3], ms_error *err)
{
    ms_status st = MS_OK;
    if (w->vertices_left != 0)
        st = ms_error_set(err, MS_ERR_ARG, "%s: triangle written before all vertices", w->path);
    else if (w->triangles_left == 0)
        st = ms_error_set(err, MS_ERR_ARG, "%s: more triangles than declared", w->path);
    else if (tri[0] >= w->vertex_count || tri[1] >= w->vertex_count || tri[2] >= w->vertex_count)
        st = ms_error_set(err, MS_ERR_RANGE, "%s: triangle index out of range", w->path);
    if (st != MS_OK) {
        ms_ply_writer_abort(w);
        return st;
    }
    w->triangles_left--;
    int failed;
    if (w->binary) {
        uint8_t buf[13];
        buf[0] = 3;
        for (int k = 0; k < 3; ++k) {
            int32_t idx = (int32_t)tri[k];
            put_le(buf + 1 + 4 * k, &idx, 4);
        }
        failed = fwrite(buf, 1, 13, w->file) != 13;
    } else {
        failed = fprintf(w->file, "3 %" PRIu32 " %" PRIu32 " %" PRIu32 "\n", tri[0], tri[1],
                         tri[2]) < 0;
    }
    return failed ? writer_fail(w, err) : MS_OK;
}

ms_status ms_ply_writer_finish(ms_ply_writer *w, ms_error *err)
{
    if (w->vertices_left || w->triangles_left) {
        ms_status st = ms_error_set(err, MS_ERR_ARG, "%s: fewer elements written than declared",
                                    w->path);
        ms_ply_writer_abort(w);
        return st;
    }
    FILE *f = w->file;
    w->file = NULL;
    if (fclose(f) != 0 || rename(w->tmp_path, w->path) != 0) {
        ms_status st = ms_error_set(err, MS_ERR_IO, "%s: write failed: %s", w->path, strerror(errno));
        ms_ply_writer_abort(w);
        return st;
    }
    writer_free(w);
    return MS_OK;
}

ms_status ms_ply_write(const char *path, const ms_mesh *mesh, bool binary, bool use_double,
                       ms_error *err)
{
    ms_ply_writer *w;
    int channels = mesh->colours ? (mesh->colour_alpha ? 4 : 3) : 0;
    ms_status st = ms_ply_writer_open_colour(path, mesh->vertex_count, mesh->triangle_count,
                                             binary, use_double, channels, &w, err);
    for (size_t v = 0; st == MS_OK && v < mesh->vertex_count; ++v)
        st = channels ? ms_ply_writer_coloured_vertex(w, mesh->positions + 3 * v,
                                                      mesh->colours + 4 * v, err)
                      : ms_ply_writer_vertex(w, mesh->positions + 3 * v, err);
    for (size_t t = 0; st == MS_OK && t < mesh->triangle_count; ++t)
        st = ms_ply_writer_triangle(w, mesh->triangles + 3 * t, err);
    return st == MS_OK ? ms_ply_writer_finish(w, err) : st;
}
