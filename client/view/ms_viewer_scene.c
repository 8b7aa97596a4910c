/* A scene on screen (ms_viewer_scene.h): streams per model, the room as
 * one-cell models, one picture. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_render_impostor.h"
#include "ms_viewer_scene.h"

/* Impostors: image size, the step of the cross-fade per drawn frame, and the
 * hysteresis of the switch back to geometry. */
#define IMPOSTOR_PIXELS 128
#define IMPOSTOR_FADE_STEP 0.25f
#define IMPOSTOR_LEAVE_FACTOR 1.15

#define IMPLEMENTED_EFFECTS MS_EFFECTS_ALL

/* The room's floor and walls are cut into tiles of at most this side (metres),
 * so that tessellation (at most 64 per edge) can resolve a relief's atoms. */
#define ROOM_TILE 0.5

typedef struct scene_model {
    ms_viewer_model model;
    ms_viewer_stream *stream;
    double lo[3], hi[3];       /* the model's bounds the placement was made from */
    double placement[16];      /* model to scene */
    double inverse_linear[9];  /* column-major 3x3 inverse of the linear part */
    double scale;
    double centre[3], radius;  /* placed bounding sphere, metres */
    bool settled;
    uint64_t generation;       /* of the frame the renderer holds */
    uint64_t uploads;          /* steps that completed cells on the GPU */
    ms_impostor *impostor;     /* made on first use */
    uint64_t captured_generation, captured_uploads; /* what the impostor shows */
    bool far;                  /* below the impostor threshold (with hysteresis) */
    float coverage;            /* of the impostor: 0 geometry only .. 1 impostor only */
    ms_render_draw_stats drawn; /* its geometry's, at the last draw */
} scene_model;

/* A part of the room: boxes' faces as one one-cell model. */
typedef struct room_part {
    ms_render *render;
    const ms_scene_material *material;
    const ms_scene_displacement *displacement; /* NULL: none declared */
} room_part;

struct ms_viewer_scene {
    const ms_scene *scene;
    scene_model *models;
    size_t model_count;
    room_part parts[3];        /* floor, walls, plinths */
    size_t part_count;
    uint32_t *order;           /* model indices, nearest first (scratch) */
    double *distance;          /* per model (scratch) */
    unsigned effects;
    bool force_all;
    double lo[3], hi[3];
    ms_render_light lights[MS_RENDER_MAX_LIGHTS];
    unsigned light_count;
    ms_core_budget *budget;    /* the models' one memory budget; NULL: none */
    ms_core_link *link;        /* from a server: the models' one connection; NULL: a
                                  local directory, or one connection per model */
    bool from_server;
    ms_viewer_model_list listed; /* the source's models, while the pieces open */
};

/* ---- the room ------------------------------------------------------------ */

typedef struct mesh_builder {
    double *positions;
    uint32_t *triangles;
    size_t vertex_count, triangle_count, vertex_cap, triangle_cap;
    bool failed;
} mesh_builder;

/* A quad a, b, c, d (counter-clockwise seen from the side it faces). */
static void add_quad(mesh_builder *m, const double a[3], const double b[3], const double c[3], const double d[3])
{
    if (m->failed)
        return;
    if (m->vertex_count + 4 > m->vertex_cap) {
        size_t cap = m->vertex_cap ? 2 * m->vertex_cap : 64;
        double *p = realloc(m->positions, 3 * cap * sizeof *p);
        uint32_t *t = realloc(m->triangles, 3 * cap * sizeof *t); /* 2 triangles per 4 vertices */
        if (p)
            m->positions = p;
        if (t)
            m->triangles = t;
        if (!p || !t) {
            m->failed = true;
            return;
        }
        m->vertex_cap = m->triangle_cap = cap;
    }
    uint32_t base = (uint32_t)m->vertex_count;
    const double *corners[4] = {a, b, c, d};
    for (int k = 0; k < 4; ++k)
        memcpy(&m->positions[3 * (m->vertex_count + (size_t)k)], corners[k], 3 * sizeof(double));
    m->vertex_count += 4;
    uint32_t tri[6] = {base, base + 1, base + 2, base, base + 2, base + 3};
    memcpy(&m->triangles[3 * m->triangle_count], tri, sizeof tri);
    m->triangle_count += 2;
}

