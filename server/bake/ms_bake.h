/* A whole bake: input mesh -> ARCHIVE_DIR/NAME.msa + its catalogue entry.
 *
 * Phases: read (stream the input into spools), quantise (keys), distribute (the
 * out-of-core nSP-tree, ms_nsp_build.h), encode (ms_nsp_encode.h, on `threads`
 * threads, each cell's APO chunk built right after its stream when apo.enabled;
 * report.seconds_apo is APO's share of this phase) and write (the archive writer's finish, then the catalogue update).
 * Temporary files live in tmp_dir (default: the archive directory) and are unlinked
 * when created; the archive appears under its final name only once complete
 * (docs/ARCHIVE.md), so a failed or killed bake leaves neither a partial archive
 * nor a catalogue entry. A stale NAME.msa.partial from an earlier killed bake is
 * removed first.
 *
 * Phases and memory (docs/ARCHIVE.md, "Memory"): no array per input vertex or
 * triangle is held. read spools the input to disk; quantise writes the keys to a
 * key file; distribute holds a quarter of mem_mb of key-file pages, an eighth of
 * mem_mb of leaf buffers and the tree; lone (ms_nsp_lone.h) and encode hold, per
 * thread, the working set of one cell (its records, its complex and the codec's
 * state: proportional to min_triangles for a leaf; for an internal cell its
 * children's start states, bounded by the precision window), plus the tree and
 * the post-order's pending start states; with APO, also the
 * cell's M (a leaf's own triangles; an internal cell's children's meshes at their
 * bits_max, bounded by the precision window, not by the model: ms_nsp_encode.h)
 * with an Embree scene over it, and the finished cells' meshes waiting for their
 * parents. With apo.sample_leaves or apo.accuracy, the full-precision triangles
 * below the internal cell (the whole model for the root: not bounded).
 * Thread-safety: one bake per process at a time (it runs its own threads).
 */
#ifndef MS_BAKE_H
#define MS_BAKE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "ms_apo_format.h"
#include "ms_bake_apo.h"
#include "ms_bake_apo_budget.h"
#include "ms_error.h"
#include "ms_metadata.h"
#include "ms_nsp_build.h"

/* The smallest mem_mb a bake works in: MS_BAKE_MEM_BASE_MB for the fixed buffers
 * (the key cache's floor, spool chunks, the leaf buffers' floor) plus, per
 * thread, one leaf's working set (about MS_BAKE_BYTES_PER_LEAF_TRIANGLE per
 * triangle of min_triangles, rounded up to whole MB). */
#define MS_BAKE_MEM_BASE_MB 2
#define MS_BAKE_BYTES_PER_LEAF_TRIANGLE 512
size_t ms_bake_min_mem_mb(unsigned threads, uint32_t min_triangles);

typedef struct ms_bake_options {
    const char *input;
    const char *archive_dir;
    const char *name;      /* NULL: derived from the input file name */
    const char *tmp_dir;   /* NULL: archive_dir */
    unsigned bits, n, root_bits, threads;
    int public_bits;       /* catalogue public_max_bits (preview), 0..bits; < 0: bits (all public) */
    uint32_t min_triangles; /* N_min; 0: by model size (ms_nsp_default_min_triangles) */
    size_t mem_mb;
    size_t buffer_bytes;   /* leaf buffer budget; 0: an eighth of mem_mb (tests force flushes) */
    size_t key_cache_bytes;/* key-file pages while distributing; 0: a quarter of mem_mb */
    FILE *progress;        /* progress bar target (drawn only on a terminal), or NULL */
    FILE *notes;           /* one-line notices (stale files removed), or NULL */
    ms_bake_apo_params apo; /* per-cell APO chunks (ms_bake_apo.h) */
    unsigned subtree_levels;  /* levels per index subtree, 1..8; 0: the default for n
                               * (ms_subtree_default_levels) */
    unsigned ahead;        /* geometry ahead of connectivity, kd-levels (ms_codec.h) */
    /* Where geometry ahead stops, bits, 0..MS_CODEC_MAX_AHEAD_UNTIL (0: never;
     * ms_codec_encode_params.ahead_until): past it the smoothing alone draws
     * the coarse points, and a cut there costs no byte for geometry ahead */
    unsigned ahead_until;
    /* Rounds of smoothing a client draws the coarse precisions with
     * (ms_codec_state_smooth; 0..MS_CODEC_SMOOTH_ROUNDS_MAX, 0: none): below
     * the precision where half the model's vertices are alone in their
     * kd-cell (ms_bake_smooth_bits) */
    unsigned smooth_rounds;
    /* Per-vertex colour, when the input has it (ms_bake_colour.h): colour_bits
     * per channel, 1..8 (0: MS_COLOUR_DEFAULT_BITS); no_colour leaves it out. */
    unsigned colour_bits;
    bool no_colour;
    const ms_metadata *metadata; /* NULL, or the sidecar's (kept in the catalogue entry;
                                  * NULL keeps what a previous bake of NAME had) */
    bool no_thumbnail;     /* skip DIR/NAME.thumb.png (ms_bake_thumbnail.h) */
    int thumbnail_up;      /* the thumbnail's world up: 0 x, 1 y, 2 z; < 0 (default):
                            * a previous bake's of NAME, else z */
} ms_bake_options;

