/* Quantisation of a world-coordinate mesh onto a cubic 2^p grid, and welding.
 *
 * The box is cubic: origin = the bounding box minimum, size = its largest extent
 * (1.0 when every point coincides). A coordinate x becomes
 *   q = min(2^p - 1, floor((x - origin) / size * 2^p))
 * and decodes to the centre of its grid cell, origin + (q + 0.5) * size / 2^p.
 * origin and size are kept as exact doubles in every stream, so decoding returns
 * the same points on any machine.
 *
 * Welding: vertices whose quantised positions coincide become one; triangle
 * indices are remapped; triangles with a repeated vertex after remapping are
 * dropped, and so is every triangle whose vertex set equals an earlier kept one
 * (the codec carries a simplicial complex). Unreferenced vertices are kept (they
 * are isolated vertices of the complex). The welded vertices are sorted by their
 * interleaved kd key (ms_quant_key), which is the codec's canonical order.
 *
 * Ownership: ms_qmesh owns its arrays; release with ms_qmesh_free.
 * Thread-safety: no shared state; distinct objects are independent.
 */
#ifndef MS_QUANT_H
#define MS_QUANT_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_mesh.h"

#define MS_QUANT_MIN_BITS 8
#define MS_QUANT_MAX_BITS 20

typedef struct ms_quant_box {
    double origin[3]; /* world coordinates of the box minimum corner */
    double size;      /* edge length of the cube, world units, > 0 */
} ms_quant_box;

/* A welded, quantised simplicial complex at `bits` bits per coordinate. */
typedef struct ms_qmesh {
    unsigned bits;
    ms_quant_box box;
    uint32_t *coords;  /* 3 * vertex_count integers in [0, 2^bits) */
    uint32_t *tris;    /* 3 * tri_count vertex indices, oriented as in the input */
    size_t vertex_count;
    size_t tri_count;
} ms_qmesh;

typedef struct ms_weld_report {
    size_t input_vertices;
    size_t input_triangles;
    size_t welded_vertices;       /* input vertices merged into another one */
    size_t degenerate_triangles;  /* dropped: a repeated vertex after welding */
    size_t duplicate_triangles;   /* dropped: same vertex set as a kept triangle */
    size_t isolated_vertices;     /* kept vertices used by no kept triangle */
} ms_weld_report;

/* Fits the cubic box around every vertex of mesh. MS_ERR_EMPTY for no vertex,
 * MS_ERR_RANGE for a non-finite coordinate or an extent that overflows. */
ms_status ms_quant_fit_box(const ms_mesh *mesh, ms_quant_box *box, ms_error *err);

/* Quantises and welds mesh at `bits` (8..20) into *out (zeroed or freed first).
 * report may be NULL. MS_ERR_EMPTY for a mesh without vertices. */
ms_status ms_quantise_mesh(const ms_mesh *mesh, unsigned bits, ms_qmesh *out,
                           ms_weld_report *report, ms_error *err);

/* Integer grid coordinate of world coordinate x on one axis: floor of its
 * place in 2^bits cells, clamped to [0, 2^bits - 1] (NaN gives 0). */
uint32_t ms_quantise(const ms_quant_box *box, unsigned bits, int axis, double x);

/* World coordinate of integer grid coordinate q on one axis. */
double ms_dequantise(const ms_quant_box *box, unsigned bits, int axis, uint32_t q);

/* Spreads the low 21 bits of v so that bit i lands at bit 3*i. */
static inline uint64_t ms_quant_spread3(uint32_t v)
{
    uint64_t x = v & 0x1FFFFFu;
    x = (x | (x << 32)) & 0x001F00000000FFFFull;
    x = (x | (x << 16)) & 0x001F0000FF0000FFull;
    x = (x | (x << 8)) & 0x100F00F00F00F00Full;
    x = (x | (x << 4)) & 0x10C30C30C30C30C3ull;
    x = (x | (x << 2)) & 0x1249249249249249ull;
    return x;
}

/* Interleaves x, y, z (each < 2^bits) most significant bit first, x before y
 * before z, into a 3*bits-bit key (inline: the codec orders a split's
 * neighbours by the keys of their doubled centres in its inner loop). */
static inline uint64_t ms_quant_key(uint32_t x, uint32_t y, uint32_t z, unsigned bits)
{
    (void)bits; /* x occupies the most significant bit of each triple */
    return (ms_quant_spread3(x) << 2) | (ms_quant_spread3(y) << 1) | ms_quant_spread3(z);
}

/* Inverse of ms_quant_key. */
void ms_quant_unkey(uint64_t key, unsigned bits, uint32_t xyz[3]);

/* Length in kd-levels of the common prefix of two distinct D-bit keys. */
static inline unsigned ms_key_lcp(uint64_t a, uint64_t b, unsigned D)
{
    uint64_t x = a ^ b;
    unsigned high = 63u - (unsigned)__builtin_clzll(x);
    return D - 1 - high;
}

void ms_qmesh_free(ms_qmesh *q);

#endif
