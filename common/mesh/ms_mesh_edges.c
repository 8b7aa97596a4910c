/* The edges of a triangle mesh (ms_mesh_edges.h): every triangle side as a
 * key (low vertex, high vertex) with its direction, radix-sorted so that the
 * sides of one edge are neighbours. */
#include "ms_mesh_edges.h"

#include <stdlib.h>
#include <string.h>

#include "ms_radix_sort.h"

ms_status ms_mesh_count_edges(const uint32_t *triangles, size_t triangle_count, ms_mesh_edge_counts *counts,
                              ms_error *err)
{
    memset(counts, 0, sizeof *counts);
    if (triangle_count > (SIZE_MAX / 3) / sizeof(uint64_t) || 3 * triangle_count > UINT32_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "edges: %zu triangles are too many to count", triangle_count);
    size_t sides = 3 * triangle_count;
    uint64_t *keys = malloc((sides ? sides : 1) * sizeof *keys);
    uint32_t *forward = malloc((sides ? sides : 1) * sizeof *forward);
    if (!keys || !forward) {
        free(keys);
        free(forward);
        return ms_error_set(err, MS_ERR_NOMEM, "edges: no memory for %zu triangles", triangle_count);
    }
    size_t n = 0;
    uint32_t highest = 0;
    for (size_t t = 0; t < triangle_count; ++t)
        for (int k = 0; k < 3; ++k) {
            uint32_t a = triangles[3 * t + (size_t)k], b = triangles[3 * t + (size_t)((k + 1) % 3)];
            if (a == b)
                continue;
            uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
            highest = hi > highest ? hi : highest;
            keys[n] = (uint64_t)lo << 32 | hi;
            forward[n++] = a < b; /* the side runs from the lower index up */
        }
    /* only the bits the indices use, both halves: the high half's lowest bit
     * is bit 32, so sort all 64 when the indices need any */
    ms_status st = ms_radix_sort_pairs(keys, forward, n, highest ? 64 : 1, err);
    if (st == MS_OK)
        for (size_t i = 0; i < n;) {
            size_t j = i + 1;
            uint32_t ups = forward[i];
            while (j < n && keys[j] == keys[i])
                ups += forward[j++];
            size_t uses = j - i;
            counts->edges++;
            if (uses == 1)
                counts->boundary++;
            else if (uses > 2)
                counts->non_manifold++;
            else if (ups == 1)
                counts->manifold++;
            else
                counts->flipped++;
            i = j;
        }
    free(keys);
    free(forward);
    return st;
}
