/* Reception buffers (the rx of ms_core_decoder.h): one stream of one
 * cell (or one subtree), its bytes from `base` on, pieces that arrived out of
 * order as intervals. Plain buffers of the decode thread; nothing here calls
 * into another file of the core. */
#include "ms_client_core_internal.h"

#include <stdlib.h>
#include <string.h>

void ms_core_rx_free(rx *r)
{
    free(r->buf);
    memset(r, 0, sizeof *r);
}

/* Forgets what was received beyond `keep` (>= base). */
void ms_core_rx_cut(rx *r, uint32_t keep)
{
    if (r->end > keep)
        r->end = keep;
    r->niv = 0;
}

uint64_t ms_core_rx_cap_for(const rx *r, uint64_t end)
{
    if (end <= r->base || end - r->base <= r->cap)
        return r->cap;
    uint64_t cap = r->cap ? r->cap : 4096;
    while (cap < end - r->base)
        cap *= 2;
    return cap;
}

/* Adds received bytes; ignores what is already held or below base. */
bool ms_core_rx_add(rx *r, uint32_t offset, const uint8_t *data, uint32_t length)
{
    uint64_t end = (uint64_t)offset + length;
    if (end <= r->end)
        return true;
    if (offset < r->end) {
        data += r->end - offset;
        length -= r->end - offset;
        offset = r->end;
    }
    if (end - r->base > r->cap) {
        uint64_t cap = ms_core_rx_cap_for(r, end);
        uint8_t *b = realloc(r->buf, cap);
        if (!b)
            return false;
        r->buf = b;
        r->cap = (uint32_t)cap;
    }
    memcpy(r->buf + (offset - r->base), data, length);
    if (offset == r->end) {
        r->end = (uint32_t)end;
    } else if (r->niv < 8) {
        r->iv[r->niv][0] = offset, r->iv[r->niv][1] = (uint32_t)end;
        r->niv++;
    }
    /* absorb pieces that now touch the contiguous part */
    for (bool moved = true; moved;) {
        moved = false;
        for (unsigned i = 0; i < r->niv; ++i) {
            if (r->iv[i][0] <= r->end) {
                if (r->iv[i][1] > r->end)
                    r->end = r->iv[i][1];
                r->iv[i][0] = r->iv[--r->niv][0];
                r->iv[i][1] = r->iv[r->niv][1];
                moved = true;
                break;
            }
        }
    }
    return true;
}

/* Drops bytes below `upto` from the buffer (the consumer took them). */
void ms_core_rx_consume(rx *r, uint32_t upto)
{
    if (upto <= r->base)
        return;
    uint32_t drop = upto - r->base;
    uint32_t held = r->end > upto ? r->end - upto : 0;
    uint32_t span = 0;
    for (unsigned i = 0; i < r->niv; ++i)
        if (r->iv[i][1] - upto > span)
            span = r->iv[i][1] - upto;
    if (span < held)
        span = held;
    if (span == 0) {
        free(r->buf);
        r->buf = NULL;
        r->cap = 0;
    } else {
        memmove(r->buf, r->buf + drop, span);
    }
    r->base = upto;
}
