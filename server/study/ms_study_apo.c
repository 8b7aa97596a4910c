/* APO chunks for the CPU renderer (ms_study_apo.h). */
#include "ms_study_apo.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_filter.h"
#include "ms_apo_stream.h"

typedef struct apo_cell {
    double origin[3], side;
    ms_apo_chunk chunk;
    ms_apo_view view;
    bool present;
} apo_cell;

struct ms_study_apo {
    apo_cell *cells;
    uint32_t cell_count, chunk_count;
    uint32_t levels, depth_cap;
    ms_apo_missing_rule rule;
    ms_study_apo_filter filter;
};

/* A view of the chunk's first `levels` levels (0: all). */
static ms_status view_levels(const ms_apo_chunk *chunk, uint32_t levels, ms_apo_view *view, ms_error *err)
{
    size_t received = chunk->texel_count;
    if (levels && levels < chunk->level_count) {
        received = 0;
        for (uint32_t l = 0; l < levels; ++l)
            received += chunk->level_texels[l];
    }
    return ms_apo_view_init(view, chunk->level_texels, chunk->level_count, chunk->texels, received, err);
}

ms_status ms_study_apo_set_levels(ms_study_apo *s, uint32_t cell, uint32_t levels, ms_error *err)
{
    if (cell >= s->cell_count)
        return ms_error_set(err, MS_ERR_RANGE, "study apo: cell %u of %u", cell, s->cell_count);
    apo_cell *c = &s->cells[cell];
    if (!c->present)
        return MS_OK;
    ms_apo_view view;
    ms_status st = view_levels(&c->chunk, levels, &view, err);
    if (st == MS_OK)
        c->view = view;
    return st;
}

void ms_study_cell_cube(const ms_archive_header *h, const ms_archive_cell *c, double origin[3], double *side)
{
    *side = h->box_side / pow((double)h->n, c->level);
    for (int k = 0; k < 3; ++k)
        origin[k] = h->box_origin[k] + *side * c->position[k];
}

ms_status ms_study_apo_new(uint32_t cell_count, uint32_t levels, uint32_t depth_cap, ms_apo_missing_rule rule,
                           ms_study_apo **out, ms_error *err)
{
    *out = NULL;
    ms_study_apo *s = calloc(1, sizeof *s);
    if (!s || !(s->cells = calloc(cell_count ? cell_count : 1, sizeof *s->cells))) {
        free(s);
        return ms_error_set(err, MS_ERR_NOMEM, "study apo: out of memory for %u cells", cell_count);
    }
    s->cell_count = cell_count;
    s->levels = levels;
    s->depth_cap = depth_cap;
    s->rule = rule;
    s->filter = MS_STUDY_APO_FILTER_LINEAR;
    *out = s;
    return MS_OK;
}

void ms_study_apo_free(ms_study_apo *s)
{
    if (!s)
        return;
    for (uint32_t i = 0; i < s->cell_count; ++i)
        ms_apo_chunk_free(&s->cells[i].chunk);
    free(s->cells);
    free(s);
}

ms_status ms_study_apo_put(ms_study_apo *s, uint32_t cell, const double origin[3], double side,
                           ms_apo_chunk *chunk, ms_error *err)
{
    ms_apo_chunk taken = *chunk;
    memset(chunk, 0, sizeof *chunk);
    if (cell >= s->cell_count || !(side > 0) || !isfinite(side) || !isfinite(origin[0]) ||
        !isfinite(origin[1]) || !isfinite(origin[2])) {
        ms_apo_chunk_free(&taken);
        return ms_error_set(err, MS_ERR_RANGE, "study apo: cell %u (of %u) with cube side %g", cell,
                            s->cell_count, side);
    }
    apo_cell *c = &s->cells[cell];
    ms_apo_view view;
    ms_status st = view_levels(&taken, s->levels, &view, err);
    if (st != MS_OK) {
        ms_apo_chunk_free(&taken);
        return st;
    }
    if (c->present)
        s->chunk_count--;
    ms_apo_chunk_free(&c->chunk);
    c->chunk = taken;
    c->view = view; /* borrows c->chunk's words, which stay where they are */
    memcpy(c->origin, origin, sizeof c->origin);
    c->side = side;
    c->present = true;
    s->chunk_count++;
    return MS_OK;
}

