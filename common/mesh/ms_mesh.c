#include "ms_mesh.h"

#include "ms_grow.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void ms_mesh_free(ms_mesh *mesh)
{
    if (!mesh)
        return;
    free(mesh->positions);
    free(mesh->triangles);
    free(mesh->colours);
    memset(mesh, 0, sizeof *mesh);
}

/* The capacity, from *capacity doubling, that holds `want` items of item_size
 * bytes: so that repeated appends stay linear. */
static ms_status next_capacity(size_t capacity, size_t want, size_t item_size, size_t *out,
                               ms_error *err)
{
    size_t cap = capacity ? capacity : 1024;
    while (cap < want) {
        if (cap > SIZE_MAX / 2)
            return ms_error_set(err, MS_ERR_NOMEM, "mesh too large (%zu items)", want);
        cap *= 2;
    }
    if (cap > SIZE_MAX / item_size)
        return ms_error_set(err, MS_ERR_NOMEM, "mesh too large (%zu items)", want);
    *out = cap;
    return MS_OK;
}

ms_status ms_mesh_reserve(ms_mesh *mesh, size_t vertex_capacity, size_t triangle_capacity,
                          ms_error *err)
{
    if (vertex_capacity > mesh->vertex_capacity) {
        /* Positions and colours grow together; the capacity is raised only when
         * both have the room. */
        size_t cap = 0;
        ms_status st = next_capacity(mesh->vertex_capacity, vertex_capacity, 3 * sizeof(double),
                                     &cap, err);
        if (st != MS_OK)
            return st;
        double *positions = realloc(mesh->positions, cap * 3 * sizeof(double));
        if (!positions)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory reserving %zu mesh items",
                                vertex_capacity);
        mesh->positions = positions;
        if (mesh->colours) {
            uint8_t *colours = realloc(mesh->colours, cap * 4);
            if (!colours)
                return ms_error_set(err, MS_ERR_NOMEM, "out of memory reserving %zu mesh items",
                                    vertex_capacity);
            mesh->colours = colours;
        }
        mesh->vertex_capacity = cap;
    }
    void *triangles = mesh->triangles;
    bool grown = ms_grow(&triangles, &mesh->triangle_capacity, triangle_capacity, 3 * sizeof(uint32_t));
    mesh->triangles = triangles;
    return grown ? MS_OK
                 : ms_error_set(err, MS_ERR_NOMEM, "out of memory reserving %zu mesh triangles", triangle_capacity);
}

ms_status ms_mesh_add_colours(ms_mesh *mesh, bool alpha, ms_error *err)
{
    if (mesh->colours) {
        mesh->colour_alpha = mesh->colour_alpha || alpha;
        return MS_OK;
    }
    size_t room = mesh->vertex_capacity ? mesh->vertex_capacity : 1;
    if (room > SIZE_MAX / 4)
        return ms_error_set(err, MS_ERR_NOMEM, "mesh too large (%zu items)", room);
    mesh->colours = malloc(room * 4);
    if (!mesh->colours)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for %zu vertex colours", room);
    memset(mesh->colours, 255, mesh->vertex_count * 4);
    mesh->colour_alpha = alpha;
    return MS_OK;
}
