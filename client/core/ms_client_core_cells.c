/* The client core's per-cell reception state (dcell), kept per sibling group
 * like the view's cells (ms_view_decoder.h): a block for each group of which
 * the view knows a record, so that with an index that comes by subtree what
 * the core holds follows the records it holds. Decode thread only. */
#include "ms_client_core_internal.h"

#include <stdlib.h>

static uint32_t group_of(const ms_core *c, uint32_t cell)
{
    return cell == 0 ? 0 : 1 + (cell - 1) / c->dec.group_size;
}

static uint32_t group_cells(const ms_core *c, uint32_t group)
{
    return group == 0 ? 1 : c->dec.group_size;
}

dcell *ms_core_dcell(const ms_core *c, uint32_t cell)
{
    if (!c->dec.view || !ms_view_known(c->dec.view, cell))
        return NULL;
    dcell *block = c->dec.cell_groups[group_of(c, cell)];
    return block ? &block[cell == 0 ? 0 : (cell - 1) % c->dec.group_size] : NULL;
}

bool ms_core_dcells_grow(ms_core *c, const uint32_t *cells, size_t count)
{
    if (!c->dec.cell_groups) {
        const ms_archive_header *h = ms_view_header(c->dec.view);
        c->dec.group_size = (uint32_t)h->n * h->n * h->n;
        c->dec.group_count = 1 + (h->cell_count - 1) / c->dec.group_size;
        c->dec.cell_groups = calloc(c->dec.group_count, sizeof *c->dec.cell_groups);
        if (!c->dec.cell_groups)
            return false;
    }
    for (size_t k = 0; k < count; ++k) {
        uint32_t g = group_of(c, cells[k]);
        if (!c->dec.cell_groups[g] &&
            !(c->dec.cell_groups[g] = calloc(group_cells(c, g), sizeof *c->dec.cell_groups[g])))
            return false;
    }
    return true;
}

void ms_core_dcell_clear(dcell *d)
{
    ms_core_rx_free(&d->geo);
    ms_core_apo_drop(d);
    ms_core_rx_free(&d->col);
    free(d->header);
    *d = (dcell){0};
}

/* Whether the view knows a record of group g. */
static bool group_known(const ms_core *c, uint32_t g)
{
    uint32_t first = g == 0 ? 0 : 1 + (g - 1) * c->dec.group_size;
    for (uint32_t k = 0; k < group_cells(c, g); ++k)
        if (ms_view_known(c->dec.view, first + k))
            return true;
    return false;
}

void ms_core_dcells_release(ms_core *c, const uint32_t *cells, size_t count)
{
    for (size_t k = 0; c->dec.cell_groups && k < count; ++k) {
        uint32_t g = group_of(c, cells[k]);
        if (!c->dec.cell_groups[g] || group_known(c, g))
            continue;
        for (uint32_t m = 0; m < group_cells(c, g); ++m)
            ms_core_dcell_clear(&c->dec.cell_groups[g][m]);
        free(c->dec.cell_groups[g]);
        c->dec.cell_groups[g] = NULL;
    }
}

void ms_core_dcells_free(ms_core *c)
{
    for (uint32_t g = 0; c->dec.cell_groups && g < c->dec.group_count; ++g) {
        for (uint32_t k = 0; c->dec.cell_groups[g] && k < group_cells(c, g); ++k)
            ms_core_dcell_clear(&c->dec.cell_groups[g][k]);
        free(c->dec.cell_groups[g]);
    }
    free(c->dec.cell_groups);
    c->dec.cell_groups = NULL;
}

size_t ms_core_state_bytes_per_cell(void) { return ms_view_cell_state_size() + sizeof(dcell); }

uint64_t ms_core_state_bytes_held(const ms_core *c)
{
    return c->dec.view ? (uint64_t)ms_view_state_cells(c->dec.view) * ms_core_state_bytes_per_cell() : 0;
}

/* Drops a cell's APO bytes: its reception buffer and the frames' copy (which
 * frames still holding it keep until they are freed). */
void ms_core_apo_drop(dcell *d)
{
    ms_core_rx_free(&d->apo);
    d->apo_given = 0;
    ms_core_bytes_release(d->apo_shared);
    d->apo_shared = NULL;
}