/* The parallelogram corner + [0, 1] u + [0, 1] v (counter-clockwise seen from
 * the side u x v points to) as tiles of at most `tile` a side. */
static void add_tiled(mesh_builder *m, const double corner[3], const double u[3], const double v[3], double tile)
{
    double lu = sqrt(u[0] * u[0] + u[1] * u[1] + u[2] * u[2]), lv = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    int nu = (int)fmax(1.0, ceil(lu / tile)), nv = (int)fmax(1.0, ceil(lv / tile));
    for (int j = 0; j < nv; ++j)
        for (int i = 0; i < nu; ++i) {
            double q[4][3];
            const int di[4] = {0, 1, 1, 0}, dj[4] = {0, 0, 1, 1};
            for (int k = 0; k < 4; ++k)
                for (int a = 0; a < 3; ++a)
                    q[k][a] = corner[a] + u[a] * (i + di[k]) / nu + v[a] * (j + dj[k]) / nv;
            add_quad(m, q[0], q[1], q[2], q[3]);
        }
}

/* The faces of the box [lo, hi] facing out, but its bottom (a plinth on the floor). */
static void add_box(mesh_builder *m, const double lo[3], const double hi[3])
{
    double c[8][3];
    for (int k = 0; k < 8; ++k) {
        c[k][0] = (k & 1) ? hi[0] : lo[0];
        c[k][1] = (k & 2) ? hi[1] : lo[1];
        c[k][2] = (k & 4) ? hi[2] : lo[2];
    }
    /* counter-clockwise seen from outside: -x, +x, -z, +z, +y */
    static const int faces[5][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 2, 3, 1}, {4, 5, 7, 6}, {2, 6, 7, 3}};
    for (int f = 0; f < 5; ++f)
        add_quad(m, c[faces[f][0]], c[faces[f][1]], c[faces[f][2]], c[faces[f][3]]);
}

/* A one-cell model holding the mesh, uploaded whole. */
static ms_status make_part(mesh_builder *m, const ms_scene_material *material, room_part *part, ms_error *err)
{
    if (m->failed)
        return ms_error_set(err, MS_ERR_NOMEM, "scene: no memory for the room");
    double lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (size_t v = 0; v < m->vertex_count; ++v)
        for (int a = 0; a < 3; ++a) {
            lo[a] = fmin(lo[a], m->positions[3 * v + (size_t)a]);
            hi[a] = fmax(hi[a], m->positions[3 * v + (size_t)a]);
        }
    ms_archive_header h;
    memset(&h, 0, sizeof h);
    h.box_side = fmax(fmax(hi[0] - lo[0], hi[1] - lo[1]), hi[2] - lo[2]);
    memcpy(h.box_origin, lo, sizeof lo);
    h.bits = 16;
    h.n = 2;
    h.root_bits = 7;
    h.cell_count = 1;
    ms_archive_cell cell;
    memset(&cell, 0, sizeof cell);
    cell.parent = cell.first_child = MS_ARCHIVE_NONE;
    ms_status st = ms_render_new(&h, &cell, &part->render, err);
    if (st != MS_OK)
        return st;
    uint32_t *tri_cell = calloc(m->triangle_count ? m->triangle_count : 1, sizeof *tri_cell);
    if (!tri_cell)
        return ms_error_set(err, MS_ERR_NOMEM, "scene: no memory for the room");
    ms_view_mesh mesh;
    memset(&mesh, 0, sizeof mesh);
    mesh.vertex_count = m->vertex_count;
    mesh.triangle_count = m->triangle_count;
    mesh.positions = m->positions;
    mesh.triangles = m->triangles;
    mesh.triangle_cell = tri_cell;
    st = ms_render_set_frame(part->render, &mesh, NULL, 0, err);
    ms_render_upload_stats up;
    if (st == MS_OK)
        st = ms_render_upload(part->render, UINT64_MAX, &up, err);
    free(tri_cell);
    part->material = material;
    return st;
}

