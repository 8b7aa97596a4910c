/* The simplicial complex shared by the codec's encoder and decoder (internal).
 *
 * Vertices are kd-cells identified by an aligned key (the cell's kd prefix shifted
 * left to the full 3P-bit width, so keys of cells at different levels compare in
 * space order and a cell's first child keeps its key). The complex stores only
 * maximal simplices: oriented triangles and maximal edges; a vertex with neither
 * is isolated. Each vertex keeps one list of incident simplices (tagged ids:
 * triangle id << 1, edge id << 1 | 1), small lists inline. A long list (room for
 * MS_CX_INDEXED entries or more: a high-valence vertex, such as the centre of a
 * fan) also keeps a hash index from entry to position, so that taking one entry
 * off costs O(1), not a scan: without it, coarsening a vertex of valence k costs
 * O(k^2). The index never changes the list's order: removal is the same swap
 * with the last entry either way.
 *
 * Slot numbers and list orders depend on history; everything the codec codes is
 * enumerated canonically (ms_cx_star sorts by key), so encoder and decoder agree
 * whatever their slot assignment.
 *
 * Capacity: ms_cx_reserve grows the arrays up to hard caps fixed at init; adding
 * past the reserved room is a programming error (asserted). List growth failure is
 * sticky in cx->nomem. Not thread-safe; no global state.
 */
#ifndef MS_COMPLEX_H
#define MS_COMPLEX_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* Inline list entries: with the list pointer overlapping them the vertex record
 * is 64 bytes, one cache line. */
#define MS_CX_INLINE 10
#define MS_CX_NONE UINT32_MAX
/* Lists with room for at least this many entries keep a position index. */
#define MS_CX_INDEXED 64

/* The cell's geometry (level, corner and centre) lives in ms_complex.cen,
 * derived from key and level; the record holds what the codec touches on every
 * visit. */
typedef struct ms_cx_vert {
    uint64_t key;     /* aligned kd key (the kd-level is ms_cx_level) */
    uint8_t birth;    /* level at which the cell's lineage last split in two */
    uint8_t alive;
    uint8_t frozen;   /* codec: a foreign cell no longer refined (ms_codec.h, regions) */
    uint32_t n, cap;  /* list size; cap 0 = inline storage */
    union {
        struct {                     /* cap > 0 */
            uint32_t *ext;           /* the list */
            /* cap >= MS_CX_INDEXED: 2 cap (entry, position) pairs, open
             * addressing with linear probing, MS_CX_NONE = empty; else NULL */
            uint32_t *where;
        };
        uint32_t inl[MS_CX_INLINE];  /* cap == 0 */
    };
} ms_cx_vert;

typedef struct ms_complex {
    unsigned P, D;            /* bits per coordinate, D = 3P kd-levels */
    ms_cx_vert *v;
    int32_t (*cen)[4];        /* per slot: twice the cell centre per axis, then the level */
    /* Geometry ahead (codec decoder only, with_ahead set before the first
     * reserve; NULL otherwise): per slot, the occupied descendants known ahead
     * (bit i: the descendant whose kd bits below the cell's level read i, the
     * first split's bit highest; 0 for a cell that does not run ahead) and twice
     * the point drawn for the cell (their barycentre; the centre when mask is 0),
     * laid out as cen. Kept by the codec, moved by ms_cx_compact. */
    uint64_t *ahead;
    int32_t (*rep)[4];
    bool with_ahead;
    uint32_t (*tri)[3];
    uint32_t (*edge)[2];
    uint32_t nv, nt, ne;      /* slots used (live + free) */
    uint32_t cv, ct, ce;      /* allocated slots */
    uint32_t live_v, live_t, live_e;
    uint32_t max_v, max_t, max_e; /* hard caps */
    uint32_t *free_v, *free_t, *free_e;
    uint32_t nfree_v, nfree_t, nfree_e;
    /* scratch: per-slot marks (valid when stamp[slot] == cur) */
    uint32_t *mark, *stamp, cur;
    uint32_t *mark2, *stamp2, cur2;
    int nomem;
} ms_complex;

ms_status ms_cx_init(ms_complex *cx, unsigned P, uint32_t max_v, uint32_t max_t, uint32_t max_e,
                     ms_error *err);
void ms_cx_free(ms_complex *cx);

/* Makes room for `v` more vertices, `t` triangles and `e` edges. MS_ERR_CORRUPT
 * when a hard cap would be exceeded, MS_ERR_NOMEM when allocation fails. */
ms_status ms_cx_reserve(ms_complex *cx, uint32_t v, uint32_t t, uint32_t e, ms_error *err);

