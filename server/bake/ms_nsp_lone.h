/* Lone levels of the baker's vertices: for each input vertex, the first kd-level
 * at which its kd-cell holds no other (distinct) vertex of the whole model.
 *
 * A cell stream may stop refining a foreign vertex (a neighbour cell's vertex
 * that came with a shared triangle) from that level on (ms_codec_region in
 * ms_codec.h): the renderer snaps it to the neighbour's own vertex, which is the
 * only one in that kd-cell at any precision.
 *
 * keys: n kd keys of key_bits bits (coincident vertices share a key). *out
 * (malloc'd, n bytes, caller frees) receives the levels, 0..key_bits (0 when the
 * model has a single distinct key). Memory: 24 bytes per vertex while it runs.
 * MS_ERR_NOMEM on allocation failure. Thread-safety: no shared state. */
#ifndef MS_NSP_LONE_H
#define MS_NSP_LONE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

ms_status ms_nsp_lone_levels(const uint64_t *keys, size_t n, unsigned key_bits, uint8_t **out,
                             ms_error *err);

#endif
