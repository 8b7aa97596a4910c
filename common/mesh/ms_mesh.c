#include "ms_mesh.h"

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

void ms_mesh_free(ms_mesh *mesh)
{
    if (!mesh)
        return;
    free(mesh->positions);
    free(mesh->triangles);
    memset(mesh, 0, sizeof *mesh);
}

/* Grows *array to hold at least `want` items of `item_size` bytes, doubling so
 * that repeated appends stay linear. */
static ms_status grow_array(void **array, size_t *capacity, size_t want, size_t item_size,
                            ms_error *err)
{
    if (want <= *capacity)
        return MS_OK;
    size_t cap = *capacity ? *capacity : 1024;
    while (cap < want) {
        if (cap > SIZE_MAX / 2)
            return ms_error_set(err, MS_ERR_NOMEM, "mesh too large (%zu items)", want);
        cap *= 2;
    }
    if (cap > SIZE_MAX / item_size)
        return ms_error_set(err, MS_ERR_NOMEM, "mesh too large (%zu items)", want);
    void *grown = realloc(*array, cap * item_size);
    if (!grown)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory reserving %zu mesh items", want);
    *array = grown;
    *capacity = cap;
    return MS_OK;
}

ms_status ms_mesh_reserve(ms_mesh *mesh, size_t vertex_capacity, size_t triangle_capacity,
                          ms_error *err)
{
    void *positions = mesh->positions;
    ms_status st = grow_array(&positions, &mesh->vertex_capacity, vertex_capacity,
                              3 * sizeof(double), err);
    mesh->positions = positions;
    if (st != MS_OK)
        return st;
    void *triangles = mesh->triangles;
    st = grow_array(&triangles, &mesh->triangle_capacity, triangle_capacity,
                    3 * sizeof(uint32_t), err);
    mesh->triangles = triangles;
    return st;
}
