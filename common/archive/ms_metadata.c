/* A model's sidecar metadata (ms_metadata.h). */
#include "ms_metadata.h"

#include <jansson.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_catalog_internal.h"
#include "ms_input_file.h"

const char *const ms_metadata_field_names[MS_METADATA_FIELDS] = {
    "title", "creator", "date", "licence", "description", "unit"};
const size_t ms_metadata_field_max[MS_METADATA_FIELDS] = {
    MS_METADATA_TITLE_MAX, MS_METADATA_CREATOR_MAX, MS_METADATA_DATE_MAX,
    MS_METADATA_LICENCE_MAX, MS_METADATA_DESCRIPTION_MAX, MS_METADATA_UNIT_MAX};

enum { DESCRIPTION = 4, UNIT = 5 };

static char **field_slot(ms_metadata *m, int k)
{
    char **slots[MS_METADATA_FIELDS] = {&m->title, &m->creator, &m->date, &m->licence,
                                        &m->description, &m->unit};
    return slots[k];
}

bool ms_metadata_unit_valid(const char *unit)
{
    static const char *const units[] = {"um", "mm", "cm", "m", "in", "ft"};
    for (size_t i = 0; unit && i < sizeof units / sizeof *units; ++i)
        if (!strcmp(unit, units[i]))
            return true;
    return false;
}

const char *ms_metadata_unit_name(const ms_metadata *m)
{
    return m && m->unit ? m->unit : MS_METADATA_NO_UNIT;
}

const char *ms_metadata_field(const ms_metadata *m, int k)
{
    return m && k >= 0 && k < MS_METADATA_FIELDS ? *field_slot((ms_metadata *)m, k) : NULL;
}

/* One code point from UTF-8 at s (n bytes left): its length, 0 when malformed
 * (truncated, overlong, a surrogate, above U+10FFFF). */
static size_t next_code_point(const unsigned char *s, size_t n, uint32_t *cp)
{
    if (s[0] < 0x80) {
        *cp = s[0];
        return 1;
    }
    size_t len = s[0] >= 0xF0 ? 4 : s[0] >= 0xE0 ? 3 : s[0] >= 0xC0 ? 2 : 0;
    if (len == 0 || len > n || s[0] > 0xF4)
        return 0;
    uint32_t v = s[0] & (0x7F >> len);
    for (size_t i = 1; i < len; ++i) {
        if ((s[i] & 0xC0) != 0x80)
            return 0;
        v = (v << 6) | (s[i] & 0x3F);
    }
    static const uint32_t least[5] = {0, 0, 0x80, 0x800, 0x10000};
    if (v < least[len] || v > 0x10FFFF || (v >= 0xD800 && v <= 0xDFFF))
        return 0;
    *cp = v;
    return len;
}

bool ms_metadata_text_ok(const char *text, size_t size, bool newlines_ok, const char **why)
{
    const unsigned char *s = (const unsigned char *)text;
    for (size_t at = 0; at < size;) {
        uint32_t cp;
        size_t len = next_code_point(s + at, size - at, &cp);
        if (!len) {
            *why = "is not valid UTF-8";
            return false;
        }
        if ((cp < 0x20 && !(cp == '\n' && newlines_ok)) || (cp >= 0x7F && cp <= 0x9F)) {
            *why = newlines_ok ? "holds a control character (only line feeds are allowed)"
                               : "holds a control character or a line break";
            return false;
        }
        if ((cp >= 0x202A && cp <= 0x202E) || (cp >= 0x2066 && cp <= 0x2069)) {
            *why = "holds a bidirectional override or isolate character";
            return false;
        }
        at += len;
    }
    return true;
}

void ms_metadata_free(ms_metadata *m) { free(m); }

/* One block: the struct, then each present string. */
static ms_metadata *build(const char *const values[MS_METADATA_FIELDS])
{
    size_t total = sizeof(ms_metadata), any = 0;
    for (int k = 0; k < MS_METADATA_FIELDS; ++k)
        if (values[k] && values[k][0])
            total += strlen(values[k]) + 1, ++any;
    if (!any)
        return NULL;
    ms_metadata *m = calloc(1, total);
    if (!m)
        return NULL;
    char *at = (char *)(m + 1);
    for (int k = 0; k < MS_METADATA_FIELDS; ++k) {
        if (!values[k] || !values[k][0])
            continue;
        size_t n = strlen(values[k]) + 1;
        memcpy(at, values[k], n);
        *field_slot(m, k) = at;
        at += n;
    }
    return m;
}

