/* An indexed triangle mesh held in memory, in world coordinates.
 *
 * This is the hand-over format between the mesh readers (ms_mesh_load), the
 * quantiser and the codec. Positions are doubles (world units of the source
 * file); triangles are counter-clockwise-as-given index triples. The struct owns
 * its two arrays: release them with ms_mesh_free. Not thread-safe per object;
 * distinct objects are independent.
 */
#ifndef MS_MESH_H
#define MS_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_mesh {
    double *positions;      /* 3 * vertex_count doubles, x y z per vertex */
    uint32_t *triangles;    /* 3 * triangle_count vertex indices */
    size_t vertex_count;
    size_t triangle_count;
    size_t vertex_capacity;   /* allocated room, in vertices */
    size_t triangle_capacity; /* allocated room, in triangles */
} ms_mesh;

/* Frees both arrays and zeroes the struct. Accepts NULL and zeroed meshes. */
void ms_mesh_free(ms_mesh *mesh);

/* Reserves room for at least the given counts, keeping the content. Returns
 * MS_ERR_NOMEM (with err set) when the allocation fails or overflows. */
ms_status ms_mesh_reserve(ms_mesh *mesh, size_t vertex_capacity, size_t triangle_capacity,
                          ms_error *err);

#endif
