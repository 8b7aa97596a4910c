/* The renderer (ms_render.h): frames in, an upload queue within a byte budget,
 * one draw call per drawing cell.
 *
 * Each cell has a current state (what is drawn: a mesh on the GPU and a range of
 * the texel buffer) and a pending one (what the latest frame wants and is not yet
 * wholly on the GPU). A pending mesh goes up in pieces into buffers of its own
 * and replaces the current one only once complete; the same for a pending APO
 * prefix and its texel range (sent after the cell's mesh). Cells wait in a queue
 * in the order they changed; an upload serves first the queued cells that draw
 * nothing yet (holes), then the others. The drawing is ms_render_draw.c's. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_render_internal.h"

void ms_render_options_default(ms_render_options *o)
{
    memset(o, 0, sizeof *o);
    o->shading = MS_SHADING_LIT;
    o->apo = true;
    o->wireframe = false;
    o->apo_depth_cap = 0;
    o->apo_nearest = false; /* a missing child is "no correction" (docs/APO.md) */
    o->apo_filter = true;
    o->apo_footprint = true;
    o->smooth = true;
    o->background[0] = o->background[1] = o->background[2] = 0.02f;
    o->effects = MS_EFFECTS_VIEWER;
    o->albedo[0] = 0.72f, o->albedo[1] = 0.69f, o->albedo[2] = 0.64f;
    o->specular = 0.18f;
    o->shininess = 40.0f;
    o->two_sided = true;
    o->haze_density = 0.0f;
    o->light_count = 1;
    o->lights[0].kind = MS_RENDER_LIGHT_HEAD;
    o->lights[0].colour[0] = o->lights[0].colour[1] = o->lights[0].colour[2] = 1.0f;
    o->placed = false;
    for (int i = 0; i < 16; ++i)
        o->placement[i] = i % 5 == 0 ? 1.0 : 0.0;
    o->clear = true;
    o->displace = false;
    o->displacement_amplitude = 0.01f;
    o->displacement_radius = 0.05f;
    o->displacement_density = 100.0f;
    o->displacement_seed = 1;
    o->tess_pixels_per_level = 8.0f;
    o->section_colour[0] = MS_SECTION_R, o->section_colour[1] = MS_SECTION_G, o->section_colour[2] = MS_SECTION_B;
}

ms_status ms_render_find_program(ms_render *r, unsigned effects, uint32_t variant, bool wireframe, bool tessellated,
                                 const ms_render_program **out, ms_error *err)
{
    for (uint32_t i = 0; i < r->program_count; ++i)
        if (r->programs[i].effects == effects && r->programs[i].variant == variant &&
            r->programs[i].wireframe == wireframe &&
            r->programs[i].tessellated == tessellated) {
            *out = &r->programs[i];
            return MS_OK;
        }
    uint32_t slot;
    if (r->program_count < MS_RENDER_PROGRAM_CACHE)
        slot = r->program_count;
    else {
        slot = r->program_next;
        r->program_next = (r->program_next + 1) % MS_RENDER_PROGRAM_CACHE;
        ms_render_program_free(&r->programs[slot]);
    }
    ms_status st = ms_render_program_build(&r->programs[slot], effects, variant, wireframe, tessellated, err);
    if (st != MS_OK) {
        /* an evicted slot is empty now: the last program fills the hole */
        if (slot < r->program_count) {
            r->programs[slot] = r->programs[r->program_count - 1];
            memset(&r->programs[--r->program_count], 0, sizeof r->programs[0]);
        }
        return st;
    }
    if (slot == r->program_count)
        r->program_count++;
    *out = &r->programs[slot];
    return MS_OK;
}

/* ---- per-cell GPU state ---------------------------------------------------- */

static void delete_gpu_mesh(ms_render *r, gpu_mesh *m)
{
    if (m->vao)
        glDeleteVertexArrays(1, &m->vao);
    if (m->vbo)
        glDeleteBuffers(1, &m->vbo);
    if (m->ibo)
        glDeleteBuffers(1, &m->ibo);
    ms_render_gl_sub(&r->gl, m->gl_bytes);
    r->mesh_bytes -= m->gl_bytes;
    memset(m, 0, sizeof *m);
}

