/* Section planes as text: see ms_section.h. */
#include "ms_section.h"

#include <math.h>
#include <string.h>

#include "ms_parse_number.h"

/* Exactly n finite decimal numbers separated by commas, the whole text. */
static bool numbers(const char *text, double *out, size_t n)
{
    const char *p = text;
    for (size_t i = 0; i < n; ++i) {
        size_t len = strcspn(p, ",");
        char field[48];
        if (len == 0 || len >= sizeof field || (i + 1 < n) != (p[len] == ','))
            return false;
        memcpy(field, p, len);
        field[len] = 0;
        if (strspn(field, "0123456789+-.eE") != len)
            return false;
        const char *end = ms_parse_double(field, &out[i]);
        if (!end || *end || !isfinite(out[i]))
            return false;
        p += len + (i + 1 < n);
    }
    return true;
}

ms_status ms_section_parse(const char *text, double point[3], double normal[3], ms_error *err)
{
    if (!text)
        return ms_error_set(err, MS_ERR_FORMAT, "section: no text");
    double v[6];
    const char *p = text + (text[0] == '-');
    for (int a = 0; a < 3; ++a)
        point[a] = normal[a] = 0;
    if (p[0] >= 'x' && p[0] <= 'z' && p[1] == '=') {
        int axis = p[0] - 'x';
        if (!numbers(p + 2, v, 1))
            return ms_error_set(err, MS_ERR_FORMAT, "section '%.64s': AXIS=VALUE wants one finite number", text);
        point[axis] = v[0];
        normal[axis] = text[0] == '-' ? -1 : 1;
        return MS_OK;
    }
    if (!numbers(text, v, 6))
        return ms_error_set(err, MS_ERR_FORMAT,
                            "section '%.64s': wants AXIS=VALUE (AXIS x, y, z, -x, -y or -z) or PX,PY,PZ,NX,NY,NZ",
                            text);
    memcpy(point, v, 3 * sizeof *v);
    memcpy(normal, v + 3, 3 * sizeof *v);
    double len2 = normal[0] * normal[0] + normal[1] * normal[1] + normal[2] * normal[2];
    if (!(len2 > 0))
        return ms_error_set(err, MS_ERR_FORMAT, "section '%.64s': the normal is zero", text);
    if (!isfinite(len2) || !isfinite(normal[0] * point[0] + normal[1] * point[1] + normal[2] * point[2]))
        return ms_error_set(err, MS_ERR_FORMAT, "section '%.64s': numbers too large", text);
    return MS_OK;
}

void ms_section_plane(const double point[3], const double normal[3], double plane[4])
{
    for (int a = 0; a < 3; ++a)
        plane[a] = normal[a];
    plane[3] = -(normal[0] * point[0] + normal[1] * point[1] + normal[2] * point[2]);
}

bool ms_section_cuts_away(const double (*planes)[4], size_t count, const double p[3])
{
    for (size_t k = 0; k < count; ++k)
        if (planes[k][0] * p[0] + planes[k][1] * p[1] + planes[k][2] * p[2] + planes[k][3] > 0)
            return true;
    return false;
}
