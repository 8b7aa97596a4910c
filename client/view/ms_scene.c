/* Scene files (ms_scene.h): JSON through jansson, every element checked for
 * unknown keys, types and ranges, with the element's path in the error
 * ("models[2].material.shininess"). */
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_scene.h"
#include "ms_input_file.h"

/* Where the parser is: the label for errors and the element's path. */
typedef struct cursor {
    const char *label;
    char path[160];
} cursor;

/* Appends s to the path, cut at its capacity (paths are short: nesting is
 * three levels and names are the format's own keys). */
static void path_append(cursor *c, const char *s)
{
    size_t used = strlen(c->path), room = sizeof c->path - 1 - used, n = strlen(s);
    memcpy(c->path + used, s, n < room ? n : room);
    c->path[used + (n < room ? n : room)] = 0;
}

static void cursor_child(const cursor *parent, const char *key, cursor *child)
{
    *child = *parent;
    if (child->path[0])
        path_append(child, ".");
    path_append(child, key);
}

static void cursor_index(const cursor *parent, size_t i, cursor *child)
{
    char index[32];
    snprintf(index, sizeof index, "[%zu]", i);
    *child = *parent;
    path_append(child, index);
}

static ms_status fail(ms_error *err, ms_status code, const cursor *at, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static ms_status fail(ms_error *err, ms_status code, const cursor *at, const char *fmt, ...)
{
    char what[320];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    if (at->path[0])
        return ms_error_set(err, code, "scene %s: %s: %s", at->label, at->path, what);
    return ms_error_set(err, code, "scene %s: %s", at->label, what);
}

/* MS_ERR_FORMAT unless obj is an object whose keys are all in allowed (NULL-ended). */
static ms_status check_object(const json_t *obj, const cursor *at, const char *const *allowed, ms_error *err)
{
    if (!json_is_object(obj))
        return fail(err, MS_ERR_FORMAT, at, "expected an object");
    const char *key;
    json_t *value;
    json_object_foreach((json_t *)obj, key, value) {
        (void)value;
        bool known = false;
        for (const char *const *a = allowed; *a && !known; ++a)
            known = strcmp(*a, key) == 0;
        if (!known)
            return fail(err, MS_ERR_FORMAT, at, "unknown key \"%s\"", key);
    }
    return MS_OK;
}

/* The value at key (NULL when absent) and its cursor; the "missing" error when it
 * is absent but required. */
static ms_status lookup(const json_t *obj, const char *key, const cursor *at, bool required, json_t **value,
                        cursor *c, ms_error *err)
{
    cursor_child(at, key, c);
    *value = json_object_get(obj, key);
    if (!*value && required)
        return fail(err, MS_ERR_FORMAT, at, "missing \"%s\"", key);
    return MS_OK;
}

/* The number v (a JSON number) if it lies in [lo, hi] (open at lo where lo_open). */
static ms_status number_in_range(const json_t *v, const cursor *c, double lo, bool lo_open, double hi, double *out,
                                 ms_error *err)
{
    double x = json_number_value(v);
    if (!isfinite(x) || (lo_open ? x <= lo : x < lo) || x > hi)
        return fail(err, MS_ERR_RANGE, c, "%g out of range %c%g, %g]", x, lo_open ? '(' : '[', lo, hi);
    *out = x;
    return MS_OK;
}

/* A number in [lo, hi] (open ends where lo_open / hi_open); absent: *out unchanged
 * unless required. */
static ms_status get_number(const json_t *obj, const char *key, const cursor *at, bool required, double lo,
                            bool lo_open, double hi, double *out, ms_error *err)
{
    cursor c;
    json_t *v;
    ms_status st = lookup(obj, key, at, required, &v, &c, err);
    if (st != MS_OK || !v)
        return st;
    if (!json_is_number(v))
        return fail(err, MS_ERR_FORMAT, &c, "expected a number");
    return number_in_range(v, &c, lo, lo_open, hi, out, err);
}

static ms_status get_float(const json_t *obj, const char *key, const cursor *at, double lo, bool lo_open,
                           double hi, float *out, ms_error *err)
{
    double x = *out;
    ms_status st = get_number(obj, key, at, false, lo, lo_open, hi, &x, err);
    *out = (float)x;
    return st;
}

/* An array of n numbers, each in [lo, hi]. */
static ms_status get_vector(const json_t *obj, const char *key, const cursor *at, bool required, size_t n,
                            double lo, double hi, double *out, ms_error *err)
{
    cursor c;
    json_t *v;
    ms_status st = lookup(obj, key, at, required, &v, &c, err);
    if (st != MS_OK || !v)
        return st;
    if (!json_is_array(v) || json_array_size(v) != n)
        return fail(err, MS_ERR_FORMAT, &c, "expected an array of %zu numbers", n);
    for (size_t i = 0; i < n && st == MS_OK; ++i) {
        json_t *e = json_array_get(v, i);
        if (!json_is_number(e))
            return fail(err, MS_ERR_FORMAT, &c, "expected an array of %zu numbers", n);
        st = number_in_range(e, &c, lo, false, hi, &out[i], err);
    }
    return st;
}

static ms_status get_colour(const json_t *obj, const char *key, const cursor *at, float out[3], ms_error *err)
{
    double rgb[3] = {out[0], out[1], out[2]};
    ms_status st = get_vector(obj, key, at, false, 3, 0.0, 1.0, rgb, err);
    for (int a = 0; a < 3; ++a)
        out[a] = (float)rgb[a];
    return st;
}

static ms_status get_bool(const json_t *obj, const char *key, const cursor *at, bool *out, ms_error *err)
{
    cursor c;
    json_t *v;
    ms_status st = lookup(obj, key, at, false, &v, &c, err);
    if (st != MS_OK || !v)
        return st;
    if (!json_is_boolean(v))
        return fail(err, MS_ERR_FORMAT, &c, "expected true or false");
    *out = json_is_true(v);
    return MS_OK;
}

/* One of the names (NULL-ended), as its index; absent: *out unchanged. */
static ms_status get_choice(const json_t *obj, const char *key, const cursor *at, bool required,
                            const char *const *names, const char *expected, int *out, ms_error *err)
{
    cursor c;
    json_t *v;
    ms_status st = lookup(obj, key, at, required, &v, &c, err);
    if (st != MS_OK || !v)
        return st;
    if (json_is_string(v))
        for (int i = 0; names[i]; ++i)
            if (strcmp(names[i], json_string_value(v)) == 0) {
                *out = i;
                return MS_OK;
            }
    return fail(err, MS_ERR_FORMAT, &c, "expected %s", expected);
}

/* The optional object at key (NULL when absent) and its cursor, checked for keys
 * outside allowed (NULL-ended). */
static ms_status open_object(const json_t *parent, const char *key, const cursor *at, const char *const *allowed,
                             json_t **obj, cursor *c, ms_error *err)
{
    ms_status st = lookup(parent, key, at, false, obj, c, err);
    return st == MS_OK && *obj ? check_object(*obj, c, allowed, err) : st;
}

static void material_default(ms_scene_material *m)
{
    memset(m, 0, sizeof *m);
    m->kind = MS_MATERIAL_DIFFUSE;
    m->albedo[0] = 0.72f, m->albedo[1] = 0.69f, m->albedo[2] = 0.64f;
    m->shininess = 40.0f;
}

static ms_status parse_material(const json_t *parent, const char *key, const cursor *at, ms_scene_material *m,
                                ms_error *err)
{
    static const char *const keys[] = {"type", "albedo", "specular", "shininess", "two_sided", NULL};
    static const char *const kinds[] = {"diffuse", "glossy", NULL};
    json_t *obj;
    cursor c;
    ms_status st = open_object(parent, key, at, keys, &obj, &c, err);
    if (!obj)
        return st;
    int kind = MS_MATERIAL_DIFFUSE;
    if (st == MS_OK)
        st = get_choice(obj, "type", &c, false, kinds, "\"diffuse\" or \"glossy\"", &kind, err);
    m->kind = (ms_material_kind)kind;
    if (st == MS_OK)
        st = get_colour(obj, "albedo", &c, m->albedo, err);
    if (st == MS_OK && m->kind == MS_MATERIAL_DIFFUSE &&
        (json_object_get(obj, "specular") || json_object_get(obj, "shininess")))
        st = fail(err, MS_ERR_FORMAT, &c, "specular and shininess need \"type\": \"glossy\"");
    m->specular = m->kind == MS_MATERIAL_GLOSSY ? 0.18f : 0.0f;
    if (st == MS_OK)
        st = get_float(obj, "specular", &c, 0.0, false, 1.0, &m->specular, err);
    if (st == MS_OK)
        st = get_float(obj, "shininess", &c, 1.0, false, 1000.0, &m->shininess, err);
    if (st == MS_OK)
        st = get_bool(obj, "two_sided", &c, &m->two_sided, err);
    return st;
}

static ms_status parse_displacement(const json_t *parent, const cursor *at, ms_scene_displacement *d,
                                    ms_error *err)
{
    static const char *const keys[] = {"amplitude", "atom_radius", "density", "seed", NULL};
    json_t *obj;
    cursor c;
    ms_status st = open_object(parent, "displacement", at, keys, &obj, &c, err);
    if (!obj)
        return st;
    d->on = true;
    d->amplitude = 0.01f, d->atom_radius = 0.05f, d->density = 100.0f;
    if (st == MS_OK)
        st = get_float(obj, "amplitude", &c, 0.0, true, 0.5, &d->amplitude, err);
    if (st == MS_OK)
        st = get_float(obj, "atom_radius", &c, 0.005, false, 2.0, &d->atom_radius, err);
    if (st == MS_OK)
        st = get_float(obj, "density", &c, 0.0, true, 10000.0, &d->density, err);
    double seed = 1;
    if (st == MS_OK)
        st = get_number(obj, "seed", &c, false, 0.0, false, 4294967295.0, &seed, err);
    if (st == MS_OK && seed != floor(seed)) {
        cursor s;
        cursor_child(&c, "seed", &s);
        st = fail(err, MS_ERR_FORMAT, &s, "expected an integer");
    }
    d->seed = (uint32_t)seed;
    return st;
}

static ms_status parse_surface(const json_t *parent, const char *key, const cursor *at, ms_scene_surface *s,
                               ms_error *err)
{
    static const char *const keys[] = {"material", "displacement", NULL};
    json_t *obj;
    cursor c;
    ms_status st = open_object(parent, key, at, keys, &obj, &c, err);
    if (!obj)
        return st;
    if (st == MS_OK)
        st = parse_material(obj, "material", &c, &s->material, err);
    if (st == MS_OK)
        st = parse_displacement(obj, &c, &s->displacement, err);
    return st;
}

static ms_status parse_model(const json_t *obj, const cursor *at, ms_scene_model *m, ms_error *err)
{
    static const char *const keys[] = {"model", "position", "yaw", "height", "up", "material", NULL};
    static const char *const axes[] = {"x", "y", "z", NULL};
    ms_status st = check_object(obj, at, keys, err);
    if (st != MS_OK)
        return st;
    json_t *name;
    cursor c;
    st = lookup(obj, "model", at, true, &name, &c, err);
    if (st != MS_OK)
        return st;
    if (!json_is_string(name) || !ms_model_name_valid(json_string_value(name)))
        return fail(err, MS_ERR_FORMAT, &c, "expected a model name (1 to 64 of A-Z a-z 0-9 _ -)");
    snprintf(m->model, sizeof m->model, "%s", json_string_value(name));
    m->height = 1.0;
    m->up_axis = 1;
    material_default(&m->material);
    st = get_vector(obj, "position", at, true, 3, -1e4, 1e4, m->position, err);
    if (st == MS_OK)
        st = get_number(obj, "yaw", at, false, -360.0, false, 360.0, &m->yaw_degrees, err);
    if (st == MS_OK)
        st = get_number(obj, "height", at, false, 0.0, true, 100.0, &m->height, err);
    if (st == MS_OK)
        st = get_choice(obj, "up", at, false, axes, "\"x\", \"y\" or \"z\"", &m->up_axis, err);
    if (st == MS_OK)
        st = parse_material(obj, "material", at, &m->material, err);
    return st;
}

static ms_status parse_light(const json_t *obj, const cursor *at, ms_scene_light *l, size_t *points,
                             bool *head, ms_error *err)
{
    static const char *const keys[] = {"type", "colour", "intensity", "direction", "position", "range", NULL};
    static const char *const kinds[] = {"head", "directional", "point", NULL};
    ms_status st = check_object(obj, at, keys, err);
    int kind = 0;
    if (st == MS_OK)
        st = get_choice(obj, "type", at, true, kinds, "\"head\", \"directional\" or \"point\"", &kind, err);
    if (st != MS_OK)
        return st;
    l->kind = (ms_light_kind)kind;
    l->colour[0] = l->colour[1] = l->colour[2] = 1.0f;
    l->intensity = 1.0f;
    l->range = 5.0;
    st = get_colour(obj, "colour", at, l->colour, err);
    if (st == MS_OK)
        st = get_float(obj, "intensity", at, 0.0, false, 10.0, &l->intensity, err);
    bool has_dir = json_object_get(obj, "direction") != NULL, has_pos = json_object_get(obj, "position") != NULL;
    bool has_range = json_object_get(obj, "range") != NULL;
    if (st != MS_OK)
        return st;
    switch (l->kind) {
    case MS_LIGHT_HEAD:
        if (*head)
            return fail(err, MS_ERR_FORMAT, at, "a second head light");
        *head = true;
        if (has_dir || has_pos || has_range)
            return fail(err, MS_ERR_FORMAT, at, "a head light takes no direction, position or range");
        return MS_OK;
    case MS_LIGHT_DIRECTIONAL: {
        if (has_pos || has_range)
            return fail(err, MS_ERR_FORMAT, at, "a directional light takes no position or range");
        st = get_vector(obj, "direction", at, true, 3, -1e4, 1e4, l->vector, err);
        double len = sqrt(l->vector[0] * l->vector[0] + l->vector[1] * l->vector[1] + l->vector[2] * l->vector[2]);
        if (st == MS_OK && !(len > 1e-9)) {
            cursor c;
            cursor_child(at, "direction", &c);
            return fail(err, MS_ERR_RANGE, &c, "zero vector");
        }
        for (int a = 0; a < 3 && st == MS_OK; ++a)
            l->vector[a] /= len;
        return st;
    }
    case MS_LIGHT_POINT:
        if (++*points > MS_SCENE_MAX_POINT_LIGHTS)
            return fail(err, MS_ERR_RANGE, at, "more than %d point lights", MS_SCENE_MAX_POINT_LIGHTS);
        if (has_dir)
            return fail(err, MS_ERR_FORMAT, at, "a point light takes no direction");
        st = get_vector(obj, "position", at, true, 3, -1e4, 1e4, l->vector, err);
        if (st == MS_OK)
            st = get_number(obj, "range", at, false, 0.0, true, 1000.0, &l->range, err);
        return st;
    }
    return MS_OK;
}

static ms_status parse_room(const json_t *root, const cursor *top, ms_scene_room *room, ms_error *err)
{
    static const char *const keys[] = {"size", "floor", "walls", "plinths", NULL};
    json_t *obj;
    cursor at;
    ms_status st = open_object(root, "room", top, keys, &obj, &at, err);
    if (st != MS_OK || !obj)
        return st;
    room->on = true;
    material_default(&room->floor.material);
    material_default(&room->walls.material);
    st = get_vector(obj, "size", &at, true, 3, 0.0, 1000.0, room->size, err);
    for (int a = 0; a < 3 && st == MS_OK; ++a)
        if (!(room->size[a] > 0.0)) {
            cursor c;
            cursor_child(&at, "size", &c);
            st = fail(err, MS_ERR_RANGE, &c, "%g out of range (0, 1000]", room->size[a]);
        }
    if (st == MS_OK)
        st = parse_surface(obj, "floor", &at, &room->floor, err);
    if (st == MS_OK)
        st = parse_surface(obj, "walls", &at, &room->walls, err);
    json_t *plinths = json_object_get(obj, "plinths");
    if (st != MS_OK || !plinths)
        return st;
    cursor pc;
    cursor_child(&at, "plinths", &pc);
    if (!json_is_array(plinths))
        return fail(err, MS_ERR_FORMAT, &pc, "expected an array");
    size_t n = json_array_size(plinths);
    if (n > MS_SCENE_MAX_PLINTHS)
        return fail(err, MS_ERR_RANGE, &pc, "%zu plinths, at most %d", n, MS_SCENE_MAX_PLINTHS);
    room->plinths = calloc(n ? n : 1, sizeof *room->plinths);
    if (!room->plinths)
        return ms_error_set(err, MS_ERR_NOMEM, "scene %s: no memory", top->label);
    room->plinth_count = n;
    for (size_t i = 0; i < n && st == MS_OK; ++i) {
        cursor c;
        cursor_index(&pc, i, &c);
        json_t *p = json_array_get(plinths, i);
        static const char *const pkeys[] = {"position", "size", "material", NULL};
        ms_scene_plinth *pl = &room->plinths[i];
        material_default(&pl->material);
        st = check_object(p, &c, pkeys, err);
        if (st == MS_OK)
            st = get_vector(p, "position", &c, true, 2, -1e4, 1e4, pl->position, err);
        if (st == MS_OK)
            st = get_vector(p, "size", &c, true, 3, 0.0, 10.0, pl->size, err);
        for (int a = 0; a < 3 && st == MS_OK; ++a)
            if (!(pl->size[a] > 0.0)) {
                cursor s;
                cursor_child(&c, "size", &s);
                st = fail(err, MS_ERR_RANGE, &s, "%g out of range (0, 10]", pl->size[a]);
            }
        if (st == MS_OK)
            st = parse_material(p, "material", &c, &pl->material, err);
    }
    return st;
}

static ms_status parse_effects(const json_t *root, const cursor *top, ms_scene *s, ms_error *err)
{
    s->effects_allowed = MS_EFFECTS_ALL;
    s->impostor_threshold_px = 100.0;
    s->impostor_angle_degrees = 5.0;
    static const char *const keys[] = {"detail_normals", "specular", "two_sided", "haze", "impostors",
                                       "displacement", "impostor_threshold_px", "impostor_angle_degrees", NULL};
    json_t *obj;
    cursor at;
    ms_status st = open_object(root, "effects", top, keys, &obj, &at, err);
    if (!obj)
        return st;
    for (unsigned bit = 1; bit <= MS_EFFECTS_ALL && st == MS_OK; bit <<= 1) {
        bool on = true;
        st = get_bool(obj, ms_effect_name(bit), &at, &on, err);
        if (!on)
            s->effects_allowed &= ~bit;
    }
    if (st == MS_OK)
        st = get_number(obj, "impostor_threshold_px", &at, false, 1.0, false, 4096.0, &s->impostor_threshold_px,
                        err);
    if (st == MS_OK)
        st = get_number(obj, "impostor_angle_degrees", &at, false, 0.0, true, 90.0, &s->impostor_angle_degrees,
                        err);
    return st;
}

static ms_status copy_string(char **out, const char *s, const cursor *top, ms_error *err)
{
    *out = strdup(s);
    return *out ? MS_OK : ms_error_set(err, MS_ERR_NOMEM, "scene %s: no memory", top->label);
}

/* Whether a scene-relative file name stays inside the scene's folder: not
 * absolute and no ".." component (a scene is a document that may come from
 * anywhere; what it names beside it is all it may reach, so a shared scene
 * cannot make meshview read /etc/... or a neighbour's files). */
static bool inside_folder(const char *p)
{
    if (p[0] == '/')
        return false;
    for (const char *part = p; *part;) {
        size_t n = strcspn(part, "/");
        if (n == 2 && part[0] == '.' && part[1] == '.')
            return false;
        part += n;
        part += *part == '/';
    }
    return true;
}

static ms_status parse_root(const json_t *root, const cursor *top, const char *base_dir, ms_scene *s,
                            ms_error *err)
{
    static const char *const keys[] = {"scene", "name", "models", "lights", "room", "haze", "effects",
                                       "camera_path", NULL};
    ms_status st = check_object(root, top, keys, err);
    if (st != MS_OK)
        return st;
    json_t *version = json_object_get(root, "scene");
    cursor c;
    cursor_child(top, "scene", &c);
    if (!version)
        return fail(err, MS_ERR_FORMAT, top, "missing \"scene\" (the format version, %d)", MS_SCENE_VERSION);
    if (!json_is_integer(version))
        return fail(err, MS_ERR_FORMAT, &c, "expected an integer");
    if (json_integer_value(version) != MS_SCENE_VERSION)
        return fail(err, MS_ERR_UNSUPPORTED, &c, "version %lld, this viewer reads %d",
                    (long long)json_integer_value(version), MS_SCENE_VERSION);
    json_t *name = json_object_get(root, "name");
    cursor_child(top, "name", &c);
    if (name && !json_is_string(name))
        return fail(err, MS_ERR_FORMAT, &c, "expected a string");
    st = copy_string(&s->name, name ? json_string_value(name) : "", top, err);
    if (st != MS_OK)
        return st;

    json_t *models;
    cursor mc;
    st = lookup(root, "models", top, true, &models, &mc, err);
    if (st != MS_OK)
        return st;
    if (!json_is_array(models))
        return fail(err, MS_ERR_FORMAT, &mc, "expected an array");
    size_t n = json_array_size(models);
    if (n == 0 || n > MS_SCENE_MAX_MODELS)
        return fail(err, MS_ERR_RANGE, &mc, "%zu models, 1 to %d", n, MS_SCENE_MAX_MODELS);
    s->models = calloc(n, sizeof *s->models);
    if (!s->models)
        return ms_error_set(err, MS_ERR_NOMEM, "scene %s: no memory", top->label);
    s->model_count = n;
    for (size_t i = 0; i < n && st == MS_OK; ++i) {
        cursor_index(&mc, i, &c);
        st = parse_model(json_array_get(models, i), &c, &s->models[i], err);
    }
    if (st != MS_OK)
        return st;

    json_t *lights = json_object_get(root, "lights");
    cursor lc;
    cursor_child(top, "lights", &lc);
    if (lights && !json_is_array(lights))
        return fail(err, MS_ERR_FORMAT, &lc, "expected an array");
    size_t ln = lights ? json_array_size(lights) : 0;
    if (ln > 2 + MS_SCENE_MAX_POINT_LIGHTS + 2)
        return fail(err, MS_ERR_RANGE, &lc, "%zu lights, at most %d", ln, 2 + MS_SCENE_MAX_POINT_LIGHTS + 2);
    s->lights = calloc(ln ? ln : 1, sizeof *s->lights);
    if (!s->lights)
        return ms_error_set(err, MS_ERR_NOMEM, "scene %s: no memory", top->label);
    if (!lights) {
        s->light_count = 1;
        s->lights[0] = (ms_scene_light){MS_LIGHT_HEAD, {1, 1, 1}, 1.0f, {0, 0, 0}, 5.0};
    } else {
        s->light_count = ln;
        size_t points = 0;
        bool head = false;
        for (size_t i = 0; i < ln && st == MS_OK; ++i) {
            cursor_index(&lc, i, &c);
            st = parse_light(json_array_get(lights, i), &c, &s->lights[i], &points, &head, err);
        }
    }
    if (st == MS_OK)
        st = parse_room(root, top, &s->room, err);

    json_t *haze = json_object_get(root, "haze");
    if (st == MS_OK && haze) {
        cursor_child(top, "haze", &c);
        static const char *const hkeys[] = {"density", "colour", NULL};
        st = check_object(haze, &c, hkeys, err);
        s->haze.colour[0] = s->haze.colour[1] = s->haze.colour[2] = 0.5f;
        double density = 0;
        if (st == MS_OK)
            st = get_number(haze, "density", &c, true, 0.0, false, 10.0, &density, err);
        s->haze.density = (float)density;
        if (st == MS_OK)
            st = get_colour(haze, "colour", &c, s->haze.colour, err);
    }
    if (st == MS_OK)
        st = parse_effects(root, top, s, err);

    json_t *path = json_object_get(root, "camera_path");
    if (st == MS_OK && path) {
        cursor_child(top, "camera_path", &c);
        if (!json_is_string(path) || !json_string_value(path)[0])
            return fail(err, MS_ERR_FORMAT, &c, "expected a file name");
        const char *p = json_string_value(path);
        if (!inside_folder(p))
            return fail(err, MS_ERR_FORMAT, &c,
                        "must name a file inside the scene's folder (no absolute path, no "
                        "'..'; give another path with --path)");
        if (!base_dir || !base_dir[0])
            return copy_string(&s->camera_path, p, top, err);
        size_t len = strlen(base_dir) + 1 + strlen(p) + 1;
        s->camera_path = malloc(len);
        if (!s->camera_path)
            return ms_error_set(err, MS_ERR_NOMEM, "scene %s: no memory", top->label);
        snprintf(s->camera_path, len, "%s/%s", base_dir, p);
    }
    return st;
}

ms_status ms_scene_parse(const char *text, size_t size, const char *label, const char *base_dir, ms_scene *scene,
                         ms_error *err)
{
    if (!scene)
        return ms_error_set(err, MS_ERR_ARG, "scene: no result");
    memset(scene, 0, sizeof *scene);
    cursor top = {label ? label : "(text)", ""};
    if (!text && size)
        return ms_error_set(err, MS_ERR_ARG, "scene %s: no text", top.label);
    if (size > MS_SCENE_MAX_BYTES)
        return ms_error_set(err, MS_ERR_RANGE, "scene %s: larger than %u bytes", top.label, MS_SCENE_MAX_BYTES);
    json_error_t jerr;
    json_t *root = json_loadb(text ? text : "", size, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return ms_error_set(err, MS_ERR_FORMAT, "scene %s: line %d, column %d: %s", top.label, jerr.line,
                            jerr.column, jerr.text);
    ms_status st = parse_root(root, &top, base_dir, scene, err);
    json_decref(root);
    if (st != MS_OK)
        ms_scene_free(scene);
    return st;
}

ms_status ms_scene_load(const char *path, ms_scene *scene, ms_error *err)
{
    if (!scene || !path)
        return ms_error_set(err, MS_ERR_ARG, "scene: no file or result");
    memset(scene, 0, sizeof *scene);
    char *text;
    size_t size;
    ms_error why;
    if (ms_input_read_most(path, MS_SCENE_MAX_BYTES, &text, &size, &why) != MS_OK)
        return ms_error_set(err, why.code, "scene %s", why.text);
    /* the folder of the file, for a relative camera path */
    char dir[4096];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (slash)
        *(slash == dir ? slash + 1 : slash) = 0;
    else
        dir[0] = 0;
    ms_status st = ms_scene_parse(text, size, path, dir, scene, err);
    free(text);
    return st;
}

void ms_scene_free(ms_scene *s)
{
    if (!s)
        return;
    free(s->name);
    free(s->camera_path);
    free(s->models);
    free(s->lights);
    free(s->room.plinths);
    memset(s, 0, sizeof *s);
}

ms_status ms_scene_check_models(const ms_scene *s, const char *label, const ms_viewer_model_list *list,
                                ms_error *err)
{
    if (!s || !list)
        return ms_error_set(err, MS_ERR_ARG, "scene: no scene or model list");
    for (size_t i = 0; i < s->model_count; ++i) {
        bool found = false;
        for (size_t k = 0; k < list->count && !found; ++k)
            found = strcmp(list->entries[k].name, s->models[i].model) == 0;
        if (!found)
            return ms_error_set(err, MS_ERR_RANGE, "scene %s: models[%zu].model: \"%s\" is not in the catalogue",
                                label ? label : "(text)", i, s->models[i].model);
    }
    return MS_OK;
}

static bool material_glossy(const ms_scene_material *m)
{
    return m->kind == MS_MATERIAL_GLOSSY && m->specular > 0.0f;
}

unsigned ms_scene_effects(const ms_scene *s)
{
    if (!s)
        return 0;
    unsigned want = MS_EFFECT_DETAIL_NORMALS;
    const ms_scene_material *materials[2 + MS_SCENE_MAX_MODELS + MS_SCENE_MAX_PLINTHS];
    size_t n = 0;
    for (size_t i = 0; i < s->model_count; ++i)
        materials[n++] = &s->models[i].material;
    if (s->room.on) {
        materials[n++] = &s->room.floor.material;
        materials[n++] = &s->room.walls.material;
        for (size_t i = 0; i < s->room.plinth_count; ++i)
            materials[n++] = &s->room.plinths[i].material;
        if (s->room.floor.displacement.on || s->room.walls.displacement.on)
            want |= MS_EFFECT_DISPLACEMENT;
    }
    for (size_t i = 0; i < n; ++i) {
        if (material_glossy(materials[i]))
            want |= MS_EFFECT_SPECULAR;
        if (materials[i]->two_sided)
            want |= MS_EFFECT_TWO_SIDED;
    }
    if (s->haze.density > 0.0f)
        want |= MS_EFFECT_HAZE;
    /* far objects: the farthest a visitor can stand from a model is about the
     * room's diagonal; seen from there at the reference view (45 degrees over
     * 720 pixels), is it shorter than the threshold? */
    double far = 20.0;
    if (s->room.on)
        far = sqrt(s->room.size[0] * s->room.size[0] + s->room.size[1] * s->room.size[1] +
                   s->room.size[2] * s->room.size[2]);
    double px_per_rad_metre = 720.0 / (2.0 * tan(0.5 * 45.0 * M_PI / 180.0));
    for (size_t i = 0; i < s->model_count; ++i)
        if (s->models[i].height / far * px_per_rad_metre < s->impostor_threshold_px)
            want |= MS_EFFECT_IMPOSTORS;
    return want & s->effects_allowed;
}

void ms_scene_model_transform(const ms_scene_model *m, const double lo[3], const double hi[3], double out[16])
{
    /* model axes to scene axes: the model's up axis becomes y by a cyclic
     * permutation, which keeps the frame right-handed (x up: x->y, y->z, z->x;
     * z up: z->y, x->z, y->x) */
    int up = m->up_axis;
    double extent = hi[up] - lo[up];
    double scale = extent > 0.0 ? m->height / extent : 1.0;
    /* cyclic permutation sending model axis `up` to scene y (1): scene axis
     * (k + 1 - up) mod 3 receives model axis k */
    double perm[3][3] = {{0}}; /* perm[scene][model] */
    for (int k = 0; k < 3; ++k)
        perm[(k + 1 - up + 3) % 3][k] = 1.0;
    double yaw = m->yaw_degrees * M_PI / 180.0, c = cos(yaw), s = sin(yaw);
    double rot[3][3] = {{c, 0, s}, {0, 1, 0}, {-s, 0, c}};
    double lin[3][3];
    for (int r = 0; r < 3; ++r)
        for (int k = 0; k < 3; ++k) {
            double v = 0;
            for (int j = 0; j < 3; ++j)
                v += rot[r][j] * perm[j][k];
            lin[r][k] = v * scale;
        }
    /* the bottom centre of the bounds goes to position */
    double anchor[3];
    for (int k = 0; k < 3; ++k)
        anchor[k] = k == up ? lo[k] : 0.5 * (lo[k] + hi[k]);
    memset(out, 0, 16 * sizeof *out);
    for (int r = 0; r < 3; ++r) {
        double t = m->position[r];
        for (int k = 0; k < 3; ++k) {
            out[4 * k + r] = lin[r][k];
            t -= lin[r][k] * anchor[k];
        }
        out[12 + r] = t;
    }
    out[15] = 1.0;
}

void ms_scene_placed_sphere(const double t[16], const double lo[3], const double hi[3], double centre[3],
                            double *radius)
{
    double mid[3], r2 = 0;
    for (int a = 0; a < 3; ++a) {
        mid[a] = 0.5 * (lo[a] + hi[a]);
        r2 += 0.25 * (hi[a] - lo[a]) * (hi[a] - lo[a]);
    }
    for (int r = 0; r < 3; ++r)
        centre[r] = t[r] * mid[0] + t[4 + r] * mid[1] + t[8 + r] * mid[2] + t[12 + r];
    *radius = sqrt(r2) * sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2]);
}
