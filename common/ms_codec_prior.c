/* The codec's built-in prior: model initialisation and its estimation. */
#include "ms_codec_prior.h"

#include "ms_codec.h"

enum { PRIOR_MIN = MS_RC_PROB_MIN, PRIOR_MAX = MS_RC_PROB_MAX };

size_t ms_codec_prior_contexts(void) { return MS_PRIOR_SIZE; }

void ms_codec_model_init(ms_rc_prob *model, unsigned D, unsigned version)
{
    uint32_t n = ms_model_size(D);
    for (uint32_t i = 0; i < n; ++i) {
        if (version == MS_CODEC_VERSION_FLAT || !ms_prior_has(i, D)) {
            model[i] = MS_RC_PROB_INIT;
        } else {
            /* the table is estimated inside the bounds (ms_codec_prior_estimate);
             * clamping again keeps the coder's invariant whatever it holds */
            uint16_t p0 = ms_codec_prior_p0[ms_prior_index(i, D)];
            p0 = p0 < PRIOR_MIN ? PRIOR_MIN : p0 > PRIOR_MAX ? PRIOR_MAX : p0;
            model[i] = (ms_rc_prob){p0, p0};
        }
    }
}

void ms_codec_prior_estimate(const uint64_t *counts, uint16_t p0[MS_PRIOR_SIZE])
{
    for (uint32_t i = 0; i < MS_PRIOR_SIZE; ++i) {
        uint64_t n0 = counts[2 * i], n = n0 + counts[2 * i + 1];
        uint64_t q = ((n0 + 1) * 65536 + (n + 2) / 2) / (n + 2);
        p0[i] = (uint16_t)(q < PRIOR_MIN ? PRIOR_MIN : q > PRIOR_MAX ? PRIOR_MAX : q);
    }
}
