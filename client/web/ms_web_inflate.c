/* Inflating one zlib stream: see ms_web_inflate.h. */
#include "ms_web_inflate.h"

#include <stdbool.h>
#include <stdlib.h>
#include <string.h>

#define MAX_BITS 15
#define LITLEN_CODES 288
#define DIST_CODES 32

/* A canonical Huffman code: how many codes of each length, and the symbols
 * in the order of their codes (by length, then by symbol). */
typedef struct code {
    unsigned longest; /* the longest code's length (0: no code) */
    uint16_t count[MAX_BITS + 1];
    uint16_t symbol[LITLEN_CODES];
} code;

typedef struct reader {
    const uint8_t *in;
    size_t size, at;      /* the input and the next byte to load */
    uint32_t bits;        /* loaded bits not yet used, lowest first */
    unsigned have;        /* how many */
    uint8_t *out;
    size_t length, room, max;
    ms_web_inflate_result fault;
    const char *why;
} reader;

static bool fault(reader *r, ms_web_inflate_result what, const char *why)
{
    if (r->fault == MS_WEB_INFLATE_OK) {
        r->fault = what;
        r->why = why;
    }
    return false;
}

/* The next n (0..16) bits, lowest first; false at the input's end. */
static bool take(reader *r, unsigned n, unsigned *value)
{
    while (r->have < n) {
        if (r->at == r->size)
            return fault(r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
        r->bits |= (uint32_t)r->in[r->at++] << r->have;
        r->have += 8;
    }
    *value = r->bits & ((1u << n) - 1u);
    r->bits >>= n;
    r->have -= n;
    return true;
}

static bool put(reader *r, uint8_t byte)
{
    if (r->length == r->room) {
        if (r->length == r->max)
            return fault(r, MS_WEB_INFLATE_TOO_BIG, "it inflates to more than the room allowed");
        size_t room = r->room ? 2 * r->room : 4096;
        if (room > r->max || room < r->room)
            room = r->max;
        uint8_t *grown = realloc(r->out, room);
        if (!grown)
            return fault(r, MS_WEB_INFLATE_NOMEM, "out of memory inflating");
        r->out = grown;
        r->room = room;
    }
    r->out[r->length++] = byte;
    return true;
}

/* What a code is for, which decides the incomplete codes it may be (zlib's
 * rule, so that both inflaters take the same streams: tests/fuzz/
 * fuzz_web_inflate.c). */
typedef enum code_kind {
    CODE_FIXED,   /* the fixed block's, built here: its distance code leaves two codes out */
    CODE_LENGTHS, /* a dynamic block's code of code lengths: complete, or no code at all */
    CODE_DATA     /* a dynamic block's literal/length or distance code: complete, no code at
                     all, or a single code of one bit */
} code_kind;

/* Builds the code of `n` symbols from their lengths (0: unused). Over-
 * subscribed lengths are refused, and incomplete ones but where `kind`
 * allows them; a code not in an incomplete code fails when read. */
static bool build(reader *r, code *c, const uint8_t *lengths, unsigned n, code_kind kind)
{
    memset(c->count, 0, sizeof c->count);
    for (unsigned s = 0; s < n; ++s)
        c->count[lengths[s]]++;
    int left = 1;
    unsigned longest = 0;
    for (unsigned len = 1; len <= MAX_BITS; ++len) {
        left = 2 * left - c->count[len];
        if (left < 0)
            return fault(r, MS_WEB_INFLATE_BAD, "a Huffman code has too many codes of a length");
        if (c->count[len])
            longest = len;
    }
    if (left > 0 && longest > 0 && kind != CODE_FIXED && (kind == CODE_LENGTHS || longest != 1))
        return fault(r, MS_WEB_INFLATE_BAD, "an incomplete Huffman code");
    c->longest = longest;
    uint16_t first[MAX_BITS + 1];
    first[1] = 0;
    for (unsigned len = 1; len < MAX_BITS; ++len)
        first[len + 1] = (uint16_t)(first[len] + c->count[len]);
    for (unsigned s = 0; s < n; ++s)
        if (lengths[s])
            c->symbol[first[lengths[s]]++] = (uint16_t)s;
    c->count[0] = 0;
    return true;
}

/* Reads one symbol of code c, a bit at a time: the codes of each length are
 * consecutive numbers, the first of them following the last of the length
 * before, doubled. Bits that no code of c starts with fail once the longest
 * code's length is read (no further bit is asked for, as zlib does). */
static bool decode(reader *r, const code *c, unsigned *symbol)
{
    int value = 0, first = 0, index = 0;
    for (unsigned len = 1; len <= c->longest; ++len) {
        unsigned bit;
        if (!take(r, 1, &bit))
            return false;
        value |= (int)bit;
        int count = c->count[len];
        if (value - first < count) {
            *symbol = c->symbol[index + value - first];
            return true;
        }
        index += count;
        first = (first + count) << 1;
        value <<= 1;
    }
    return fault(r, MS_WEB_INFLATE_BAD, "a code not in the block's Huffman code");
}

static const uint16_t length_base[29] = {3,  4,  5,  6,  7,  8,  9,  10, 11,  13,  15,  17,  19,  23, 27,
                                         31, 35, 43, 51, 59, 67, 83, 99, 115, 131, 163, 195, 227, 258};
static const uint8_t length_extra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                         2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};
static const uint16_t dist_base[30] = {1,    2,    3,    4,    5,    7,     9,     13,    17,  25,
                                       33,   49,   65,   97,   129,  193,   257,   385,   513, 769,
                                       1025, 1537, 2049, 3073, 4097, 6145, 8193, 12289, 16385, 24577};