static void drop_pending_mesh(ms_render *r, pending_mesh *p)
{
    free(p->vertices);
    free(p->normals);
    free(p->colours);
    free(p->indices);
    delete_gpu_mesh(r, &p->gpu);
    memset(p, 0, sizeof *p);
}

static void drop_pending_apo(ms_render *r, pending_apo *p)
{
    if (p->allocated)
        ms_render_texels_release(&r->texels, p->range.start, p->range.count);
    free(p->words);
    memset(p, 0, sizeof *p);
}

static void drop_current_apo(ms_render *r, render_cell *c)
{
    if (c->apo.count)
        ms_render_texels_release(&r->texels, c->apo.start, c->apo.count);
    memset(&c->apo, 0, sizeof c->apo);
}

static void drop_cell(ms_render *r, render_cell *c)
{
    free(c->touch);
    c->touch = NULL;
    c->touch_count = 0;
    c->has_version = false;
    free(c->corners);
    c->corners = NULL;
    c->corner_count = 0;
    delete_gpu_mesh(r, &c->mesh);
    drop_pending_mesh(r, &c->next_mesh);
    drop_pending_apo(r, &c->next_apo);
    drop_current_apo(r, c);
    c->failed_apo_levels = 0;
    c->in_frame = false;
}

/* ---- cells by sibling group ------------------------------------------------- */

static uint32_t group_of(const ms_render *r, uint32_t id)
{
    return id == 0 ? 0 : 1 + (id - 1) / r->group_size;
}

static uint32_t place_in_group(const ms_render *r, uint32_t id)
{
    return id == 0 ? 0 : (id - 1) % r->group_size;
}

render_cell *ms_render_cell_at(const ms_render *r, uint32_t id)
{
    if (id >= r->header.cell_count)
        return NULL;
    render_cell *block = r->groups[group_of(r, id)];
    return block ? &block[place_in_group(r, id)] : NULL;
}

const ms_archive_cell *ms_render_record(const ms_render *r, uint32_t id)
{
    if (id >= r->header.cell_count)
        return NULL;
    if (r->records)
        return &r->records[id];
    const render_cell *c = ms_render_cell_at(r, id);
    return c && c->known ? &c->record : NULL;
}

/* The state of cell id, its group's block made when absent; NULL when out of
 * memory. */
static render_cell *cell_made(ms_render *r, uint32_t id)
{
    uint32_t g = group_of(r, id);
    if (!r->groups[g] && !(r->groups[g] = calloc(r->group_size, sizeof *r->groups[g])))
        return NULL;
    return &r->groups[g][place_in_group(r, id)];
}

/* ---- life cycle ------------------------------------------------------------ */

static ms_status check_record(const ms_archive_header *h, uint32_t id, const ms_archive_cell *c, ms_error *err)
{
    double cells_per_side = pow((double)h->n, (double)c->level);
    if (c->level > 32 || c->position[0] >= cells_per_side || c->position[1] >= cells_per_side ||
        c->position[2] >= cells_per_side)
        return ms_error_set(err, MS_ERR_ARG, "render: cell %u position outside its level %u", id, c->level);
    if (c->apo_levels > MS_APO_MAX_LEVELS)
        return ms_error_set(err, MS_ERR_ARG, "render: cell %u has %u APO levels", id, c->apo_levels);
    return MS_OK;
}

static ms_status check_model(const ms_archive_header *h, const ms_archive_cell *cells, ms_error *err)
{
    if (!h)
        return ms_error_set(err, MS_ERR_ARG, "render: no model header");
    if (h->cell_count == 0 || h->cell_count > MS_ARCHIVE_MAX_CELLS)
        return ms_error_set(err, MS_ERR_ARG, "render: %u cells", h->cell_count);
    if (!(h->box_side > 0.0) || !isfinite(h->box_side) || !isfinite(h->box_origin[0]) ||
        !isfinite(h->box_origin[1]) || !isfinite(h->box_origin[2]))
        return ms_error_set(err, MS_ERR_ARG, "render: model box not finite and positive");
    if (h->n < 2 || h->n > 64)
        return ms_error_set(err, MS_ERR_ARG, "render: %u children per axis", h->n);
    for (uint32_t i = 0; cells && i < h->cell_count; ++i) {
        ms_status st = check_record(h, i, &cells[i], err);
        if (st != MS_OK)
            return st;
    }
    return MS_OK;
}

