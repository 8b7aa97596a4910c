/* An indexed triangle mesh held in memory, in world coordinates.
 *
 * This is the hand-over format between the mesh readers (ms_mesh_load), the
 * quantiser and the codec. Positions are doubles (world units of the source
 * file); triangles are counter-clockwise-as-given index triples.
 *
 * Colour is optional: `colours` is NULL for a mesh without colour (no memory
 * spent), else it holds r g b a (8 bits each) per vertex, with room for
 * vertex_capacity vertices like positions. colour_alpha says whether the input
 * had an alpha channel; without one every a is 255. Readers fill it
 * (docs/INPUT.md); the codec, the archive and the renderer do not carry it yet.
 *
 * Ownership: the struct owns its arrays (positions, triangles, colours): release
 * them with ms_mesh_free. Code that builds a mesh from another one's vertices
 * (copies, welds, filters) carries colours along with positions. Not thread-safe
 * per object; distinct objects are independent.
 */
#ifndef MS_MESH_H
#define MS_MESH_H

#include <stdbool.h>
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
    uint8_t *colours;         /* NULL, or 4 * vertex_capacity bytes: r g b a per vertex */
    bool colour_alpha;        /* colours came with alpha (else every a is 255) */
} ms_mesh;

/* Frees the arrays and zeroes the struct. Accepts NULL and zeroed meshes. */
void ms_mesh_free(ms_mesh *mesh);

/* Reserves room for at least the given counts, keeping the content (colours
 * too, when the mesh has them). Returns MS_ERR_NOMEM (with err set) when the
 * allocation fails or overflows; the mesh is then still consistent. */
ms_status ms_mesh_reserve(ms_mesh *mesh, size_t vertex_capacity, size_t triangle_capacity,
                          ms_error *err);

/* Gives the mesh colours if it has none: room for vertex_capacity vertices, the
 * vertices already there opaque white; sets colour_alpha to alpha. A mesh that
 * has colours keeps them (colour_alpha becomes true if alpha is). MS_ERR_NOMEM. */
ms_status ms_mesh_add_colours(ms_mesh *mesh, bool alpha, ms_error *err);

#endif
