#include "ms_rangecoder.h"

#include <stdlib.h>
#include <string.h>

void ms_rc_encoder_init(ms_rc_encoder *e)
{
    memset(e, 0, sizeof *e);
    e->range = 0xFFFFFFFFu;
    e->cache_size = 1;
    e->skip = 1;
}

void ms_rc_encoder_free(ms_rc_encoder *e)
{
    free(e->buf);
    memset(e, 0, sizeof *e);
}

static void put_byte(ms_rc_encoder *e, uint8_t b)
{
    if (e->skip) {
        e->skip = 0;
        return;
    }
    if (e->size == e->cap) {
        size_t cap = e->cap ? e->cap * 2 : 4096;
        uint8_t *grown = realloc(e->buf, cap);
        if (!grown) {
            e->failed = 1;
            return;
        }
        e->buf = grown;
        e->cap = cap;
    }
    e->buf[e->size++] = b;
}

/* Moves the top byte of low out, resolving a pending carry into the bytes held
 * back (one cached byte followed by cache_size - 1 bytes of 0xFF). */
void ms_rc_encoder_shift_low(ms_rc_encoder *e)
{
    if ((uint32_t)e->low < 0xFF000000u || (e->low >> 32) != 0) {
        uint8_t carry = (uint8_t)(e->low >> 32);
        uint8_t held = e->cache;
        do {
            if (!e->failed)
                put_byte(e, (uint8_t)(held + carry));
            held = 0xFF;
        } while (--e->cache_size != 0);
        e->cache = (uint8_t)(e->low >> 24);
    }
    e->cache_size++;
    e->low = (e->low & 0x00FFFFFFu) << 8;
}

void ms_rc_encoder_flush(ms_rc_encoder *e)
{
    for (int i = 0; i < 5; ++i)
        ms_rc_encoder_shift_low(e);
    e->low = 0;
    e->range = 0xFFFFFFFFu;
    e->cache = 0;
    e->cache_size = 1;
    /* The first byte of every chunk is the initial cache, always 0 (low + range
     * never exceeds 2^32 before the first shift): it is not stored. */
    e->skip = 1;
}

void ms_rc_decoder_init(ms_rc_decoder *d, const uint8_t *data, size_t size)
{
    d->data = data;
    d->pos = 0;
    d->end = size;
    d->range = 0xFFFFFFFFu;
    d->code = 0;
    d->overrun = 0;
    for (int i = 0; i < 4; ++i)
        d->code = (d->code << 8) | ms_rc_next_byte(d);
}
