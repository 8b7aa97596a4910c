/* libFuzzer target on the APO chunk readers (common/apo/ms_apo_chunk.c,
 * ms_apo_stream.c, ms_apo_blob.c, ms_apo_traverse.c): what a client does with
 * the APO bytes of a cell and the level table of the index, and what it does
 * with the words of a partly received chunk.
 *
 * Input: byte 0 chooses the path (modulo 3), the rest is
 *   0 "words":  byte 1 = level count L, then L little-endian words (words per
 *               level), then texel words: ms_apo_view_init over them;
 *   1 "stream": byte 1 = L, then 2 L words (the stored level table: compressed
 *               end and texels so far, per level), 4 bytes = how many of the
 *               following bytes were received, then the stored (zlib) bytes:
 *               ms_apo_stream_inflate of that prefix, then ms_apo_view_init;
 *   2 "blob":   the rest is a stored chunk for ms_apo_blob_read.
 * A view that loads is decoded (ms_apo_view_decode) and traversed at points
 * drawn from the input, with both missing-child rules.
 *
 * Besides the sanitizers, the target checks the readers' contract and aborts
 * when it is broken: a refusal leaves a one-line error and nothing owned; a
 * view has no more complete levels than its table and no more words than its
 * total; a decoded tree passes ms_apo_tree_check with one level per complete
 * level; a lookup stops on a word inside the received ones at a depth within
 * the complete levels (EMPTY exactly when none is complete), with a unit
 * normal, or 0 where it is "smooth" (no texel: EMPTY, a missing child, a mean
 * word MS_APO_NORMAL_SMOOTH).
 *
 * tests/test_fuzz_replay.c includes this file to replay tests/corpus/apo_chunk/
 * in `make test` through ms_fuzz_apo_chunk_one(). Its seeds (seed-*-ok
 * accepted, the other seed-* refused) were made from ms_test_random_tree
 * trees, encoded by ms_apo_chunk_encode, ms_apo_stream_compress and
 * ms_apo_blob_write; the blob seeds were re-marked for blob version 2 (bytes
 * 4-5 and the header CRC rewritten: the words are valid in both versions),
 * seed-blob-version-1 keeps a version-1 blob (refused), seed-words-smooth-ok
 * has mean words MS_APO_NORMAL_SMOOTH and seed-words-smooth-leaf a leaf with
 * that code (refused). */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_apo_blob.h"
#include "ms_apo_chunk.h"
#include "ms_apo_stream.h"
#include "ms_apo_traverse.h"
#include "ms_apo_tree.h"

#define MS_FUZZ_APO_CHECK(cond)                                                                \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_apo_chunk: contract broken: %s (%s:%d)\n", #cond, __FILE__,  \
                    __LINE__);                                                                 \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

static uint32_t ms_fuzz_apo_le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void ms_fuzz_apo_refused(const ms_error *err)
{
    MS_FUZZ_APO_CHECK(err->text[0] != '\0' && !strchr(err->text, '\n'));
}

static bool ms_fuzz_apo_chunk_zero(const ms_apo_chunk *c)
{
    return c->texels == NULL && c->texel_count == 0 && c->level_count == 0;
}