/* The model's part of a renderer: per-group state and, with a whole index,
 * its records. */
static ms_status take_model(ms_render *r, const ms_archive_header *header, const ms_archive_cell *cells,
                            ms_error *err)
{
    ms_status st = check_model(header, cells, err);
    if (st != MS_OK)
        return st;
    size_t n = header->cell_count;
    uint32_t group_size = header->n * header->n * header->n;
    uint32_t group_count = 1 + (uint32_t)((n - 1 + group_size - 1) / group_size);
    render_cell **groups = calloc(group_count, sizeof *groups);
    ms_archive_cell *records = cells ? malloc(n * sizeof *records) : NULL;
    if (!groups || (cells && !records)) {
        free(groups);
        free(records);
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %zu cells", n);
    }
    if (cells)
        memcpy(records, cells, n * sizeof *records);
    r->header = *header;
    r->group_size = group_size;
    r->group_count = group_count;
    r->groups = groups;
    r->records = records;
    r->has_model = true;
    return MS_OK;
}

ms_status ms_render_new(const ms_archive_header *header, const ms_archive_cell *cells, ms_render **out,
                        ms_error *err)
{
    if (!out)
        return ms_error_set(err, MS_ERR_ARG, "render: no result pointer");
    *out = NULL;
    if (header || cells) {
        ms_status st = check_model(header, cells, err);
        if (st != MS_OK)
            return st;
    }
    if (!glGetString(GL_VERSION))
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: no current OpenGL context");
    if (epoxy_gl_version() < 41)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: OpenGL %d.%d, 4.1 needed", epoxy_gl_version() / 10,
                            epoxy_gl_version() % 10);
    ms_render *r = calloc(1, sizeof *r);
    if (!r)
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory");
    r->crease_angle_deg = MS_RENDER_CREASE_ANGLE_DEFAULT;
    r->derived_crease = -1.0;
    ms_status st = header ? take_model(r, header, cells, err) : MS_OK;
    ms_render_split_init(&r->split, &r->header);
    const ms_render_program *viewer = NULL, *unused;
    ms_render_options defaults; /* the viewer's first draw: no colour, no section, the head light */
    ms_render_options_default(&defaults);
    if (st == MS_OK)
        st = ms_render_find_program(r, MS_EFFECTS_VIEWER, ms_render_program_variant(&defaults, false, false, false),
                                    false, false, &viewer, err);
    if (st == MS_OK)
        st = ms_render_find_program(r, MS_EFFECTS_VIEWER, ms_render_program_variant(&defaults, false, true, false),
                                    true, false, &unused, err);
    if (st == MS_OK)
        st = ms_render_texels_init(&r->texels, &r->gl, err);
    /* the viewer's first draw compiles nothing more: the model's first frame
     * is drawn as soon as it comes (docs/VIEWER.md, "Opening a model") */
    if (st == MS_OK)
        ms_render_warm_up(r, viewer);
    if (st != MS_OK) {
        ms_render_free(r);
        return st;
    }
    *out = r;
    return MS_OK;
}

ms_status ms_render_set_model(ms_render *r, const ms_archive_header *header, ms_error *err)
{
    if (!r)
        return ms_error_set(err, MS_ERR_ARG, "render: no renderer");
    if (r->has_model)
        return ms_error_set(err, MS_ERR_ARG, "render: the renderer already has a model");
    if (!header)
        return ms_error_set(err, MS_ERR_ARG, "render: no model header");
    ms_status st = take_model(r, header, NULL, err);
    if (st == MS_OK)
        ms_render_split_init(&r->split, &r->header);
    return st;
}

