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
 * With APO on (params->apo enabled), each cell with vertices also gets its APO
 * chunk (ms_bake_apo.h) on the same thread, right after its stream: m is the
 * stream just encoded, decoded to bits_max (exactly what a client gets); M is,
 * for a leaf, its input triangles at full precision (p bits, positions at their
 * grid cells' centres; duplicates, same three vertices, kept once in record
 * order), and for an internal cell the union of its children's m
 * (ms_bake_apo_union): each child decoded at its own bits_max, log2(n) bits finer
 * than the cell's (a leaf child: full precision). A child's m waits in its
 * parent's task and is freed as soon as the parent's M is built, so the meshes
 * held are bounded like the pending start states, not by the model: the root's M
 * is the model at root_bits + log2(n) bits, not the whole input. (With
 * apo->sample_leaves, the former rule: an internal cell's M is every leaf record
 * below it, re-read from the block file.) Each worker thread owns one APO builder.
 *
 * Thread-safety: one call at a time; it runs its own threads.
 */
#ifndef MS_NSP_ENCODE_H
#define MS_NSP_ENCODE_H

#include <stdint.h>

#include "ms_apo_format.h"
#include "ms_archive_writer.h"
#include "ms_bake_apo.h"
#include "ms_bake_apo_budget.h"
#include "ms_error.h"
#include "ms_nsp_build.h"

typedef struct ms_nsp_encode_params {
    unsigned threads; /* >= 1 */
    const ms_bake_apo_params *apo; /* NULL or not enabled: no APO chunks */
    unsigned ahead;   /* geometry ahead of connectivity, kd-levels (ms_codec.h) */
    unsigned ahead_until; /* where it stops, bits (ms_codec_encode_params.ahead_until) */
    /* the smoothing the error tables measure (ms_codec_encode_params) */
    unsigned smooth_rounds, smooth_level;
    /* NULL: no colour. Else every cell with vertices gets its colour stream
     * (ms_bake_colour.h) at colour_bits (1..8) per channel. */
    const struct ms_bake_colours *colours;
    unsigned colour_bits;
    void (*progress)(void *context, const char *phase, double fraction);
    void *progress_context;
    /* Freed heap memory the encoder leaves resident between internal cells'
     * APO work: above it, the heap is given back to the kernel (a bake's
     * budget, ms_bake_options.mem_mb, counts what stays resident); 0: always
     * given back. Giving it back costs the next cell its page faults again
     * (the dragon: 0.32 s of a 4.8 s bake on one thread). */
    size_t resident_free_max;
} ms_nsp_encode_params;

typedef struct ms_nsp_encode_stats {
    uint64_t welded_vertices;   /* distinct keys over the model */
    uint64_t welded_triangles;  /* distinct triangles over the model */
    uint64_t leaf_triangles;    /* triangles over all leaves (duplicates across cells counted) */
    uint64_t leaf_duplicates;   /* input triangles unified inside leaves (same vertex set) */
    uint64_t isolated_vertices;
    uint64_t geometry_bytes;    /* all payloads */
    uint64_t colour_bytes;      /* all colour streams */
    uint32_t empty_cells;
    uint64_t apo_bytes;         /* compressed chunks */
    uint64_t apo_raw_bytes;     /* texel bytes */
    uint64_t apo_level_texels[MS_APO_MAX_LEVELS]; /* over all chunks, per depth */
    uint32_t apo_levels;        /* deepest chunk's level count */
    uint32_t apo_chunks;        /* cells with a chunk */
    uint64_t apo_internal_nodes, apo_leaves;
    uint64_t apo_rays, apo_point_queries; /* the APO builder's sampling work, summed */
    uint64_t apo_triangle_visits;         /* the APO builder's own triangle work, summed */
    uint64_t apo_samples, apo_sampled_leaves, apo_agreed_leaves; /* samples, leaves sampled, settled by two */
    uint64_t apo_smooth_leaves; /* leaves dropped: m's smooth normal gives M's (docs/APO.md) */
    double apo_thread_seconds;  /* time spent on APO, summed over the threads */
    uint64_t apo_sample_triangles;     /* M's triangles, summed over the internal cells */
    uint64_t apo_sample_triangles_max; /* the largest internal cell's M */
    ms_bake_apo_accuracy apo_accuracy; /* internal cells, with apo->accuracy */
    /* what the byte budget then cut (ms_bake_apo_budget.h): the apo_ figures
     * above are the chunks as built, these their changes (bytes_after: stored) */
    ms_bake_apo_budget_report apo_budget;
    ms_nsp_io io;               /* read back: leaves' blocks and lone-level segments */
    /* per leaf depth: leaves, their triangles, and the triangles they own (smallest
     * key inside): stored - owned are the depth's duplicates */
    uint64_t depth_leaves[MS_NSP_MAX_DEPTH], depth_triangles[MS_NSP_MAX_DEPTH],
        depth_owned[MS_NSP_MAX_DEPTH];
    double seconds;
} ms_nsp_encode_stats;

/* cell_of_node[i] is the archive cell number of build node i. The leaves' lone
 * levels must have been written (ms_nsp_lone_segments): a leaf looks its foreign
 * vertices' levels up in their own leaves' segments. */
ms_status ms_nsp_encode_all(ms_nsp_build *build, const uint32_t *cell_of_node,
                            ms_archive_writer *writer, const ms_nsp_encode_params *params,
                            ms_nsp_encode_stats *stats, ms_error *err);

#endif
