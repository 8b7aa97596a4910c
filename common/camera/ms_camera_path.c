/* Camera path files: see ms_camera_path.h. */
#include "ms_camera_path.h"
#include "ms_input_file.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_LINE 1024
#define MAX_FILE (16u << 20)

void ms_camera_path_free(ms_camera_path *p)
{
    free(p->keys);
    p->keys = NULL;
    p->count = 0;
}

/* Parses the 11 numbers of a keyframe line; false on anything else. */
static bool parse_key(const char *line, ms_camera_key *k)
{
    double v[11];
    const char *s = line;
    for (int i = 0; i < 11; ++i) {
        char *end;
        errno = 0;
        v[i] = strtod(s, &end);
        if (end == s || errno == ERANGE || !isfinite(v[i]))
            return false;
        s = end;
    }
    while (*s == ' ' || *s == '\t' || *s == '\r')
        ++s;
    if (*s)
        return false;
    k->time = v[0];
    for (int a = 0; a < 3; ++a) {
        k->position[a] = v[1 + a];
        k->target[a] = v[4 + a];
        k->up[a] = v[7 + a];
    }
    k->fovy_degrees = v[10];
    return true;
}

ms_status ms_camera_path_parse(const char *text, size_t size, const char *name,
                               ms_camera_path *p, ms_error *err)
{
    memset(p, 0, sizeof *p);
    size_t capacity = 0;
    unsigned line_number = 0;
    bool saw_magic = false;
    ms_status st = MS_OK;
    for (size_t pos = 0; pos < size && st == MS_OK;) {
        size_t end = pos;
        while (end < size && text[end] != '\n')
            ++end;
        ++line_number;
        size_t len = end - pos;
        if (len >= MAX_LINE) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%s:%u: line longer than %d bytes", name,
                              line_number, MAX_LINE);
            break;
        }
        char line[MAX_LINE];
        memcpy(line, text + pos, len);
        line[len] = '\0';
        pos = end + 1;
        if (memchr(line, '\0', len)) {
            st = ms_error_set(err, MS_ERR_FORMAT, "%s:%u: NUL byte", name, line_number);
            break;
        }
        if (!saw_magic) {
            if (len && line[len - 1] == '\r')
                line[len - 1] = '\0';
            if (strcmp(line, MS_CAMERA_PATH_MAGIC) != 0) {
                st = ms_error_set(err, MS_ERR_FORMAT, "%s:1: not a camera path (expected '%s')",
                                  name, MS_CAMERA_PATH_MAGIC);
                break;
            }
            saw_magic = true;
            continue;
        }
        char *hash = strchr(line, '#');
        if (hash)
            *hash = '\0';
        char *s = line;
        while (*s == ' ' || *s == '\t' || *s == '\r')
            ++s;
        if (!*s)
            continue;
        ms_camera_key k;
        if (!parse_key(s, &k)) {
            st = ms_error_set(err, MS_ERR_FORMAT,
                              "%s:%u: expected 11 finite numbers: time, position, target, up, fovy",
                              name, line_number);
            break;
        }
        if (k.time < 0 || (p->count && !(k.time > p->keys[p->count - 1].time))) {
            st = ms_error_set(err, MS_ERR_RANGE, "%s:%u: times must start at >= 0 and increase",
                              name, line_number);
            break;
        }
        ms_camera probe;
        ms_error why;
        if (ms_camera_look_at(k.position, k.target, k.up, k.fovy_degrees, 1, 1, 1, 2, &probe,
                              &why) != MS_OK) {
            st = ms_error_set(err, MS_ERR_RANGE, "%s:%u: %s", name, line_number, why.text);
            break;
        }
        if (p->count == MS_CAMERA_PATH_MAX_KEYS) {
            st = ms_error_set(err, MS_ERR_RANGE, "%s:%u: more than %d keyframes", name,
                              line_number, MS_CAMERA_PATH_MAX_KEYS);
            break;
        }
        if (p->count == capacity) {
            size_t grown = capacity ? 2 * capacity : 16;
            ms_camera_key *keys = realloc(p->keys, grown * sizeof *keys);
            if (!keys) {
                st = ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory", name);
                break;
            }
            p->keys = keys;
            capacity = grown;
        }
        p->keys[p->count++] = k;
    }
    if (st == MS_OK && !saw_magic)
        st = ms_error_set(err, MS_ERR_FORMAT, "%s: empty file", name);
    if (st == MS_OK && p->count == 0)
        st = ms_error_set(err, MS_ERR_EMPTY, "%s: no keyframe", name);
    if (st != MS_OK)
        ms_camera_path_free(p);
    return st;
}