ms_status ms_render_set_crease_angle(ms_render *r, double degrees, ms_error *err)
{
    if (!r)
        return ms_error_set(err, MS_ERR_ARG, "render: no renderer");
    if (!(degrees >= 0.0 && degrees <= 180.0))
        return ms_error_set(err, MS_ERR_ARG, "render: crease angle %g degrees (0 to 180)", degrees);
    r->crease_angle_deg = degrees;
    return MS_OK;
}

double ms_render_crease_angle(const ms_render *r) { return r->crease_angle_deg; }

ms_status ms_render_learn(ms_render *r, const uint32_t *ids, const ms_archive_cell *records, size_t count,
                          ms_error *err)
{
    if (!r || (count && (!ids || !records)))
        return ms_error_set(err, MS_ERR_ARG, "render: nothing to learn from");
    if (!r->has_model)
        return ms_error_set(err, MS_ERR_ARG, "render: no model yet (ms_render_set_model)");
    for (size_t i = 0; i < count; ++i) {
        if (ids[i] >= r->header.cell_count)
            return ms_error_set(err, MS_ERR_ARG, "render: record of cell %u of %u", ids[i], r->header.cell_count);
        ms_status st = check_record(&r->header, ids[i], &records[i], err);
        if (st != MS_OK)
            return st;
    }
    for (size_t i = 0; i < count; ++i) {
        render_cell *c = cell_made(r, ids[i]);
        if (!c)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", ids[i]);
        c->record = records[i];
        c->known = true;
    }
    return MS_OK;
}

void ms_render_free(ms_render *r)
{
    if (!r)
        return;
    for (uint32_t g = 0; r->groups && g < r->group_count; ++g) {
        if (!r->groups[g])
            continue;
        for (uint32_t k = 0; k < r->group_size; ++k)
            drop_cell(r, &r->groups[g][k]);
        free(r->groups[g]);
    }
    ms_render_texels_free(&r->texels);
    for (uint32_t i = 0; i < r->program_count; ++i)
        ms_render_program_free(&r->programs[i]);
    ms_render_split_free(&r->split);
    ms_render_touch_map_free(&r->touch);
    free(r->keys);
    free(r->shade);
    free(r->fan_vertices);
    free(r->key_set);
    free(r->records);
    free(r->groups);
    free(r->frame_cells);
    free(r->queue);
    free(r);
}

/* ---- frames ------------------------------------------------------------------ */

ms_status ms_render_take_mesh(ms_render *r, render_cell *c, const ms_render_cell_mesh *m, ms_error *err)
{
    bool coloured = m->colours != NULL;
    bool same_as_current = c->mesh.vao && c->mesh.hash == m->hash && c->mesh.vertex_count == m->vertex_count &&
                           c->mesh.triangle_count == m->triangle_count && c->mesh.coloured == coloured;
    if (c->next_mesh.active) {
        const gpu_mesh *g = &c->next_mesh.gpu;
        if (g->hash == m->hash && g->vertex_count == m->vertex_count && g->triangle_count == m->triangle_count &&
            g->coloured == coloured)
            return MS_OK;
        drop_pending_mesh(r, &c->next_mesh);
    }
    if (same_as_current)
        return MS_OK;
    pending_mesh *p = &c->next_mesh;
    p->vertices = malloc(3 * (size_t)m->vertex_count * sizeof *p->vertices);
    p->normals = malloc((size_t)m->vertex_count * sizeof *p->normals);
    p->indices = malloc(3 * (size_t)m->triangle_count * sizeof *p->indices);
    p->colours = coloured ? malloc((size_t)m->vertex_count * sizeof *p->colours) : NULL;
    if (!p->vertices || !p->normals || !p->indices || (coloured && !p->colours)) {
        drop_pending_mesh(r, p);
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", m->cell);
    }
    memcpy(p->vertices, m->vertices, 3 * (size_t)m->vertex_count * sizeof *p->vertices);
    memcpy(p->normals, m->normals, (size_t)m->vertex_count * sizeof *p->normals);
    memcpy(p->indices, m->indices, 3 * (size_t)m->triangle_count * sizeof *p->indices);
    if (coloured)
        memcpy(p->colours, m->colours, (size_t)m->vertex_count * sizeof *p->colours);
    p->gpu.coloured = coloured;
    p->gpu.vertex_count = m->vertex_count;
    p->gpu.triangle_count = m->triangle_count;
    p->gpu.hash = m->hash;
    p->active = true;
    return MS_OK;
}