uint32_t ms_cx_add_vertex(ms_complex *cx, uint64_t key, unsigned level, const uint32_t c[3]);
void ms_cx_free_vertex(ms_complex *cx, uint32_t s);
uint32_t ms_cx_add_tri(ms_complex *cx, uint32_t a, uint32_t b, uint32_t c);
uint32_t ms_cx_add_edge(ms_complex *cx, uint32_t a, uint32_t b);
void ms_cx_del_tri(ms_complex *cx, uint32_t t);
void ms_cx_del_edge(ms_complex *cx, uint32_t e);

static inline uint32_t *ms_cx_list(ms_cx_vert *v)
{
    return v->cap ? v->ext : v->inl;
}

/* Doubles v's list room (moving it off the inline entries, building the
 * position index once the room reaches MS_CX_INDEXED); false, with cx->nomem
 * set, when that fails. */
bool ms_cx_list_grow(ms_complex *cx, ms_cx_vert *v);
/* Records in v's position index (v->cap >= MS_CX_INDEXED) that `tagged` is at
 * position pos of the list. */
void ms_cx_index_put(ms_cx_vert *v, uint32_t tagged, uint32_t pos);
/* Rebuilds v's position index (when it has one) from the list: call after
 * rewriting a list in place other than through the ms_cx_list_* functions. */
void ms_cx_list_reindex(ms_cx_vert *v);
/* Appends a tagged entry to s's list when `keep`, without a branch on it (the
 * entry is written past the end either way); on growth failure, cx->nomem. */
static inline void ms_cx_list_add_if(ms_complex *cx, uint32_t s, uint32_t tagged, bool keep)
{
    ms_cx_vert *v = &cx->v[s];
    if (v->n == (v->cap ? v->cap : MS_CX_INLINE) && !ms_cx_list_grow(cx, v))
        return;
    ms_cx_list(v)[v->n] = tagged;
    if (v->cap >= MS_CX_INDEXED && keep) /* rare: a long list */
        ms_cx_index_put(v, tagged, v->n);
    v->n += keep;
}
/* Appends a tagged entry to s's list; on growth failure, cx->nomem. */
static inline void ms_cx_list_add(ms_complex *cx, uint32_t s, uint32_t tagged)
{
    ms_cx_list_add_if(cx, s, tagged, true);
}
void ms_cx_list_remove(ms_complex *cx, uint32_t s, uint32_t tagged);

/* Width of a cell at `level` along `axis`, in full-grid units. */
static inline uint32_t ms_cx_width(const ms_complex *cx, unsigned level, int axis)
{
    unsigned nb = (level + 2 - (unsigned)axis) / 3;
    return 1u << (cx->P - nb);
}

/* Twice the cell centre along axis (integer, full-grid units * 2). */
static inline int64_t ms_cx_centre2(const ms_complex *cx, uint32_t s, int axis)
{
    return cx->cen[s][axis];
}

/* kd-level of cell s. */
static inline unsigned ms_cx_level(const ms_complex *cx, uint32_t s)
{
    return (unsigned)cx->cen[s][3];
}

/* Minimum corner of cell s on the full grid. */
static inline void ms_cx_corner(const ms_complex *cx, uint32_t s, uint32_t c[3])
{
    unsigned level = ms_cx_level(cx, s);
    for (int a = 0; a < 3; ++a)
        c[a] = ((uint32_t)cx->cen[s][a] - ms_cx_width(cx, level, a)) >> 1;
}

/* ms_cx_refine_cell with L's axis and the child's width w along it given (a
 * loop over one level computes them once). */
static inline void ms_cx_refine_cell_by(ms_complex *cx, uint32_t s, unsigned L, int axis,
                                        int32_t w, int second)
{
    cx->cen[s][axis] += second ? w : -w;
    cx->cen[s][3] = (int32_t)(L + 1);
}
/* Cell s (at kd-level L) becomes its first or second half along L's axis: level
 * L + 1, centre moved by the child's width. The key is the caller's. */
static inline void ms_cx_refine_cell(ms_complex *cx, uint32_t s, unsigned L, int second)
{
    int axis = (int)(L % 3);
    ms_cx_refine_cell_by(cx, s, L, axis, (int32_t)ms_cx_width(cx, L + 1, axis), second);
}

/* The point drawn for cell s back on its centre (a cell that does not run
 * ahead, after its centre moved); nothing without geometry ahead. */
static inline void ms_cx_rep_follow(ms_complex *cx, uint32_t s)
{
    if (cx->rep)
        for (int a = 0; a < 4; ++a)
            cx->rep[s][a] = cx->cen[s][a];
}

/* Where the point drawn for cell s lies in it, per axis in 1/65536 of the
 * cell's width from its minimum corner (ms_codec_state.rep). */
