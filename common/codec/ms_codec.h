/* Progressive lossless geometry + connectivity codec (public API).
 *
 * A quantised simplicial complex (vertices on a 2^P grid, oriented triangles,
 * maximal edges, isolated vertices) is coded as a kd-tree refinement: kd-level L
 * (0 <= L < 3P) halves every cell along axis L mod 3 (x, y, z in turn). Each split
 * of an occupied cell is one symbol {first half, second half, both}; after a
 * "both" comes a generalised vertex split describing how the simplices incident
 * to the cell are shared between its two halves, with one orientation bit per
 * created triangle. Everything is coded with a binary adaptive range coder
 * (ms_rangecoder.h) and context models; docs/CODEC.md documents the stream.
 *
 * The complex at kd-level L is the image of the full complex under the map
 * "vertex -> its kd-cell at level L" (duplicates removed, only maximal simplices
 * kept). A stream covers the precision window [p_min, p_max] (kd-levels
 * [3 p_min, 3 p_max]) and starts from the complex at p_min ("start state"): for
 * p_min = 0 that is one vertex, otherwise the caller supplies it (the parent
 * nSP cell's decoder gives it). The body is cut into one chunk per precision
 * bit; the header lists each chunk's end offset and CRC, so a prefix of the
 * stream decodes up to the last complete bit.
 *
 * Units: integer grid coordinates / kd keys; world coordinates only in
 * ms_codec_decoder_mesh (cell centres in the box of the header).
 * Errors: every function that can fail returns an ms_status and fills err with
 * one line. Hostile streams are rejected (MS_ERR_FORMAT, MS_ERR_CORRUPT,
 * MS_ERR_UNSUPPORTED, MS_ERR_NOMEM for declared sizes over the caps), never read
 * out of bounds, and allocate at most in proportion to the declared counts.
 * Thread-safety: no global state; one encoder call or one decoder object per
 * thread (distinct decoders are independent).
 */
#ifndef MS_CODEC_H
#define MS_CODEC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh.h"
#include "ms_quant.h"

/* The stream version written and the only one read (docs/CODEC.md): every
 * context starts from the built-in prior (ms_codec_prior.h) and geometry may
 * run ahead of connectivity (MS_CODEC_MAX_AHEAD). A stream of another version
 * is refused with MS_ERR_UNSUPPORTED naming it. */
#define MS_CODEC_VERSION 3
/* Geometry ahead of connectivity: at most this many kd-levels (two bits). */
#define MS_CODEC_MAX_AHEAD 6
/* The default of the encoding programs (meshcodec, meshbake), by measurement
 * (docs/CODEC.md §4.1). */
#define MS_CODEC_DEFAULT_AHEAD 3
/* Geometry ahead may stop at a precision inside the window (header flags bits
 * 5-7, docs/CODEC.md §4.1): at most this many bits; 0 is "never stops". */
#define MS_CODEC_MAX_AHEAD_UNTIL 7
#define MS_CODEC_MAX_BITS 20
#define MS_CODEC_MAX_VERTICES (1u << 26)
#define MS_CODEC_MAX_TRIANGLES (1u << 27)
#define MS_CODEC_MAX_EDGES (1u << 27)

/* A complex whose vertices all sit at one kd-level: vertex i is the kd-cell with
 * prefix cells[i] (the top `level` bits of the 3*bits-bit interleaved key).
 * Triangles are oriented index triples, edges maximal unordered pairs. Owned by
 * the struct; release with ms_codec_state_free. */
typedef struct ms_codec_state {
    unsigned bits;   /* P: full precision of the key space */
    unsigned level;  /* kd-level of every vertex, 0..3*bits */
    size_t vertex_count, tri_count, edge_count;
    uint64_t *cells; /* vertex_count kd prefixes, each < 2^level */
    uint32_t *tris;  /* 3 * tri_count */
    uint32_t *edges; /* 2 * edge_count */
    /* Optional (NULL: every vertex at its cell's centre): where each vertex is
     * drawn inside its cell, 3 per vertex, in 1/65536 of the cell's width along
     * each axis from its minimum corner (32768: the centre). A decoder of a
     * stream with geometry ahead gives the barycentre of the vertex's known
     * descendants; ignored by the encoder, equality and checksums. */
    uint16_t *rep;
    /* Optional (NULL from every producer but a decoder): per vertex, an upper
     * bound, in grid units (box size / 2^bits), of the distance from the point
     * drawn for it (rep, or its centre) to every full-precision vertex it
     * stands for (ms_codec_decoder_error_bound); follows the vertices in
     * ms_codec_state_canonicalise. */
    float *bound;
} ms_codec_state;

void ms_codec_state_free(ms_codec_state *s);