static ms_status build_room(ms_viewer_scene *vs, ms_error *err)
{
    const ms_scene_room *room = &vs->scene->room;
    if (!room->on)
        return MS_OK;
    const double w = room->size[0] / 2, h = room->size[1], d = room->size[2] / 2;
    ms_status st = MS_OK;
    mesh_builder floor = {0}, walls = {0}, plinths = {0};
    /* the floor faces up, the walls in; both tiled (for displacement) */
    add_tiled(&floor, (double[3]){-w, 0, d}, (double[3]){2 * w, 0, 0}, (double[3]){0, 0, -2 * d}, ROOM_TILE);
    add_tiled(&walls, (double[3]){-w, 0, -d}, (double[3]){2 * w, 0, 0}, (double[3]){0, h, 0}, ROOM_TILE);
    add_tiled(&walls, (double[3]){w, 0, d}, (double[3]){-2 * w, 0, 0}, (double[3]){0, h, 0}, ROOM_TILE);
    add_tiled(&walls, (double[3]){-w, 0, d}, (double[3]){0, 0, -2 * d}, (double[3]){0, h, 0}, ROOM_TILE);
    add_tiled(&walls, (double[3]){w, 0, -d}, (double[3]){0, 0, 2 * d}, (double[3]){0, h, 0}, ROOM_TILE);
    for (size_t i = 0; i < room->plinth_count; ++i) {
        const ms_scene_plinth *p = &room->plinths[i];
        double lo[3] = {p->position[0] - p->size[0] / 2, 0, p->position[1] - p->size[2] / 2};
        double hi[3] = {p->position[0] + p->size[0] / 2, p->size[1], p->position[1] + p->size[2] / 2};
        add_box(&plinths, lo, hi);
    }
    st = make_part(&floor, &room->floor.material, &vs->parts[vs->part_count++], err);
    if (st == MS_OK && room->floor.displacement.on)
        vs->parts[vs->part_count - 1].displacement = &room->floor.displacement;
    if (st == MS_OK)
        st = make_part(&walls, &room->walls.material, &vs->parts[vs->part_count++], err);
    if (st == MS_OK && room->walls.displacement.on)
        vs->parts[vs->part_count - 1].displacement = &room->walls.displacement;
    /* plinths share the first one's material (the format gives each its own;
     * one draw keeps the room cheap) */
    if (st == MS_OK && room->plinth_count)
        st = make_part(&plinths, &room->plinths[0].material, &vs->parts[vs->part_count++], err);
    free(floor.positions), free(floor.triangles);
    free(walls.positions), free(walls.triangles);
    free(plinths.positions), free(plinths.triangles);
    return st;
}

/* ---- opening -------------------------------------------------------------- */

static void place_model(const ms_scene_model *sm, scene_model *m)
{
    double *lo = m->lo, *hi = m->hi;
    ms_viewer_model_bounds(&m->model, lo, hi);
    ms_scene_model_transform(sm, lo, hi, m->placement);
    const double *t = m->placement;
    m->scale = sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
    /* linear part = scale * rotation: its inverse is the transpose over scale^2 */
    for (int c = 0; c < 3; ++c)
        for (int r = 0; r < 3; ++r)
            m->inverse_linear[3 * c + r] = t[4 * r + c] / (m->scale * m->scale);
    ms_scene_placed_sphere(m->placement, lo, hi, m->centre, &m->radius);
}

/* The pieces' streams, all started before any is waited for: their models
 * are asked for together (over a shared link, in one round trip for the lot)
 * instead of one after another. */
static ms_status open_pieces(ms_viewer_scene *vs, const ms_viewer_source *source,
                             const ms_viewer_stream_settings *each, ms_error *err)
{
    const ms_scene *scene = vs->scene;
    ms_status st = MS_OK;
    for (size_t i = 0; i < scene->model_count && st == MS_OK; ++i) {
        scene_model *m = &vs->models[i];
        st = ms_viewer_model_open_listed(source, &vs->listed, scene->models[i].model, &m->model, err);
        if (st == MS_OK) {
            vs->model_count = i + 1;
            st = ms_viewer_stream_start(source, &m->model, each, &m->stream, err);
        }
    }
    ms_viewer_model_list_free(&vs->listed);
    for (size_t i = 0; i < vs->model_count && st == MS_OK; ++i) {
        st = ms_viewer_stream_wait_open(vs->models[i].stream, err);
        if (st == MS_OK) /* the bounds came with the opening: the root's, before any draw */
            place_model(&scene->models[i], &vs->models[i]);
    }
    return st;
}

