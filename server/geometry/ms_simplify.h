/* Quadric-error mesh simplification (OpenMesh's decimater), behind a C interface.
 *
 * This is the only C++ in the project: server/geometry/ms_simplify.cpp wraps OpenMesh.
 * Faces OpenMesh refuses (they would make an edge non-manifold) are left out of
 * the simplification and counted; everything else is collapsed edge by edge in
 * order of quadric error until at most `target_triangles` remain (or no legal
 * collapse is left).
 *
 * Ownership: *out must be zeroed; on success it owns new arrays (ms_mesh_free).
 * Vertex colour is not carried: out->colours stays NULL whatever in has.
 * Errors: MS_ERR_EMPTY (no usable triangle), MS_ERR_ARG (bad index, target 0),
 * MS_ERR_NOMEM. Thread-safety: independent calls may run concurrently, except
 * that OpenMesh's own error stream is silenced during a call (a process-wide
 * switch in OpenMesh), so run one call at a time if OpenMesh logs elsewhere.
 */
#ifndef MS_SIMPLIFY_H
#define MS_SIMPLIFY_H

#include <stddef.h>

/* The common headers are plain C without linkage guards. */
#ifdef __cplusplus
extern "C" {
#endif

#include "ms_error.h"
#include "ms_mesh.h"

typedef struct ms_simplify_report {
    size_t input_triangles;
    size_t refused_faces;     /* not accepted by OpenMesh (non-manifold, degenerate) */
    size_t output_triangles;
    size_t output_vertices;
} ms_simplify_report;

ms_status ms_simplify(const ms_mesh *in, size_t target_triangles, ms_mesh *out, ms_simplify_report *report,
                      ms_error *err);

#ifdef __cplusplus
}
#endif

#endif
