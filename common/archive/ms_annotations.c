/* A model's annotations (ms_annotations.h). */
#include "ms_annotations.h"

#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_input_file.h"
#include "ms_metadata.h"

/* One annotation: its strings in one block (owned), the public view of them. */
typedef struct entry {
    ms_annotation a;
    char *block;
} entry;

struct ms_annotations {
    entry *items;
    size_t count, capacity;
};

ms_annotations *ms_annotations_new(void)
{
    return calloc(1, sizeof(ms_annotations));
}

void ms_annotations_free(ms_annotations *set)
{
    if (!set)
        return;
    for (size_t i = 0; i < set->count; ++i)
        free(set->items[i].block);
    free(set->items);
    free(set);
}

size_t ms_annotations_count(const ms_annotations *set)
{
    return set ? set->count : 0;
}

const ms_annotation *ms_annotations_get(const ms_annotations *set, size_t i)
{
    return set && i < set->count ? &set->items[i].a : NULL;
}

long ms_annotations_find(const ms_annotations *set, const char *id)
{
    for (size_t i = 0; set && id && i < set->count; ++i)
        if (strcmp(set->items[i].a.id, id) == 0)
            return (long)i;
    return -1;
}

static bool id_char(char c)
{
    return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '.' ||
           c == '_' || c == '-';
}

ms_status ms_annotation_check(const ms_annotation *a, const char *where, ms_error *err)
{
    size_t n = a->id ? strlen(a->id) : 0;
    if (n == 0 || n > MS_ANNOTATION_ID_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: id is %zu bytes, 1 to %d", where, n, MS_ANNOTATION_ID_MAX);
    for (size_t i = 0; i < n; ++i)
        if (!id_char(a->id[i]))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: id holds a character other than A-Z a-z 0-9 . _ -",
                                where);
    for (int k = 0; k < 3; ++k)
        if (!isfinite(a->point[k]))
            return ms_error_set(err, MS_ERR_RANGE, "%s: point coordinate %d is not finite", where, k + 1);
    if (!isfinite(a->radius) || a->radius < 0)
        return ms_error_set(err, MS_ERR_RANGE, "%s: radius is not a finite number >= 0", where);
    const char *why = NULL;
    n = a->title ? strlen(a->title) : 0;
    if (n == 0 || n > MS_ANNOTATION_TITLE_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: title is %zu bytes, 1 to %d", where, n,
                            MS_ANNOTATION_TITLE_MAX);
    if (!ms_metadata_text_ok(a->title, n, false, &why))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: title %s", where, why);
    n = a->text ? strlen(a->text) : 0;
    if (n > MS_ANNOTATION_TEXT_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: text is %zu bytes, at most %d", where, n,
                            MS_ANNOTATION_TEXT_MAX);
    if (!ms_metadata_text_ok(a->text ? a->text : "", n, true, &why))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: text %s", where, why);
    if (a->view) {
        n = strlen(a->view);
        if (n > MS_ANNOTATION_VIEW_MAX)
            return ms_error_set(err, MS_ERR_RANGE, "%s: view is %zu bytes, at most %d", where, n,
                                MS_ANNOTATION_VIEW_MAX);
        if (strncmp(a->view, "mv1:", 4) != 0)
            return ms_error_set(err, MS_ERR_FORMAT, "%s: view does not start with mv1:", where);
        for (size_t i = 0; i < n; ++i)
            if (a->view[i] <= ' ' || a->view[i] > '~')
                return ms_error_set(err, MS_ERR_FORMAT, "%s: view holds a space or a character outside printable ASCII",
                                    where);
    }
    return MS_OK;
}

/* A copy of a's strings in one block into e. */
static bool copy_entry(entry *e, const ms_annotation *a)
{
    const char *text = a->text ? a->text : "";
    size_t ni = strlen(a->id) + 1, nt = strlen(a->title) + 1, nx = strlen(text) + 1;
    size_t nv = a->view ? strlen(a->view) + 1 : 0;
    char *block = malloc(ni + nt + nx + nv);
    if (!block)
        return false;
    e->a = *a;
    e->a.radius = a->radius > 0 ? a->radius : 0; /* not -0: the file leaves a zero radius out */
    e->block = block;
    e->a.id = memcpy(block, a->id, ni);
    e->a.title = memcpy(block + ni, a->title, nt);
    e->a.text = memcpy(block + ni + nt, text, nx);
    e->a.view = a->view ? memcpy(block + ni + nt + nx, a->view, nv) : NULL;
    return true;
}

