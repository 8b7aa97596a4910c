/* Internal pieces shared by the codec's encoder and decoder. */
#ifndef MS_CODEC_INTERNAL_H
#define MS_CODEC_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_complex.h"
#include "ms_rangecoder.h"

#define MS_CODEC_MAGIC "MSGC"
#define MS_CODEC_FIXED_HEADER 72

#define MS_CODEC_REGION_BYTES 16

/* Writes h (version, window, box unless compact, counts, region, table) and the
 * header CRC into p and returns its size; with p NULL only returns the size. */
size_t ms_codec_write_header(uint8_t *p, const ms_codec_header *h);
uint32_t ms_codec_crc(const uint8_t *p, size_t n);
/* Whether r obeys ms_codec_region's rules for the window [p_min, p_max]
 * (MS_ERR_FORMAT with the reason otherwise). */
ms_status ms_codec_region_check(const ms_codec_region *r, unsigned p_min, unsigned p_max,
                                ms_error *err);

/* Whether the cell with minimum corner c lies outside the region (cells of the
 * window lie wholly inside or outside). */
static inline bool ms_codec_outside(const ms_codec_region *r, const uint32_t c[3])
{
    uint32_t side = 1u << r->log2_side;
    return (uint32_t)(c[0] - r->min[0]) >= side || (uint32_t)(c[1] - r->min[1]) >= side ||
           (uint32_t)(c[2] - r->min[2]) >= side;
}
/* Whether cell s of cx lies outside the region. */
static inline bool cell_outside(const ms_complex *cx, const ms_codec_region *r, uint32_t s)
{
    uint32_t c[3];
    ms_cx_corner(cx, s, c);
    return ms_codec_outside(r, c);
}
/* ms_codec_read_header with the header CRC check optional (fuzzing). */
ms_status ms_codec_parse_header(const uint8_t *data, size_t size, ms_codec_header *h,
                                bool verify_crc, ms_error *err);

/* What the surface error of an encode is measured against (ms_codec_surface.c):
 * points in key order at the stream's precision with their keys, and where
 * the forward pass writes the error of every precision of the window
 * (ms_codec_encode_params.surface_error). */
typedef struct ms_surface_truth {
    ms_codec_truth points;
    const uint64_t *keys;
    uint64_t *keys_owned; /* keys when they are not the complex's own */
    double *error;        /* p_max - p_min + 1 entries, grid units */
    /* the smoothing a client applies below kd-level smooth_level (rounds 0:
     * none; ms_codec_encode_params.smooth_rounds) */
    unsigned smooth_rounds, smooth_level;
} ms_surface_truth;

/* The encoder's forward pass: runs the decoder from `start` over the window of h,
 * taking each binary decision from decisions[0..n) (decode order), or for the
 * geometry ahead (h->ahead > 0) from the sorted full keys[0..nkeys), and coding it
 * into enc with the decoder's contexts; fills h's chunk table. context_counts
 * (may be NULL) accumulates the decisions per context (ms_codec_encode_params);
 * mesh (may be NULL) receives the decoded mesh at the end (ms_codec_decoder_mesh);
 * truth (may be NULL) receives the surface error of every bit (ms_surface_error). */
ms_status ms_codec_run_encoder(ms_codec_header *h, const ms_codec_state *start,
                               const uint8_t *decisions, size_t n, const uint64_t *keys,
                               size_t nkeys, ms_rc_encoder *enc, uint64_t *context_counts,
                               ms_mesh *mesh, const ms_surface_truth *truth, ms_error *err);

/* Exports a complex whose live cells (order[0..n), sorted by key) all sit at
 * `level` as a canonical ms_codec_state; bound (NULL, or n values in order's
 * order) becomes its per-vertex bound. */
ms_status ms_codec_export_complex(const ms_complex *cx, const uint32_t *order, uint32_t n,
                                  unsigned level, const float *bound, ms_codec_state *out,
                                  ms_error *err);

/* Sorts n tuples of `arity` (2 or 3) vertex indices, each below index_limit,
 * lexicographically in place (stable; radix sort). MS_ERR_NOMEM on allocation
 * failure, x unchanged. */
ms_status ms_sort_index_tuples(uint32_t *x, size_t n, unsigned arity, size_t index_limit,
                               ms_error *err);

/* The decoder's state (ms_codec_decode.c decodes, ms_codec_decoder_start.c
 * loads its start state, ms_codec_decoder_out.c reads it out). */
typedef struct birth_stack {
    uint8_t *b;
    uint32_t n, cap;
} birth_stack;

struct ms_codec_decoder {
    uint8_t *data;          /* copy of the stream */
    size_t size;
    ms_codec_header h;
    const uint8_t *body;
    size_t body_avail;      /* bytes of body present */
    unsigned D, Lmin, level, avail_level;
    ms_complex cx;
    uint32_t *order, *order2;
    uint32_t norder, cap_order;
    uint32_t nmodel;
    ms_rc_prob *model;
    ms_rc_prob *snap;       /* per chunk: model at the chunk's start */
    uint8_t *snap_valid, *crc_ok;
    ms_rc_decoder rc;
    unsigned rc_chunk;      /* chunk the range decoder is in, or UINT_MAX */
    birth_stack births[3 * MS_CODEC_MAX_BITS];
    ms_cx_star star;
    uint8_t *code, *side, *cov;
    uint8_t *partners;      /* per neighbour: partner_flag of its partners coded so far */
    int32_t *vote;          /* per neighbour: orientation votes (the encoder's star_votes) */
    uint32_t *pivot;        /* the neighbours with code 4, in order */
    uint8_t *tcode;
    size_t cap_code, cap_tcode;
    uint32_t compact_nv;    /* slots in use after the last compaction */
    uint32_t frozen;        /* frozen foreign cells now */
    /* Encode mode (the encoder's forward pass): decisions come from src and are
     * range-coded into enc with the very contexts the decoder uses. */
    ms_rc_encoder *enc;
    const uint8_t *src;
    size_t src_n, src_pos;
    ms_codec_header *enc_h;
    uint64_t *train;        /* encode mode: context counts in the prior's layout */
    /* Encode mode with geometry ahead: every vertex's full key, sorted; the
     * ahead decisions are read off it (ms_codec_ahead.c). */
    const uint64_t *okeys;
    size_t nokeys;
    bool skip_crc;
    bool has_box;           /* world positions known (ms_codec_decoder_mesh) */
    bool broken;
};