ms_status ms_viewer_scene_open(const ms_viewer_source *source, const ms_scene *scene, const char *label,
                               const ms_viewer_scene_settings *settings, ms_viewer_scene **out, ms_error *err)
{
    *out = NULL;
    if (!scene || !settings || scene->model_count == 0)
        return ms_error_set(err, MS_ERR_ARG, "scene: nothing to open");
    ms_viewer_model_list list = {0};
    ms_status st = ms_viewer_list_models(source, &list, err);
    if (st == MS_OK)
        st = ms_scene_check_models(scene, label, &list, err);
    ms_viewer_scene *vs = st == MS_OK ? calloc(1, sizeof *vs) : NULL;
    if (!vs) {
        ms_viewer_model_list_free(&list);
        return st != MS_OK ? st : ms_error_set(err, MS_ERR_NOMEM, "scene: no memory");
    }
    vs->listed = list; /* the pieces open from this listing: no round trip each */
    vs->scene = scene;
    vs->models = calloc(scene->model_count, sizeof *vs->models);
    vs->order = calloc(scene->model_count, sizeof *vs->order);
    vs->distance = calloc(scene->model_count, sizeof *vs->distance);
    if (!vs->models || !vs->order || !vs->distance) {
        ms_viewer_scene_close(vs);
        return ms_error_set(err, MS_ERR_NOMEM, "scene: no memory");
    }
    unsigned effects = settings->force_all ? MS_EFFECTS_ALL : ms_scene_effects(scene);
    vs->effects = effects & ~settings->effects_off & MS_EFFECTS_ALL;
    vs->force_all = settings->force_all;
    ms_viewer_stream_settings each = settings->stream;
    /* one memory budget for all the models (ceiling 1.5x, as a stream's own):
     * near pieces refine first, far ones stay coarse */
    if (settings->stream.memory_mb > 0) {
        uint64_t target = (uint64_t)(settings->stream.memory_mb * 1048576.0);
        st = ms_core_budget_new(target, target + target / 2, &vs->budget, err);
        if (st != MS_OK) {
            ms_viewer_scene_close(vs);
            return st;
        }
        each.memory_mb = 0;
        each.shared_budget = vs->budget;
    }
    vs->from_server = !source->archive_dir;
    if (vs->from_server && !settings->connection_per_model) {
        /* one connection for all the models, with the scene's whole bandwidth:
         * their requests merged by priority, near pieces' bytes first */
        ms_core_link_options lo = {.host = source->host, .port = source->port,
                                   .token = source->token, .agent = MS_VIEWER_AGENT,
                                   .bandwidth = settings->stream.bandwidth,
                                   .give_up_seconds = MS_VIEWER_GIVE_UP_S,
                                   .whole_index = settings->stream.whole_index};
        st = ms_core_link_new(&lo, &vs->link, err);
        if (st != MS_OK) {
            ms_viewer_scene_close(vs);
            return st;
        }
        each.shared_link = vs->link;
    } else {
        each.bandwidth = settings->stream.bandwidth / (double)scene->model_count;
    }
    st = open_pieces(vs, source, &each, err);
    if (st == MS_OK)
        st = build_room(vs, err);
    if (st != MS_OK) {
        ms_viewer_scene_close(vs);
        return st;
    }
    /* bounds: the room, else the models' spheres */
    if (scene->room.on) {
        vs->lo[0] = -scene->room.size[0] / 2, vs->lo[1] = 0, vs->lo[2] = -scene->room.size[2] / 2;
        vs->hi[0] = scene->room.size[0] / 2, vs->hi[1] = scene->room.size[1], vs->hi[2] = scene->room.size[2] / 2;
    } else {
        for (int a = 0; a < 3; ++a)
            vs->lo[a] = INFINITY, vs->hi[a] = -INFINITY;
        for (size_t i = 0; i < vs->model_count; ++i)
            for (int a = 0; a < 3; ++a) {
                vs->lo[a] = fmin(vs->lo[a], vs->models[i].centre[a] - vs->models[i].radius);
                vs->hi[a] = fmax(vs->hi[a], vs->models[i].centre[a] + vs->models[i].radius);
            }
    }
    /* lights: colour times intensity */
    for (size_t i = 0; i < scene->light_count && vs->light_count < MS_RENDER_MAX_LIGHTS; ++i) {
        const ms_scene_light *l = &scene->lights[i];
        ms_render_light *r = &vs->lights[vs->light_count++];
        r->kind = l->kind == MS_LIGHT_HEAD          ? MS_RENDER_LIGHT_HEAD
                  : l->kind == MS_LIGHT_DIRECTIONAL ? MS_RENDER_LIGHT_DIRECTIONAL
                                                    : MS_RENDER_LIGHT_POINT;
        for (int a = 0; a < 3; ++a) {
            r->colour[a] = l->colour[a] * l->intensity;
            r->vector[a] = l->vector[a];
        }
        r->range = l->range;
    }
    *out = vs;
    return MS_OK;
}

