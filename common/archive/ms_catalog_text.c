/* catalog.json's text cut into entry spans: see ms_catalog_internal.h. */
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#include "ms_catalog_internal.h"

typedef struct cursor {
    const char *text;
    size_t size, at;
} cursor;

static void skip_space(cursor *c)
{
    while (c->at < c->size && (c->text[c->at] == ' ' || c->text[c->at] == '\t' ||
                               c->text[c->at] == '\n' || c->text[c->at] == '\r'))
        c->at++;
}

/* Consumes token (after whitespace); false when the text differs. */
static bool expect(cursor *c, const char *token)
{
    skip_space(c);
    size_t n = strlen(token);
    if (c->size - c->at < n || memcmp(c->text + c->at, token, n) != 0)
        return false;
    c->at += n;
    return true;
}

/* Consumes one balanced object starting at '{'; its span in *span. */
static bool object_span(cursor *c, ms_catalog_span *span)
{
    skip_space(c);
    if (c->at >= c->size || c->text[c->at] != '{')
        return false;
    size_t start = c->at, depth = 0;
    bool in_string = false;
    for (; c->at < c->size; ++c->at) {
        char ch = c->text[c->at];
        if (in_string) {
            if (ch == '\\')
                ++c->at; /* the escaped character, whatever it is */
            else if (ch == '"')
                in_string = false;
            continue;
        }
        if (ch == '"') {
            in_string = true;
        } else if (ch == '{' || ch == '[') {
            ++depth;
        } else if (ch == '}' || ch == ']') {
            if (--depth == 0) {
                ++c->at;
                span->offset = start;
                span->length = c->at - start;
                return true;
            }
        }
    }
    return false;
}

int ms_catalog_cut_spans(const char *text, size_t size, size_t max_count, ms_catalog_span **spans,
                         size_t *count)
{
    *spans = NULL;
    *count = 0;
    cursor c = {text, size, 0};
    if (!expect(&c, "{") || !expect(&c, "\"models\"") || !expect(&c, ":") || !expect(&c, "["))
        return -1;
    size_t cap = 0, n = 0;
    ms_catalog_span *out = NULL;
    bool ok = true;
    if (!expect(&c, "]")) {
        for (;;) {
            ms_catalog_span span;
            if (n == max_count || !object_span(&c, &span)) {
                ok = false;
                break;
            }
            if (n == cap) {
                size_t grown = cap ? 2 * cap : 256;
                ms_catalog_span *bigger = realloc(out, grown * sizeof *out);
                if (!bigger) {
                    ok = false;
                    break;
                }
                out = bigger;
                cap = grown;
            }
            out[n++] = span;
            if (expect(&c, "]"))
                break;
            if (!expect(&c, ",")) {
                ok = false;
                break;
            }
        }
    }
    ok = ok && expect(&c, ",") && expect(&c, "\"version\"") && expect(&c, ":") &&
         expect(&c, "1") && expect(&c, "}");
    skip_space(&c);
    if (!ok || c.at != c.size) {
        free(out);
        return -1;
    }
    *spans = out;
    *count = n;
    return 0;
}

uint64_t ms_catalog_span_hash(const char *text, ms_catalog_span span)
{
    uint64_t hash = 1469598103934665603ull;
    for (size_t i = 0; i < span.length; ++i)
        hash = (hash ^ (unsigned char)text[span.offset + i]) * 1099511628211ull;
    return hash ? hash : 1;
}