/* The full-precision state of a welded quantised mesh (level = 3 * bits, no
 * edges). */
ms_status ms_codec_state_from_qmesh(const ms_qmesh *q, ms_codec_state *out, ms_error *err);

/* Smoothing of a coarse state's drawn points (docs/CODEC.md §4.4): `rounds`
 * rounds of Taubin's lambda|mu smoothing over s's triangles, every point kept
 * inside its kd-cell, written to s->rep (allocated when NULL, else replaced;
 * the points start from s->rep, or the centres without it). Exact integer
 * arithmetic: the result depends on the complex, not on its vertex order.
 * rounds 0 leaves s as it is. The caller decides where it applies (never at
 * the model's full precision: that would not be lossless). MS_ERR_ARG for more
 * than MS_CODEC_SMOOTH_ROUNDS_MAX rounds or a level beyond 3 bits,
 * MS_ERR_CORRUPT for a triangle naming no vertex, MS_ERR_NOMEM; s is unchanged
 * on error. Not thread-safe on one state. */
#define MS_CODEC_SMOOTH_ROUNDS_MAX 8u
ms_status ms_codec_state_smooth(ms_codec_state *s, unsigned rounds, ms_error *err);

/* Sorts vertices by cell, rotates each triangle to start at its smallest index
 * and sorts triangles and edges, so equal complexes compare equal with memcmp. */
ms_status ms_codec_state_canonicalise(ms_codec_state *s, ms_error *err);

/* True when a and b hold the same complex. oriented: triangles must also agree in
 * orientation (cyclic order). Both must be canonicalised. */
bool ms_codec_state_equal(const ms_codec_state *a, const ms_codec_state *b, bool oriented);

/* The region a stream owns (an nSP cell): the cube [min, min + 2^log2_side) on
 * every axis of the 2^P grid, aligned (min a multiple of the side) and coarse
 * enough that every kd-cell of the window lies wholly inside or outside it
 * (3 (P - log2_side) <= 3 p_min). A cell outside is *foreign*: a copy of a
 * neighbour's vertex that a renderer snaps to the neighbour's own vertex, so its
 * stream may stop refining it ("freeze" it) once its kd-cell holds no other
 * vertex of the whole model: refining it further would repeat the neighbour's
 * bits. Each foreign cell not yet frozen codes one "frozen?" decision per
 * kd-level; a frozen cell keeps its kd-level and codes nothing more. */
typedef struct ms_codec_region {
    uint32_t min[3];
    unsigned log2_side;
} ms_codec_region;

#define MS_CODEC_NO_FREEZE 255

/* Points on a model's surface with normals, what a surface error is measured
 * against (ms_codec_encode_params.truth): n points, positions 3 doubles each
 * in grid units (a vertex of full-precision kd-cell c stands at c + 0.5),
 * normals 3 floats each, area-weighted (their lengths weigh them); a zero
 * normal marks a sharp point (a corner, a crease, a lone vertex), whose whole
 * distance from its drawn point counts. Owned by the struct; release with
 * ms_codec_truth_free. */
typedef struct ms_codec_truth {
    size_t n;
    double *positions;
    float *normals;
} ms_codec_truth;

void ms_codec_truth_free(ms_codec_truth *truth);