void ms_viewer_scene_close(ms_viewer_scene *vs)
{
    if (!vs)
        return;
    for (size_t i = 0; i < vs->model_count; ++i) {
        ms_impostor_free(vs->models[i].impostor);
        ms_viewer_stream_close(vs->models[i].stream);
        ms_viewer_model_close(&vs->models[i].model);
    }
    for (size_t i = 0; i < vs->part_count; ++i)
        ms_render_free(vs->parts[i].render);
    ms_core_budget_free(vs->budget); /* after the streams' cores stopped */
    ms_core_link_free(vs->link);
    ms_viewer_model_list_free(&vs->listed);
    free(vs->models);
    free(vs->order);
    free(vs->distance);
    free(vs);
}

/* ---- per frame ------------------------------------------------------------ */

/* The scene camera in the model's coordinates: same picture, distances over scale. */
static void model_camera(const scene_model *m, const ms_camera *camera, ms_camera *out)
{
    *out = *camera;
    const double *L = m->inverse_linear;
    double rel[3];
    for (int a = 0; a < 3; ++a)
        rel[a] = camera->position[a] - m->placement[12 + a];
    for (int r = 0; r < 3; ++r) {
        out->position[r] = L[r] * rel[0] + L[3 + r] * rel[1] + L[6 + r] * rel[2];
        /* directions: the rotation's inverse (L times scale) keeps them unit */
        out->forward[r] = m->scale * (L[r] * camera->forward[0] + L[3 + r] * camera->forward[1] +
                                      L[6 + r] * camera->forward[2]);
        out->up[r] = m->scale * (L[r] * camera->up[0] + L[3 + r] * camera->up[1] + L[6 + r] * camera->up[2]);
        out->right[r] =
            m->scale * (L[r] * camera->right[0] + L[3 + r] * camera->right[1] + L[6 + r] * camera->right[2]);
    }
    out->near_distance = camera->near_distance / m->scale;
    out->far_distance = camera->far_distance / m->scale;
}

static int by_distance(const void *a, const void *b, void *arg)
{
    const double *d = arg;
    double x = d[*(const uint32_t *)a], y = d[*(const uint32_t *)b];
    return x < y ? -1 : x > y;
}

/* Models nearest first: insertion sort (a few dozen models). */
static void sort_models(ms_viewer_scene *vs, const ms_camera *camera)
{
    for (size_t i = 0; i < vs->model_count; ++i) {
        const scene_model *m = &vs->models[i];
        double d2 = 0;
        for (int a = 0; a < 3; ++a)
            d2 += (m->centre[a] - camera->position[a]) * (m->centre[a] - camera->position[a]);
        vs->distance[i] = fmax(0.0, sqrt(d2) - m->radius);
        vs->order[i] = (uint32_t)i;
    }
    for (size_t i = 1; i < vs->model_count; ++i) {
        uint32_t v = vs->order[i];
        size_t j = i;
        while (j > 0 && by_distance(&vs->order[j - 1], &v, vs->distance) > 0) {
            vs->order[j] = vs->order[j - 1];
            j--;
        }
        vs->order[j] = v;
    }
}

