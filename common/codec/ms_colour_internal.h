/* Colour codec internals shared by its encoder and decoder (docs/COLOUR.md).
 *
 * The encoder runs the decoder's own level step in encode mode (details taken
 * from a list instead of the range decoder), so both sides compute every
 * context and prediction with one code path.
 */
#ifndef MS_COLOUR_INTERNAL_H
#define MS_COLOUR_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_colour.h"
#include "ms_rangecoder.h"

#define MS_COLOUR_MAGIC "MSCL"
#define MS_COLOUR_LEAD 20  /* magic .. final cells */
#define MS_COLOUR_BASE_ENTRY 8
#define MS_COLOUR_CHUNK_ENTRY 12

/* The coded slots of a split: Y, Co, Cg of the detail d (r g b) by the
 * lossless YCoCg-R transform, then d of alpha (d = lower child - upper child,
 * per channel). */
enum { CC_SLOTS = 4, CC_ACT = 8, CC_CLASSES = 10, CC_SIGNS = 3 };

/* One adaptive model of a signed residual: zero?, sign (by predicted sign),
 * Elias-gamma class in unary, mantissa (top bit by class, the rest per class
 * and position). */
typedef struct cc_residual {
    ms_rc_prob zero;
    ms_rc_prob sign[CC_SIGNS];
    ms_rc_prob cls[CC_CLASSES];
    ms_rc_prob top[CC_CLASSES];
} cc_residual;

typedef struct cc_model {
    cc_residual slot[CC_SLOTS][CC_ACT];
    ms_rc_prob low[CC_SLOTS][CC_CLASSES][CC_CLASSES];
    cc_residual base[CC_SLOTS];
} cc_model;

/* The cells of one kd-level with their colours (c-bit values, r g b a) and the
 * state the contexts need: per cell and slot the magnitude of the last split
 * in its lineage (act). */
typedef struct cc_level {
    uint64_t *cells;
    uint8_t *col;   /* 4 per cell */
    uint32_t *par;  /* index of each cell's parent in the level above (cc_step) */
    uint16_t *act;  /* CC_SLOTS per cell */
    size_t n, cap;
} cc_level;

/* Neighbours of the children of the splits at one kd-level: cell i's at
 * adj[off[i] .. off[i] + deg[i]), distinct (deg 0 for a cell that
 * is not the child of a split). */
typedef struct cc_graph {
    uint32_t *off, *adj, *deg;
    size_t n;
} cc_graph;

/* The graph of the cells (n, sorted) at kd-level `level` from the complex cx at
 * a level at or below it (cx->level >= level): cells joined by one of its
 * triangles' sides or edges. MS_ERR_ARG when cx's cells do not have exactly
 * these prefixes; the caller has checked cx's indices. */
ms_status cc_graph_build(const ms_codec_state *cx, unsigned level, const uint64_t *cells, size_t n,
                         cc_graph *g, ms_error *err);
void cc_graph_free(cc_graph *g);

typedef struct cc_coder {
    bool encoding;
    ms_rc_encoder enc;
    ms_rc_decoder dec;
    const int16_t *src; /* encode mode: 4 details (r g b a) per split of the level */
    size_t src_n, src_at;
    unsigned bits;      /* colour precision c */
    unsigned slots;     /* 3, or 4 with alpha */
    cc_model *m;
} cc_coder;

void cc_model_init(cc_model *m);

ms_status cc_level_reserve(cc_level *l, size_t n, ms_error *err);
void cc_level_free(cc_level *l);

/* Codes the colours of the n cells of l (base chunk): each channel against
 * the previous cell's. Decode mode fills l->col; act is zeroed. */
ms_status cc_code_base(cc_coder *c, cc_level *l, ms_error *err);

/* One kd-level: cur (at kd-level `level`) refines to next, whose cells
 * (next_cells, n) and neighbour graph g the caller gives; their parents must be exactly cur's cells
 * (MS_ERR_ARG otherwise). Fills next (cells copied). Decode mode: MS_ERR_CORRUPT
 * for a detail that makes a colour leave [0, 2^c). */
ms_status cc_step(cc_coder *c, const cc_level *cur, unsigned level, const uint64_t *next_cells,
                  size_t n, const cc_graph *g, cc_level *next, ms_error *err);

/* The colours of the parents of l's cells (the rule of ms_colour.h) into out,
 * cells and colours only (out may not alias l). */
ms_status cc_coarsen(const cc_level *l, cc_level *out, ms_error *err);

/* Header (full layout, little-endian): writes h at p (NULL: only counts) and
 * returns its size. */
size_t cc_write_header(uint8_t *p, const ms_colour_header *h);
/* ms_colour_read_header, the header CRC checked only when check_crc. */
ms_status cc_read_header(const uint8_t *data, size_t size, ms_colour_header *h, bool check_crc,
                         ms_error *err);

static inline int cc_floor_half(int v)
{
    return v >= 0 ? v / 2 : -((-v + 1) / 2);
}

#endif