/* Decodes and traverses a loaded view. */
static void ms_fuzz_apo_use_view(const ms_apo_view *view, const uint8_t *data, size_t size)
{
    MS_FUZZ_APO_CHECK(view->complete_levels <= view->level_count);
    MS_FUZZ_APO_CHECK(view->texel_count <= view->total_texels);
    for (uint32_t d = 0; d < view->level_count; ++d)
        MS_FUZZ_APO_CHECK(view->level_start[d] <= view->level_start[d + 1]);
    ms_apo_tree tree;
    memset(&tree, 0, sizeof tree);
    ms_error err;
    ms_error_clear(&err);
    if (ms_apo_view_decode(view, &tree, &err) == MS_OK) {
        ms_error check;
        MS_FUZZ_APO_CHECK(ms_apo_tree_check(&tree, &check) == MS_OK);
        MS_FUZZ_APO_CHECK(tree.level_count == view->complete_levels);
        ms_apo_tree_free(&tree);
    } else {
        ms_fuzz_apo_refused(&err);
    }
    /* points from the input's bytes (a fixed walk when it is short) */
    uint64_t x = 0x9E3779B97F4A7C15ull ^ size;
    for (size_t i = 0; i < size && i < 64; ++i)
        x = (x ^ data[i]) * 0x100000001B3ull;
    for (int k = 0; k < 8; ++k) {
        uint32_t fixed[3];
        for (int a = 0; a < 3; ++a) {
            x ^= x >> 29;
            x *= 0xBF58476D1CE4E5B9ull;
            x ^= x >> 32;
            fixed[a] = (uint32_t)x;
        }
        uint32_t cap = (uint32_t)(x >> 8) % (MS_APO_MAX_LEVELS + 1);
        ms_apo_missing_rule rule = k & 1 ? MS_APO_MISSING_NEAREST : MS_APO_MISSING_STOP;
        ms_apo_lookup_result r;
        ms_apo_stop stop = ms_apo_lookup_fixed(view, fixed, cap, rule, &r);
        MS_FUZZ_APO_CHECK(stop == r.stop);
        if (view->complete_levels == 0) {
            MS_FUZZ_APO_CHECK(stop == MS_APO_STOP_EMPTY);
            MS_FUZZ_APO_CHECK(r.normal[0] == 0 && r.normal[1] == 0 && r.normal[2] == 0);
            continue;
        }
        MS_FUZZ_APO_CHECK(stop != MS_APO_STOP_EMPTY);
        MS_FUZZ_APO_CHECK(r.word < view->texel_count);
        MS_FUZZ_APO_CHECK(r.depth < view->complete_levels && r.depth <= cap);
        float n2 = r.normal[0] * r.normal[0] + r.normal[1] * r.normal[1] + r.normal[2] * r.normal[2];
        if (r.smooth) /* no texel: the caller's smooth normal */
            MS_FUZZ_APO_CHECK(n2 == 0.0f && r.code == MS_APO_NORMAL_SMOOTH);
        else
            MS_FUZZ_APO_CHECK(fabsf(n2 - 1.0f) < 1e-3f);
    }
}

/* Returns true when the input was accepted (a view loaded, or a blob read). */
static bool ms_fuzz_apo_chunk_one(const uint8_t *data, size_t size)
{
    if (size < 1)
        return false;
    unsigned mode = data[0] % 3;
    data++, size--;
    ms_error err;
    ms_error_clear(&err);
    ms_apo_chunk chunk;
    memset(&chunk, 0, sizeof chunk);
    ms_apo_view view;
    bool accepted = false;
    if (mode == 2) {
        if (ms_apo_blob_read(data, size, &chunk, &err) != MS_OK) {
            ms_fuzz_apo_refused(&err);
            MS_FUZZ_APO_CHECK(ms_fuzz_apo_chunk_zero(&chunk));
            return false;
        }
        MS_FUZZ_APO_CHECK(ms_apo_view_of_chunk(&view, &chunk, &err) == MS_OK);
        MS_FUZZ_APO_CHECK(view.complete_levels == view.level_count);
        ms_fuzz_apo_use_view(&view, data, size);
        ms_apo_chunk_free(&chunk);
        return true;
    }
    if (size < 1)
        return false;
    uint32_t levels = data[0];
    data++, size--;
    uint32_t table_words = mode == 0 ? levels : 2 * levels;
    if (size < 4 * (size_t)table_words + (mode == 1 ? 4 : 0))
        return false;
    uint32_t table[2 * 256];
    for (uint32_t i = 0; i < table_words; ++i)
        table[i] = ms_fuzz_apo_le32(data + 4 * i);
    data += 4 * (size_t)table_words, size -= 4 * (size_t)table_words;
    if (mode == 0) {
        size_t count = size / 4;
        uint32_t *words = malloc(count ? count * sizeof *words : 1);
        if (!words)
            return false;
        for (size_t i = 0; i < count; ++i)
            words[i] = ms_fuzz_apo_le32(data + 4 * i);
        if (ms_apo_view_init(&view, table, levels, words, count, &err) == MS_OK) {
            ms_fuzz_apo_use_view(&view, data, size);
            accepted = true;
        } else {
            ms_fuzz_apo_refused(&err);
        }
        free(words);
        return accepted;
    }
    size_t received = ms_fuzz_apo_le32(data);
    data += 4, size -= 4;
    if (received > size)
        received = size;
    if (ms_apo_stream_inflate(data, received, table, levels, &chunk, &err) != MS_OK) {
        ms_fuzz_apo_refused(&err);
        MS_FUZZ_APO_CHECK(ms_fuzz_apo_chunk_zero(&chunk));
        return false;
    }
    if (ms_apo_view_init(&view, chunk.level_texels, chunk.level_count, chunk.texels,
                         chunk.texel_count, &err) == MS_OK) {
        ms_fuzz_apo_use_view(&view, data, size);
        accepted = true;
    } else {
        ms_fuzz_apo_refused(&err);
    }
    ms_apo_chunk_free(&chunk);
    return accepted;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_apo_chunk_one(data, size);
    return 0;
}
#endif
