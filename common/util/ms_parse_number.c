#include "ms_parse_number.h"

#include <math.h>
#include <stdlib.h>

/* Powers of ten that are exact doubles. */
static const double exact_powers_of_ten[23] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

/* Steps over an optional sign; true when it was a minus. */
static inline bool skip_sign(const char **p)
{
    if (**p == '-') {
        ++*p;
        return true;
    }
    if (**p == '+')
        ++*p;
    return false;
}

/* Appends the decimal digits at p to *value (wrapping past 19 of them: the
 * callers count the digits); returns the first non-digit. */
static inline const char *accumulate_digits(const char *p, uint64_t *value)
{
    uint64_t v = *value;
    while ((unsigned)(*p - '0') < 10)
        v = v * 10 + (unsigned)(*p++ - '0');
    *value = v;
    return p;
}

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
    bool negative = skip_sign(&p);
    /* Accumulate every digit; with at most 19 of them the mantissa cannot wrap
     * (more go to strtod). Leading zeros cost nothing numerically. */
    uint64_t mantissa = 0;
    const char *digits = p;
    p = accumulate_digits(p, &mantissa);
    long digit_count = p - digits;
    int exponent = 0;
    if (*p == '.') {
        const char *fraction = ++p;
        p = accumulate_digits(p, &mantissa);
        digit_count += p - fraction;
        exponent = -(int)(p - fraction > 100000 ? 100000 : p - fraction);
    }
    if (digit_count == 0 || digit_count > 19)
        return parse_double_slow(s, out);
    if (*p == 'e' || *p == 'E') {
        const char *q = p + 1;
        bool exp_negative = skip_sign(&q);
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
    } else if (mantissa <= (UINT64_C(1) << 53) && exponent >= -22 && exponent <= 22) {
        /* Clinger's fast path: both operands exact, so one rounding. */
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
    bool negative = skip_sign(&p);
    const char *digits = p;
    uint64_t v = 0;
    p = accumulate_digits(p, &v);
    long count = p - digits;
    if (count == 0)
        return NULL;
    if (count >= 19) {
        /* Might have wrapped: redo with overflow checks (rare). */
        while (*digits == '0' && count > 1) {
            ++digits;
            --count;
        }
        v = 0;
        for (const char *q = digits; q < p; ++q)
            if (__builtin_mul_overflow(v, 10, &v) ||
                __builtin_add_overflow(v, (uint64_t)(*q - '0'), &v))
                return NULL;
    }
    if (v > (uint64_t)INT64_MAX + (negative ? 1 : 0))
        return NULL;
    if (negative)
        *out = v == (uint64_t)INT64_MAX + 1 ? INT64_MIN : -(int64_t)v;
    else
        *out = (int64_t)v;
    return p;
}

ms_status ms_option_int(const char *name, const char *text, int64_t min, int64_t max,
                        int64_t *out, ms_error *err)
{
    int64_t v;
    const char *end = ms_parse_int64(text, &v);
    if (!end || *end || v < min || v > max)
        return ms_error_set(err, MS_ERR_RANGE, "%s wants an integer in [%lld, %lld], got '%.200s'",
                            name, (long long)min, (long long)max, text);
    *out = v;
    return MS_OK;
}

ms_status ms_option_double(const char *name, const char *text, double min, double max,
                           double *out, ms_error *err)
{
    double v;
    const char *end = ms_parse_double(text, &v);
    if (!end || *end || !isfinite(v) || v < min || v > max)
        return ms_error_set(err, MS_ERR_RANGE, "%s wants a number in [%.10g, %.10g], got '%.200s'", name,
                            min, max, text);
    *out = v;
    return MS_OK;
}
