/* PLY writer (ascii and binary little-endian). See ms_mesh_io.h. */
#include "ms_mesh_io.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int host_is_little_endian(void)
{
    const uint16_t probe = 1;
    return *(const uint8_t *)&probe == 1;
}

/* Appends one little-endian value of `size` bytes to out. */
static void put_le(uint8_t *out, const void *value, size_t size)
{
    const uint8_t *v = value;
    if (host_is_little_endian())
        memcpy(out, v, size);
    else
        for (size_t i = 0; i < size; ++i)
            out[i] = v[size - 1 - i];
}

static int write_header(FILE *f, const ms_mesh *mesh, bool binary, bool use_double)
{
    const char *type = use_double ? "double" : "float";
    return fprintf(f,
                   "ply\nformat %s 1.0\ncomment written by meshstream\n"
                   "element vertex %zu\nproperty %s x\nproperty %s y\nproperty %s z\n"
                   "element face %zu\nproperty list uchar int vertex_indices\nend_header\n",
                   binary ? "binary_little_endian" : "ascii", mesh->vertex_count, type, type,
                   type, mesh->triangle_count) < 0;
}

static int write_binary_body(FILE *f, const ms_mesh *mesh, bool use_double)
{
    uint8_t buf[32];
    for (size_t v = 0; v < mesh->vertex_count; ++v) {
        size_t n = 0;
        for (int a = 0; a < 3; ++a) {
            double d = mesh->positions[3 * v + a];
            if (use_double) {
                put_le(buf + n, &d, 8);
                n += 8;
            } else {
                float x = (float)d;
                put_le(buf + n, &x, 4);
                n += 4;
            }
        }
        if (fwrite(buf, 1, n, f) != n)
            return 1;
    }
    for (size_t t = 0; t < mesh->triangle_count; ++t) {
        buf[0] = 3;
        for (int k = 0; k < 3; ++k) {
            int32_t idx = (int32_t)mesh->triangles[3 * t + k];
            put_le(buf + 1 + 4 * k, &idx, 4);
        }
        if (fwrite(buf, 1, 13, f) != 13)
            return 1;
    }
    return 0;
}

static int write_ascii_body(FILE *f, const ms_mesh *mesh, bool use_double)
{
    for (size_t v = 0; v < mesh->vertex_count; ++v) {
        const double *p = mesh->positions + 3 * v;
        int r = use_double ? fprintf(f, "%.17g %.17g %.17g\n", p[0], p[1], p[2])
                           : fprintf(f, "%.9g %.9g %.9g\n", (float)p[0], (float)p[1], (float)p[2]);
        if (r < 0)
            return 1;
    }
    for (size_t t = 0; t < mesh->triangle_count; ++t) {
        const uint32_t *tri = mesh->triangles + 3 * t;
        if (fprintf(f, "3 %" PRIu32 " %" PRIu32 " %" PRIu32 "\n", tri[0], tri[1], tri[2]) < 0)
            return 1;
    }
    return 0;
}

ms_status ms_ply_write(const char *path, const ms_mesh *mesh, bool binary, bool use_double,
                       ms_error *err)
{
    if (mesh->vertex_count > INT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %zu vertices exceed PLY int indices", path,
                            mesh->vertex_count);
    size_t len = strlen(path);
    char *tmp = malloc(len + 16);
    if (!tmp)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", path);
    snprintf(tmp, len + 16, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        ms_status st = ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", tmp, strerror(errno));
        free(tmp);
        return st;
    }
    int failed = write_header(f, mesh, binary, use_double);
    if (!failed)
        failed = binary ? write_binary_body(f, mesh, use_double)
                        : write_ascii_body(f, mesh, use_double);
    int saved_errno = errno;
    if (fclose(f) != 0 && !failed) {
        failed = 1;
        saved_errno = errno;
    }
    if (!failed && rename(tmp, path) != 0) {
        failed = 1;
        saved_errno = errno;
    }
    if (failed) {
        remove(tmp);
        free(tmp);
        return ms_error_set(err, MS_ERR_IO, "%s: write failed: %s", path, strerror(saved_errno));
    }
    free(tmp);
    return MS_OK;
}
