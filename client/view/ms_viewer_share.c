/* Shareable views: see ms_viewer_share.h. */
#include "ms_viewer_share.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "ms_parse_number.h"

#define PITCH_LIMIT (89.0 * M_PI / 180.0)
#define NUMBER_MAX 40 /* "-1.2345678901234567e-308" and room */

bool ms_viewer_numbers(const char *text, char sep, double *out, size_t n)
{
    const char *p = text;
    for (size_t i = 0; i < n; ++i) {
        size_t len = 0;
        while (p[len] && p[len] != sep)
            ++len;
        char field[NUMBER_MAX];
        if (len == 0 || len >= sizeof field || (i + 1 < n) != (p[len] == sep))
            return false;
        memcpy(field, p, len);
        field[len] = 0;
        if (strspn(field, "0123456789+-.eE") != len) /* no spaces, hex or names */
            return false;
        const char *end = ms_parse_double(field, &out[i]);
        if (!end || *end || !isfinite(out[i]))
            return false;
        p += len + (i + 1 < n);
    }
    return true;
}

/* The shortest %.Ng that reads back to exactly x. */
static int shortest(char *out, size_t size, double x)
{
    int len = 0;
    for (int digits = 1; digits <= 17; ++digits) {
        len = snprintf(out, size, "%.*g", digits, x);
        double back;
        const char *end = ms_parse_double(out, &back);
        if (end && !*end && memcmp(&back, &x, sizeof x) == 0)
            break;
    }
    /* an exponent with fewer digits than the integer part: an integer, "4e+01" as "40" */
    if (strchr(out, 'e') && fabs(x) >= 1 && fabs(x) < 1e17)
        len = snprintf(out, size, "%.0f", x);
    return len;
}

/* Appends the numbers separated by commas. */
static void append_numbers(char *text, size_t size, size_t *used, const double *v, size_t n)
{
    for (size_t i = 0; i < n && *used < size; ++i) {
        if (i && *used + 1 < size)
            text[(*used)++] = ',';
        char number[NUMBER_MAX];
        int len = shortest(number, sizeof number, v[i]);
        *used += (size_t)snprintf(text + *used, size - *used, "%.*s", len, number);
    }
    if (*used >= size)
        *used = size - 1;
}

static void append(char *text, size_t size, size_t *used, const char *s)
{
    *used += (size_t)snprintf(text + *used, size - *used, "%s", s);
    if (*used >= size)
        *used = size - 1;
}

void ms_viewer_share_print(const ms_viewer_share *v, char *text, size_t size)
{
    size_t used = 0;
    text[0] = 0;
    append(text, size, &used, "mv1:t=");
    append_numbers(text, size, &used, v->target, 3);
    append(text, size, &used, ":d=");
    append_numbers(text, size, &used, &v->distance, 1);
    append(text, size, &used, ":o=");
    double o[2] = {v->yaw, v->pitch};
    append_numbers(text, size, &used, o, 2);
    append(text, size, &used, ":f=");
    append_numbers(text, size, &used, &v->fovy_degrees, 1);
    append(text, size, &used, v->up_axis == 0 ? ":u=x" : v->up_axis == 1 ? ":u=y" : ":u=z");
    if (v->light.directional) {
        append(text, size, &used, ":l=");
        double l[2] = {v->light.azimuth_deg, v->light.elevation_deg};
        append_numbers(text, size, &used, l, 2);
    }
    for (size_t i = 0; i < v->sections.count && i < MS_SECTIONS_MAX; ++i) {
        append(text, size, &used, i ? "/" : ":s=");
        double p[6] = {v->sections.point[i][0],  v->sections.point[i][1],  v->sections.point[i][2],
                       v->sections.normal[i][0], v->sections.normal[i][1], v->sections.normal[i][2]};
        append_numbers(text, size, &used, p, 6);
    }
    for (size_t i = 0; i < v->points; ++i) {
        append(text, size, &used, i ? "/" : ":m=");
        double p[6] = {v->anchor[i][0],    v->anchor[i][1],    v->anchor[i][2],
                       v->direction[i][0], v->direction[i][1], v->direction[i][2]};
        append_numbers(text, size, &used, p, 6);
    }
}

/* The next field "KEY=VALUE" of the text at *p (up to ':' or the end) into
 * value; false when there is none or it is not that key. */
static bool field(const char **p, char key, char *value, size_t size)
{
    const char *s = *p;
    if (s[0] != key || s[1] != '=')
        return false;
    s += 2;
    size_t len = strcspn(s, ":");
    if (len >= size)
        return false;
    memcpy(value, s, len);
    value[len] = 0;
    *p = s + len + (s[len] == ':');
    return true;
}

static ms_status bad(ms_error *err, const char *what)
{
    return ms_error_set(err, MS_ERR_FORMAT, "%s (docs/VIEWER.md, \"Shareable views\")", what);
}

/* The measuring chain "X,Y,Z,DX,DY,DZ/..." */
static ms_status parse_points(char *value, ms_viewer_share *v, ms_error *err)
{
    for (char *p = value;;) {
        if (v->points >= MS_VIEWER_MEASURE_MAX_POINTS)
            return bad(err, "more than 16 measuring points");
        char *slash = strchr(p, '/');
        if (slash)
            *slash = 0;
        double n[6];
        if (!ms_viewer_numbers(p, ',', n, 6))
            return bad(err, "a measuring point wants six numbers X,Y,Z,DX,DY,DZ");
        double len2 = n[3] * n[3] + n[4] * n[4] + n[5] * n[5];
        if (!(len2 > 0) || !isfinite(len2))
            return bad(err, "a measuring point's direction is zero");
        memcpy(v->anchor[v->points], n, 3 * sizeof *n);
        memcpy(v->direction[v->points], n + 3, 3 * sizeof *n);
        v->points++;
        if (!slash)
            return MS_OK;
        p = slash + 1;
    }
}

