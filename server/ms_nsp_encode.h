/* Per-cell encoding of a built nSP-tree into an archive (reference 003 §5.3), the
 * second half of a bake.
 *
 * Cells are encoded in post-order on a pool of threads. A leaf's complex is its
 * records at full precision (keys as vertices, duplicated input triangles unified
 * keeping the first one in input order); it is encoded over its window
 * [bits_min, p] and its complex at bits_min (the codec's start state) goes up to
 * its parent. An internal cell's complex at bits_max is the union of its
 * children's start states, duplicated simplices unified by kd key; before encoding
 * it, the encoder checks that splitting it again with ms_nsp_partition_state (what
 * the client does) gives back every child's start state exactly, and fails with
 * MS_ERR_CORRUPT if not. Each cell's output depends only on its own input, and the
 * writer places payloads by cell number, so the archive is byte-identical for any
 * thread count. Ready cells are taken lowest post-order number first, which keeps
 * the pending children's states to about one path of the tree.
 *
 * Thread-safety: one call at a time; it runs its own threads.
 */
#ifndef MS_NSP_ENCODE_H
#define MS_NSP_ENCODE_H

#include <stdint.h>

#include "ms_archive_writer.h"
#include "ms_error.h"
#include "ms_nsp_build.h"

typedef struct ms_nsp_encode_params {
    unsigned threads; /* >= 1 */
    void (*progress)(void *context, const char *phase, double fraction);
    void *progress_context;
} ms_nsp_encode_params;

typedef struct ms_nsp_encode_stats {
    uint64_t welded_vertices;   /* distinct keys over the model */
    uint64_t welded_triangles;  /* distinct triangles over the model */
    uint64_t leaf_triangles;    /* triangles over all leaves (duplicates across cells counted) */
    uint64_t leaf_duplicates;   /* input triangles unified inside leaves (same vertex set) */
    uint64_t isolated_vertices;
    uint64_t geometry_bytes;    /* all payloads */
    uint32_t empty_cells;
    double seconds;
} ms_nsp_encode_stats;

/* cell_of_node[i] is the archive cell number of build node i. */
ms_status ms_nsp_encode_all(const ms_nsp_build *build, const uint32_t *cell_of_node,
                            ms_archive_writer *writer, const ms_nsp_encode_params *params,
                            ms_nsp_encode_stats *stats, ms_error *err);

#endif
