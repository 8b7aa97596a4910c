/* Inside the view decoder (ms_view_decoder.h): the per-cell state that
 * decoding (ms_view_decoder.c) and stitching (ms_view_stitch.c) share.
 * Private to the view decoder's files. */
#ifndef MS_VIEW_DECODER_INTERNAL_H
#define MS_VIEW_DECODER_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_codec.h"
#include "ms_nsp.h"
#include "ms_view_decoder.h"

typedef struct vcell {
    ms_archive_cell rec;
    uint8_t state;
    uint8_t bits;           /* current precision (SHOWN), bits_max (SPLIT) */
    bool has_start;         /* start state held (non-root cells once their parent split) */
    ms_codec_state start;
    ms_codec_decoder *dec;
    size_t dec_bytes;       /* bytes the decoder was created from */
    uint8_t *bytes;
    size_t nbytes;
    /* stitching cache: the complex at `cache_bits` */
    bool cache_valid;
    uint8_t cache_bits;
    ms_codec_state cache;
    uint32_t *out_index;    /* per cache vertex: index in the stitched mesh, or NONE */
    uint32_t *owner;        /* per cache vertex: shown cell holding it, NONE = finer cells */
    uint8_t *levels;        /* per cache vertex: its kd-level, when some foreign vertex is
                             * frozen coarser than the cell (else NULL: all at its level) */
} vcell;

struct ms_view {
    ms_archive_header header;
    ms_nsp_shape shape;
    uint32_t count;
    vcell *cells;
    uint32_t stamp_epoch;
};

#define NONE 0xFFFFFFFFu
#define OWNER_FINER 0xFFFFFFFEu

/* Drops a cell's stitching cache. */
void ms_view_cache_drop(vcell *c);

#endif
