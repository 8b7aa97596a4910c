/* A triangle mesh moved into an APO cube's frame (the cube becomes [0,1]^3), in
 * single precision, with what the builder needs per triangle (unit face normal,
 * area; bounds are recomputed from the vertices where needed, which costs less
 * than 24 bytes per triangle of a large M) and per vertex (area-weighted unit
 * normal). pos has one float of padding after the last vertex (Embree reads
 * vertices 16 bytes at a time from the buffer it shares). Internal to the APO
 * builder (server/apo/ms_apo_build.c, server/apo/ms_apo_sample.c).
 *
 * Ownership: the struct owns every array except `tri`, which borrows the source
 * mesh's triangles (the source must outlive it). Read-only after make: any number
 * of threads may read it.
 */
#ifndef MS_APO_LOCAL_MESH_H
#define MS_APO_LOCAL_MESH_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh.h"

typedef struct ms_apo_local_mesh {
    float *pos;      /* 3 per vertex */
    uint32_t *tri;   /* 3 per triangle */
    float *fnormal;  /* 3 per triangle, unit (0 for degenerate) */
    float *area;     /* per triangle */
    float *vnormal;  /* 3 per vertex, unit (0 if no valid face) */
    size_t vertex_count, triangle_count;
} ms_apo_local_mesh;

/* Moves `mesh` into the cube [origin, origin + size)^3 (mesh units). Errors:
 * MS_ERR_RANGE for a non-finite coordinate, MS_ERR_ARG for a bad index or a mesh
 * beyond 32-bit indices, MS_ERR_NOMEM; `name` ("m", "M") goes into the message.
 * On error *lm is left zeroed. */
ms_status ms_apo_local_mesh_make(const ms_mesh *mesh, const double origin[3], double size, const char *name,
                                 ms_apo_local_mesh *lm, ms_error *err);
void ms_apo_local_mesh_free(ms_apo_local_mesh *lm);

/* Interpolated vertex normal at barycentric (1-u-v, u, v) of triangle t,
 * normalised; the face normal where the vertex normals cancel (zero for a
 * degenerate triangle). */
void ms_apo_local_mesh_normal_at(const ms_apo_local_mesh *lm, uint32_t t, float u, float v, double out[3]);

/* How crowded Embree's boxes of the mesh are: the sum of its triangles' squared
 * bounding-box diagonals over the sum of their areas (cube units; 0 without
 * area). About 4 for a mesh of well-shaped triangles, whatever its size;
 * about N / pi for a fan of N slivers around one vertex, whose boxes all hold
 * the hub, so that a ray there visits a good part of them. */
double ms_apo_crowding(const ms_apo_local_mesh *big);

#endif
