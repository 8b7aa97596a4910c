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
    float *box;      /* 6 per triangle: its bounds, low x y z then high x y z
                        (the octree's split reads them, not the corners) */
    float *vnormal;  /* 3 per vertex, unit (0 if no valid face) */
    float *cnormal;  /* NULL, or 9 per triangle: its corners' smooth normals
                        (ms_apo_local_mesh_corner_normals), unit or 0 */
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

/* The smooth normals a client draws m with (docs/RENDERER.md, "Vertex normals"),
 * as closely as the builder computes them, into lm->cnormal: around each vertex,
 * its triangles are grouped greedily in index order, each joining the first
 * group whose first triangle's normal lies within crease + both triangles'
 * slack of its own (or of its reverse: a triangle wound the other way joins
 * turned over), else starting a group (at most 16; beyond that it joins the
 * nearest); a corner gets its group's area-weighted sum turned to its own
 * triangle's side. A triangle's slack is atan(e / height) with height = twice
 * its area over its longest side: how far its normal may be off when its
 * corners are up to e (cube units: vertex_error) from where they stand for; 0
 * for e = 0. Linear in the triangles (a fan's hub costs its valence times 16).
 * crease in radians (>= pi joins every triangle of a vertex). MS_ERR_NOMEM. */
ms_status ms_apo_local_mesh_corner_normals(ms_apo_local_mesh *lm, double crease, double vertex_error,
                                           ms_error *err);

/* The smooth normal at barycentric (1-u-v, u, v) of triangle t: the corners'
 * normals (cnormal) interpolated, normalised, or ms_apo_local_mesh_normal_at
 * without them; the face normal where they cancel. */
void ms_apo_local_mesh_smooth_at(const ms_apo_local_mesh *lm, uint32_t t, float u, float v, double out[3]);

/* How crowded Embree's boxes of the mesh are: the sum of its triangles' squared
 * bounding-box diagonals over the sum of their areas (cube units; 0 without
 * area). About 4 for a mesh of well-shaped triangles, whatever its size;
 * about N / pi for a fan of N slivers around one vertex, whose boxes all hold
 * the hub, so that a ray there visits a good part of them. */
double ms_apo_crowding(const ms_apo_local_mesh *big);

#endif
