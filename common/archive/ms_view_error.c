/* The error of a cut: the true error bound of a shown cell's complex
 * (ms_view_cell_error_bound, ms_view_decoder.h; docs/CLIENT.md, "The error
 * of a cut"). */
#include <math.h>

#include "ms_view_decoder_internal.h"

double ms_view_cell_error_bound(ms_view *v, uint32_t cell)
{
    vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SHOWN)
        return -1.0;
    if (c->rec.geometry_length == 0)
        return 0.0;
    if (c->bound_valid && c->bound_bits == c->bits && c->bound_dec == c->dec)
        return c->bound;
    double bound;
    if (c->dec) {
        /* the stream's grid: its key space is p_max bits */
        unsigned p = ms_codec_decoder_header(c->dec)->p_max;
        bound = ms_codec_decoder_error_bound(c->dec) * ldexp(v->header.box_side, -(int)p);
    } else {
        /* its start state, drawn at the kd-cells' centres */
        bound = 0.5 * sqrt(3.0) * ldexp(v->header.box_side, -(int)c->bits) * (1.0 + 0x1p-40);
    }
    c->bound = bound;
    c->bound_bits = c->bits;
    c->bound_dec = c->dec;
    c->bound_valid = true;
    return bound;
}