typedef struct ms_codec_encode_params {
    unsigned p_min;       /* first precision bit of the window (0 = from one vertex) */
    ms_quant_box box;     /* world box written to the header */
    /* Optional (both NULL for a stream without a region). region: the owned
     * region, written to the header. freeze_level[i] (vertex i of `full`): the
     * kd-level at which its foreign cell freezes, or MS_CODEC_NO_FREEZE. The caller
     * guarantees what the encoder cannot see, that the kd-cell at that level holds
     * no other vertex of the model; the encoder checks what it can: the vertex is
     * foreign, 3 p_min <= level < 3 P, and no other vertex of `full` shares that
     * kd-cell (else MS_ERR_ARG). */
    const ms_codec_region *region;
    const uint8_t *freeze_level;
    /* The compact header of a stream inside an archive: the box is left out (the
     * archive has it; decoders are given it, ms_codec_decoder_options.box), counts
     * and chunk ends are varints. */
    bool compact_header;
    /* Geometry ahead of connectivity, in kd-levels, 0..MS_CODEC_MAX_AHEAD: the
     * stream codes each own cell's occupied descendants this many levels before
     * its connectivity, so a decoder draws a vertex at their barycentre (foreign
     * cells of a region never run ahead). 0: every vertex at its cell centre. */
    unsigned ahead;
    /* Where geometry ahead stops, in precision bits, 0..MS_CODEC_MAX_AHEAD_UNTIL
     * (0: at the window's end): a cell at kd-level L knows its descendants down
     * to min(L + ahead, 3 ahead_until) only, and from kd-level 3 ahead_until on
     * cells code their geometry with their connectivity and are drawn at their
     * centres (the smoothing, ms_codec_state_smooth, takes over there). Costs no
     * byte to a cut at or past that precision. Ignored without ahead; a window
     * that starts at or past it is coded without geometry ahead. */
    unsigned ahead_until;
    /* Training the prior (meshcodec train), normally NULL: when set, every coded
     * decision adds 1 to context_counts[2 i + bit], i its context in the prior's
     * layout; the array has 2 * ms_codec_prior_contexts() entries, owned by the
     * caller and accumulated across calls. Not thread-safe across concurrent
     * encodes sharing one array. */
    uint64_t *context_counts;
    /* Optional, normally NULL: when set, receives the mesh the stream decodes to
     * at its full precision (what ms_codec_decoder_mesh gives at level 3 P),
     * taken from the encoder's own forward pass instead of a second decode (the
     * bake's APO m of an internal cell). Freed by the caller (ms_mesh_free). */
    ms_mesh *mesh;
    /* Optional, normally NULL: when set, receives the measured surface error
     * of each precision of the window (docs/CODEC.md §4.3), P - p_min + 1
     * entries, entry k for precision p_min + k, in grid units (box size / 2^P):
     * over the cells of the stream's own region (all without a region), the
     * largest distance of a full-precision vertex of `full` from the point
     * drawn for it, along the summed normal of the vertices that point stands
     * for (the whole distance where they face both ways; 0 at P measured
     * against full itself). Taken by the
     * forward pass, one pass over the points per bit. */
    double *surface_error;
    /* With surface_error: the smoothing a client draws this stream's vertices
     * with (ms_codec_state_smooth, smooth_rounds rounds, 0..
     * MS_CODEC_SMOOTH_ROUNDS_MAX, 0: none) at kd-levels below smooth_level
     * (the model's, counted from its root like the stream's own), so the
     * error is measured at the points drawn. */
    unsigned smooth_rounds, smooth_level;
    /* Optional with surface_error: the points it is measured against instead of
     * `full`'s own vertices (an internal nSP cell's stream, whose vertices are
     * not the model's: its children's summaries), in this stream's grid units. */
    const ms_codec_truth *truth;
    /* Optional: receives what a parent stream measures against in place of the
     * points this one stands for: per vertex of the start state, the two of
     * them farthest apart along their summed normal, sharing it, and of its
     * sharp ones (a corner or a crease: a zero normal) the two farthest apart
     * along their widest axis, in this stream's grid units
     * (ms_codec_truth_free). */
    ms_codec_truth *summary;
} ms_codec_encode_params;

/* Number of contexts of the prior (every kd-level of 20 bits plus connectivity). */
size_t ms_codec_prior_contexts(void);

/* Encodes `full` (level must be 3 * full->bits, the p_max of the stream) over
 * [params->p_min, full->bits]. On success *out (malloc'd, caller frees) holds the
 * stream and, when start is non-NULL, *start receives the complex at p_min that a
 * decoder must be created from. Invalid input complexes (index out of range,
 * repeated or duplicate simplices) fail with MS_ERR_ARG; no vertex: MS_ERR_EMPTY.
 * The output is a deterministic function of the input. */
ms_status ms_codec_encode(const ms_codec_state *full, const ms_codec_encode_params *params,
                          uint8_t **out, size_t *out_size, ms_codec_state *start,
                          ms_error *err);

/* Header fields, as validated by ms_codec_read_header. */
typedef struct ms_codec_header {
    unsigned version, p_min, p_max;
    ms_quant_box box;
    bool has_region;            /* flags bit 0: a region follows the counts */
    ms_codec_region region;
    bool compact;               /* flags bit 1: compact layout, box not in the stream (zero
                                 * here unless the decoder was given it) */
    unsigned ahead;             /* flags bits 2-4: geometry ahead, kd-levels */
    unsigned ahead_until;       /* flags bits 5-7: where it stops, bits (0: the window's end) */
    uint32_t start_vertices, start_tris, start_edges;
    uint64_t start_checksum;
    uint32_t end_vertices, end_tris, end_edges;
    size_t header_size;         /* bytes before the body */
    size_t body_size;           /* declared body size */
    uint32_t chunk_end[MS_CODEC_MAX_BITS]; /* body offset after bit p_min + i */
    uint32_t chunk_crc[MS_CODEC_MAX_BITS];
} ms_codec_header;

ms_status ms_codec_read_header(const uint8_t *data, size_t size, ms_codec_header *h,
                               ms_error *err);

typedef struct ms_codec_decoder ms_codec_decoder;

