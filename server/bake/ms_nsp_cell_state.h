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

#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_error.h"

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

#endif
