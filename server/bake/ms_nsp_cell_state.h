/* The complexes the baker encodes cells from (ms_nsp_encode.h): a leaf's, at
 * full precision from its records, and an internal cell's, the union of its
 * children's start states; and the key indexing both use (and the APO's
 * full-precision mesh).
 *
 * Ownership: each function fills caller-owned arrays or a caller-owned
 * ms_codec_state (freed with ms_codec_state_free; on failure it is freed
 * already).
 * Errors: MS_ERR_NOMEM; ms_nsp_merge_states also MS_ERR_CORRUPT when the
 * children disagree on a triangle's orientation.
 * Thread-safety: no shared state; calls on different states run in parallel.
 */
#ifndef MS_NSP_CELL_STATE_H
#define MS_NSP_CELL_STATE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_error.h"
#include "ms_mesh.h"
#include "ms_nsp.h"
#include "ms_quant.h"

/* Indexes the n vertex references ref[] (keys of key_bits bits): writes the
 * distinct keys in order to cells (*ncells of them, room for n) and each
 * reference's rank to rank[]. ref may be clobbered. Scratch: about 12 bytes
 * per reference. */
ms_status ms_nsp_index_keys(uint64_t *ref, size_t n, unsigned key_bits, uint64_t *cells,
                            size_t *ncells, uint32_t *rank, ms_error *err);

/* A leaf's complex at full precision (bits) from its n records (3 keys each;
 * a point record has its first two equal): keys as vertices, repeated triangles
 * unified keeping the first in record order; *removed: the triangles
 * unified. */
ms_status ms_nsp_leaf_complex(const uint64_t *rec, size_t n, unsigned bits, ms_codec_state *st,
                              size_t *removed, ms_error *err);

/* An internal cell's complex at bits_max: the union of its nc children's
 * start states ch[], simplices repeated across children unified by kd key,
 * vertices in key order. cell (its archive number) names it in an error. */
ms_status ms_nsp_merge_states(const ms_codec_state *ch, unsigned nc, unsigned bits_max,
                              uint32_t cell, ms_codec_state *st, ms_error *err);

/* A leaf's full-precision complex as the mesh its stream decodes to at bits_max
 * (same positions as ms_codec_decoder_mesh), for its APO chunk: the decoded one
 * has its frozen foreign vertices at coarse positions. m is the caller's
 * (ms_mesh_free). */
ms_status ms_nsp_leaf_mesh(const ms_codec_state *st, const ms_quant_box *box, ms_mesh *m, ms_error *err);

/* A leaf's region and the levels its foreign vertices freeze at: the lone level,
 * not before the window starts, nor before a kd-cell lies inside one cell of the
 * deepest nSP level (a renderer finds the shown cell holding a frozen vertex
 * from its kd-cell). False when the tree's shape gives a region too fine for the
 * window (p_r < log2 n), where nothing freezes. lone: the n vertices' lone levels
 * (ms_nsp_lone.h), rewritten as their freeze levels; max_depth: the tree's. */
bool ms_nsp_leaf_freezing(const ms_nsp_shape *shape, unsigned max_depth, unsigned depth, const uint32_t position[3],
                          unsigned lo, uint8_t *lone, size_t n, ms_codec_region *region);

#endif