/* Loads the caller's start state (NULL: the single root cell, for a stream
 * from precision 0) into d->cx and d->order, after checking it against the
 * stream's header: MS_ERR_ARG when it does not match (level, counts,
 * checksum, indices), MS_ERR_NOMEM. ms_codec_decoder_start.c. */
ms_status ms_codec_decoder_load_start(ms_codec_decoder *d, const ms_codec_state *start,
                                      ms_error *err);

/* Geometry ahead of connectivity (ms_codec_ahead.c, docs/CODEC.md §4.1). A cell
 * runs ahead when its mask (cx.ahead) is not 0: h.ahead > 0 and the cell is not
 * foreign. Its depth at kd-level L is min(h.ahead, E - L), E the window's end D
 * or where geometry ahead stops (3 h.ahead_until), 0 from E on: there a cell
 * (mask 1, itself) codes its geometry inline and is drawn at its centre. */
static inline unsigned ms_ahead_depth(const ms_codec_decoder *d, unsigned level)
{
    unsigned end = d->h.ahead_until ? 3 * d->h.ahead_until : d->D;
    unsigned left = level < end ? end - level : 0;
    return left < d->h.ahead ? left : d->h.ahead;
}
/* The prelude at the start of the first chunk: every cell that runs ahead
 * (mask reset to itself) learns its descendants ahead_depth(Lmin) levels down,
 * level by level; then the drawn points. */
ms_status ms_ahead_prelude(ms_codec_decoder *d, ms_error *err);
/* Every cell that runs ahead back to knowing only itself, drawn at its centre
 * (the state at Lmin before the prelude). */
void ms_ahead_forget(ms_codec_decoder *d);
/* Cell s (at `level`, mask of depth - 1, its point up to date) learns its
 * descendants one level deeper; its point follows. */
void ms_ahead_deepen(ms_codec_decoder *d, uint32_t s, unsigned level, unsigned depth);
/* The error bound of cell s (ms_codec_decoder_error_bound), its mask of
 * `depth` levels (0: it knows only itself), grid units, rounded up. */
double ms_ahead_cell_bound(const ms_complex *cx, uint32_t s, unsigned depth);
/* The depth of the masks of the current state's cells: 0 at the window's first
 * level (before the prelude) and without geometry ahead. */
unsigned ms_ahead_state_depth(const ms_codec_decoder *d);
/* Recomputes the point drawn for cell s at `level` from its mask of `depth`. */
void ms_ahead_update_rep(ms_complex *cx, uint32_t s, unsigned level, unsigned depth);
/* The mask of a cell at kd-level L (depth d) from its children's at L + 1
 * (depth dc; lo, hi: the first and second child's masks, 0 when absent). */
uint64_t ms_ahead_parent_mask(uint64_t lo, uint64_t hi, unsigned d, unsigned dc);
/* Coarsening: cell keep (now at `level`) takes the mask merged from its
 * children's (lo, hi: the first and second child's, 0 when absent), or knows
 * only itself past where geometry ahead stops; then its point. */
void ms_ahead_merged(ms_codec_decoder *d, uint32_t keep, unsigned level, uint64_t lo, uint64_t hi);

/* ms_codec_surface.c (docs/CODEC.md §4.3). The points of a measurement: the
 * given ones (NULL: canon's own vertices at their cells' centres with their
 * area-weighted normals) in key order at canon's precision; release with
 * ms_surface_release. MS_ERR_NOMEM. */
ms_status ms_surface_prepare(const ms_codec_state *canon, const ms_codec_truth *given,
                             ms_surface_truth *truth, ms_error *err);
void ms_surface_release(ms_surface_truth *truth);
/* The surface error of what d draws now (at a bit boundary), grid units, into
 * *error: over the cells of its own region, the largest distance of a point
 * from its cell's drawn point (smoothed where truth says) along the cluster's
 * summed normal, or the whole distance where those normals do not agree on a
 * side. MS_ERR_NOMEM. */
ms_status ms_surface_error(const ms_codec_decoder *d, const ms_surface_truth *truth, double *error,
                           ms_error *err);
/* Runs d (an encoder's forward pass) bit by bit over its window, writing the
 * surface error of each precision to truth->error. */
ms_status ms_surface_measure(ms_codec_decoder *d, const ms_surface_truth *truth, ms_error *err);
/* Per vertex of start (canonical, at its level) the two of the points it
 * stands for that lie farthest apart along their summed normal, each with half
 * of it (ms_codec_encode_params.summary). MS_ERR_NOMEM. */
ms_status ms_surface_summary(const ms_surface_truth *truth, const ms_codec_state *start, ms_codec_truth *out,
                             ms_error *err);

#endif
