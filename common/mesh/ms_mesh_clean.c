#include "ms_mesh_clean.h"

#include <stdlib.h>
#include <string.h>

void ms_mesh_cleaner_init(ms_mesh_cleaner *cleaner)
{
    memset(cleaner, 0, sizeof *cleaner);
}

ms_status ms_mesh_cleaner_set_vertex_count(ms_mesh_cleaner *cleaner, uint64_t vertex_count,
                                           ms_error *err)
{
    if (vertex_count < cleaner->vertex_count)
        return ms_error_set(err, MS_ERR_ARG, "internal: vertex count went down");
    uint64_t words = (vertex_count + 63) / 64;
    if (words > cleaner->used_words) {
        uint64_t grown = cleaner->used_words ? cleaner->used_words : 256;
        while (grown < words)
            grown *= 2;
        if (grown > SIZE_MAX / sizeof(uint64_t))
            return ms_error_set(err, MS_ERR_NOMEM, "too many vertices (%llu)",
                                (unsigned long long)vertex_count);
        uint64_t *used = realloc(cleaner->used, (size_t)grown * sizeof(uint64_t));
        if (!used)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory tracking %llu vertices",
                                (unsigned long long)vertex_count);
        memset(used + cleaner->used_words, 0,
               (size_t)(grown - cleaner->used_words) * sizeof(uint64_t));
        cleaner->used = used;
        cleaner->used_words = (size_t)grown;
    }
    cleaner->vertex_count = vertex_count;
    return MS_OK;
}

size_t ms_mesh_cleaner_filter(ms_mesh_cleaner *cleaner, uint32_t *triangles, size_t count)
{
    /* Locals, so the bitmap stores do not force reloads of the counters. */
    uint64_t *used = cleaner->used;
    size_t kept = 0;
    for (size_t t = 0; t < count; ++t) {
        uint32_t a = triangles[3 * t], b = triangles[3 * t + 1], c = triangles[3 * t + 2];
        if (a == b || b == c || a == c)
            continue;
        used[a >> 6] |= UINT64_C(1) << (a & 63);
        used[b >> 6] |= UINT64_C(1) << (b & 63);
        used[c >> 6] |= UINT64_C(1) << (c & 63);
        triangles[3 * kept] = a;
        triangles[3 * kept + 1] = b;
        triangles[3 * kept + 2] = c;
        ++kept;
    }
    cleaner->kept_triangles += kept;
    cleaner->dropped_faces += count - kept;
    return kept;
}

void ms_mesh_cleaner_stats(const ms_mesh_cleaner *cleaner, ms_mesh_clean_stats *stats)
{
    uint64_t used = 0;
    uint64_t full_words = cleaner->vertex_count / 64;
    for (uint64_t w = 0; w < full_words; ++w)
        used += (uint64_t)__builtin_popcountll(cleaner->used[w]);
    unsigned rest = (unsigned)(cleaner->vertex_count % 64);
    if (rest)
        used += (uint64_t)__builtin_popcountll(cleaner->used[full_words] &
                                               ((UINT64_C(1) << rest) - 1));
    stats->kept_triangles = cleaner->kept_triangles;
    stats->dropped_faces = cleaner->dropped_faces;
    stats->isolated_vertices = cleaner->vertex_count - used;
}

void ms_mesh_cleaner_free(ms_mesh_cleaner *cleaner)
{
    free(cleaner->used);
    memset(cleaner, 0, sizeof *cleaner);
}
