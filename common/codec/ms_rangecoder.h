/* Binary adaptive range coder used by the geometry codec.
 *
 * A carry-propagating byte-oriented range coder with a 32-bit range and a 64-bit
 * low register. Every coded decision is binary and uses an adaptive probability
 * (ms_rc_prob, 16-bit estimate of P(bit = 0), two adaptation speeds averaged).
 * Multi-symbol values are binarised by the caller.
 *
 * Encoder: owns a growable output buffer (ms_rc_encoder.buf, freed with
 * ms_rc_encoder_free). ms_rc_encoder_flush terminates the current chunk so that a
 * decoder started at the chunk's first byte reads exactly the chunk's bytes.
 * Decoder: reads a caller-owned byte range and never reads outside it; bytes past
 * the end read as zero and are counted in `overrun`, so a truncated or corrupted
 * chunk is detected by the caller (overrun != 0 or pos != end after the chunk).
 *
 * Not thread-safe per object; distinct objects are independent. No global state.
 */
#ifndef MS_RANGECODER_H
#define MS_RANGECODER_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* Adaptive probability: two estimators of P(0) in 1/65536 units, fast and slow.
 * Both must start inside [MS_RC_PROB_MIN, MS_RC_PROB_MAX]; the updates then keep
 * fast inside [15, 65520] and slow inside [127, 65408] (a step moves an estimate
 * by its distance to the bound >> shift, which is 0 that close), so P(0) =
 * their mean stays inside [71, 65464]: neither symbol ever becomes impossible,
 * with no clamp in the coder's inner loop. */
typedef struct ms_rc_prob {
    uint16_t fast;
    uint16_t slow;
} ms_rc_prob;

#define MS_RC_PROB_INIT ((ms_rc_prob){32768, 32768})
#define MS_RC_PROB_MIN 1024
#define MS_RC_PROB_MAX (65536 - 1024)
#define MS_RC_FAST_SHIFT 4
#define MS_RC_SLOW_SHIFT 7

static inline uint32_t ms_rc_p0(const ms_rc_prob *p)
{
    return ((uint32_t)p->fast + p->slow) >> 1;
}

/* One estimator's step after a 0 (towards 65535) or a 1 (towards 0). */
static inline uint32_t ms_rc_step_after_0(uint32_t x, unsigned shift)
{
    return x + ((65535u - x) >> shift);
}
static inline uint32_t ms_rc_step_after_1(uint32_t x, unsigned shift)
{
    return x - (x >> shift);
}

static inline void ms_rc_update(ms_rc_prob *p, int bit)
{
    if (bit) {
        p->fast = (uint16_t)ms_rc_step_after_1(p->fast, MS_RC_FAST_SHIFT);
        p->slow = (uint16_t)ms_rc_step_after_1(p->slow, MS_RC_SLOW_SHIFT);
    } else {
        p->fast = (uint16_t)ms_rc_step_after_0(p->fast, MS_RC_FAST_SHIFT);
        p->slow = (uint16_t)ms_rc_step_after_0(p->slow, MS_RC_SLOW_SHIFT);
    }
}

typedef struct ms_rc_encoder {
    uint8_t *buf;      /* output bytes (owned) */
    size_t size;       /* bytes written */
    size_t cap;
    uint64_t low;
    uint32_t range;
    uint8_t cache;
    uint64_t cache_size;
    int failed;        /* set when growing the buffer failed */
    int skip;          /* the next byte is a chunk's constant leading 0: not stored */
} ms_rc_encoder;

void ms_rc_encoder_init(ms_rc_encoder *e);
void ms_rc_encoder_free(ms_rc_encoder *e);
/* Ends the current chunk (5 bytes) and restarts the coder for the next one. */
void ms_rc_encoder_flush(ms_rc_encoder *e);
void ms_rc_encoder_shift_low(ms_rc_encoder *e);

static inline void ms_rc_encode(ms_rc_encoder *e, ms_rc_prob *p, int bit)
{
    uint32_t bound = (e->range >> 16) * ms_rc_p0(p);
    if (bit) {
        e->low += bound;
        e->range -= bound;
    } else {
        e->range = bound;
    }
    ms_rc_update(p, bit);
    while (e->range < (1u << 24)) {
        e->range <<= 8;
        ms_rc_encoder_shift_low(e);
    }
}

typedef struct ms_rc_decoder {
    const uint8_t *data; /* chunk start (not owned) */
    size_t pos;          /* next byte to read, relative to data */
    size_t end;          /* chunk length */
    uint32_t range;
    uint32_t code;
    size_t overrun;      /* bytes requested past the end */
} ms_rc_decoder;

/* Starts decoding the chunk data[0 .. size). */
void ms_rc_decoder_init(ms_rc_decoder *d, const uint8_t *data, size_t size);

static inline uint32_t ms_rc_next_byte(ms_rc_decoder *d)
{
    if (d->pos < d->end)
        return d->data[d->pos++];
    d->overrun++;
    return 0;
}

/* Refills the range to at least 2^24, a byte at a time. */
static inline void ms_rc_decoder_normalize(ms_rc_decoder *d)
{
    while (d->range < (1u << 24)) {
        d->range <<= 8;
        d->code = (d->code << 8) | ms_rc_next_byte(d);
    }
}

static inline int ms_rc_decode(ms_rc_decoder *d, ms_rc_prob *p)
{
    uint32_t bound = (d->range >> 16) * ms_rc_p0(p);
    int bit;
    if (d->code < bound) {
        d->range = bound;
        bit = 0;
    } else {
        d->code -= bound;
        d->range -= bound;
        bit = 1;
    }
    ms_rc_update(p, bit);
    ms_rc_decoder_normalize(d);
    return bit;
}

/* ms_rc_decode for a decision close to a coin toss: the same arithmetic with
 * no branch on the decoded bit, which a predictor would miss half the time. */
static inline int ms_rc_decode_unpredictable(ms_rc_decoder *d, ms_rc_prob *p)
{
    uint32_t bound = (d->range >> 16) * ms_rc_p0(p);
    uint32_t bit = d->code >= bound;
    uint32_t ones = 0u - bit;
    d->code -= bound & ones;
    d->range = (bound & ~ones) | ((d->range - bound) & ones);
    /* ms_rc_update, both steps computed and one selected */
    uint32_t f0 = ms_rc_step_after_0(p->fast, MS_RC_FAST_SHIFT);
    uint32_t f1 = ms_rc_step_after_1(p->fast, MS_RC_FAST_SHIFT);
    uint32_t s0 = ms_rc_step_after_0(p->slow, MS_RC_SLOW_SHIFT);
    uint32_t s1 = ms_rc_step_after_1(p->slow, MS_RC_SLOW_SHIFT);
    p->fast = (uint16_t)((f0 & ~ones) | (f1 & ones));
    p->slow = (uint16_t)((s0 & ~ones) | (s1 & ones));
    ms_rc_decoder_normalize(d);
    return (int)bit;
}

/* True when the chunk was consumed exactly and nothing was read past its end. */
static inline int ms_rc_decoder_clean_end(const ms_rc_decoder *d)
{
    return d->overrun == 0 && d->pos == d->end;
}

#endif