ms_metadata *ms_metadata_dup(const ms_metadata *m, bool *failed)
{
    if (!m)
        return NULL;
    const char *values[MS_METADATA_FIELDS];
    for (int k = 0; k < MS_METADATA_FIELDS; ++k)
        values[k] = ms_metadata_field(m, k);
    ms_metadata *copy = build(values);
    if (!copy && failed)
        *failed = true;
    return copy;
}

bool ms_metadata_equal(const ms_metadata *a, const ms_metadata *b)
{
    for (int k = 0; k < MS_METADATA_FIELDS; ++k) {
        const char *x = ms_metadata_field(a, k), *y = ms_metadata_field(b, k);
        if ((x == NULL) != (y == NULL) || (x && strcmp(x, y) != 0))
            return false;
    }
    return true;
}

ms_status ms_metadata_from_json(json_t *obj, const char *where, ms_metadata **out, ms_error *err)
{
    *out = NULL;
    if (!json_is_object(obj))
        return ms_error_set(err, MS_ERR_FORMAT, "%s: metadata is not a JSON object", where);
    const char *values[MS_METADATA_FIELDS] = {NULL};
    const char *key;
    json_t *value;
    json_object_foreach(obj, key, value) {
        int k = 0;
        while (k < MS_METADATA_FIELDS && strcmp(key, ms_metadata_field_names[k]) != 0)
            ++k;
        if (k == MS_METADATA_FIELDS)
            return ms_error_set(err, MS_ERR_FORMAT,
                                "%s: unknown metadata field '%.40s' (title, creator, date, "
                                "licence, description, unit)", where, key);
        if (!json_is_string(value))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: metadata %s is not a string", where,
                                key);
        size_t n = json_string_length(value);
        if (k == UNIT && n && (strlen(json_string_value(value)) != n ||
                               !ms_metadata_unit_valid(json_string_value(value))))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: metadata unit is not one of %s", where,
                                MS_METADATA_UNITS);
        if (n > ms_metadata_field_max[k])
            return ms_error_set(err, MS_ERR_RANGE, "%s: metadata %s is %zu bytes, at most %zu",
                                where, key, n, ms_metadata_field_max[k]);
        const char *why = NULL;
        if (!ms_metadata_text_ok(json_string_value(value), n, k == DESCRIPTION, &why))
            return ms_error_set(err, MS_ERR_FORMAT, "%s: metadata %s %s", where, key, why);
        values[k] = json_string_value(value);
    }
    bool any = false;
    for (int k = 0; k < MS_METADATA_FIELDS; ++k)
        any = any || (values[k] && values[k][0]);
    if (any && !(*out = build(values)))
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", where);
    return MS_OK;
}

json_t *ms_metadata_to_json(const ms_metadata *m)
{
    json_t *obj = json_object();
    for (int k = 0; obj && k < MS_METADATA_FIELDS; ++k) {
        const char *v = ms_metadata_field(m, k);
        if (v && json_object_set_new(obj, ms_metadata_field_names[k], json_string(v)) != 0) {
            json_decref(obj);
            return NULL;
        }
    }
    return obj;
}

ms_status ms_metadata_parse(const char *text, size_t size, const char *where, ms_metadata **out,
                            ms_error *err)
{
    *out = NULL;
    if (size > MS_METADATA_FILE_MAX)
        return ms_error_set(err, MS_ERR_RANGE, "%s: %zu bytes, a metadata file holds at most %d",
                            where, size, MS_METADATA_FILE_MAX);
    json_error_t jerr;
    json_t *root = json_loadb(text, size, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: line %d: %s", where, jerr.line, jerr.text);
    ms_status st = ms_metadata_from_json(root, where, out, err);
    json_decref(root);
    return st;
}

ms_status ms_metadata_load(const char *path, ms_metadata **out, ms_error *err)
{
    *out = NULL;
    char *text;
    size_t got;
    ms_status st = ms_input_read_most(path, MS_METADATA_FILE_MAX, &text, &got, err);
    if (st != MS_OK)
        return st;
    st = ms_metadata_parse(text, got, path, out, err); /* it says when got is too many */
    free(text);
    return st;
}
