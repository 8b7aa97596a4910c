/* The codec's built-in prior: model initialisation and its estimation. */
#include "ms_codec_prior.h"

#include "ms_codec.h"

/* An estimate of P(0) brought inside the coder's start bounds (ms_rangecoder.h). */
static uint16_t prior_clamp(uint64_t q)
{
    return (uint16_t)(q < MS_RC_PROB_MIN ? MS_RC_PROB_MIN : q > MS_RC_PROB_MAX ? MS_RC_PROB_MAX : q);
}

size_t ms_codec_prior_contexts(void) { return MS_PRIOR_SIZE; }

void ms_codec_model_init(ms_rc_prob *model, unsigned D)
{
    uint32_t n = ms_model_size(D);
    for (uint32_t i = 0; i < n; ++i) {
        if (!ms_prior_has(i, D)) {
            model[i] = MS_RC_PROB_INIT;
        } else {
            /* the table is estimated inside the bounds (ms_codec_prior_estimate);
             * clamping again keeps the coder's invariant whatever it holds */
            uint16_t p0 = prior_clamp(ms_codec_prior_p0[ms_prior_index(i, D)]);
            model[i] = (ms_rc_prob){p0, p0};
        }
    }
}

void ms_codec_prior_estimate(const uint64_t *counts, uint16_t p0[MS_PRIOR_SIZE])
{
    for (uint32_t i = 0; i < MS_PRIOR_SIZE; ++i) {
        uint64_t n0 = counts[2 * i], n = n0 + counts[2 * i + 1];
        uint64_t q = ((n0 + 1) * 65536 + (n + 2) / 2) / (n + 2);
        p0[i] = prior_clamp(q);
    }
}
