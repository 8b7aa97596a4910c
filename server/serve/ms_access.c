/* Payload access rules: see ms_access.h. */
#include "ms_access.h"

#include <string.h>

#include "ms_preview.h"
#include "ms_subtree.h"

/* The grant for a model of bits geometry bits, apo_levels APO levels and a
 * public preview of public_bits. */
static ms_access grant_of(unsigned bits, uint8_t apo_levels, unsigned public_bits,
                          bool token_accepted)
{
    ms_access grant;
    grant.geometry_steps = (uint8_t)(bits + 1u);
    grant.apo_steps = apo_levels;
    /* The registry clamps public_max_bits to bits; clamp again rather than trust it. */
    bool full = token_accepted || public_bits >= bits;
    grant.permitted_geometry_steps = (uint8_t)(full ? bits + 1u : public_bits + 1u);
    /* APO is limited cell by cell (ms_access_cell_apo_steps); the grant says
     * the most any cell gives, a cell at level 0: public_max_bits + 1 levels. */
    grant.permitted_apo_steps = apo_levels;
    if (!full && public_bits + 1u < grant.permitted_apo_steps)
        grant.permitted_apo_steps = (uint8_t)(public_bits + 1u);
    return grant;
}

ms_access ms_access_grant(const ms_model *model, bool token_accepted)
{
    return grant_of(ms_archive_get_header(model->archive)->bits, model->max_apo_levels,
                    model->entry.public_max_bits, token_accepted);
}

ms_access ms_access_grant_listed(const ms_catalog_entry *entry, bool token_accepted)
{
    return grant_of(entry->bits, entry->apo_levels, entry->public_max_bits, token_accepted);
}

bool ms_access_document(const ms_catalog_entry *entry, int kind)
{
    switch (kind) {
    case MS_DOCUMENT_THUMBNAIL:
        return entry->has_thumbnail && entry->thumbnail_bits <= entry->public_max_bits;
    case MS_DOCUMENT_METADATA:
    case MS_DOCUMENT_ANNOTATIONS:
        return true;
    default:
        return false;
    }
}

bool ms_access_is_full(const ms_access *grant)
{
    return grant->permitted_geometry_steps >= grant->geometry_steps &&
           grant->permitted_apo_steps >= grant->apo_steps;
}

bool ms_access_cell_hidden(const ms_model *model, const ms_access *grant, uint32_t cell)
{
    const ms_archive_cell *c = ms_archive_get_cell(model->archive, cell);
    return c && grant->permitted_geometry_steps < grant->geometry_steps &&
           c->bits_min >= grant->permitted_geometry_steps;
}

uint8_t ms_access_cell_apo_steps(const ms_model *model, const ms_access *grant, uint32_t cell)
{
    const ms_archive_cell *c = ms_archive_get_cell(model->archive, cell);
    if (!c)
        return 0;
    if (grant->permitted_geometry_steps >= grant->geometry_steps)
        return grant->apo_steps;
    unsigned levels = ms_archive_preview_apo_levels(ms_archive_get_header(model->archive), c,
                                                    grant->permitted_geometry_steps);
    return (uint8_t)(levels < grant->apo_steps ? levels : grant->apo_steps);
}

static ms_status access_fault(ms_proto_fault *fault, uint16_t code, uint64_t detail,
                              ms_error *err, const char *text)
{
    if (fault) {
        memset(fault, 0, sizeof *fault);
        fault->code = code;
        fault->detail = detail;
    }
    return ms_error_set(err, MS_ERR_RANGE, "%s", text);
}

/* A subtree of the index (stream INDEX, PROTOCOL.md section 4.10): one step,
 * the whole stored subtree. Every reader of the model may read its index, so
 * the grant widens nothing and limits nothing here; the range rules (BYTES
 * inside the stream) are the payloads'. */
