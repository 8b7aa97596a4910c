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
#include "ms_view_decoder.h"

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
    /* ms_view_cell_error_bound's last answer (world units), for bound_bits
     * with decoder bound_dec */
    bool bound_valid;
    uint8_t bound_bits;
    const ms_codec_decoder *bound_dec;
    double bound;
    /* over_valid: its bound at over_bits (the same whenever it is decoded
     * there), which the selection found above the tolerance and refined from */
    bool over_valid;
    uint8_t over_bits;
    double over_bound;
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

/* Drops a cell's stitching cache. */
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
