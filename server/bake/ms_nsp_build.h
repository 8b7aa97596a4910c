/* Out-of-core construction of the nSP-tree (reference 003 §4.2), the first half
 * of a bake.
 *
 * ms_nsp_build_run streams the input mesh once (ms_mesh_read), spooling vertices
 * (3 doubles) and triangles (3 u32) to unlinked temporary files while it finds the
 * bounding box; fits the cubic quantisation box (as ms_quant_fit_box); writes every
 * input vertex's interleaved key at p bits to a key file (8 bytes per input
 * vertex, on disk; two blocks of the spool at a time, on params.threads); then
 * streams the triangles again, looks their vertices' keys up through a bounded
 * cache of key-file pages (key_cache_bytes), and inserts each non-degenerate
 * triangle (three distinct keys: welding is implicit, vertices are their keys)
 * into every leaf holding one of its vertices. A leaf that reaches
 * N_min triangles splits into n^3 children and redistributes its content. With
 * two threads or more the look-ups and the insertions run as a two-stage
 * pipeline (the next chunk's keys on one thread while the other inserts the
 * last chunk's records, in input order): the tree is that of one thread. Input
 * vertices used by no kept triangle (the key file marks the used ones) are then
 * inserted as point records (isolated vertices), in input order.
 *
 * Leaf content is a list of 24-byte records (the three vertices' keys, input
 * order kept; a point record repeats one key) held in a per-leaf memory buffer
 * and a chain of 4 KiB blocks in an unlinked temporary file; when the buffers
 * together exceed the budget they are flushed largest first down to half of it,
 * and the blocks of a split leaf are reused; at the end every buffer is flushed,
 * so that the encoding phase starts with only the tree in memory. RAM is
 * therefore the key cache + the buffer budget + the tree (about 100 bytes per
 * cell) + one splitting leaf's records, whatever the number of vertices: no
 * per-vertex array is held. The records carry their keys, so that nothing after
 * this phase needs the input vertex numbering.
 *
 * After the run, ms_nsp_build_read_leaf and ms_nsp_build_leaf_of may be called
 * from several threads at once (they only read the block file with pread and the
 * tree). Everything else is not thread-safe. Temporary files are unlinked at
 * creation: a killed process leaves nothing behind.
 */
#ifndef MS_NSP_BUILD_H
#define MS_NSP_BUILD_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh_reader.h"
#include "ms_nsp.h"
#include "ms_quant.h"

#define MS_NSP_NONE UINT32_MAX
#define MS_NSP_MAX_DEPTH 32              /* deeper than any shape allows (p <= 20) */
#define MS_NSP_RECORD_BYTES 24         /* a leaf record: three u64 keys */
#define MS_NSP_KEY_CACHE_MIN (256u << 10) /* bytes: the smallest key cache (64 pages) */

typedef struct ms_nsp_node {
    uint32_t parent;       /* MS_NSP_NONE for the root */
    uint32_t first_child;  /* node index of the first of n^3 children, or MS_NSP_NONE */
    uint32_t position[3];
    uint8_t depth;
    uint64_t triangles;    /* triangle records inserted (leaves; duplicates of input included) */
    uint64_t records;      /* all records (triangles and points) */
    int64_t head_block;    /* newest block of the chain on disk, -1 for none */
    uint32_t blocks;
    uint32_t buffered;     /* records in buf */
    uint32_t buffer_cap;
    uint64_t *buf;         /* 3 * buffer_cap keys */
    int64_t lone_at;       /* leaves: its lone-level segment (ms_nsp_lone.h), -1 before */
    uint32_t lone_count;   /* distinct keys of its own vertices in that segment */
} ms_nsp_node;

/* Bytes a phase wrote to temporary files (spilled) and read back from them. */
typedef struct ms_nsp_io {
    uint64_t spilled, read_back;
} ms_nsp_io;

/* The default split threshold N_min by model size (issue 23): 8000 (the thesis's
 * value) up to MS_NSP_DEFAULT_SCALE_FROM input triangles; above, 8000 times the
 * fourth root of (triangles / MS_NSP_DEFAULT_SCALE_FROM), rounded down to a multiple
 * of 100, at most MS_NSP_DEFAULT_MIN_TRIANGLES_MAX: 10,000 at 10 M triangles,
 * 17,800 at 100 M, the maximum from 324 M on. A split into n^3 children leaves
 * about C / n^2 triangles in each child a surface crosses (C: the cell's), so the
 * leaves range from about N_min / n^2 to N_min, and the copies a leaf stores for
 * its border go as 1 / sqrt(its triangles): with a fixed N_min the deeper trees
 * of large models end in many small leaves (10.2 % stored duplication at 100 M
 * with 8000; docs/PERFORMANCE.md, "Baking at scale"). The fourth root keeps the leaves
 * large enough for at most 8 % there while the number of cells still grows
 * nearly as the model (T^(3/4)); models up to 4 M triangles (every shared model)
 * keep 8000, and their archives are unchanged. scale_from replaces
 * MS_NSP_DEFAULT_SCALE_FROM when not 0. Pure function: thread-safe. */
