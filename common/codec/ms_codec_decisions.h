/* One binary decision of the codec, decoded or (encode mode) taken from the
 * caller and coded: shared by the decoder's files (internal). */
#ifndef MS_CODEC_DECISIONS_H
#define MS_CODEC_DECISIONS_H

#include "ms_codec_internal.h"
#include "ms_codec_prior.h"
#include "ms_rangecoder.h"

/* Encode mode: `bit` counted (training) and coded with p. */
static inline int dbit_code(ms_codec_decoder *d, ms_rc_prob *p, int bit)
{
    if (d->train && ms_prior_has((uint32_t)(p - d->model), d->D))
        d->train[2 * ms_prior_index((uint32_t)(p - d->model), d->D) + (unsigned)bit]++;
    ms_rc_encode(d->enc, p, bit);
    return bit;
}

/* Encode mode: the next decision taken from src, counted and coded. */
static __attribute__((noinline, unused)) int dbit_encode(ms_codec_decoder *d, ms_rc_prob *p)
{
    int bit = 0;
    if (d->src_pos < d->src_n)
        bit = d->src[d->src_pos];
    d->src_pos++;
    return dbit_code(d, p, bit);
}

/* One binary decision: decoded, or (encode mode) taken from src and coded. */
static inline __attribute__((always_inline)) int dbit(ms_codec_decoder *d, ms_rc_prob *p)
{
    return d->enc ? dbit_encode(d, p) : ms_rc_decode(&d->rc, p);
}

/* dbit for a decision close to a coin toss (ms_rc_decode_unpredictable). */
static inline __attribute__((always_inline)) int dbit_coin(ms_codec_decoder *d, ms_rc_prob *p)
{
    return d->enc ? dbit_encode(d, p) : ms_rc_decode_unpredictable(&d->rc, p);
}

#endif
