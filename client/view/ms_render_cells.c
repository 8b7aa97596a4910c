/* Which cells' meshes a frame derives again (ms_render_derive_cells,
 * ms_render_internal.h; the rule in ms_render.h, ms_render_frame_stats).
 *
 * A cell's mesh is a function of its triangles (named by the frame's version
 * of them) and of the corner normals at their vertices, which depend on every
 * triangle around those vertices, of whichever cell. So a frame derives the
 * cells whose version changed (or that are new), plus every other cell that
 * touches a vertex such a cell, or a cell that left, touched before or touches
 * now: only there can a vertex's fan have changed, since the triangles of an
 * unchanged cell are the same. Vertices are named across frames by a hash of
 * their position (the stitched mesh's indices change from frame to frame); a
 * table keeps which cells touch each such key, updated for the cells derived
 * and those leaving, so finding the neighbours costs what the changed cells
 * hold, not the frame. Normals are then made only at the places that changed
 * (every vertex of a changed cell; a neighbour's vertices at those keys), from
 * the fans of the cells at them (ms_render_split_normals): the same as over the
 * whole stitched mesh. A changed cell's mesh is made again; a neighbour keeps
 * the corner normals its mesh was made with (render_cell.corners), compares
 * those at the changed places, and is made again only when one moved. So the
 * picture is the one a renderer deriving every cell would draw. */
#include <stdlib.h>
#include <string.h>

#include "ms_render_internal.h"

/* ---- the touch table ------------------------------------------------------ */

static size_t slot_of(uint64_t key, size_t cap)
{
    uint64_t h = key * 0x9E3779B97F4A7C15ull;
    return (size_t)(h ^ h >> 31) & (cap - 1);
}

void ms_render_touch_map_free(ms_render_touch_map *map)
{
    free(map->slots);
    memset(map, 0, sizeof *map);
}

/* Room for one more pair: rebuilt (removed slots dropped) at half full. */
static bool map_room(ms_render_touch_map *map)
{
    if (map->cap && 2 * (map->used + 1) <= map->cap)
        return true;
    size_t cap = 1024;
    while (cap < 4 * (map->held + 1))
        cap *= 2;
    ms_render_touch_slot *slots = calloc(cap, sizeof *slots);
    if (!slots)
        return false;
    for (size_t i = 0; i < map->cap; ++i) {
        if (map->slots[i].state != 1)
            continue;
        size_t at = slot_of(map->slots[i].key, cap);
        while (slots[at].state)
            at = (at + 1) & (cap - 1);
        slots[at] = map->slots[i];
    }
    free(map->slots);
    map->slots = slots;
    map->cap = cap;
    map->used = map->held;
    return true;
}

static bool map_add(ms_render_touch_map *map, uint64_t key, uint32_t cell)
{
    if (!map_room(map))
        return false;
    size_t at = slot_of(key, map->cap);
    while (map->slots[at].state == 1)
        at = (at + 1) & (map->cap - 1);
    map->used += map->slots[at].state == 0;
    map->slots[at] = (ms_render_touch_slot){key, cell, 1};
    map->held++;
    return true;
}

static void map_remove(ms_render_touch_map *map, uint64_t key, uint32_t cell)
{
    for (size_t at = map->cap ? slot_of(key, map->cap) : 0; map->cap && map->slots[at].state;
         at = (at + 1) & (map->cap - 1))
        if (map->slots[at].state == 1 && map->slots[at].key == key && map->slots[at].cell == cell) {
            map->slots[at].state = 2;
            map->held--;
            return;
        }
}

/* ---- per-cell bookkeeping --------------------------------------------------- */

static bool keys_room(ms_render *r, size_t more)
{
    size_t need = r->key_count + more;
    if (need <= r->key_cap)
        return true;
    size_t cap = r->key_cap ? r->key_cap : 1024;
    while (cap < need)
        cap *= 2;
    uint64_t *keys = realloc(r->keys, cap * sizeof *keys);
    if (!keys)
        return false;
    r->keys = keys;
    r->key_cap = cap;
    return true;
}

static uint64_t vertex_key(const double *p)
{
    uint64_t h = 0x6A09E667F3BCC909ull;
    for (int a = 0; a < 3; ++a) {
        uint64_t w;
        double x = p[a] == 0.0 ? 0.0 : p[a]; /* -0 and 0 are one place */
        memcpy(&w, &x, sizeof w);
        h = (h ^ w) * 0x9E3779B97F4A7C15ull;
        h ^= h >> 29;
    }
    return h;
}

/* The cell's touch list out of the table, its keys onto r->keys (the places
 * whose fans may change). */