/* The section planes "PX,PY,PZ,NX,NY,NZ/..." */
static ms_status parse_sections(char *value, ms_viewer_share *v, ms_error *err)
{
    for (char *p = value;;) {
        if (v->sections.count >= MS_SECTIONS_MAX)
            return bad(err, "more than 3 section planes");
        char *slash = strchr(p, '/');
        if (slash)
            *slash = 0;
        double n[6];
        if (!ms_viewer_numbers(p, ',', n, 6))
            return bad(err, "a section plane wants six numbers PX,PY,PZ,NX,NY,NZ");
        if (!ms_viewer_sections_add(&v->sections, n, n + 3))
            return bad(err, "a section plane's normal is zero or its numbers too large");
        if (!slash)
            return MS_OK;
        p = slash + 1;
    }
}

ms_status ms_viewer_share_parse(const char *text, ms_viewer_share *v, ms_error *err)
{
    memset(v, 0, sizeof *v);
    if (!text || strnlen(text, MS_VIEWER_SHARE_MAX) >= MS_VIEWER_SHARE_MAX)
        return bad(err, "missing or longer than 4095 bytes");
    if (strncmp(text, "mv1:", 4) != 0)
        return bad(err, "does not start with mv1:");
    const char *p = text + 4;
    char value[MS_VIEWER_SHARE_MAX];
    double o[2];
    if (!field(&p, 't', value, sizeof value) || !ms_viewer_numbers(value, ',', v->target, 3))
        return bad(err, "t= wants the orbit centre X,Y,Z");
    if (!field(&p, 'd', value, sizeof value) || !ms_viewer_numbers(value, ',', &v->distance, 1) ||
        !(v->distance > 0))
        return bad(err, "d= wants a distance > 0");
    if (!field(&p, 'o', value, sizeof value) || !ms_viewer_numbers(value, ',', o, 2) ||
        !(fabs(o[1]) <= PITCH_LIMIT))
        return bad(err, "o= wants YAW,PITCH in radians, |PITCH| at most 89 degrees");
    v->yaw = o[0], v->pitch = o[1];
    if (!field(&p, 'f', value, sizeof value) || !ms_viewer_numbers(value, ',', &v->fovy_degrees, 1) ||
        !(v->fovy_degrees > 0 && v->fovy_degrees < 180))
        return bad(err, "f= wants a field of view in (0, 180) degrees");
    if (!field(&p, 'u', value, sizeof value) || strlen(value) != 1 || value[0] < 'x' || value[0] > 'z')
        return bad(err, "u= wants x, y or z");
    v->up_axis = value[0] - 'x';
    if (*p == 'l') {
        if (!field(&p, 'l', value, sizeof value) || !ms_viewer_light_parse(value, &v->light))
            return bad(err, "l= wants AZ,EL in degrees, AZ in [-180, 180], EL in [-90, 90]");
    }
    if (*p == 's') {
        if (!field(&p, 's', value, sizeof value))
            return bad(err, "s= wants section planes");
        ms_status st = parse_sections(value, v, err);
        if (st != MS_OK)
            return st;
    }
    if (*p == 'm') {
        if (!field(&p, 'm', value, sizeof value))
            return bad(err, "m= wants measuring points");
        ms_status st = parse_points(value, v, err);
        if (st != MS_OK)
            return st;
    }
    if (*p || p[-1] == ':')
        return bad(err, "unknown or misplaced field after u= (l=, s=, then m=, may follow)");
    return MS_OK;
}

void ms_viewer_share_take(const ms_viewer_controls *c, const ms_viewer_light *light, const ms_viewer_measure *m,
                          ms_viewer_share *v)
{
    memset(v, 0, sizeof *v);
    memcpy(v->target, c->target, sizeof v->target);
    v->distance = c->distance;
    v->yaw = c->yaw, v->pitch = c->pitch;
    v->fovy_degrees = c->fovy_degrees;
    v->up_axis = c->up_axis;
    if (light)
        v->light = *light;
    for (size_t i = 0; m && i < m->count; ++i) {
        memcpy(v->anchor[i], m->anchor[i], sizeof v->anchor[i]);
        memcpy(v->direction[i], m->direction[i], sizeof v->direction[i]);
        v->points++;
    }
}

void ms_viewer_share_give(const ms_viewer_share *v, ms_viewer_controls *c, ms_viewer_light *light,
                          ms_viewer_measure *m)
{
    if (c) {
        memcpy(c->target, v->target, sizeof c->target);
        c->distance = v->distance;
        c->yaw = v->yaw, c->pitch = v->pitch;
        c->fovy_degrees = v->fovy_degrees;
        c->up_axis = v->up_axis;
        c->fly = false;
    }
    if (light)
        *light = v->light;
    if (m) {
        ms_viewer_measure_clear(m);
        for (size_t i = 0; i < v->points; ++i)
            ms_viewer_measure_add_anchor(m, v->anchor[i], v->direction[i]);
    }
}
