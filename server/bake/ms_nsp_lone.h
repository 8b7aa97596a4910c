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
 * model has a single distinct key). Memory: 24 bytes per vertex while it runs:
 * the baker uses the per-leaf form below, this whole-model one is its reference.
 * MS_ERR_NOMEM on allocation failure. Thread-safety: no shared state. */
#ifndef MS_NSP_LONE_H
#define MS_NSP_LONE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_nsp_build.h"

ms_status ms_nsp_lone_levels(const uint64_t *keys, size_t n, unsigned key_bits, uint8_t **out,
                             ms_error *err);

/* The baker's lone levels, out of core and per leaf.
 *
 * A leaf's cube is one range of the interleaved key order (a depth-D cell is a
 * kd-cell at kd-level 3 D log2(n)), so a key's nearest distinct keys in the whole
 * model lie in its own leaf whenever that leaf holds another distinct key of its
 * own: the lone level is then found inside the leaf alone. When the leaf holds a
 * single distinct key, its lone level is at most 3 D log2(n), which the encoder
 * never uses (a foreign vertex freezes no earlier than kd-level 3 log2(n) times the
 * tree's depth, ms_nsp_encode.h): 0 is stored. The levels the encoder uses are
 * therefore exactly those of ms_nsp_lone_levels over the whole model.
 *
 * ms_nsp_lone_segments reads every leaf once (on `threads` threads), and writes
 * its own vertices' distinct keys in order and their levels (9 bytes a key) to a
 * temporary file of the build (build->lone_fd, nodes' lone_at and lone_count).
 * Memory: one leaf's records per thread. *io receives the bytes read from the
 * block file and written to the segment file. Errors: MS_ERR_IO, MS_ERR_NOMEM.
 * Not thread-safe (it runs its own threads). */
ms_status ms_nsp_lone_segments(ms_nsp_build *build, unsigned threads, ms_nsp_io *io,
                               ms_error *err);

/* Lone levels of n keys sorted ascending, each an own vertex of some leaf
 * (MS_ERR_CORRUPT if not), into levels[]; *bytes_read (if not NULL) is increased
 * by the segment bytes read. Reads each leaf's segment once per run of keys in
 * it. Thread-safe after ms_nsp_lone_segments. */
ms_status ms_nsp_lone_lookup(const ms_nsp_build *build, const uint64_t *keys, size_t n,
                             uint8_t *levels, uint64_t *bytes_read, ms_error *err);

#endif