static bool forget_touch(ms_render *r, uint32_t id, render_cell *c)
{
    if (!keys_room(r, c->touch_count))
        return false;
    for (uint32_t i = 0; i < c->touch_count; ++i) {
        map_remove(&r->touch, c->touch[i], id);
        r->keys[r->key_count++] = c->touch[i];
    }
    free(c->touch);
    c->touch = NULL;
    c->touch_count = 0;
    c->has_version = false;
    free(c->corners);
    c->corners = NULL;
    c->corner_count = 0;
    return true;
}

void ms_render_cell_forget(ms_render *r, uint32_t id, render_cell *c)
{
    if (c->has_version || c->touch)
        r->frame_stats.cells_left++;
    if (!forget_touch(r, id, c))
        r->derived_crease = -1.0; /* no room to say where: derive every cell next time */
}

/* The present cell k's touch list made from its triangles now (each vertex
 * once: the splitter's per-vertex stamps), into the table and onto r->keys. */
static bool make_touch(ms_render *r, uint32_t k, render_cell *c)
{
    ms_render_split *s = &r->split;
    const ms_view_mesh *m = s->mesh;
    uint32_t count = s->present_start[k + 1] - s->present_start[k];
    uint64_t *touch = malloc(3 * (size_t)count * sizeof *touch);
    if (!touch)
        return false;
    if (++s->pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->stamp, 0, s->vertex_cap * sizeof *s->stamp);
        s->pass = 1;
    }
    size_t n = 0;
    for (uint32_t i = 0; i < count; ++i) {
        size_t t = ms_render_split_triangle(s, k, i);
        for (int j = 0; j < 3; ++j) {
            uint32_t v = m->triangles[3 * t + (size_t)j];
            /* a bad index is reported by the normals' check */
            if (v < m->vertex_count && s->stamp[v] != s->pass) {
                s->stamp[v] = s->pass;
                touch[n++] = vertex_key(&m->positions[3 * (size_t)v]);
            }
        }
    }
    if (!keys_room(r, n)) {
        free(touch);
        return false;
    }
    c->touch = touch;
    c->touch_count = (uint32_t)n;
    for (size_t i = 0; i < n; ++i) {
        r->keys[r->key_count++] = touch[i];
        if (!map_add(&r->touch, touch[i], s->present[k]))
            return false;
    }
    return true;
}

/* ---- the frame -------------------------------------------------------------- */

static bool set_room(ms_render *r, size_t need)
{
    if (need <= r->set_cap)
        return true;
    size_t cap = r->set_cap ? r->set_cap : 64;
    while (cap < need)
        cap *= 2;
    uint32_t *shade = realloc(r->shade, cap * sizeof *shade);
    if (!shade)
        return false;
    r->shade = shade;
    r->set_cap = cap;
    return true;
}

/* Every cell present and marked in this pass, for the cells touching key, onto
 * list (present indices). */
static void add_touching(ms_render *r, uint64_t key, uint32_t *list, size_t *count)
{
    const ms_render_touch_map *map = &r->touch;
    for (size_t at = map->cap ? slot_of(key, map->cap) : 0; map->cap && map->slots[at].state;
         at = (at + 1) & (map->cap - 1)) {
        if (map->slots[at].state != 1 || map->slots[at].key != key)
            continue;
        render_cell *c = ms_render_cell_at(r, map->slots[at].cell);
        if (!c || !c->in_frame || c->mark == r->mark_pass)
            continue;
        c->mark = r->mark_pass;
        list[(*count)++] = c->frame_index;
    }
}

static int compare_u32(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return (x > y) - (x < y);
}

static void new_mark_pass(ms_render *r)
{
    if (++r->mark_pass != 0)
        return;
    for (uint32_t g = 0; g < r->group_count; ++g)
        for (uint32_t k = 0; r->groups[g] && k < r->group_size; ++k)
            r->groups[g][k].mark = 0;
    r->mark_pass = 1;
}

/* The keys of this frame's changed places (r->keys) as a set. */
static bool make_key_set(ms_render *r)
{
    size_t cap = 64;
    while (cap < 2 * r->key_count + 2)
        cap *= 2;
    if (cap > r->key_set_cap) {
        uint64_t *set = realloc(r->key_set, cap * sizeof *set);
        if (!set)
            return false;
        r->key_set = set;
        r->key_set_cap = cap;
    }
    memset(r->key_set, 0, cap * sizeof *r->key_set);
    r->key_set_cap = cap;
    for (size_t i = 0; i < r->key_count; ++i) {
        uint64_t key = r->keys[i] ? r->keys[i] : 1; /* 0 marks an empty slot */
        size_t at = slot_of(key, cap);
        while (r->key_set[at] && r->key_set[at] != key)
            at = (at + 1) & (cap - 1);
        r->key_set[at] = key;
    }
    return true;
}