ms_status ms_viewer_scene_step(ms_viewer_scene *vs, const ms_camera *camera, uint64_t budget_bytes,
                               ms_viewer_step *step, ms_error *err)
{
    memset(step, 0, sizeof *step);
    sort_models(vs, camera);
    uint64_t left = budget_bytes;
    step->settled = true;
    for (size_t k = 0; k < vs->model_count; ++k) {
        scene_model *m = &vs->models[vs->order[k]];
        ms_camera mc;
        model_camera(m, camera, &mc);
        ms_viewer_step s;
        /* a model past the budget still takes its camera and frame; 1 byte is
         * the least an upload may be given */
        ms_status st = ms_viewer_stream_step(m->stream, &mc, left > 0 ? left : 1, &s, err);
        if (st != MS_OK)
            return st;
        left = s.upload.bytes < left ? left - s.upload.bytes : 0;
        step->new_frame |= s.new_frame;
        if (s.generation > step->generation)
            step->generation = s.generation;
        step->upload.bytes += s.upload.bytes;
        step->upload.cells_completed += s.upload.cells_completed;
        step->upload.cells_pending += s.upload.cells_pending;
        step->frame_triangles += s.frame_triangles;
        step->settled &= s.settled;
        m->settled = s.settled;
        m->generation = s.generation;
        m->uploads += s.upload.cells_completed > 0;
    }
    return MS_OK;
}

static void merge_stats(ms_render_draw_stats *sum, const ms_render_draw_stats *one)
{
    sum->cells_drawn += one->cells_drawn;
    sum->triangles_drawn += one->triangles_drawn;
    sum->effects_ran |= one->effects_ran;
}

/* The effects a piece calls for: only the effects of its own material and
 * surface (all of the scene's with force_all), within the scene's. */
static unsigned piece_effects(const ms_viewer_scene *vs, const ms_scene_material *mat, bool model, bool relief)
{
    if (vs->force_all)
        return vs->effects;
    unsigned e = MS_EFFECT_HAZE;
    if (model)
        e |= MS_EFFECT_DETAIL_NORMALS | MS_EFFECT_IMPOSTORS;
    if (mat->kind == MS_MATERIAL_GLOSSY && mat->specular > 0.0f)
        e |= MS_EFFECT_SPECULAR;
    if (mat->two_sided)
        e |= MS_EFFECT_TWO_SIDED;
    if (relief)
        e |= MS_EFFECT_DISPLACEMENT;
    return e & vs->effects;
}

/* The model's projected diameter in pixels for camera. */
static double projected_pixels(const scene_model *m, const ms_camera *camera)
{
    double d2 = 0;
    for (int a = 0; a < 3; ++a)
        d2 += (m->centre[a] - camera->position[a]) * (m->centre[a] - camera->position[a]);
    double d = fmax(sqrt(d2), 1e-9);
    return 2.0 * m->radius * camera->height / (2.0 * tan(0.5 * camera->fovy)) / d;
}

/* Geometry, impostor or both (crossing over) for one model. */
static ms_status draw_model(ms_viewer_scene *vs, scene_model *m, const ms_camera *camera,
                            const ms_render_options *mo, ms_render_draw_stats *sum, ms_error *err)
{
    ms_render_draw_stats one;
    memset(&m->drawn, 0, sizeof m->drawn);
    bool impostors = (mo->effects & MS_EFFECT_IMPOSTORS) != 0;
    if (impostors) {
        double px = projected_pixels(m, camera), threshold = vs->scene->impostor_threshold_px;
        if (px < threshold)
            m->far = true;
        else if (px > threshold * IMPOSTOR_LEAVE_FACTOR)
            m->far = false;
    } else
        m->far = false;
    float target = m->far ? 1.0f : 0.0f;
    m->coverage = m->coverage < target ? fminf(target, m->coverage + IMPOSTOR_FADE_STEP)
                                       : fmaxf(target, m->coverage - IMPOSTOR_FADE_STEP);
    ms_status st = MS_OK;
    if (m->coverage > 0.0f) {
        if (!m->impostor)
            st = ms_impostor_new(IMPOSTOR_PIXELS, &m->impostor, err);
        /* captured again when the view turned past the angle, or the cut
         * changed or reached the GPU (a frame's cells upload over several
         * steps) */
        if (st == MS_OK && (ms_impostor_angle(m->impostor, camera) > vs->scene->impostor_angle_degrees ||
                            m->captured_generation != m->generation || m->captured_uploads != m->uploads)) {
            st = ms_impostor_capture(m->impostor, ms_viewer_stream_render(m->stream), mo, m->centre, m->radius,
                                     camera, err);
            m->captured_generation = m->generation;
            m->captured_uploads = m->uploads;
        }
    }
    /* the geometry's draw (wholly dissolved when the impostor covers all) also
     * clears the picture when it is the first draw of the frame */
    if (st == MS_OK && (m->coverage < 1.0f || mo->clear)) {
        ms_render_options g = *mo;
        g.dissolve = m->coverage;
        st = ms_viewer_stream_draw(m->stream, camera, &g, &one, err);
        merge_stats(sum, &one);
        m->drawn = one;
    }
    if (st == MS_OK && m->coverage > 0.0f) {
        st = ms_impostor_draw(m->impostor, camera, m->coverage, mo->haze_density, mo->haze_colour, err);
        sum->effects_ran |= MS_EFFECT_IMPOSTORS;
    }
    return st;
}

