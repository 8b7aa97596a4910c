/* The error of a cut: what a shown cell draws now, from its record's
 * surface error table (ms_view_cell_error_bound, ms_view_decoder.h;
 * docs/CLIENT.md, "The error of a cut"). */
#include "ms_view_decoder_internal.h"

double ms_view_cell_error_bound(ms_view *v, uint32_t cell)
{
    const vcell *c = ms_view_vcell(v, cell);
    if (!c || c->state != MS_VIEW_SHOWN)
        return -1.0;
    if (c->rec.geometry_length == 0)
        return 0.0;
    return ms_archive_cell_error(&v->header, &c->rec, c->bits);
}
