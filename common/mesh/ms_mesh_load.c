/* ms_mesh_load: the whole mesh in memory, on top of the streaming reader. */
#include "ms_mesh_io.h"
#include "ms_mesh_reader.h"

#include <string.h>

static ms_status append_vertices(void *context, const double *positions, size_t count,
                                 ms_error *err)
{
    ms_mesh *mesh = context;
    ms_status st = ms_mesh_reserve(mesh, mesh->vertex_count + count, 0, err);
    if (st != MS_OK)
        return st;
    memcpy(mesh->positions + 3 * mesh->vertex_count, positions, 3 * count * sizeof(double));
    mesh->vertex_count += count;
    return MS_OK;
}

/* Called right after append_vertices with the same vertices, which are the last
 * `count` of the mesh. */
static ms_status append_colours(void *context, const uint8_t *rgba, size_t count, ms_error *err)
{
    ms_mesh *mesh = context;
    if (!mesh->colours) {
        ms_status st = ms_mesh_add_colours(mesh, false, err);
        if (st != MS_OK)
            return st;
    }
    memcpy(mesh->colours + 4 * (mesh->vertex_count - count), rgba, 4 * count);
    return MS_OK;
}

static ms_status append_triangles(void *context, const uint32_t *indices, size_t count,
                                  ms_error *err)
{
    ms_mesh *mesh = context;
    ms_status st = ms_mesh_reserve(mesh, 0, mesh->triangle_count + count, err);
    if (st != MS_OK)
        return st;
    memcpy(mesh->triangles + 3 * mesh->triangle_count, indices, 3 * count * sizeof(uint32_t));
    mesh->triangle_count += count;
    return MS_OK;
}

ms_status ms_mesh_load(const char *path, ms_mesh *mesh, ms_mesh_load_report *report,
                       ms_error *err)
{
    if (!mesh)
        return ms_error_set(err, MS_ERR_ARG, "ms_mesh_load: mesh is required");
    memset(mesh, 0, sizeof *mesh);
    const ms_mesh_sink sink = {
        .context = mesh, .vertices = append_vertices, .triangles = append_triangles,
        .colours = append_colours,
    };
    ms_mesh_read_report read;
    ms_status st = ms_mesh_read(path, &sink, &read, err);
    if (st != MS_OK)
        ms_mesh_free(mesh);
    else
        mesh->colour_alpha = mesh->colours && read.colour_alpha;
    if (report) {
        report->format = ms_mesh_format_name(read.format);
        report->gzip = read.gzip;
        report->input_bytes = read.input_bytes;
        report->input_faces = read.input_faces;
        report->dropped_faces = read.dropped_faces;
        report->isolated_vertices = read.isolated_vertices;
    }
    return st;
}