static bool in_key_set(const ms_render *r, uint64_t key)
{
    key = key ? key : 1;
    for (size_t at = slot_of(key, r->key_set_cap); r->key_set[at]; at = (at + 1) & (r->key_set_cap - 1))
        if (r->key_set[at] == key)
            return true;
    return false;
}

/* The mesh vertices whose fans may have changed, each once, onto
 * r->fan_vertices: every vertex of a changed cell, and of the neighbours the
 * vertices at a changed place (their other vertices' fans hold the same
 * triangles as when their mesh was made). */
static bool pick_fan_vertices(ms_render *r)
{
    ms_render_split *s = &r->split;
    const ms_view_mesh *m = s->mesh;
    r->fan_vertex_count = 0;
    if (++s->pass == 0) { /* wrapped: every stamp is stale again */
        memset(s->stamp, 0, s->vertex_cap * sizeof *s->stamp);
        s->pass = 1;
    }
    for (size_t j = 0; j < r->shade_count; ++j) {
        uint32_t k = r->shade[j], count = s->present_start[k + 1] - s->present_start[k];
        bool whole = !ms_render_cell_at(r, s->present[k])->has_version;
        if (!whole)
            r->frame_stats.triangles_walked += count;
        for (uint32_t i = 0; i < count; ++i) {
            size_t t = ms_render_split_triangle(s, k, i);
            for (int c = 0; c < 3; ++c) {
                uint32_t v = m->triangles[3 * t + (size_t)c];
                /* a bad index is reported by the normals' check */
                if (v >= m->vertex_count || s->stamp[v] == s->pass)
                    continue;
                s->stamp[v] = s->pass;
                if (!whole && !in_key_set(r, vertex_key(&m->positions[3 * (size_t)v])))
                    continue;
                if (!ms_render_grow((void **)&r->fan_vertices, &r->fan_vertex_cap, r->fan_vertex_count + 1,
                                    sizeof *r->fan_vertices))
                    return false;
                r->fan_vertices[r->fan_vertex_count++] = v;
            }
        }
    }
    return true;
}

/* An unchanged neighbour k's corners: those at the fans made compared with
 * the ones its mesh was made with (true when one moved), the others filled in
 * from them, so that its mesh can be made again. */
static bool neighbour_moved(ms_render *r, uint32_t k, const render_cell *c)
{
    ms_render_split *s = &r->split;
    const ms_view_mesh *m = s->mesh;
    uint32_t count = s->present_start[k + 1] - s->present_start[k];
    bool moved = false;
    for (uint32_t i = 0; i < count; ++i) {
        size_t t = ms_render_split_triangle(s, k, i);
        for (size_t j = 0; j < 3; ++j) {
            uint32_t v = m->triangles[3 * t + j];
            uint32_t *packed = &s->corner_packed[3 * t + j];
            if (s->fan_vstamp[v] == s->fan_pass)
                moved |= *packed != c->corners[3 * (size_t)i + j];
            else
                *packed = c->corners[3 * (size_t)i + j];
        }
    }
    return moved;
}

/* The present cell k's mesh made again from the normals in hand, taken, and
 * its corners kept for the frames after. */
static ms_status rebuild(ms_render *r, uint32_t k, render_cell *c, ms_error *err)
{
    ms_render_split *s = &r->split;
    ms_render_cell_mesh m;
    ms_status st = ms_render_split_cell(s, k, &c->record, &m, err);
    if (st != MS_OK)
        return st;
    bool waiting = c->next_mesh.active && c->next_mesh.gpu.hash == m.hash;
    bool drawn = c->mesh.vao && c->mesh.hash == m.hash;
    st = ms_render_take_mesh(r, c, &m, err);
    if (st != MS_OK)
        return st;
    r->frame_stats.cells_rebuilt++;
    r->frame_stats.triangles_rebuilt += m.triangle_count;
    r->frame_stats.cells_queued += c->next_mesh.active && !waiting && !drawn;
    uint32_t corners = 3 * m.triangle_count;
    if (corners != c->corner_count) {
        free(c->corners);
        c->corners = malloc((corners ? corners : 1) * sizeof *c->corners);
        c->corner_count = c->corners ? corners : 0;
        if (!c->corners)
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u's normals", s->present[k]);
    }
    for (uint32_t i = 0; i < m.triangle_count; ++i) {
        size_t t = ms_render_split_triangle(s, k, i);
        memcpy(&c->corners[3 * (size_t)i], &s->corner_packed[3 * t], 3 * sizeof *c->corners);
    }
    c->has_version = true;
    c->version = s->present_version[k];
    return MS_OK;
}