static const uint8_t dist_extra[30] = {0, 0, 0, 0, 1, 1, 2, 2,  3,  3,  4,  4,  5,  5,  6,
                                       6, 7, 7, 8, 8, 9, 9, 10, 10, 11, 11, 12, 12, 13, 13};

/* A block's data, literals and copies, up to its end code. */
static bool codes(reader *r, const code *litlen, const code *dist)
{
    for (;;) {
        unsigned s;
        if (!decode(r, litlen, &s))
            return false;
        if (s < 256) {
            if (!put(r, (uint8_t)s))
                return false;
            continue;
        }
        if (s == 256)
            return true;
        s -= 257;
        if (s >= 29)
            return fault(r, MS_WEB_INFLATE_BAD, "a length code out of range");
        unsigned extra, d;
        if (!take(r, length_extra[s], &extra))
            return false;
        unsigned length = length_base[s] + extra;
        if (!decode(r, dist, &d))
            return false;
        if (d >= 30)
            return fault(r, MS_WEB_INFLATE_BAD, "a distance code out of range");
        if (!take(r, dist_extra[d], &extra))
            return false;
        size_t distance = dist_base[d] + extra;
        if (distance > r->length)
            return fault(r, MS_WEB_INFLATE_BAD, "a distance back past the start of the output");
        for (unsigned k = 0; k < length; ++k)
            if (!put(r, r->out[r->length - distance]))
                return false;
    }
}