typedef struct ms_codec_decoder_options {
    bool skip_crc; /* do not verify header and chunk CRCs (fuzzing the decoder logic) */
    /* The world box of a compact-header stream (its archive's); ignored for a
     * stream that carries its own. Without it a compact stream decodes, but
     * ms_codec_decoder_mesh, which needs world positions, fails. */
    const ms_quant_box *box;
} ms_codec_decoder_options;

/* Creates a decoder over data[0..size) (copied; size may be a prefix of the
 * stream: bits whose chunk is incomplete are unavailable). start is the state at
 * kd-level 3 p_min (NULL allowed when p_min = 0); its `bits` field does not
 * matter, so the final state of a parent stream whose p_max is this stream's
 * p_min is a valid start state. It must equal (checksum) the start state the
 * encoder reported. options may be NULL. The decoder starts at precision p_min. */
ms_status ms_codec_decoder_create(const uint8_t *data, size_t size, const ms_codec_state *start,
                                  const ms_codec_decoder_options *options,
                                  ms_codec_decoder **out, ms_error *err);
void ms_codec_decoder_destroy(ms_codec_decoder *d);

/* Gives the decoder a longer prefix of its stream: data[0..size) must begin with
 * the bytes it holds (size at least as many; the header is compared). The new
 * bytes are copied; decoding goes on from the current level, so bits that arrive
 * one by one cost no re-decoding. Errors: MS_ERR_ARG when the bytes do not
 * continue the stream, MS_ERR_CORRUPT after a corrupted stream, MS_ERR_NOMEM;
 * the decoder is unchanged on error. */
ms_status ms_codec_decoder_extend(ms_codec_decoder *d, const uint8_t *data, size_t size,
                                  ms_error *err);

/* The window of kd-levels (precision bits = level / 3). */
unsigned ms_codec_decoder_min_level(const ms_codec_decoder *d);
unsigned ms_codec_decoder_max_level(const ms_codec_decoder *d);
/* Highest kd-level the available bytes allow (complete chunks only). */
unsigned ms_codec_decoder_available_level(const ms_codec_decoder *d);
const ms_codec_header *ms_codec_decoder_header(const ms_codec_decoder *d);

/* Refines (or coarsens) to exactly kd-level `level`. Refining past the available
 * bytes fails with MS_ERR_FORMAT ("truncated"); a corrupted stream fails with
 * MS_ERR_CORRUPT and leaves the decoder unusable (further calls fail). */
ms_status ms_codec_decoder_set_level(ms_codec_decoder *d, unsigned level, ms_error *err);

/* Current counts. */
size_t ms_codec_decoder_vertex_count(const ms_codec_decoder *d);
size_t ms_codec_decoder_tri_count(const ms_codec_decoder *d);
size_t ms_codec_decoder_edge_count(const ms_codec_decoder *d);

/* The current mesh for rendering: representative points (cell centres, world
 * units, vertices in kd order) and oriented triangles. Maximal edges are not
 * included. *out must be zeroed or freed; it is reused when it has room. */
ms_status ms_codec_decoder_mesh(const ms_codec_decoder *d, ms_mesh *out, ms_error *err);

/* The current complex as an ms_codec_state (vertices in kd order). A frozen
 * foreign cell, which stays at a coarser kd-level than the others, is given as
 * the prefix of its first descendant at the state's level (its lower bits zero);
 * ms_codec_decoder_vertex_levels tells which. */
ms_status ms_codec_decoder_state(const ms_codec_decoder *d, ms_codec_state *out, ms_error *err);

/* The true error of the points drawn (docs/CODEC.md §4.1, "The error of a
 * drawn point"): every full-precision vertex a cell of the current state
 * stands for lies in one of its known occupied descendants (geometry ahead),
 * else in its kd-cell; the bound of a cell is the largest distance from its
 * drawn point (as ms_codec_state.rep places it, rounding included) to a point
 * of those boxes, in grid units (box size / 2^P), computed exactly per axis and
 * rounded up. Returns the largest over the cells of the stream's own region
 * (all cells without a region; foreign cells are drawn at their owner's
 * point), 0 without a vertex. At most the full diagonal of a cell; the
 * half-diagonal when the cell is drawn at its centre knowing nothing below it
 * (no geometry ahead, the window's first level, its last). */
double ms_codec_decoder_error_bound(const ms_codec_decoder *d);

/* levels[i] = kd-level of vertex i of ms_codec_decoder_state (the current level,
 * or the coarser one at which a foreign cell froze); levels has
 * ms_codec_decoder_vertex_count entries. Returns the number of frozen cells. */
size_t ms_codec_decoder_vertex_levels(const ms_codec_decoder *d, uint8_t *levels);

/* 64-bit checksum of a complex (canonical form), as stored for the start state. */
uint64_t ms_codec_state_checksum(const ms_codec_state *canonical);

#endif
