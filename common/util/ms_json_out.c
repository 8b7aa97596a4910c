/* JSON reports through jansson: see ms_json_out.h. */
#include "ms_json_out.h"

#include <assert.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Length of the valid UTF-8 sequence starting at s (1..4), or 0 when the bytes
 * there are not one (overlong forms, surrogates and code points past U+10FFFF
 * included, as jansson refuses them too). */
static size_t utf8_sequence_length(const unsigned char *s)
{
    unsigned char c = s[0];
    if (c < 0x80)
        return 1;
    size_t n;
    unsigned long cp;
    if (c >= 0xC2 && c <= 0xDF) {
        n = 2;
        cp = c & 0x1F;
    } else if (c >= 0xE0 && c <= 0xEF) {
        n = 3;
        cp = c & 0x0F;
    } else if (c >= 0xF0 && c <= 0xF4) {
        n = 4;
        cp = c & 0x07;
    } else {
        return 0;
    }
    for (size_t i = 1; i < n; ++i) {
        if ((s[i] & 0xC0) != 0x80) /* also stops at the terminating NUL */
            return 0;
        cp = (cp << 6) | (s[i] & 0x3F);
    }
    if ((n == 3 && cp < 0x800) || (n == 4 && cp < 0x10000) || (cp >= 0xD800 && cp <= 0xDFFF) ||
        cp > 0x10FFFF)
        return 0;
    return n;
}

json_t *ms_json_text(const char *s)
{
    if (!s)
        return json_null();
    const unsigned char *in = (const unsigned char *)s;
    size_t len = strlen(s);
    /* Each invalid byte becomes the three bytes of U+FFFD. */
    char *clean = malloc(3 * len + 1);
    if (!clean)
        return NULL;
    size_t out = 0;
    for (size_t i = 0; i < len;) {
        size_t n = utf8_sequence_length(in + i);
        if (n == 0) {
            memcpy(clean + out, "\xEF\xBF\xBD", 3);
            out += 3;
            i += 1;
        } else {
            memcpy(clean + out, in + i, n);
            out += n;
            i += n;
        }
    }
    json_t *text = json_stringn(clean, out);
    free(clean);
    return text;
}

json_t *ms_json_number(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

json_t *ms_json_fixed(double v, int decimals)
{
    static const double scale[] = {1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9};
    assert(decimals >= 0 && decimals <= 9);
    if (!isfinite(v))
        return json_null();
    double scaled = round(v * scale[decimals]);
    return json_real(fabs(scaled) < 9e15 ? scaled / scale[decimals] : v);
}

int ms_json_print(FILE *out, json_t *root, int layout)
{
    if (!root)
        return -1;
    size_t flags = JSON_REAL_PRECISION(layout & MS_JSON_EXACT ? 17 : 15);
    if (layout & MS_JSON_COMPACT)
        flags |= JSON_COMPACT;
    char *text = json_dumps(root, flags);
    json_decref(root);
    if (!text)
        return -1;
    int rc = fprintf(out, "%s\n", text) < 0 ? -1 : 0;
    free(text);
    return rc;
}