/* Defaults: 16 bits, n = 4, p_r = 7, N_min by model size (8000 up to 4 M input
 * triangles: ms_nsp_default_min_triangles), threads = online CPUs, 512 MB,
 * APO on with ms_bake_apo_params_default, geometry ahead by MS_CODEC_DEFAULT_AHEAD,
 * stopping at MS_BAKE_DEFAULT_AHEAD_UNTIL bits, MS_BAKE_DEFAULT_SMOOTH_ROUNDS rounds
 * of smoothing (docs/ACCURACY.md). */
#define MS_BAKE_DEFAULT_AHEAD_UNTIL 5u
#define MS_BAKE_DEFAULT_SMOOTH_ROUNDS 5u
void ms_bake_options_default(ms_bake_options *options);

/* The precision below which a client draws smoothed points: the first bit
 * 1..bits at which at least half of the model's distinct vertices are alone
 * in their kd-cell (lone_at_level[l]: how many are first alone at kd-level l,
 * 0..3 bits; ms_nsp_build_stats). Above it most points stand for themselves
 * and smoothing would move them off the surface. 0 for a model without
 * vertices. */
unsigned ms_bake_smooth_bits(const uint64_t *lone_at_level, unsigned bits);

typedef struct ms_bake_report {
    char name[65];
    char archive_path[4096];
    uint64_t input_vertices, input_triangles;  /* as read (after the reader's cleaning) */
    uint64_t vertices, triangles;              /* welded, quantised */
    unsigned smooth_rounds, smooth_bits;       /* the archive's smoothing (ms_archive_header) */
    uint64_t leaf_triangles;                   /* over all leaves */
    double duplicated_percent;                 /* (leaf_triangles - triangles) / triangles */
    uint64_t insertion_copies;                 /* ms_nsp_build_stats.insertion_copies */
    double duplicated_at_insertion_percent;    /* insertion_copies / triangles: the thesis's
                                                * table 4.1 figure, lower than the stored
                                                * overhead (docs/ARCHIVE.md, "Duplication") */
    uint32_t cells, leaves, empty_cells, depth;
    uint32_t min_triangles;                    /* N_min used (options' or the default) */
    uint64_t archive_bytes, geometry_bytes;
    bool colour, colour_alpha;                 /* colour streams baked (with alpha) */
    unsigned colour_bits;                      /* their precision, 0 without colour */
    uint64_t colour_bytes;                     /* all cells' colour streams */
    double seconds_colour;                     /* reading the colours (a second read) */
    double bits_per_vertex;                    /* 8 archive_bytes / vertices */
    double seconds_read, seconds_quantise, seconds_distribute, seconds_lone, seconds_encode,
        seconds_write, seconds_total;
    double seconds_thumbnail;                  /* inside seconds_write */
    uint64_t thumbnail_bytes;                  /* 0: none made */
    unsigned thumbnail_bits;
    double peak_rss_mb;
    double peak_rss_build_mb;              /* peak when the tree was built (before encoding) */
    unsigned threads;
    uint64_t blocks_written, flushes; /* leaf content spilled to the block file */
    uint64_t key_page_misses;         /* key-file pages read while distributing */
    /* temporary-file bytes per phase: spilled (written) and read back */
    ms_nsp_io io_read, io_quantise, io_distribute, io_lone, io_encode;
    /* duplication by leaf depth (ms_nsp_encode_stats) */
    uint64_t depth_leaves[MS_NSP_MAX_DEPTH], depth_triangles[MS_NSP_MAX_DEPTH],
        depth_owned[MS_NSP_MAX_DEPTH];
    /* APO (all zero when off) */
    uint64_t apo_bytes, apo_raw_bytes;         /* compressed in the archive / texel bytes */
    ms_bake_apo_budget_report apo_budget;      /* what the byte budget cut (all 0: nothing) */
    uint64_t apo_level_texels[MS_APO_MAX_LEVELS]; /* texels per depth over all chunks */
    uint32_t apo_levels;                       /* entries of apo_level_texels used */
    uint32_t apo_chunks;
    uint64_t apo_internal_nodes, apo_leaves;
    uint64_t apo_rays, apo_point_queries; /* sampling work: rays and closest-point queries cast */
    uint64_t apo_triangle_visits;         /* the builder's own work: triangles looked at one by one */
    uint64_t apo_samples;         /* samples taken (at most MS_APO_SAMPLES_PER_LEAF per leaf) */
    uint64_t apo_sampled_leaves;  /* leaves sampled, before the correction rule */
    uint64_t apo_agreed_leaves;   /* of which settled by two agreeing samples (adaptive sampling) */
    uint64_t apo_smooth_leaves; /* sampled leaves dropped: the client's smooth normal suffices there */
    double seconds_apo;   /* APO's share of the encode phase: thread-seconds / threads */
    uint64_t apo_sample_triangles;     /* triangles of the internal cells' M, summed */
    uint64_t apo_sample_triangles_max; /* the largest internal cell's M (memory driver) */
    /* with apo.accuracy: internal cells' chunks against the full-precision
     * triangles below them (ms_bake_apo_accuracy), degrees */
    uint64_t apo_accuracy_points;
    double apo_accuracy_mean, apo_accuracy_median, apo_accuracy_p90;
} ms_bake_report;

/* Derives a valid model name from a file path (basename without extensions, other
 * characters replaced by '_'), into out (at least 65 bytes). */
void ms_bake_default_name(const char *path, char *out, size_t size);

ms_status ms_bake(const ms_bake_options *options, ms_bake_report *report, ms_error *err);

#endif