ms_status ms_annotations_add(ms_annotations *set, const ms_annotation *a, ms_error *err)
{
    char where[MS_ANNOTATION_ID_MAX + 40];
    snprintf(where, sizeof where, "annotation %zu", set->count + 1);
    ms_status st = ms_annotation_check(a, where, err);
    if (st != MS_OK)
        return st;
    if (ms_annotations_find(set, a->id) >= 0)
        return ms_error_set(err, MS_ERR_RANGE, "%s: id '%s' is already used", where, a->id);
    if (set->count >= MS_ANNOTATIONS_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: a model has at most %d annotations", where,
                            MS_ANNOTATIONS_MAX);
    if (set->count == set->capacity) {
        size_t cap = set->capacity ? 2 * set->capacity : 8;
        entry *grown = realloc(set->items, cap * sizeof *grown);
        if (!grown)
            return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
        set->items = grown;
        set->capacity = cap;
    }
    if (!copy_entry(&set->items[set->count], a))
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    set->count++;
    return MS_OK;
}

bool ms_annotations_remove(ms_annotations *set, size_t i)
{
    if (!set || i >= set->count)
        return false;
    free(set->items[i].block);
    memmove(set->items + i, set->items + i + 1, (set->count - i - 1) * sizeof *set->items);
    set->count--;
    return true;
}

void ms_annotations_next_id(const ms_annotations *set, char *id, size_t size)
{
    for (unsigned long k = 1;; ++k) {
        snprintf(id, size, "a%lu", k);
        if (ms_annotations_find(set, id) < 0)
            return;
    }
}

/* ---- the file ---------------------------------------------------------- */

static const char *const members[] = {"id", "point", "radius", "title", "text", "view"};

/* A string member of o (NULL when absent); false with err set when it is not a string. */
static bool string_member(json_t *o, const char *name, const char *where, const char **out, ms_error *err)
{
    json_t *v = json_object_get(o, name);
    *out = NULL;
    if (!v)
        return true;
    if (!json_is_string(v)) {
        ms_error_set(err, MS_ERR_FORMAT, "%s: %s is not a string", where, name);
        return false;
    }
    /* a NUL inside (\u0000) would cut the C string short: refused as a control character */
    if (strlen(json_string_value(v)) != json_string_length(v)) {
        ms_error_set(err, MS_ERR_FORMAT, "%s: %s holds a control character", where, name);
        return false;
    }
    *out = json_string_value(v);
    return true;
}

static ms_status one_from_json(json_t *o, const char *where, ms_annotations *set, ms_error *err)
{
    if (!json_is_object(o))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: not a JSON object", where);
    const char *key;
    json_t *value;
    json_object_foreach(o, key, value) {
        size_t k = 0;
        while (k < sizeof members / sizeof *members && strcmp(key, members[k]) != 0)
            ++k;
        if (k == sizeof members / sizeof *members)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "%s: unknown member '%.40s' (id, point, radius, title, text, view)", where, key);
    }
    ms_annotation a = {0};
    if (!string_member(o, "id", where, &a.id, err) || !string_member(o, "title", where, &a.title, err) ||
        !string_member(o, "text", where, &a.text, err) || !string_member(o, "view", where, &a.view, err))
        return err ? err->code : MS_ERR_FORMAT;
    if (!a.id)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: no id", where);
    if (!a.title)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: no title", where);
    json_t *point = json_object_get(o, "point");
    if (!point)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: no point", where);
    if (!json_is_array(point) || json_array_size(point) != 3)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: point is not an array of 3 numbers", where);
    for (size_t k = 0; k < 3; ++k) {
        json_t *c = json_array_get(point, k);
        if (!json_is_number(c))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: point is not an array of 3 numbers", where);
        a.point[k] = json_number_value(c);
    }
    json_t *radius = json_object_get(o, "radius");
    if (radius && !json_is_number(radius))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: radius is not a number", where);
    a.radius = radius ? json_number_value(radius) : 0;
    ms_status st = ms_annotation_check(&a, where, err);
    if (st != MS_OK)
        return st;
    if (ms_annotations_find(set, a.id) >= 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: id '%s' is used twice", where, a.id);
    return ms_annotations_add(set, &a, err);
}