static ms_status resolve_subtree(const ms_model *model, const ms_proto_cell_request *request,
                                 ms_proto_byte_range *out, ms_proto_fault *fault, ms_error *err)
{
    size_t stored_size = 0;
    const uint8_t *stored = ms_archive_subtree(model->archive, request->cell_id, &stored_size);
    if (!stored)
        return access_fault(fault, MS_PROTO_E_UNKNOWN_CELL, request->cell_id, err,
                            "no such subtree");
    if (stored_size > UINT32_MAX)
        return access_fault(fault, MS_PROTO_E_INTERNAL, 0, err, "subtree too large");
    const uint32_t end = (uint32_t)stored_size;
    const ms_proto_stream_steps steps = {0, 1, &end};
    const ms_proto_stream_access whole = {1, 1};
    return ms_proto_resolve_range(request, &steps, &whole, out, fault, err);
}

ms_status ms_access_resolve(const ms_model *model, const ms_access *grant,
                            const ms_proto_cell_request *request, ms_proto_byte_range *out,
                            ms_proto_fault *fault, ms_error *err)
{
    if (request->stream == MS_PROTO_STREAM_INDEX)
        return resolve_subtree(model, request, out, fault, err);
    const ms_archive *a = model->archive;
    const ms_archive_cell *cell = ms_archive_get_cell(a, request->cell_id);
    if (!cell)
        return access_fault(fault, MS_PROTO_E_UNKNOWN_CELL, request->cell_id, err,
                            "no such cell");
    uint32_t ends[MS_PROTO_MAX_STEPS];
    ms_proto_stream_steps steps = {0, 0, ends};
    ms_proto_stream_access access;
    if (request->stream == MS_PROTO_STREAM_GEOMETRY) {
        steps.first_step = cell->bits_min;
        steps.step_count = cell->bits_max >= cell->bits_min ? cell->bits_max - cell->bits_min + 1u : 0;
        if (steps.step_count > MS_PROTO_MAX_STEPS)
            steps.step_count = MS_PROTO_MAX_STEPS; /* resolve_range reports the bad window */
        for (uint32_t i = 0; i < steps.step_count; ++i)
            ends[i] = ms_archive_geometry_prefix(a, request->cell_id, cell->bits_min + i);
        access = (ms_proto_stream_access){grant->geometry_steps, grant->permitted_geometry_steps};
    } else if (request->stream == MS_PROTO_STREAM_COLOUR) {
        /* Colour follows the geometric preview (section 8): the same steps,
         * precision bits of the cell's window, and the same permitted count,
         * so a preview reader sees no vertex's colour finer than its shape. */
        steps.first_step = cell->bits_min;
        steps.step_count = cell->bits_max >= cell->bits_min ? cell->bits_max - cell->bits_min + 1u : 0;
        if (steps.step_count > MS_PROTO_MAX_STEPS)
            steps.step_count = MS_PROTO_MAX_STEPS;
        for (uint32_t i = 0; i < steps.step_count; ++i)
            ends[i] = ms_archive_colour_prefix(a, request->cell_id, cell->bits_min + i);
        access = (ms_proto_stream_access){grant->geometry_steps, grant->permitted_geometry_steps};
    } else {
        /* APO detail follows the geometric preview cell by cell (section 8):
         * nothing of a hidden cell, and no texel finer than the preview's
         * grid step (ms_archive_preview_apo_levels). */
        if (ms_access_cell_hidden(model, grant, request->cell_id))
            return access_fault(fault, MS_PROTO_E_FORBIDDEN, grant->permitted_geometry_steps, err,
                                "the cell is beyond the public preview");
        steps.step_count = cell->apo_levels;
        for (uint32_t i = 0; i < steps.step_count; ++i)
            ends[i] = ms_archive_apo_prefix(a, request->cell_id, i, NULL);
        access = (ms_proto_stream_access){grant->apo_steps,
                                          ms_access_cell_apo_steps(model, grant, request->cell_id)};
    }
    return ms_proto_resolve_range(request, &steps, &access, out, fault, err);
}
