/* Range, If-None-Match and Authorization parsing: see ms_http_parse.h. */
#include "ms_http_parse.h"

#include <stddef.h>
#include <string.h>
#include <strings.h>

#define VALUE_MAX 0x7fffffffffffffffull /* nginx's off_t cut-off */

static const char *skip_spaces(const char *p)
{
    while (*p == ' ')
        ++p;
    return p;
}

/* Reads one or more decimal digits at *p into *value; false on no digit or a
 * value past VALUE_MAX. */
static bool read_number(const char **p, uint64_t *value)
{
    const char *s = *p;
    if (*s < '0' || *s > '9')
        return false;
    uint64_t v = 0;
    for (; *s >= '0' && *s <= '9'; ++s) {
        unsigned digit = (unsigned)(*s - '0');
        if (v > (VALUE_MAX - digit) / 10)
            return false;
        v = v * 10 + digit;
    }
    *p = s;
    *value = v;
    return true;
}

ms_http_range_result ms_http_parse_range(const char *header, uint64_t length, uint64_t *first,
                                         uint64_t *last)
{
    if (!header || strncmp(header, "bytes=", 6) != 0)
        return MS_HTTP_RANGE_NONE;
    if (strchr(header, ','))
        return MS_HTTP_RANGE_UNSATISFIABLE; /* several ranges: one per request */
    const char *p = skip_spaces(header + 6);
    uint64_t start = 0, end = 0;
    bool suffix = *p == '-';
    if (suffix) {
        ++p;
    } else {
        if (!read_number(&p, &start))
            return MS_HTTP_RANGE_UNSATISFIABLE;
        p = skip_spaces(p);
        if (*p++ != '-')
            return MS_HTTP_RANGE_UNSATISFIABLE;
    }
    p = skip_spaces(p);
    bool open_end = *p == '\0';
    if (!open_end) {
        if (!read_number(&p, &end))
            return MS_HTTP_RANGE_UNSATISFIABLE;
        p = skip_spaces(p);
        if (*p != '\0')
            return MS_HTTP_RANGE_UNSATISFIABLE;
    }
    if (suffix) {
        /* "-N": the last N bytes; a bare "-" (as nginx reads it) all of them. */
        uint64_t n = open_end ? length : end;
        if (n == 0 || length == 0)
            return MS_HTTP_RANGE_UNSATISFIABLE;
        *first = n < length ? length - n : 0;
        *last = length - 1;
        return MS_HTTP_RANGE_OK;
    }
    if (!open_end && start > end)
        return MS_HTTP_RANGE_UNSATISFIABLE;
    if (start >= length)
        return MS_HTTP_RANGE_UNSATISFIABLE;
    *first = start;
    *last = open_end || end >= length ? length - 1 : end;
    return MS_HTTP_RANGE_OK;
}

bool ms_http_none_match(const char *header, const char *etag)
{
    if (!header)
        return false;
    size_t etag_length = strlen(etag);
    const char *p = header;
    for (;;) {
        while (*p == ' ' || *p == '\t' || *p == ',')
            ++p;
        if (*p == '\0')
            return false;
        if (*p == '*') {
            const char *after = p + 1;
            while (*after == ' ' || *after == '\t')
                ++after;
            if (*after == '\0' || *after == ',')
                return true;
        }
        if (!strncmp(p, "W/", 2))
            p += 2;
        size_t n = strcspn(p, ",");
        size_t trimmed = n;
        while (trimmed && (p[trimmed - 1] == ' ' || p[trimmed - 1] == '\t'))
            --trimmed;
        if (trimmed == etag_length && !strncmp(p, etag, etag_length))
            return true;
        p += n;
    }
}

static bool is_space_or_tab(char c) { return c == ' ' || c == '\t'; }

bool ms_http_bearer_credential(const char *header, const char **token, size_t *length)
{
    if (!header)
        return false;
    const char *p = header;
    while (is_space_or_tab(*p))
        ++p;
    static const char scheme[] = "bearer";
    for (size_t i = 0; i < sizeof scheme - 1; ++i, ++p)
        if ((*p | 0x20) != scheme[i]) /* ASCII letters only: '\0' never matches */
            return false;
    if (*p != ' ')
        return false; /* "Bearerx", or no credential */
    while (*p == ' ')
        ++p;
    const char *start = p;
    while (*p > ' ' && *p < 0x7f)
        ++p;
    size_t n = (size_t)(p - start);
    while (is_space_or_tab(*p))
        ++p;
    if (n == 0 || *p != '\0')
        return false;
    *token = start;
    *length = n;
    return true;
}

/* The weight of one Accept-Encoding element's parameters [p, end): 1000 for
 * none, 0..1000 (thousandths) for ";q=VALUE", -1 when malformed. */
static int coding_weight(const char *p, const char *end)
{
    int weight = 1000;
    while (p < end) {
        while (p < end && (is_space_or_tab(*p) || *p == ';'))
            ++p;
        if (p == end)
            break;
        const char *param_end = p;
        while (param_end < end && *param_end != ';')
            ++param_end;
        const char *value_end = param_end;
        while (value_end > p && is_space_or_tab(value_end[-1]))
            --value_end;
        if (value_end - p < 3 || (p[0] != 'q' && p[0] != 'Q') || p[1] != '=')
            return -1; /* the only parameter a coding takes is its weight */
        const char *v = p + 2;
        if (*v != '0' && *v != '1')
            return -1;
        int whole = *v++ - '0', thousandths = 0, digits = 0;
        if (v < value_end && *v == '.') {
            for (++v; v < value_end && digits < 3 && *v >= '0' && *v <= '9'; ++v, ++digits)
                thousandths = 10 * thousandths + (*v - '0');
            for (int d = digits; d < 3; ++d)
                thousandths *= 10;
        }
        if (v != value_end || (whole == 1 && thousandths != 0))
            return -1;
        weight = whole * 1000 + thousandths;
        p = param_end;
    }
    return weight;
}

bool ms_http_accepts_coding(const char *header, const char *coding)
{
    if (!header)
        return false;
    size_t coding_length = strlen(coding);
    int named = -2, star = -2; /* -2: not listed */
    const char *p = header;
    while (*p) {
        while (*p == ',' || is_space_or_tab(*p))
            ++p;
        if (!*p)
            break;
        const char *element_end = p + strcspn(p, ",");
        const char *name_end = p;
        while (name_end < element_end && *name_end != ';' && !is_space_or_tab(*name_end))
            ++name_end;
        int weight = coding_weight(name_end, element_end);
        size_t n = (size_t)(name_end - p);
        if (n == 1 && *p == '*')
            star = weight;
        else if (n == coding_length && !strncasecmp(p, coding, n))
            named = weight;
        p = element_end;
    }
    if (named != -2)
        return named > 0;
    return star > 0;
}