/* The cell's APO prefix in the new frame (levels 0: none). A prefix that does not
 * load leaves the cell on its geometric normals. */
static ms_status take_apo(ms_render *r, uint32_t cell, const ms_core_apo_chunk *chunk, unsigned levels,
                          ms_error *err)
{
    render_cell *c = ms_render_cell_at(r, cell);
    if (levels == 0) {
        drop_pending_apo(r, &c->next_apo);
        drop_current_apo(r, c);
        c->failed_apo_levels = 0;
        return MS_OK;
    }
    if (c->next_apo.active) {
        if (c->next_apo.range.levels == levels)
            return MS_OK;
        drop_pending_apo(r, &c->next_apo);
    }
    if (c->apo.levels == levels || c->failed_apo_levels == levels)
        return MS_OK;
    uint32_t *words;
    size_t count;
    bool root_internal;
    ms_error why;
    ms_status st =
        ms_render_apo_words(ms_render_record(r, cell), chunk->data, chunk->length, levels, &words, &count, &root_internal, &why);
    if (st == MS_ERR_NOMEM)
        return ms_error_set(err, st, "%s", why.text);
    if (st != MS_OK || count > UINT32_MAX) {
        if (st == MS_OK)
            free(words);
        c->failed_apo_levels = levels;
        return MS_OK;
    }
    c->failed_apo_levels = 0;
    pending_apo *p = &c->next_apo;
    p->words = words;
    p->range = (apo_range){levels, 0, (uint32_t)count, root_internal};
    p->active = true;
    return MS_OK;
}

/* Frees the blocks of groups none of whose cells is in the frame (their cells
 * were dropped when they left it), records learned there included. */
static void free_idle_groups(ms_render *r)
{
    for (uint32_t g = 0; g < r->group_count; ++g) {
        render_cell *block = r->groups[g];
        if (!block)
            continue;
        bool used = false;
        for (uint32_t k = 0; k < r->group_size && !used; ++k)
            used = block[k].in_frame || block[k].queued;
        if (used)
            continue;
        for (uint32_t k = 0; k < r->group_size; ++k)
            drop_cell(r, &block[k]);
        free(block);
        r->groups[g] = NULL;
    }
}

