/* The codec's built-in prior: the probability each context starts from.
 *
 * Every stream of version MS_CODEC_VERSION starts its adaptive contexts from one
 * fixed table, trained once on scanned meshes (`meshcodec train`, docs/CODEC.md
 * section 4) and compiled in (ms_codec_prior_table.c). Nothing is transmitted: a
 * small nSP cell no longer spends its first symbols learning what every cell
 * learns, which is most of what separate cell streams cost over one stream.
 *
 * Thread-safety: the table is constant; every function here is reentrant.
 */
#ifndef MS_CODEC_PRIOR_H
#define MS_CODEC_PRIOR_H

#include <stddef.h>
#include <stdint.h>

#include "ms_codec_model.h"
#include "ms_rangecoder.h"

/* P(bit = 0) of every context of the prior's layout, in 1/65536 units. */
extern const uint16_t ms_codec_prior_p0[MS_PRIOR_SIZE];

/* Initial state of the model of a stream with D kd-levels (ms_model_size(D)
 * entries): the prior where it has the context, flat (P = 1/2) elsewhere. */
void ms_codec_model_init(ms_rc_prob *model, unsigned D);

/* The prior estimated from training counts (counts[2 i + bit], the layout of
 * ms_codec_encode_params.context_counts): (n0 + 1) / (n + 2), kept inside
 * [1/64, 63/64] so that no context starts too sure of itself. */
void ms_codec_prior_estimate(const uint64_t *counts, uint16_t p0[MS_PRIOR_SIZE]);

#endif
