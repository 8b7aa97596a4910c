/* The study's Embree 3 scene over one triangle mesh: what the CPU reference
 * renderer casts rays at (ms_study_render.h) and what the geometric error
 * measures query closest points on (ms_study_measure.h).
 *
 * Precision: the mesh is copied relative to its own origin (the centre of its
 * bounding box, in doubles) and handed to Embree in single precision, so a model
 * far from the world origin (a scan at 1e7) keeps float precision relative to its
 * own extent. Closest-point distances are computed in doubles from the copied
 * double positions; Embree only prunes.
 *
 * Triangles are used as given (no cleaning); a degenerate triangle is never hit
 * by a ray and its closest point is its nearest vertex/edge point.
 *
 * Ownership: the scene copies the mesh and owns its Embree device and scene
 * (ms_study_scene_free). Thread-safety: read-only after _new; any number of
 * threads may render with it or query it at once.
 */
#ifndef MS_STUDY_SCENE_H
#define MS_STUDY_SCENE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_study_scene ms_study_scene;

/* positions: 3 * vertex_count doubles (world units); triangles: 3 *
 * triangle_count indices. Errors: MS_ERR_ARG for an index out of range or more
 * than 2^32 - 1 vertices or triangles, MS_ERR_RANGE for a non-finite coordinate,
 * MS_ERR_NOMEM, MS_ERR_UNSUPPORTED when Embree fails. An empty mesh makes an
 * empty scene (no ray hits; closest-point queries find nothing). */
ms_status ms_study_scene_new(const double *positions, size_t vertex_count, const uint32_t *triangles,
                             size_t triangle_count, ms_study_scene **scene, ms_error *err);
void ms_study_scene_free(ms_study_scene *scene);

size_t ms_study_scene_triangle_count(const ms_study_scene *scene);

/* The axis-aligned bounding box of the scene's vertices (world units); lo > hi
 * (+inf, -inf) for a mesh without vertices. */
void ms_study_scene_bounds(const ms_study_scene *scene, double lo[3], double hi[3]);

/* Total area of the triangles (world units squared). */
double ms_study_scene_area(const ms_study_scene *scene);

/* The closest point of the scene's surface to `point` (world units): returns the
 * distance (+infinity for an empty scene) and, when triangle is not NULL, the
 * triangle it lies on (the lowest index among equally close ones). */
double ms_study_scene_closest(const ms_study_scene *scene, const double point[3], uint32_t *triangle);

#endif