ms_status ms_viewer_scene_draw(ms_viewer_scene *vs, const ms_camera *camera, const ms_render_options *base,
                               ms_render_draw_stats *stats, ms_error *err)
{
    ms_render_draw_stats sum, one;
    memset(&sum, 0, sizeof sum);
    const ms_scene *scene = vs->scene;
    ms_render_options o = *base;
    o.light_count = vs->light_count;
    memcpy(o.lights, vs->lights, sizeof o.lights);
    o.haze_density = (vs->effects & MS_EFFECT_HAZE) ? scene->haze.density : 0.0f;
    memcpy(o.haze_colour, scene->haze.colour, sizeof o.haze_colour);
    if (o.haze_density > 0)
        memcpy(o.background, scene->haze.colour, sizeof o.background);
    o.clear = true;
    ms_status st = MS_OK;
    /* the room: flat boxes, never APO */
    for (size_t i = 0; i < vs->part_count && st == MS_OK; ++i) {
        const ms_scene_material *mat = vs->parts[i].material;
        const ms_scene_displacement *disp = vs->parts[i].displacement;
        ms_render_options po = o;
        po.effects = piece_effects(vs, mat, false, disp != NULL);
        memcpy(po.albedo, mat->albedo, sizeof po.albedo);
        po.specular = mat->specular;
        po.shininess = mat->shininess;
        po.two_sided = mat->two_sided;
        po.smooth = false;
        po.apo = false;
        po.placed = false;
        if (disp && (po.effects & MS_EFFECT_DISPLACEMENT)) {
            po.displace = true;
            po.displacement_amplitude = disp->amplitude;
            po.displacement_radius = disp->atom_radius;
            po.displacement_density = disp->density;
            po.displacement_seed = disp->seed;
        }
        st = ms_render_draw(vs->parts[i].render, camera, &po, &one, err);
        merge_stats(&sum, &one);
        sum.effects_compiled |= po.effects;
        o.clear = false;
    }
    for (size_t i = 0; i < vs->model_count && st == MS_OK; ++i) {
        scene_model *m = &vs->models[i];
        const ms_scene_material *mat = &scene->models[i].material;
        ms_render_options mo = o;
        mo.effects = piece_effects(vs, mat, true, false);
        memcpy(mo.albedo, mat->albedo, sizeof mo.albedo);
        mo.specular = mat->specular;
        mo.shininess = mat->shininess;
        mo.two_sided = mat->two_sided;
        mo.placed = true;
        memcpy(mo.placement, m->placement, sizeof mo.placement);
        st = draw_model(vs, m, camera, &mo, &sum, err);
        o.clear = false; /* without a room, the first model's draw cleared */
        sum.effects_compiled |= mo.effects;
    }
    if (stats)
        *stats = sum;
    return st;
}

uint64_t ms_viewer_scene_connections(ms_viewer_scene *vs)
{
    if (vs->link) {
        ms_core_link_stats ls;
        ms_core_link_get_stats(vs->link, &ls);
        return ls.connections;
    }
    uint64_t n = 0;
    for (size_t i = 0; vs->from_server && i < vs->model_count; ++i) {
        ms_core_stats s;
        ms_viewer_stream_stats(vs->models[i].stream, &s);
        n += 1 + s.reconnects;
    }
    return n;
}