ms_status ms_study_apo_from_archive(const ms_archive *a, uint32_t levels, uint32_t depth_cap,
                                    ms_apo_missing_rule rule, ms_study_apo **out, ms_error *err)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    ms_study_apo *s;
    ms_status st = ms_study_apo_new(h->cell_count, levels, depth_cap, rule, &s, err);
    if (st != MS_OK)
        return st;
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(a, i);
        if (!c->apo_levels)
            continue;
        size_t length;
        const uint8_t *data = ms_archive_apo(a, i, &length);
        if (!data) {
            ms_study_apo_free(s);
            return ms_error_set(err, MS_ERR_ARG, "study apo: the archive holds no payloads (an index only)");
        }
        if ((st = ms_archive_check_payload(a, i, true, data, length, err)) != MS_OK) {
            ms_study_apo_free(s);
            return st;
        }
        uint32_t table[2 * MS_ARCHIVE_MAX_APO_LEVELS];
        for (uint32_t l = 0; l < c->apo_levels; ++l)
            table[2 * l] = ms_archive_apo_prefix(a, i, l, &table[2 * l + 1]);
        ms_apo_chunk chunk = {0};
        if ((st = ms_apo_stream_inflate(data, length, table, c->apo_levels, &chunk, err)) != MS_OK) {
            ms_study_apo_free(s);
            return st;
        }
        double origin[3], side;
        ms_study_cell_cube(h, c, origin, &side);
        if ((st = ms_study_apo_put(s, i, origin, side, &chunk, err)) != MS_OK) {
            ms_study_apo_free(s);
            return st;
        }
    }
    *out = s;
    return MS_OK;
}

void ms_study_apo_set_filter(ms_study_apo *s, ms_study_apo_filter filter)
{
    s->filter = filter;
}

bool ms_study_apo_filter_parse(const char *name, ms_study_apo_filter *filter)
{
    static const char *const names[] = {"linear", "nearest", "none"};
    for (int f = 0; f < 3; ++f)
        if (!strcmp(name, names[f])) {
            *filter = (ms_study_apo_filter)f;
            return true;
        }
    return false;
}

bool ms_study_apo_normal(const ms_study_apo *s, uint32_t cell, const double x[3], double footprint,
                         const double smooth[3], double normal[3])
{
    if (cell >= s->cell_count || !s->cells[cell].present)
        return false;
    const apo_cell *c = &s->cells[cell];
    float local[3];
    for (int k = 0; k < 3; ++k)
        local[k] = (float)((x[k] - c->origin[k]) / c->side);
    uint32_t cap = s->depth_cap;
    if (s->filter != MS_STUDY_APO_FILTER_NONE && footprint > 0) {
        uint32_t d = ms_apo_footprint_depth((float)(footprint / c->side));
        cap = d < cap ? d : cap;
    }
    const float *n;
    ms_apo_lookup_result r;
    ms_apo_filter_result fr;
    if (s->filter == MS_STUDY_APO_FILTER_LINEAR) {
        const float sm[3] = {(float)smooth[0], (float)smooth[1], (float)smooth[2]};
        if (ms_apo_lookup_filtered_smooth(&c->view, local, cap, s->rule, sm, &fr) ==
                MS_APO_STOP_EMPTY ||
            fr.texels == 0)
            return false;
        n = fr.normal;
    } else {
        if (ms_apo_lookup(&c->view, local, cap, s->rule, &r) == MS_APO_STOP_EMPTY || r.smooth)
            return false;
        n = r.normal;
    }
    double len = sqrt((double)n[0] * n[0] + (double)n[1] * n[1] + (double)n[2] * n[2]);
    if (!(len > 0))
        return false;
    for (int k = 0; k < 3; ++k)
        normal[k] = n[k] / len;
    return true;
}

uint32_t ms_study_apo_chunk_count(const ms_study_apo *s)
{
    return s->chunk_count;
}
