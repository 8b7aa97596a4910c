#include "ms_parse_number.h"

#include <stdlib.h>

/* Powers of ten that are exact doubles. */
static const double exact_powers_of_ten[23] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

static const char *parse_double_slow(const char *s, double *out)
{
    char *end = NULL;
    double v = strtod(s, &end);
    if (end == s || !ms_is_token_end(*end))
        return NULL;
    *out = v;
    return end;
}

const char *ms_parse_double(const char *s, double *out)
{
    const char *p = s;
    bool negative = false;
    if (*p == '-') {
        negative = true;
        ++p;
    } else if (*p == '+') {
        ++p;
    }
    uint64_t mantissa = 0;
    int significant = 0;
    int exponent = 0;
    bool any_digit = false;
    bool inexact = false;
    for (; (unsigned)(*p - '0') < 10; ++p) {
        unsigned d = (unsigned)(*p - '0');
        any_digit = true;
        if (mantissa == 0 && d == 0)
            continue; /* leading zero */
        if (significant < 19) {
            mantissa = mantissa * 10 + d;
            ++significant;
        } else {
            ++exponent;
            inexact = true;
        }
    }
    if (*p == '.') {
        ++p;
        for (; (unsigned)(*p - '0') < 10; ++p) {
            unsigned d = (unsigned)(*p - '0');
            any_digit = true;
            if (mantissa == 0 && d == 0) {
                --exponent;
            } else if (significant < 19) {
                mantissa = mantissa * 10 + d;
                ++significant;
                --exponent;
            } else {
                inexact = true;
            }
        }
    }
    if (!any_digit)
        return parse_double_slow(s, out);
    if (*p == 'e' || *p == 'E') {
        const char *q = p + 1;
        bool exp_negative = false;
        if (*q == '-') {
            exp_negative = true;
            ++q;
        } else if (*q == '+') {
            ++q;
        }
        if ((unsigned)(*q - '0') >= 10)
            return parse_double_slow(s, out);
        int e = 0;
        for (; (unsigned)(*q - '0') < 10; ++q)
            if (e < 100000)
                e = e * 10 + (*q - '0');
        exponent += exp_negative ? -e : e;
        p = q;
    }
    if (!ms_is_token_end(*p))
        return parse_double_slow(s, out);
    double v;
    if (mantissa == 0) {
        v = 0.0;
    } else if (!inexact && mantissa <= (UINT64_C(1) << 53) && exponent >= -22 &&
               exponent <= 22) {
        v = (double)mantissa;
        v = exponent < 0 ? v / exact_powers_of_ten[-exponent] : v * exact_powers_of_ten[exponent];
    } else {
        return parse_double_slow(s, out);
    }
    *out = negative ? -v : v;
    return p;
}

const char *ms_parse_int64(const char *s, int64_t *out)
{
    const char *p = s;
    bool negative = false;
    if (*p == '-') {
        negative = true;
        ++p;
    } else if (*p == '+') {
        ++p;
    }
    if ((unsigned)(*p - '0') >= 10)
        return NULL;
    uint64_t v = 0;
    const uint64_t limit = negative ? (uint64_t)INT64_MAX + 1 : (uint64_t)INT64_MAX;
    for (; (unsigned)(*p - '0') < 10; ++p) {
        unsigned d = (unsigned)(*p - '0');
        if (v > (limit - d) / 10)
            return NULL;
        v = v * 10 + d;
    }
    if (negative)
        *out = v == (uint64_t)INT64_MAX + 1 ? INT64_MIN : -(int64_t)v;
    else
        *out = (int64_t)v;
    return p;
}