static ms_status from_json(json_t *root, const char *where, ms_annotations *set, ms_error *err)
{
    if (!json_is_object(root))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: not a JSON object", where);
    const char *key;
    json_t *value;
    json_object_foreach(root, key, value) {
        if (strcmp(key, "format") != 0 && strcmp(key, "version") != 0 && strcmp(key, "annotations") != 0)
            return ms_error_set(err, MS_ERR_FORMAT, "%s: unknown member '%.40s' (format, version, annotations)",
                                where, key);
    }
    json_t *format = json_object_get(root, "format");
    if (!json_is_string(format) || strcmp(json_string_value(format), MS_ANNOTATIONS_FORMAT) != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: format is not \"%s\"", where, MS_ANNOTATIONS_FORMAT);
    json_t *version = json_object_get(root, "version");
    if (!json_is_integer(version))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: version is not an integer", where);
    if (json_integer_value(version) != MS_ANNOTATIONS_VERSION)
        return ms_error_set(err, MS_ERR_UNSUPPORTED, "%s: version %lld is not supported (%d)", where,
                            (long long)json_integer_value(version), MS_ANNOTATIONS_VERSION);
    json_t *list = json_object_get(root, "annotations");
    if (!json_is_array(list))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: annotations is not an array", where);
    if (json_array_size(list) > MS_ANNOTATIONS_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %zu annotations, at most %d", where, json_array_size(list),
                            MS_ANNOTATIONS_MAX);
    for (size_t i = 0; i < json_array_size(list); ++i) {
        char at[600];
        json_t *id = json_object_get(json_array_get(list, i), "id");
        if (json_is_string(id) && json_string_length(id) <= MS_ANNOTATION_ID_MAX &&
            strlen(json_string_value(id)) == json_string_length(id))
            snprintf(at, sizeof at, "%.400s: annotation %zu (%.64s)", where, i + 1, json_string_value(id));
        else
            snprintf(at, sizeof at, "%.400s: annotation %zu", where, i + 1);
        /* an id of other characters is not echoed: the check names the fault */
        for (size_t k = strlen(where) < 400 ? strlen(where) : 400; at[k]; ++k)
            if ((unsigned char)at[k] < 0x20 || (unsigned char)at[k] > 0x7e)
                at[k] = '?';
        ms_status st = one_from_json(json_array_get(list, i), at, set, err);
        if (st != MS_OK)
            return st;
    }
    return MS_OK;
}

