/* The colour half of `meshcodec roundtrip` (docs/COLOUR.md, "Measuring"): codes
 * the welded vertices' colours with the colour codec (common/codec/ms_colour.h),
 * decodes them at full precision and compares.
 *
 * Reentrant; no global state.
 */
#ifndef MS_COLOUR_ROUNDTRIP_H
#define MS_COLOUR_ROUNDTRIP_H

#include <stdbool.h>
#include <stddef.h>

#include "ms_colour.h"

typedef struct ms_colour_roundtrip_report {
    size_t bytes;          /* the colour stream */
    double encode_seconds, decode_seconds;
    bool lossless;         /* decoded colours equal the input at colour_bits */
} ms_colour_roundtrip_report;

/* q: the quantised welded mesh (vertices in key order), rgba its welded
 * colours (ms_colour_weld), coded over [0, q->bits] at colour_bits with alpha
 * when `alpha`. MS_ERR_* from the codec. */
ms_status ms_colour_roundtrip(const ms_qmesh *q, const uint8_t *rgba, bool alpha,
                              unsigned colour_bits, ms_colour_roundtrip_report *report,
                              ms_error *err);

#endif