ms_status ms_render_set_frame(ms_render *r, const ms_view_mesh *mesh, const ms_core_apo_chunk *apo, size_t apo_count,
                              ms_error *err)
{
    if (!r)
        return ms_error_set(err, MS_ERR_ARG, "render: no renderer");
    if (!r->has_model)
        return ms_error_set(err, MS_ERR_ARG, "render: no model yet (ms_render_set_model)");
    if (apo_count && !apo)
        return ms_error_set(err, MS_ERR_ARG, "render: %zu APO chunks but no array", apo_count);
    uint32_t n = r->header.cell_count;
    for (size_t i = 0; i < apo_count; ++i) {
        if (apo[i].cell >= n)
            return ms_error_set(err, MS_ERR_ARG, "render: APO chunk %zu for cell %u of %u", i, apo[i].cell, n);
        if (apo[i].length && !apo[i].data)
            return ms_error_set(err, MS_ERR_ARG, "render: APO chunk %zu has no bytes", i);
    }
    memset(&r->frame_stats, 0, sizeof r->frame_stats);
    ms_status st = ms_render_split_frame(&r->split, mesh, r->crease_angle_deg, err);
    if (st != MS_OK)
        return st;
    uint32_t present = r->split.present_count;
    for (uint32_t k = 0; k < present; ++k)
        if (!ms_render_record(r, r->split.present[k]))
            return ms_error_set(err, MS_ERR_ARG, "render: cell %u draws without its record", r->split.present[k]);
    if (present > r->frame_cap) {
        size_t cap = r->frame_cap ? r->frame_cap : 64;
        while (cap < present)
            cap *= 2;
        uint32_t *frame_cells = realloc(r->frame_cells, cap * sizeof *frame_cells);
        if (frame_cells)
            r->frame_cells = frame_cells;
        uint32_t *queue = frame_cells ? realloc(r->queue, cap * sizeof *queue) : NULL;
        if (!queue)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %u cells", present);
        r->queue = queue;
        r->frame_cap = cap;
    }
    /* every drawing cell gets its state (the whole index's record copied in) */
    for (uint32_t k = 0; k < present; ++k) {
        uint32_t id = r->split.present[k];
        render_cell *c = cell_made(r, id);
        if (!c)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u", id);
        if (!c->known) {
            c->record = r->records[id]; /* known above: the whole index has it */
            c->known = true;
        }
    }
    for (size_t i = 0; i < apo_count; ++i) {
        render_cell *c = ms_render_cell_at(r, apo[i].cell);
        if (!c || !c->known)
            continue; /* a cell that draws nothing: no APO to show */
        unsigned levels = apo[i].levels < c->record.apo_levels ? apo[i].levels : c->record.apo_levels;
        c->frame_apo_levels = apo[i].length ? levels : 0;
        c->frame_apo_entry = (uint32_t)i + 1;
    }
    /* cells leaving the frame stop drawing at once */
    for (uint32_t k = 0; k < r->frame_cell_count; ++k)
        ms_render_cell_at(r, r->frame_cells[k])->in_frame = false;
    for (uint32_t k = 0; k < present; ++k)
        ms_render_cell_at(r, r->split.present[k])->in_frame = true;
    for (uint32_t k = 0; k < r->frame_cell_count; ++k) {
        render_cell *c = ms_render_cell_at(r, r->frame_cells[k]);
        if (!c->in_frame) {
            ms_render_cell_forget(r, r->frame_cells[k], c);
            drop_cell(r, c);
        }
    }
    /* the meshes of the cells whose triangles or normals may have changed */
    st = ms_render_derive_cells(r, err);
    for (uint32_t k = 0; k < present && st == MS_OK; ++k) {
        render_cell *c = ms_render_cell_at(r, r->split.present[k]);
        uint32_t e = c->frame_apo_entry;
        st = take_apo(r, r->split.present[k], e ? &apo[e - 1] : NULL, e ? c->frame_apo_levels : 0, err);
    }
    for (size_t i = 0; i < apo_count; ++i) {
        render_cell *c = ms_render_cell_at(r, apo[i].cell);
        if (c)
            c->frame_apo_levels = c->frame_apo_entry = 0;
    }
    if (present)
        memcpy(r->frame_cells, r->split.present, present * sizeof *r->frame_cells);
    r->frame_cell_count = present;
    /* the queue: cells still waiting keep their turn, newly changed ones follow */
    uint32_t kept = 0;
    for (uint32_t k = 0; k < r->queue_count; ++k) {
        render_cell *c = ms_render_cell_at(r, r->queue[k]);
        if (c->in_frame && (c->next_mesh.active || c->next_apo.active))
            r->queue[kept++] = r->queue[k];
        else
            c->queued = false;
    }
    r->queue_count = kept;
    for (uint32_t k = 0; k < r->frame_cell_count; ++k) {
        uint32_t cell = r->frame_cells[k];
        render_cell *c = ms_render_cell_at(r, cell);
        if ((c->next_mesh.active || c->next_apo.active) && !c->queued) {
            c->queued = true;
            r->queue[r->queue_count++] = cell;
        }
    }
    free_idle_groups(r);
    return st;
}

/* ---- uploads ----------------------------------------------------------------- */

/* Sends up to *left bytes of a pending mesh; true once it is current. The vertex
 * buffer holds the positions (3 floats per vertex) followed by the packed
 * normals (4 bytes per vertex) and, with colours, the colours (4 bytes per
 * vertex): 16 bytes per vertex, 20 with colours. */
