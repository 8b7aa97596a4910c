/* The built-in demo model: a closed, sculpture-like surface with fine relief,
 * generated procedurally so that demos and tests need no data file.
 *
 * The surface is a cubed sphere (each of the 6 cube faces is an n x n grid of
 * quads, 2 triangles each) pushed radially by a deterministic relief function:
 * a few broad lumps give the silhouette, several octaves of lattice noise and
 * carved grooves give the fine detail. Radial displacement of a sphere keeps the
 * surface closed, manifold, consistently oriented (outward) and free of
 * self-intersections. Counts: 12 n^2 triangles and 6 n^2 + 2 vertices.
 *
 * Everything is a pure function of (n, seed): no global state, thread-safe.
 * Vertex indices and the triangle order are fixed, so output is byte-identical
 * from run to run.
 */
#ifndef MS_DEMO_MODEL_H
#define MS_DEMO_MODEL_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh.h"

#define MS_DEMO_MIN_GRID 2u
#define MS_DEMO_MAX_GRID 4096u /* 201 M triangles: far beyond any demo */

typedef struct ms_demo_model {
    uint32_t grid;  /* n: quads per cube-face edge */
    uint64_t seed;  /* selects the relief; 0 is the documented default */
} ms_demo_model;

/* The grid whose triangle count 12 n^2 is nearest to `triangles`, clamped to
 * [MS_DEMO_MIN_GRID, MS_DEMO_MAX_GRID]. */
uint32_t ms_demo_grid_for_triangles(uint64_t triangles);

uint64_t ms_demo_vertex_count(const ms_demo_model *model);
uint64_t ms_demo_triangle_count(const ms_demo_model *model);

/* World position (unit-ish radius, metres if you like) of vertex `index`. */
void ms_demo_vertex(const ms_demo_model *model, uint64_t index, double out[3]);

/* Vertex indices of triangle `index`, counter-clockwise seen from outside. */
void ms_demo_triangle(const ms_demo_model *model, uint64_t index, uint32_t out[3]);

/* Builds the whole model in memory. *mesh must be zeroed; MS_ERR_ARG for a grid
 * outside the valid range, MS_ERR_NOMEM if it does not fit. */
ms_status ms_demo_build(const ms_demo_model *model, ms_mesh *mesh, ms_error *err);

#endif
