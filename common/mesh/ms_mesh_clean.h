/* The input cleaning policy, in one place (see docs/INPUT.md).
 *
 *  - A triangle with a repeated vertex index (a==b, b==c or a==c) is dropped and
 *    counted: it has no area and no orientation, and the codec and the simplifier
 *    both assume three distinct corners.
 *  - A triangle with three distinct indices is kept even when its area is zero
 *    (collinear or coincident positions): dropping it could open cracks, and
 *    deciding "zero" needs a tolerance the input does not give us.
 *  - Vertices referenced by no kept triangle ("isolated") are kept, so indices
 *    stay as in the file, and counted.
 *
 * Every mesh reader runs its triangles through an ms_mesh_cleaner before handing
 * them on, so every consumer sees the same cleaned stream. The cleaner keeps one
 * bit per vertex (125 MB per billion vertices).
 *
 * Ownership: the cleaner owns its bitmap; release with ms_mesh_cleaner_free. Not
 * thread-safe per object.
 */
#ifndef MS_MESH_CLEAN_H
#define MS_MESH_CLEAN_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_mesh_cleaner {
    uint64_t *used;        /* bit per vertex: referenced by a kept triangle */
    size_t used_words;     /* allocated 64-bit words */
    uint64_t vertex_count; /* vertices announced so far */
    uint64_t kept_triangles;
    uint64_t dropped_faces;
} ms_mesh_cleaner;

typedef struct ms_mesh_clean_stats {
    uint64_t kept_triangles;
    uint64_t dropped_faces;     /* triangles with a repeated vertex index */
    uint64_t isolated_vertices; /* vertices no kept triangle references */
} ms_mesh_clean_stats;

/* Starts empty; ms_mesh_cleaner_free must be called even if nothing was added. */
void ms_mesh_cleaner_init(ms_mesh_cleaner *cleaner);

/* Announces that the mesh now has vertex_count vertices (never fewer than
 * before). MS_ERR_NOMEM if the bitmap cannot grow. */
ms_status ms_mesh_cleaner_set_vertex_count(ms_mesh_cleaner *cleaner, uint64_t vertex_count,
                                           ms_error *err);

/* Applies the policy to one triangle whose indices are already known to be below
 * the announced vertex count. Returns true to keep it. */
static inline bool ms_mesh_cleaner_keep(ms_mesh_cleaner *cleaner, uint32_t a, uint32_t b,
                                        uint32_t c)
{
    if (a == b || b == c || a == c) {
        ++cleaner->dropped_faces;
        return false;
    }
    cleaner->used[a >> 6] |= UINT64_C(1) << (a & 63);
    cleaner->used[b >> 6] |= UINT64_C(1) << (b & 63);
    cleaner->used[c >> 6] |= UINT64_C(1) << (c & 63);
    ++cleaner->kept_triangles;
    return true;
}

/* Filters `count` triangles (3 indices each, all below the announced vertex
 * count) in place, keeping the order of the kept ones; returns how many were
 * kept. Same policy as ms_mesh_cleaner_keep, for whole batches. */
size_t ms_mesh_cleaner_filter(ms_mesh_cleaner *cleaner, uint32_t *triangles, size_t count);

/* The totals so far; isolated vertices are counted over all announced vertices. */
void ms_mesh_cleaner_stats(const ms_mesh_cleaner *cleaner, ms_mesh_clean_stats *stats);

void ms_mesh_cleaner_free(ms_mesh_cleaner *cleaner);

#endif