static bool upload_mesh(ms_render *r, render_cell *c, uint64_t *left, uint64_t *bytes)
{
    pending_mesh *p = &c->next_mesh;
    gpu_mesh *g = &p->gpu;
    uint64_t position_bytes = 12ull * g->vertex_count, normal_end = position_bytes + 4ull * g->vertex_count;
    uint64_t vertex_bytes = normal_end + (g->coloured ? 4ull * g->vertex_count : 0);
    uint64_t index_bytes = 12ull * g->triangle_count;
    if (!g->vbo) {
        glGenBuffers(1, &g->vbo);
        glGenBuffers(1, &g->ibo);
        glBindBuffer(GL_ARRAY_BUFFER, g->vbo);
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)vertex_bytes, NULL, GL_STATIC_DRAW);
        glBindBuffer(GL_ARRAY_BUFFER, g->ibo); /* bound as an array buffer to fill: no VAO needed */
        glBufferData(GL_ARRAY_BUFFER, (GLsizeiptr)index_bytes, NULL, GL_STATIC_DRAW);
        glBindBuffer(GL_ARRAY_BUFFER, 0);
        /* the storage is held from here, while the pieces go up */
        g->gl_bytes = vertex_bytes + index_bytes;
        ms_render_gl_add(&r->gl, g->gl_bytes);
        r->mesh_bytes += g->gl_bytes;
    }
    while (p->sent < vertex_bytes + index_bytes && *left > 0) {
        bool vertices = p->sent < vertex_bytes;
        uint64_t offset = vertices ? p->sent : p->sent - vertex_bytes;
        uint64_t part = (vertices ? vertex_bytes : index_bytes) - offset;
        if (part > *left)
            part = *left;
        const uint8_t *src;
        if (!vertices)
            src = (const uint8_t *)p->indices + offset;
        else if (offset < position_bytes) {
            src = (const uint8_t *)p->vertices + offset;
            if (part > position_bytes - offset)
                part = position_bytes - offset;
        } else if (offset < normal_end) {
            src = (const uint8_t *)p->normals + (offset - position_bytes);
            if (part > normal_end - offset)
                part = normal_end - offset;
        } else
            src = (const uint8_t *)p->colours + (offset - normal_end);
        glBindBuffer(GL_ARRAY_BUFFER, vertices ? g->vbo : g->ibo);
        glBufferSubData(GL_ARRAY_BUFFER, (GLintptr)offset, (GLsizeiptr)part, src);
        p->sent += part;
        *left -= part;
        *bytes += part;
    }
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    if (p->sent < vertex_bytes + index_bytes)
        return false;
    glGenVertexArrays(1, &g->vao);
    glBindVertexArray(g->vao);
    glBindBuffer(GL_ARRAY_BUFFER, g->vbo);
    glEnableVertexAttribArray(0);
    glVertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, 12, NULL);
    glEnableVertexAttribArray(1);
    glVertexAttribPointer(1, 4, GL_INT_2_10_10_10_REV, GL_TRUE, 4, (const void *)(uintptr_t)position_bytes);
    if (g->coloured) {
        glEnableVertexAttribArray(2);
        glVertexAttribPointer(2, 4, GL_UNSIGNED_BYTE, GL_TRUE, 4, (const void *)(uintptr_t)normal_end);
    }
    glBindBuffer(GL_ELEMENT_ARRAY_BUFFER, g->ibo);
    glBindVertexArray(0);
    glBindBuffer(GL_ARRAY_BUFFER, 0);
    delete_gpu_mesh(r, &c->mesh);
    c->mesh = *g;
    memset(g, 0, sizeof *g);
    drop_pending_mesh(r, p);
    return true;
}

/* Sends up to *left bytes of a pending APO prefix; true once it is current (or
 * given up for lack of texel space: the cell then has no APO). */