ms_status ms_annotations_parse(const char *text, size_t size, const char *where, ms_annotations **out,
                               ms_error *err)
{
    *out = NULL;
    if (size > MS_ANNOTATIONS_FILE_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %zu bytes, an annotations file holds at most %d", where, size,
                            MS_ANNOTATIONS_FILE_MAX);
    json_error_t jerr;
    json_t *root = json_loadb(text, size, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: line %d: %s", where, jerr.line, jerr.text);
    ms_annotations *set = ms_annotations_new();
    ms_status st = set ? from_json(root, where, set, err) : ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    json_decref(root);
    if (st != MS_OK) {
        ms_annotations_free(set);
        return st;
    }
    *out = set;
    return MS_OK;
}

ms_status ms_annotations_load(const char *path, ms_annotations **out, ms_error *err)
{
    *out = NULL;
    char *text;
    size_t got;
    ms_status st = ms_input_read_most(path, MS_ANNOTATIONS_FILE_MAX, &text, &got, err);
    if (st != MS_OK)
        return st;
    if (got > MS_ANNOTATIONS_FILE_MAX)
        st = ms_error_set(err, MS_ERR_RANGE, "%s: more than %d bytes, an annotations file holds at most that",
                          path, MS_ANNOTATIONS_FILE_MAX);
    else
        st = ms_annotations_parse(text, got, path, out, err);
    free(text);
    return st;
}

static json_t *one_to_json(const ms_annotation *a)
{
    json_t *o = json_pack("{s:s, s:[f, f, f]}", "id", a->id, "point", a->point[0], a->point[1], a->point[2]);
    if (o && a->radius > 0)
        json_object_set_new(o, "radius", json_real(a->radius));
    if (o) {
        json_object_set_new(o, "title", json_string(a->title));
        json_object_set_new(o, "text", json_string(a->text ? a->text : ""));
    }
    if (o && a->view)
        json_object_set_new(o, "view", json_string(a->view));
    return o;
}

ms_status ms_annotations_write(const ms_annotations *set, char **text, size_t *size, ms_error *err)
{
    *text = NULL;
    *size = 0;
    json_t *list = json_array();
    json_t *root = json_pack("{s:s, s:i, s:o}", "format", MS_ANNOTATIONS_FORMAT, "version", MS_ANNOTATIONS_VERSION,
                             "annotations", list);
    bool failed = !root;
    for (size_t i = 0; !failed && i < ms_annotations_count(set); ++i) {
        json_t *o = one_to_json(ms_annotations_get(set, i));
        failed = !o || json_array_append_new(list, o) != 0;
    }
    /* jansson writes a double with 17 significant digits: it reads back the same */
    char *dumped = failed ? NULL : json_dumps(root, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    json_decref(root);
    if (!dumped)
        return ms_error_set(err, MS_ERR_NOMEM, "annotations: out of memory writing JSON");
    size_t n = strlen(dumped);
    if (n + 1 > MS_ANNOTATIONS_FILE_MAX) {
        free(dumped);
        return ms_error_set(err, MS_ERR_RANGE, "annotations: %zu bytes, a file holds at most %d", n + 1,
                            MS_ANNOTATIONS_FILE_MAX);
    }
    dumped[n] = '\0';
    *text = dumped;
    *size = n;
    return MS_OK;
}

ms_status ms_annotations_save(const ms_annotations *set, const char *path, ms_error *err)
{
    char *text;
    size_t size;
    ms_status st = ms_annotations_write(set, &text, &size, err);
    if (st != MS_OK)
        return st;
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.partial", path);
    FILE *f = fopen(tmp, "wb");
    if (!f) {
        free(text);
        return ms_error_set(err, MS_ERR_IO, "%s: cannot create: %s", tmp, strerror(errno));
    }
    bool ok = fwrite(text, 1, size, f) == size && fputc('\n', f) != EOF && fflush(f) == 0 && fsync(fileno(f)) == 0;
    ok = fclose(f) == 0 && ok;
    free(text);
    if (!ok || rename(tmp, path) != 0) {
        remove(tmp);
        return ms_error_set(err, MS_ERR_IO, "%s: write failed", path);
    }
    return MS_OK;
}

static bool same_text(const char *x, const char *y)
{
    return (x == NULL) == (y == NULL) && (!x || strcmp(x, y) == 0);
}

bool ms_annotations_equal(const ms_annotations *a, const ms_annotations *b)
{
    if (ms_annotations_count(a) != ms_annotations_count(b))
        return false;
    for (size_t i = 0; i < ms_annotations_count(a); ++i) {
        const ms_annotation *x = ms_annotations_get(a, i), *y = ms_annotations_get(b, i);
        if (!same_text(x->id, y->id) || !same_text(x->title, y->title) || !same_text(x->text, y->text) ||
            !same_text(x->view, y->view) || memcmp(x->point, y->point, sizeof x->point) != 0 ||
            memcmp(&x->radius, &y->radius, sizeof x->radius) != 0)
            return false;
    }
    return true;
}

void ms_annotations_sidecar_path(const char *dir, const char *name, char *out, size_t size)
{
    snprintf(out, size, "%s/%s.annotations.json", dir, name);
}