static inline void ms_cx_rep_fraction(const ms_complex *cx, uint32_t s, uint16_t out[3])
{
    unsigned level = ms_cx_level(cx, s);
    for (int a = 0; a < 3; ++a) {
        int64_t w = ms_cx_width(cx, level, a); /* twice the half width */
        int64_t off = (int64_t)cx->rep[s][a] - (cx->cen[s][a] - w); /* 0 .. 2 w */
        int64_t f = (off * 32768 + w / 2) / w;
        out[a] = (uint16_t)(f < 0 ? 0 : f > 65535 ? 65535 : f);
    }
}

/* Inverse of ms_cx_refine_cell: cell s (at L + 1, `second` half) back to L. */
static inline void ms_cx_coarsen_cell(ms_complex *cx, uint32_t s, unsigned L, int second)
{
    int axis = (int)(L % 3);
    int32_t w = (int32_t)ms_cx_width(cx, L + 1, axis);
    cx->cen[s][axis] -= second ? w : -w;
    cx->cen[s][3] = (int32_t)L;
}

/* +1 when triangle t contains the directed edge a -> b in its cyclic order, -1
 * when it contains b -> a. */
static inline int ms_cx_orient(const ms_complex *cx, uint32_t t, uint32_t a, uint32_t b)
{
    const uint32_t *x = cx->tri[t];
    /* bitwise, not short-circuit: which corner holds a is unpredictable */
    int fwd = ((x[0] == a) & (x[1] == b)) | ((x[1] == a) & (x[2] == b)) |
              ((x[2] == a) & (x[0] == b));
    return 2 * fwd - 1;
}

/* The star of one or two centre vertices, canonically ordered. */
typedef struct ms_cx_pair {
    uint32_t i, j;    /* local neighbour indices, i < j */
    uint32_t t0, t1;  /* triangle (c0,x_i,x_j) / (c1,x_i,x_j), or MS_CX_NONE */
} ms_cx_pair;

typedef struct ms_cx_star {
    uint32_t nn;          /* neighbours (other than the centres) */
    uint32_t *nbr;        /* slots, sorted by key */
    uint8_t *adj;         /* per neighbour: 1 adjacent to c0, 2 to c1 */
    uint32_t *both;       /* per neighbour: triangle (c0,c1,x) or MS_CX_NONE */
    uint32_t np;
    ms_cx_pair *pairs;    /* triangles with one centre, sorted by (i, j) */
    bool adj01;           /* c0 and c1 adjacent */
    uint32_t edge01;      /* maximal edge (c0,c1) or MS_CX_NONE */
    uint32_t *perm;       /* scratch */
    uint64_t *sortbuf;
    size_t cap_n, cap_p, cap_sort;
} ms_cx_star;

void ms_cx_star_free(ms_cx_star *st);

/* Gathers the star of c0 (and c1 when c1 != MS_CX_NONE). MS_ERR_NOMEM on
 * allocation failure. A single centre with at most MS_CX_SMALL_STAR incident
 * simplices (every split the decoder makes, nearly) takes a path without the
 * per-slot marks; anything else is ms_cx_gather_general, which uses cx's mark
 * scratch. Both give the same star. */
#define MS_CX_SMALL_STAR 24
ms_status ms_cx_gather(ms_complex *cx, uint32_t c0, uint32_t c1, ms_cx_star *st, ms_error *err);
ms_status ms_cx_gather_general(ms_complex *cx, uint32_t c0, uint32_t c1, ms_cx_star *st,
                               ms_error *err);

/* Sorts n keys ascending (insertion sort when short); shared by the
 * complex's own files. */
void ms_cx_sort_keys(uint64_t *a, size_t n);

/* Merges c1 into c0: every simplex incident to c1 gets c0 instead, duplicates are
 * dropped (c0's copy wins), triangles containing both collapse to edges kept only
 * when maximal, the edge c0-c1 disappears. Frees slot c1. Key and level of c0 are
 * left to the caller. */
ms_status ms_cx_merge(ms_complex *cx, uint32_t c0, uint32_t c1, ms_error *err);

/* Renumbers the vertex slots to follow order[0..n) (all live vertices, in key
 * order) and the triangles by first incident vertex, for memory locality; order
 * becomes the identity. The complex itself is unchanged. Works in place: besides
 * four index arrays (old to new and new to old, for vertices and triangles) it
 * allocates nothing, so a compaction costs no fresh pages. */
ms_status ms_cx_compact(ms_complex *cx, uint32_t *order, uint32_t n, ms_error *err);

/* Starts a fresh mark generation (scratch marks). */
void ms_cx_new_marks(ms_complex *cx);
void ms_cx_new_marks2(ms_complex *cx);

#endif
