/* Progressive lossless per-vertex colour codec (public API), a stream of its own
 * beside the geometry stream (ms_codec.h); docs/COLOUR.md documents it.
 *
 * The colour of a kd-cell at every kd-level follows one rule: a cell with one
 * occupied child has that child's colour; a cell with two has, per channel,
 * floor((a + b) / 2) of its children's colours a (lower half) and b (upper
 * half); a full-precision cell has its vertex's colour, reduced to the stream's
 * colour precision c (value >> (8 - c)). The stream codes, for each split (a
 * cell with two children), the detail a - b per channel (an integer Haar step,
 * lossless), decorrelated and context-coded; one cell's colour and the detail
 * give both children exactly. Splits are visited as the geometry decoder
 * visits them: kd-level by kd-level, cells by increasing key; the body is cut
 * into one chunk per precision bit (three kd-levels) after a base chunk holding
 * the colours of the window's first level, so a prefix decodes to the last
 * complete chunk and a client may stop colour at fewer bits than geometry.
 *
 * The decoder is driven by the geometry: it is given the complex (cells as kd
 * prefixes, sorted, and triangles) at the level it refines to, tells which
 * cells split from the cells and predicts each split's detail from the
 * neighbours the triangles give (docs/COLOUR.md).
 * Colours are handed out 8 bits per channel (c-bit values widened by bit
 * replication), alpha 255 in a stream without alpha.
 *
 * Not covered (yet): region streams with frozen foreign cells (ms_codec.h), whose
 * coarse cells the decoder reports at a deeper level than the colour stream's.
 *
 * Errors: every function that can fail returns an ms_status and fills err with
 * one line. Hostile streams are refused (MS_ERR_FORMAT, MS_ERR_CORRUPT,
 * MS_ERR_UNSUPPORTED), never read out of bounds; allocation is bounded by the
 * header's cell counts (at most MS_CODEC_MAX_VERTICES).
 * Thread-safety: no global state; one decoder object per thread.
 */
#ifndef MS_COLOUR_H
#define MS_COLOUR_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_error.h"
#include "ms_mesh.h"
#include "ms_quant.h"

/* The stream version written and the only one read. */
#define MS_COLOUR_VERSION 1
#define MS_COLOUR_MAX_BITS 8
#define MS_COLOUR_DEFAULT_BITS 8

typedef struct ms_colour_encode_params {
    unsigned p_min;       /* first precision bit of the window, as the geometry stream's */
    unsigned colour_bits; /* 1..8 bits per channel (0: MS_COLOUR_DEFAULT_BITS) */
    bool alpha;           /* code the alpha channel (else decoded alpha is 255) */
    /* The colours of the window's first level are not coded (header flags
     * bit 1): the decoder is given them (ms_colour_decoder_set_base), e.g. by
     * the stream of an archive cell's parent. The base chunk is then empty
     * but for the range coder's flush. */
    bool base_given;
} ms_colour_encode_params;

/* Encodes the colours of `full` (the full-precision complex: level 3 * bits,
 * cells strictly increasing, as ms_codec_state_canonicalise leaves them; its
 * triangles and edges give the neighbours that predict colours, and a decoder
 * must be given the same complex's levels) over [p_min, bits]. rgba holds
 * r g b a per vertex, in the order of full->cells. On success *out (malloc'd,
 * caller frees) holds the stream. MS_ERR_ARG for cells not sorted or a bad
 * window or precision, MS_ERR_EMPTY for no vertex. Deterministic. */
ms_status ms_colour_encode(const ms_codec_state *full, const uint8_t *rgba,
                           const ms_colour_encode_params *params, uint8_t **out,
                           size_t *out_size, ms_error *err);

/* Header fields, as validated by ms_colour_read_header. Chunk 0 is the base
 * (the colours at kd-level 3 p_min); chunk i (1..p_max - p_min) holds kd-levels
 * 3 (p_min + i - 1) .. 3 (p_min + i) - 1 refined by one, and ends with
 * chunk_cells[i] cells at kd-level 3 (p_min + i). */
typedef struct ms_colour_header {
    unsigned version, p_min, p_max, colour_bits;
    bool alpha;
    bool base_given; /* flags bit 1: the base colours come from the caller */
    uint32_t start_cells, end_cells;
    size_t header_size; /* bytes before the body */
    size_t body_size;   /* declared body size */
    uint32_t chunk_end[MS_CODEC_MAX_BITS + 1]; /* body offset after chunk i */
    uint32_t chunk_crc[MS_CODEC_MAX_BITS + 1];
    uint32_t chunk_cells[MS_CODEC_MAX_BITS + 1];
} ms_colour_header;

/* Reads and validates the header of data[0..size) (size may be a prefix of the
 * stream as long as the header is complete). */
ms_status ms_colour_read_header(const uint8_t *data, size_t size, ms_colour_header *h,
                                ms_error *err);