ms_status ms_camera_path_load(const char *file, ms_camera_path *p, ms_error *err)
{
    memset(p, 0, sizeof *p);
    char *text;
    size_t size;
    ms_status st = ms_input_read_most(file, MAX_FILE, &text, &size, err);
    if (st != MS_OK)
        return st;
    if (size > MAX_FILE)
        st = ms_error_set(err, MS_ERR_RANGE, "%s: larger than 16 MiB", file);
    else
        st = ms_camera_path_parse(text, size, file, p, err);
    free(text);
    return st;
}

double ms_camera_path_duration(const ms_camera_path *p)
{
    return p->count ? p->keys[p->count - 1].time : 0.0;
}

void ms_camera_path_key_at(const ms_camera_path *p, double t, ms_camera_key *key)
{
    memset(key, 0, sizeof *key);
    if (p->count == 0)
        return;
    size_t i = 0;
    while (i + 1 < p->count && p->keys[i + 1].time <= t)
        ++i;
    const ms_camera_key *a = &p->keys[i];
    const ms_camera_key *b = i + 1 < p->count ? &p->keys[i + 1] : a;
    double w = (b == a || t <= a->time) ? 0.0 : (t - a->time) / (b->time - a->time);
    if (w > 1.0)
        w = 1.0;
    for (int k = 0; k < 3; ++k) {
        key->position[k] = a->position[k] + w * (b->position[k] - a->position[k]);
        key->target[k] = a->target[k] + w * (b->target[k] - a->target[k]);
        key->up[k] = a->up[k] + w * (b->up[k] - a->up[k]);
    }
    key->fovy_degrees = a->fovy_degrees + w * (b->fovy_degrees - a->fovy_degrees);
    key->time = a->time + w * (b->time - a->time);
}

double ms_camera_path_nearest_time(const ms_camera_path *p, const double point[3])
{
    if (p->count == 0)
        return 0.0;
    double best_time = p->keys[0].time, best = INFINITY;
    for (size_t i = 0; i < p->count; ++i) {
        const ms_camera_key *a = &p->keys[i];
        const ms_camera_key *b = i + 1 < p->count ? &p->keys[i + 1] : a;
        /* positions move linearly between two keyframes: the segment's
         * nearest point is the projection clamped to it */
        double ab[3], ap[3], len2 = 0, along = 0;
        for (int k = 0; k < 3; ++k) {
            ab[k] = b->position[k] - a->position[k];
            ap[k] = point[k] - a->position[k];
            len2 += ab[k] * ab[k];
            along += ab[k] * ap[k];
        }
        double w = len2 > 0 ? along / len2 : 0.0;
        w = w < 0 ? 0 : w > 1 ? 1 : w;
        double d2 = 0;
        for (int k = 0; k < 3; ++k)
            d2 += (ap[k] - w * ab[k]) * (ap[k] - w * ab[k]);
        if (d2 < best) {
            best = d2;
            best_time = a->time + w * (b->time - a->time);
        }
    }
    return best_time;
}

ms_status ms_camera_path_sample(const ms_camera_path *p, double t, double width, double height,
                                double near_distance, double far_distance, ms_camera *camera,
                                ms_error *err)
{
    if (p->count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "camera path has no keyframe");
    ms_camera_key key;
    ms_camera_path_key_at(p, t, &key);
    return ms_camera_look_at(key.position, key.target, key.up, key.fovy_degrees, width, height,
                             near_distance, far_distance, camera, err);
}

ms_status ms_camera_path_sample_framing(const ms_camera_path *p, double t, double width,
                                        double height, const double lo[3], const double hi[3],
                                        ms_camera *camera, ms_error *err)
{
    if (p->count == 0)
        return ms_error_set(err, MS_ERR_EMPTY, "camera path has no keyframe");
    ms_camera_key key;
    ms_camera_path_key_at(p, t, &key);
    double near_d, far_d;
    ms_camera_depth_range(key.position, lo, hi, &near_d, &far_d);
    return ms_camera_look_at(key.position, key.target, key.up, key.fovy_degrees, width, height,
                             near_d, far_d, camera, err);
}