void ms_viewer_scene_stats(ms_viewer_scene *vs, ms_core_stats *sum)
{
    memset(sum, 0, sizeof *sum);
    sum->view_complete = true;
    sum->connected = sum->model_open = true;
    sum->first_display = -1;
    for (size_t i = 0; i < vs->model_count; ++i) {
        ms_core_stats s;
        ms_viewer_stream_stats(vs->models[i].stream, &s);
        sum->time = fmax(sum->time, s.time);
        sum->connected &= s.connected;
        sum->model_open &= s.model_open;
        sum->view_complete &= s.view_complete;
        sum->achieved_error_px = fmax(sum->achieved_error_px, s.achieved_error_px);
        sum->tolerance_px = fmax(sum->tolerance_px, s.tolerance_px);
        if (s.first_display >= 0 && (sum->first_display < 0 || s.first_display < sum->first_display))
            sum->first_display = s.first_display;
        sum->bytes_received += s.bytes_received;
        sum->geometry_bytes_received += s.geometry_bytes_received;
        sum->apo_bytes_received += s.apo_bytes_received;
        sum->socket_bytes += s.socket_bytes;
        sum->bytes_in_flight += s.bytes_in_flight;
        sum->requests += s.requests, sum->cancels += s.cancels, sum->reconnects += s.reconnects;
        sum->refetches += s.refetches, sum->evictions += s.evictions;
        sum->cells_shown += s.cells_shown, sum->cells_split += s.cells_split;
        sum->cells_cached += s.cells_cached, sum->cells_loading += s.cells_loading;
        sum->cells_failed += s.cells_failed;
        sum->memory += s.memory, sum->peak_memory += s.peak_memory;
        sum->decode_seconds += s.decode_seconds;
        sum->index_by_subtree |= s.index_by_subtree;
        sum->subtrees_received += s.subtrees_received;
        sum->index_bytes_received += s.index_bytes_received;
        sum->index_bytes_held += s.index_bytes_held;
        sum->peak_index_bytes_held += s.peak_index_bytes_held;
        sum->subtrees_held += s.subtrees_held;
        sum->latency_p50 = fmax(sum->latency_p50, s.latency_p50);
        sum->latency_p99 = fmax(sum->latency_p99, s.latency_p99);
        if (s.preview && (!sum->preview || s.preview_bits < sum->preview_bits))
            sum->preview_bits = s.preview_bits; /* the coarsest piece's */
        sum->preview |= s.preview;
        sum->preview_limited |= s.preview_limited;
        if (!sum->error[0] && s.error[0])
            snprintf(sum->error, sizeof sum->error, "%.64s: %.180s", vs->models[i].model.name, s.error);
        if (!sum->warning[0] && s.warning[0])
            snprintf(sum->warning, sizeof sum->warning, "%.64s: %.180s", vs->models[i].model.name, s.warning);
    }
    if (vs->link) { /* one connection: its bytes once, not once per member */
        ms_core_link_stats ls;
        ms_core_link_get_stats(vs->link, &ls);
        sum->socket_bytes = ls.socket_bytes;
    }
}

bool ms_viewer_scene_settled(const ms_viewer_scene *vs)
{
    for (size_t i = 0; i < vs->model_count; ++i)
        if (!vs->models[i].settled)
            return false;
    return true;
}

unsigned ms_viewer_scene_effects(const ms_viewer_scene *vs)
{
    return vs->effects & IMPLEMENTED_EFFECTS;
}

void ms_viewer_scene_bounds(const ms_viewer_scene *vs, double lo[3], double hi[3])
{
    memcpy(lo, vs->lo, 3 * sizeof *lo);
    memcpy(hi, vs->hi, 3 * sizeof *hi);
}

size_t ms_viewer_scene_piece_count(const ms_viewer_scene *vs)
{
    return vs->model_count;
}

void ms_viewer_scene_piece_info(ms_viewer_scene *vs, size_t i, ms_viewer_scene_piece *piece)
{
    memset(piece, 0, sizeof *piece);
    if (i >= vs->model_count)
        return;
    const scene_model *m = &vs->models[i];
    piece->model = vs->scene->models[i].model;
    piece->material = &vs->scene->models[i].material;
    memcpy(piece->placement, m->placement, sizeof piece->placement);
    memcpy(piece->lo, m->lo, sizeof piece->lo);
    memcpy(piece->hi, m->hi, sizeof piece->hi);
    piece->impostor = m->coverage;
    piece->triangles = m->drawn.triangles_drawn;
    piece->cells = m->drawn.cells_drawn;
    ms_core_stats cs;
    ms_viewer_stream_stats(m->stream, &cs);
    piece->bytes = cs.bytes_received;
    piece->achieved_error_px = cs.achieved_error_px;
}
