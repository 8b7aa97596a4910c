/* The public preview's rules: see ms_preview.h. */
#include "ms_preview.h"

unsigned ms_archive_preview_apo_levels(const ms_archive_header *h, const ms_archive_cell *c,
                                       unsigned permitted_geometry_steps)
{
    if (permitted_geometry_steps > h->bits)
        return MS_ARCHIVE_MAX_APO_LEVELS;
    unsigned log2n = 0; /* n is 2, 4 or 8 (the archive reader checks it) */
    while ((1u << log2n) < h->n)
        ++log2n;
    unsigned coarse = log2n * c->level; /* bits above the cell's cube */
    if (c->bits_min >= permitted_geometry_steps || permitted_geometry_steps <= coarse)
        return 0; /* a hidden cell, or every texel finer than the preview's grid */
    return permitted_geometry_steps - coarse;
}
