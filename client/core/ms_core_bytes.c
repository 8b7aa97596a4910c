/* Reference-counted bytes shared between a cell's reception state and the
 * frames that show them (ms_core_bytes, ms_client_core.h: a shown cell's APO
 * chunk prefix). The count is atomic: frames are freed on the caller's
 * thread, the cell's hold on the decode thread. Nothing here calls into
 * another file of the core. */
#include "ms_client_core_internal.h"

#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

struct ms_core_bytes {
    atomic_uint refs;   /* the dcell's hold and each frame's */
    size_t length;
    uint8_t data[];
};

ms_core_bytes *ms_core_bytes_copy(const uint8_t *data, size_t length)
{
    ms_core_bytes *b = malloc(sizeof *b + (length ? length : 1));
    if (!b)
        return NULL;
    atomic_init(&b->refs, 1);
    b->length = length;
    memcpy(b->data, data, length);
    return b;
}

ms_core_bytes *ms_core_bytes_retain(ms_core_bytes *b)
{
    atomic_fetch_add_explicit(&b->refs, 1, memory_order_relaxed);
    return b;
}

/* Frames are freed on the caller's thread, the dcell's hold on the decode
 * thread: the last release frees, whichever it is. */
void ms_core_bytes_release(ms_core_bytes *b)
{
    if (b && atomic_fetch_sub_explicit(&b->refs, 1, memory_order_acq_rel) == 1)
        free(b);
}

uint8_t *ms_core_bytes_data(ms_core_bytes *b, size_t *length)
{
    *length = b->length;
    return b->data;
}