static bool stored(reader *r)
{
    r->bits = 0; /* to the byte's end: fewer than 8 bits are left */
    r->have = 0;
    if (r->size - r->at < 4)
        return fault(r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
    unsigned length = r->in[r->at] | (unsigned)r->in[r->at + 1] << 8;
    unsigned check = r->in[r->at + 2] | (unsigned)r->in[r->at + 3] << 8;
    r->at += 4;
    if (length != (~check & 0xFFFFu))
        return fault(r, MS_WEB_INFLATE_BAD, "a stored block's length and its complement disagree");
    for (unsigned k = 0; k < length; ++k) {
        if (r->at == r->size)
            return fault(r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
        if (!put(r, r->in[r->at++]))
            return false;
    }
    return true;
}

static bool fixed(reader *r)
{
    uint8_t lengths[LITLEN_CODES];
    for (unsigned s = 0; s < LITLEN_CODES; ++s)
        lengths[s] = s < 144 ? 8 : s < 256 ? 9 : s < 280 ? 7 : 8;
    code litlen, dist;
    build(r, &litlen, lengths, LITLEN_CODES, CODE_FIXED);
    memset(lengths, 5, DIST_CODES);
    build(r, &dist, lengths, DIST_CODES, CODE_FIXED);
    return codes(r, &litlen, &dist);
}

static bool dynamic(reader *r)
{
    static const uint8_t order[19] = {16, 17, 18, 0, 8, 7, 9, 6, 10, 5, 11, 4, 12, 3, 13, 2, 14, 1, 15};
    unsigned nlen, ndist, ncode;
    if (!take(r, 5, &nlen) || !take(r, 5, &ndist) || !take(r, 4, &ncode))
        return false;
    nlen += 257;
    ndist += 1;
    ncode += 4;
    if (nlen > 286 || ndist > 30)
        return fault(r, MS_WEB_INFLATE_BAD, "a block declares too many codes");
    uint8_t lengths[LITLEN_CODES + DIST_CODES];
    memset(lengths, 0, 19);
    for (unsigned k = 0; k < ncode; ++k) {
        unsigned len;
        if (!take(r, 3, &len))
            return false;
        lengths[order[k]] = (uint8_t)len;
    }
    code lencode, litlen, dist;
    if (!build(r, &lencode, lengths, 19, CODE_LENGTHS))
        return false;
    for (unsigned k = 0; k < nlen + ndist;) {
        unsigned s, repeat, extra;
        if (!decode(r, &lencode, &s))
            return false;
        if (s < 16) {
            lengths[k++] = (uint8_t)s;
            continue;
        }
        uint8_t value = 0;
        if (s == 16) {
            if (k == 0)
                return fault(r, MS_WEB_INFLATE_BAD, "a repeat of no length before it");
            value = lengths[k - 1];
            if (!take(r, 2, &extra))
                return false;
            repeat = 3 + extra;
        } else if (s == 17) {
            if (!take(r, 3, &extra))
                return false;
            repeat = 3 + extra;
        } else {
            if (!take(r, 7, &extra))
                return false;
            repeat = 11 + extra;
        }
        if (k + repeat > nlen + ndist)
            return fault(r, MS_WEB_INFLATE_BAD, "code lengths repeated past their count");
        while (repeat--)
            lengths[k++] = value;
    }
    if (lengths[256] == 0)
        return fault(r, MS_WEB_INFLATE_BAD, "a block without an end code");
    if (!build(r, &litlen, lengths, nlen, CODE_DATA) || !build(r, &dist, lengths + nlen, ndist, CODE_DATA))
        return false;
    return codes(r, &litlen, &dist);
}

static uint32_t adler32(const uint8_t *p, size_t n)
{
    uint32_t a = 1, b = 0;
    while (n > 0) {
        size_t run = n < 5552 ? n : 5552; /* no overflow before the modulo */
        n -= run;
        while (run--) {
            a += *p++;
            b += a;
        }
        a %= 65521u;
        b %= 65521u;
    }
    return b << 16 | a;
}

ms_web_inflate_result ms_web_inflate(const uint8_t *in, size_t in_size, size_t max_out,
                                     uint8_t **out, size_t *out_size, size_t *used,
                                     const char **why)
{
    reader r = {.in = in, .size = in_size, .max = max_out, .fault = MS_WEB_INFLATE_OK, .why = ""};
    if (in_size < 2) {
        fault(&r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
    } else if ((in[0] & 0x0F) != 8 || in[0] >> 4 > 7 || (in[0] << 8 | in[1]) % 31 != 0) {
        fault(&r, MS_WEB_INFLATE_BAD, "incorrect header check");
    } else if ((in[1] & 0x20) && in_size < 6) { /* zlib reads the dictionary's id first */
        fault(&r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
    } else if (in[1] & 0x20) {
        fault(&r, MS_WEB_INFLATE_DICT, "it needs a preset dictionary");
    } else {
        r.at = 2;
        unsigned last = 0;
        while (!last) {
            unsigned type;
            if (!take(&r, 1, &last) || !take(&r, 2, &type))
                break;
            bool ok = type == 0   ? stored(&r)
                      : type == 1 ? fixed(&r)
                      : type == 2 ? dynamic(&r)
                                  : fault(&r, MS_WEB_INFLATE_BAD, "a block of reserved type 3");
            if (!ok)
                break;
        }
        if (r.fault == MS_WEB_INFLATE_OK) {
            r.bits = 0;
            r.have = 0;
            if (r.size - r.at < 4)
                fault(&r, MS_WEB_INFLATE_SHORT, "the input ends inside the stream");
            else {
                const uint8_t *t = in + r.at;
                uint32_t want = (uint32_t)t[0] << 24 | (uint32_t)t[1] << 16 | (uint32_t)t[2] << 8 | t[3];
                r.at += 4;
                if (want != adler32(r.out, r.length))
                    fault(&r, MS_WEB_INFLATE_BAD, "incorrect data check");
            }
        }
    }
    *out = r.out;
    *out_size = r.length;
    *used = r.at;
    *why = r.fault == MS_WEB_INFLATE_OK ? "" : r.why;
    return r.fault;
}