static bool upload_apo(ms_render *r, render_cell *c, uint64_t *left, uint64_t *bytes)
{
    pending_apo *p = &c->next_apo;
    if (!p->allocated) {
        if (!ms_render_texels_alloc(&r->texels, p->range.count, &p->range.start)) {
            drop_pending_apo(r, p);
            drop_current_apo(r, c);
            return true;
        }
        p->allocated = true;
    }
    uint64_t total = 4ull * p->range.count;
    if (p->sent < total && *left > 0) {
        uint64_t part = total - p->sent < *left ? total - p->sent : *left;
        glBindBuffer(GL_TEXTURE_BUFFER, r->texels.buffer);
        glBufferSubData(GL_TEXTURE_BUFFER, (GLintptr)(4ull * p->range.start + p->sent), (GLsizeiptr)part,
                        (const uint8_t *)p->words + p->sent);
        glBindBuffer(GL_TEXTURE_BUFFER, 0);
        p->sent += part;
        *left -= part;
        *bytes += part;
    }
    if (p->sent < total)
        return false;
    drop_current_apo(r, c);
    c->apo = p->range;
    p->allocated = false; /* the range now belongs to the current state */
    drop_pending_apo(r, p);
    return true;
}

ms_status ms_render_upload(ms_render *r, uint64_t budget_bytes, ms_render_upload_stats *stats, ms_error *err)
{
    if (stats)
        memset(stats, 0, sizeof *stats);
    if (!r)
        return ms_error_set(err, MS_ERR_ARG, "render: no renderer");
    if (budget_bytes == 0)
        return ms_error_set(err, MS_ERR_ARG, "render: upload budget of 0 bytes");
    uint64_t left = budget_bytes, bytes = 0;
    uint32_t completed = 0;
    /* Two passes in queue order: first the cells that draw nothing yet (a hole
     * in the picture), then the ones that will replace what they draw. */
    for (int pass = 0; pass < 2 && left > 0; ++pass)
        for (uint32_t k = 0; k < r->queue_count && left > 0; ++k) {
            render_cell *c = ms_render_cell_at(r, r->queue[k]);
            if (!c->queued || (pass == 0 && c->mesh.vao))
                continue;
            if (c->next_mesh.active && upload_mesh(r, c, &left, &bytes))
                c->next_mesh.active = false;
            if (!c->next_mesh.active && c->next_apo.active && left > 0 && upload_apo(r, c, &left, &bytes))
                c->next_apo.active = false;
            if (!c->next_mesh.active && !c->next_apo.active) {
                c->queued = false;
                completed++;
            }
        }
    uint32_t kept = 0;
    for (uint32_t k = 0; k < r->queue_count; ++k)
        if (ms_render_cell_at(r, r->queue[k])->queued)
            r->queue[kept++] = r->queue[k];
    r->queue_count = kept;
    if (stats) {
        stats->bytes = bytes;
        stats->cells_completed = completed;
        stats->cells_pending = kept;
    }
    GLenum e = glGetError();
    if (e == GL_OUT_OF_MEMORY)
        return ms_error_set(err, MS_ERR_NOMEM, "render: the GPU is out of memory");
    if (e != GL_NO_ERROR)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "render: GL error 0x%x while uploading", e);
    return MS_OK;
}

void ms_render_memory(const ms_render *r, ms_render_memory_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    if (!r)
        return;
    stats->gl_bytes = r->gl.bytes;
    stats->gl_bytes_peak = r->gl.peak;
    stats->mesh_bytes = r->mesh_bytes;
    stats->texel_bytes = 4ull * r->texels.capacity;
    stats->texel_used_bytes = 4ull * r->texels.used;
}

bool ms_render_cell_texels(const ms_render *r, uint32_t cell, uint32_t *start, uint32_t *count, uint32_t *levels)
{
    const render_cell *c = r ? ms_render_cell_at(r, cell) : NULL;
    if (!c || c->apo.count == 0)
        return false;
    *start = c->apo.start;
    *count = c->apo.count;
    *levels = c->apo.levels;
    return true;
}

GLuint ms_render_texel_buffer(const ms_render *r)
{
    return r ? r->texels.buffer : 0;
}