static ms_status derive(ms_render *r, ms_error *err)
{
    ms_render_split *s = &r->split;
    uint32_t present = s->present_count;
    bool all = r->derived_crease != r->crease_angle_deg;
    if (!set_room(r, present))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for %u cells", present);
    /* the changed cells: their old and new vertices' keys (a cell whose kept
     * corners do not match its triangles counts as changed) */
    new_mark_pass(r);
    r->shade_count = 0;
    for (uint32_t k = 0; k < present; ++k) {
        render_cell *c = ms_render_cell_at(r, s->present[k]);
        c->frame_index = k;
        uint32_t tris = s->present_start[k + 1] - s->present_start[k];
        if (!all && c->has_version && c->version == s->present_version[k] && c->corner_count == 3 * tris)
            continue;
        if (!forget_touch(r, s->present[k], c) || !make_touch(r, k, c))
            return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for cell %u's vertices", s->present[k]);
        c->mark = r->mark_pass;
        r->shade[r->shade_count++] = k;
    }
    r->frame_stats.cells_changed = (uint32_t)r->shade_count;
    if (r->key_count == 0)
        return MS_OK;
    /* their neighbours, old and new: every cell at a changed place holds all
     * the triangles of the fans that may have changed */
    for (size_t i = 0; i < r->key_count; ++i)
        add_touching(r, r->keys[i], r->shade, &r->shade_count);
    qsort(r->shade, r->shade_count, sizeof *r->shade, compare_u32);
    r->frame_stats.cells_derived = (uint32_t)r->shade_count;
    if (!make_key_set(r) || !pick_fan_vertices(r))
        return ms_error_set(err, MS_ERR_NOMEM, "render: no memory for the changed vertices");
    ms_status st = ms_render_split_normals(s, r->fan_vertices, (uint32_t)r->fan_vertex_count, r->shade,
                                           (uint32_t)r->shade_count, err);
    r->frame_stats.vertex_fans = s->fans_made;
    r->frame_stats.face_normals = s->faces_made;
    for (size_t j = 0; j < r->shade_count && st == MS_OK; ++j) {
        uint32_t k = r->shade[j];
        render_cell *c = ms_render_cell_at(r, s->present[k]);
        if (c->has_version) {
            if (!neighbour_moved(r, k, c))
                continue;
            r->frame_stats.neighbours_moved++;
        }
        st = rebuild(r, k, c, err);
    }
    return st;
}

static void add_totals(ms_render_frame_totals *t, const ms_render_frame_stats *f)
{
    t->frames++;
    t->cells_present += f->cells_present;
    t->cells_changed += f->cells_changed;
    t->cells_left += f->cells_left;
    t->cells_derived += f->cells_derived;
    t->vertex_fans += f->vertex_fans;
    t->face_normals += f->face_normals;
    t->cells_rebuilt += f->cells_rebuilt;
    t->neighbours_moved += f->neighbours_moved;
    t->cells_queued += f->cells_queued;
    t->triangles_rebuilt += f->triangles_rebuilt;
    t->triangles_walked += f->triangles_walked;
}

ms_status ms_render_derive_cells(ms_render *r, ms_error *err)
{
    r->frame_stats.cells_present = r->split.present_count;
    ms_status st = derive(r, err);
    r->key_count = 0;
    if (st == MS_OK) {
        r->derived_crease = r->crease_angle_deg;
        add_totals(&r->frame_totals, &r->frame_stats);
        return MS_OK;
    }
    /* start again from nothing: every cell forgotten, the next frame derives all */
    for (uint32_t g = 0; g < r->group_count; ++g)
        for (uint32_t k = 0; r->groups[g] && k < r->group_size; ++k) {
            render_cell *c = &r->groups[g][k];
            free(c->touch);
            c->touch = NULL;
            c->touch_count = 0;
            c->has_version = false;
            free(c->corners);
            c->corners = NULL;
            c->corner_count = 0;
        }
    ms_render_touch_map_free(&r->touch);
    r->derived_crease = -1.0;
    return st;
}

void ms_render_frame_stats_get(const ms_render *r, ms_render_frame_stats *stats)
{
    memset(stats, 0, sizeof *stats);
    if (r)
        *stats = r->frame_stats;
}

void ms_render_frame_totals_get(const ms_render *r, ms_render_frame_totals *totals)
{
    memset(totals, 0, sizeof *totals);
    if (r)
        *totals = r->frame_totals;
}
