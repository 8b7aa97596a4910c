/* The edges of a triangle mesh by vertex index, counted for `meshbake --info`:
 * how well a mesh's faces agree on their orientation and how many edges are
 * not manifold. An edge is an unordered pair of distinct vertex indices used
 * by a triangle side; two triangles that agree on their orientation use a
 * shared edge in opposite directions.
 *
 * Memory: 12 bytes per triangle side (3 per triangle), freed before return.
 * Thread-safety: no shared state. */
#ifndef MS_MESH_EDGES_H
#define MS_MESH_EDGES_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_mesh_edge_counts {
    uint64_t edges;        /* distinct edges */
    uint64_t boundary;     /* used by one triangle side */
    uint64_t manifold;     /* used by two sides in opposite directions */
    uint64_t flipped;      /* used by two sides in the same direction: one of the two
                              triangles is wound against the other (inconsistent
                              orientation) */
    uint64_t non_manifold; /* used by three or more sides */
} ms_mesh_edge_counts;

/* Counts the edges of triangles[0 .. 3 * triangle_count) (vertex indices; a
 * side whose two ends are the same vertex is no edge). MS_ERR_NOMEM. */
ms_status ms_mesh_count_edges(const uint32_t *triangles, size_t triangle_count, ms_mesh_edge_counts *counts,
                              ms_error *err);

#endif