#define MS_NSP_DEFAULT_MIN_TRIANGLES 8000u
#define MS_NSP_DEFAULT_MIN_TRIANGLES_MAX 24000u
#define MS_NSP_DEFAULT_SCALE_FROM 4000000u
uint32_t ms_nsp_default_min_triangles(uint64_t input_triangles, uint64_t scale_from);

typedef struct ms_nsp_build_params {
    ms_nsp_shape shape;
    uint32_t min_triangles;  /* N_min; 0: ms_nsp_default_min_triangles of the input's
                              * triangle count (known once the input is read; the run
                              * stores the value used in its params.min_triangles) */
    uint64_t default_scale_from; /* with min_triangles 0: the size from which the default
                                  * grows; 0: MS_NSP_DEFAULT_SCALE_FROM (tests lower it to
                                  * see the rule on a small model) */
    size_t buffer_budget;    /* bytes of record buffers before flushing */
    size_t key_cache_bytes;  /* key-file pages held while distributing (at least
                              * MS_NSP_KEY_CACHE_MIN; less is raised to it) */
    unsigned threads;        /* 2 or more: the distribution looks keys up on a second
                              * thread while the first inserts (the tree is the same
                              * for any value); 0 or 1: one thread */
    const char *tmp_dir;     /* where temporary files go */
    /* optional progress: phase name and a fraction in [0, 1] */
    void (*progress)(void *context, const char *phase, double fraction);
    void *progress_context;
} ms_nsp_build_params;

typedef struct ms_nsp_build_stats {
    ms_mesh_read_report read;      /* what the reader reported */
    uint64_t input_vertices, input_triangles;
    uint64_t degenerate_triangles; /* dropped: two vertices weld together */
    uint64_t leaf_triangle_records;/* triangle records over all leaves (before per-leaf dedup) */
    uint64_t insertion_copies;     /* copies beyond the first made as the triangle records
                                    * descend the tree when read (a record reaching k leaves
                                    * adds k - 1); the copies made later, when a full leaf's
                                    * records are redistributed into its children, are not
                                    * counted. This is how the thesis's table 4.1 counts
                                    * duplication (docs/ARCHIVE.md, "Duplication"); the
                                    * stored overhead is leaf_triangle_records minus the
                                    * triangles. */
    uint64_t point_records;
    uint64_t blocks_written, flushes;
    uint64_t key_page_misses;      /* key-file pages read while distributing */
    ms_nsp_io io_read, io_quantise, io_distribute; /* temporary-file traffic per phase */
    double seconds_read, seconds_quantise, seconds_distribute;
    /* Filled by ms_nsp_lone_segments: how many of the model's distinct
     * vertices are first alone in their kd-cell at each kd-level (0..3 p) */
    uint64_t lone_at_level[3 * MS_CODEC_MAX_BITS + 1];
} ms_nsp_build_stats;

typedef struct ms_nsp_build {
    ms_nsp_build_params params;
    ms_quant_box box;
    size_t vertex_count;
    ms_nsp_node *nodes;     /* node 0 is the root; children of a node are consecutive */
    uint32_t node_count, node_cap;
    int block_fd;           /* -1 before use */
    int64_t block_file_end;
    int64_t *free_blocks;
    size_t free_count, free_cap;
    size_t buffered_bytes;
    uint8_t *block_scratch;
    int lone_fd;            /* lone-level segments (ms_nsp_lone.h), -1 before */
    uint16_t child_of_group[512]; /* child offset by the n^3 values of a level's key bits */
    ms_nsp_build_stats stats;
} ms_nsp_build;

/* Builds the tree for the mesh at path; build->params.min_triangles is the
 * threshold used (params->min_triangles, or its default). On failure everything
 * is released and the temporary files are gone. */
ms_status ms_nsp_build_run(const char *path, const ms_nsp_build_params *params,
                           ms_nsp_build *build, ms_error *err);

/* Reads a leaf's records in input order into *records (3 keys each, malloc'd,
 * caller frees; a point record has three equal keys); *count receives the number
 * of records, *bytes_read (if not NULL) is increased by the bytes read from the
 * block file. Thread-safe after the run. */
ms_status ms_nsp_build_read_leaf(const ms_nsp_build *build, uint32_t node, uint64_t **records,
                                 size_t *count, uint64_t *bytes_read, ms_error *err);

/* The leaf whose cube holds the full-precision key. Thread-safe after the run. */
uint32_t ms_nsp_build_leaf_of(const ms_nsp_build *build, uint64_t key);

/* Creates an unlinked temporary file in dir (a killed process leaves nothing);
 * returns its descriptor, or -1 with err set. */
int ms_nsp_temp_file(const char *dir, ms_error *err);

/* Breadth-first numbering: order[i] is the node of cell i; first_child[i] the cell
 * number of cell i's first child or MS_NSP_NONE (both arrays of node_count, caller
 * frees). */
ms_status ms_nsp_build_bfs(const ms_nsp_build *build, uint32_t **order, uint32_t **first_child,
                           ms_error *err);

void ms_nsp_build_free(ms_nsp_build *build);

#endif