typedef struct ms_colour_decoder ms_colour_decoder;

typedef struct ms_colour_decoder_options {
    bool skip_crc; /* do not verify header and chunk CRCs (fuzzing the decoder logic) */
} ms_colour_decoder_options;

/* Creates a decoder over data[0..size) (copied; a prefix of the stream is
 * fine: chunks that are incomplete are unavailable). options may be NULL. The
 * decoder starts at kd-level 3 p_min, its cells not known yet (the first
 * ms_colour_decoder_refine or ms_colour_decoder_colours call gives them). */
ms_status ms_colour_decoder_create(const uint8_t *data, size_t size,
                                   const ms_colour_decoder_options *options,
                                   ms_colour_decoder **out, ms_error *err);
void ms_colour_decoder_destroy(ms_colour_decoder *d);

/* Gives the decoder a longer prefix of its stream (it must begin with the bytes
 * held; MS_ERR_ARG otherwise). Decoding goes on where it stood. */
ms_status ms_colour_decoder_extend(ms_colour_decoder *d, const uint8_t *data, size_t size,
                                   ms_error *err);

/* For a stream with base_given: the colours (r g b a, 8 bits each, reduced to
 * the stream's precision as the encoder reduces its input; alpha ignored
 * without alpha) of its n cells at kd-level 3 p_min, strictly increasing
 * (copied). Before the first refine or colours call; those then check that
 * the cells are the geometry's there (else MS_ERR_ARG) and fail with MS_ERR_ARG
 * while no base was given. MS_ERR_ARG for a stream without base_given or a
 * decoder already started. */
ms_status ms_colour_decoder_set_base(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                                     const uint8_t *rgba, ms_error *err);

const ms_colour_header *ms_colour_decoder_header(const ms_colour_decoder *d);
unsigned ms_colour_decoder_min_level(const ms_colour_decoder *d);
unsigned ms_colour_decoder_max_level(const ms_colour_decoder *d);
/* Highest kd-level the available bytes allow (complete chunks only); below
 * min_level (0 when min_level is 0: then nothing is available) when even the
 * base chunk is incomplete: check ms_colour_decoder_has_base. */
unsigned ms_colour_decoder_available_level(const ms_colour_decoder *d);
bool ms_colour_decoder_has_base(const ms_colour_decoder *d);
/* The kd-level decoded so far (the decoder's frontier). */
unsigned ms_colour_decoder_level(const ms_colour_decoder *d);

/* Decodes forward to kd-level `level` (from the current level up to at most
 * min(geo->level, available level)). geo: the geometry's complex at a level at
 * or above it, e.g. ms_codec_decoder_state at the geometry decoder's level
 * (cells strictly increasing; triangles and edges give each level's
 * neighbours, which predict the colours); the cells at every level in between
 * are its cells' prefixes. It must continue what was decoded: its prefixes at
 * the current level are exactly the current cells, and at each chunk end the
 * count is the header's (else MS_ERR_ARG, decoder unchanged). The complex
 * must be the geometry of the encoded one (its image at geo->level): cells
 * without their triangles, or another complex on the same cells, decode other
 * colours or fail as corrupted, since the neighbours predict. A level at or
 * below the current one only checks the cells. Past the available bytes:
 * MS_ERR_FORMAT (truncated). A corrupted stream: MS_ERR_CORRUPT, and the
 * decoder refuses further work. */
ms_status ms_colour_decoder_refine(ms_colour_decoder *d, const ms_codec_state *geo,
                                   unsigned level, ms_error *err);

/* The colour (r g b a, 8 bits each) of each of the n cells at cells_level
 * (strictly increasing, the same set as the geometry's at that level) into
 * rgba[4 n]: a cell at or below the decoded level gets its ancestor's colour
 * there; a cell above it gets its own colour by the rule (the floor mean of its
 * two children, recursively), computed from the decoded level. */
ms_status ms_colour_decoder_colours(ms_colour_decoder *d, const uint64_t *cells, size_t n,
                                    unsigned cells_level, uint8_t *rgba, ms_error *err);

/* A c-bit channel value widened to 8 bits by bit replication (c in 1..8). */
static inline uint8_t ms_colour_widen(unsigned q, unsigned c)
{
    unsigned v = q << (8 - c);
    for (unsigned k = c; k < 8; k += c)
        v |= v >> k;
    return (uint8_t)v;
}

/* The colours of the welded vertices of q (quantised from mesh, which must
 * have colours, with ms_quantise_mesh at q->bits): per channel the rounded
 * mean (halves up) of the colours of the input vertices welded into it, in q's
 * vertex order, into *rgba (malloc'd, 4 per vertex, caller frees). An input
 * vertex whose grid point is not among q's: MS_ERR_ARG. */
ms_status ms_colour_weld(const ms_mesh *mesh, const ms_qmesh *q, uint8_t **rgba, ms_error *err);

#endif
