/* Inside the view decoder (ms_view_decoder.h): the per-cell state that
 * decoding (ms_view_decoder.c) and stitching (ms_view_stitch.c) share.
 * Private to the view decoder's files. */
#ifndef MS_VIEW_DECODER_INTERNAL_H
#define MS_VIEW_DECODER_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_colour.h"
#include "ms_nsp.h"
#include "ms_parallel.h"
#include "ms_view_decoder.h"

/* A shown cell's stitch, kept for the next stitches (ms_view_stitch.c): its
 * triangles as corners of its cache (r < vertex count: its own vertex r) or of
 * foreign vertices (r - vertex count: entry of `calls`, a neighbour's cache
 * vertex, in the order the stitch first asked for them), the cells and what of
 * them it depended on (deps: the notes of its version), its version and its
 * figures. Valid while every dep says the same (ms_view_stitch.c). */
typedef struct vpiece_dep {
    uint32_t cell;
    uint64_t word;
} vpiece_dep;

typedef struct vpiece {
    uint64_t version;
    uint32_t *corners;       /* 3 per triangle */
    size_t tri_count, tri_cap; /* tri_cap: in corners */
    uint32_t *calls;         /* 2 per call: cell, cache vertex */
    size_t call_count, call_cap;
    vpiece_dep *deps;
    size_t dep_count, dep_cap;
    size_t dropped_finer, dropped_snapped, unresolved, snapped_frozen;
} vpiece;

typedef struct vcell {
    ms_archive_cell rec;
    bool known;             /* rec holds the cell's record (ms_view_learn) */
    uint8_t state;
    uint8_t bits;           /* current precision (SHOWN), bits_max (SPLIT) */
    uint8_t target;         /* the last selection's (ms_view_select), MS_VIEW_TARGET_* or bits */
    bool has_start;         /* start state held (non-root cells once their parent split) */
    ms_codec_state start;
    ms_codec_decoder *dec;
    size_t dec_bytes;       /* bytes the decoder was created from */
    uint8_t *bytes;
    size_t nbytes;
    /* stitching cache: the complex at `cache_bits` */
    bool cache_valid;
    uint8_t cache_bits;
    ms_codec_state cache;
    uint32_t *out_index;    /* per cache vertex: index in the stitched mesh, or NONE */
    uint32_t *owner;        /* per cache vertex: shown cell holding it, NONE = finer cells */
    double *positions;      /* per cache vertex: its position, 3 doubles (world units; made
                             * with the cache, so a stitch copies them) */
    uint8_t *levels;        /* per cache vertex: its kd-level, when some foreign vertex is
                             * frozen coarser than the cell (else NULL: all at its level) */
    /* colour (ms_view_colour.c): the colour stream's bytes held, its decoder,
     * and per cache vertex its colour (valid with colour_valid) */
    uint8_t *colour_bytes;
    size_t colour_nbytes;
    ms_colour_decoder *cdec;
    bool colour_based;      /* cdec has its base colours (its own, or given from the parent) */
    uint64_t *top_cells;    /* once its whole colour is decoded: its cells at bits_max and */
    uint8_t *top_colours;   /* their colours, the base its children's streams take */
    size_t top_n;
    uint8_t *cache_colours;
    bool colour_valid;
    uint32_t colour_rev, stitched_colour_rev; /* renewed with every new colour byte */
    /* versions of the stitched triangles (ms_view_mesh.run_version) */
    uint8_t stitched_state, stitched_bits; /* as the last stitch saw them */
    uint64_t stamp;         /* renewed when a stitch sees them change */
    vpiece *piece;          /* the last stitch of the cell (NULL: none; dropped with the
                             * cache) */
} vcell;

/* Cells are kept per sibling group: ids are breadth-first, so every group of
 * n^3 siblings is a block of consecutive ids starting at 1 + k n^3 (group 0 is
 * the root alone). A group's block exists while one of its records is known,
 * so what a view holds follows the records it learned (ms_view_learn), plus one
 * pointer per n^3 cells for the whole model. */
struct ms_view {
    ms_archive_header header;
    ms_nsp_shape shape;
    uint32_t count;
    uint32_t group_size;    /* n^3 */
    uint32_t group_count;   /* 1 + (count - 1) / n^3 */
    vcell **groups;         /* group_count blocks, NULL where no record is known */
    uint32_t known;         /* cells whose records are known */
    uint32_t block_cells;   /* cells of the blocks in `groups` (known or not) */
    uint32_t stamp_epoch;
    uint64_t stitch_stamps; /* the last stamp handed out (vcell.stamp) */
    ms_pool *pool;          /* borrowed: the stitch's per-cell steps run on it (NULL:
                             * on the caller alone), ms_view_set_pool */
};

/* The group of cell id and its place in it. */
static inline uint32_t ms_view_group_of(const ms_view *v, uint32_t id)
{
    return id == 0 ? 0 : 1 + (id - 1) / v->group_size;
}

static inline uint32_t ms_view_group_first(const ms_view *v, uint32_t group)
{
    return group == 0 ? 0 : 1 + (group - 1) * v->group_size;
}

/* The state of a known cell, or NULL when its record is not known (or id is
 * out of range). */
static inline vcell *ms_view_vcell(const ms_view *v, uint32_t id)
{
    if (id >= v->count)
        return NULL;
    vcell *block = v->groups[ms_view_group_of(v, id)];
    if (!block)
        return NULL;
    vcell *c = &block[id == 0 ? 0 : (id - 1) % v->group_size];
    return c->known ? c : NULL;
}

#define NONE 0xFFFFFFFFu
#define OWNER_FINER 0xFFFFFFFEu

/* Frees a cell's kept stitch (ms_view_stitch.c). */
void ms_view_piece_free(vcell *c);
/* Frees every cell's kept stitch: the next stitch works out every cell again
 * (the tests' reference for the stitch that keeps them). */
void ms_view_pieces_forget(ms_view *view);
/* Drops a cell's stitching cache (and its kept stitch). */
void ms_view_cache_drop(vcell *c);

/* ms_view_colour.c: drops a cell's colour decoder and cached colours (keeps
 * its colour bytes), and frees everything colour of it. */
void ms_view_colour_drop(vcell *c);
void ms_view_colour_free(vcell *c);
/* Whether the cell can give colours (it holds its colour stream's base). */
bool ms_view_colour_ready(const vcell *c);
/* Fills the cache colours of cell (its valid cache; decoding its colour as far
 * as the cache's level and the bytes allow, its base from its parent's whole
 * colour stream when the stream takes it from there): one line on a damaged
 * stream. */
ms_status ms_view_colour_refresh(ms_view *view, uint32_t cell, ms_error *err);

#endif
