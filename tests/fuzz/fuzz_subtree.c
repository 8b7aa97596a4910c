/* libFuzzer target on the partial index (common/archive/ms_archive_partial.c,
 * ms_subtree_read.c): ms_archive_open_head and ms_archive_add_subtree, what a
 * client does with the index head and the stored subtrees a server (or a
 * static tree's models/NAME.head and models/NAME/subtrees/ID) sends it.
 *
 * Input: u32 head length L (little-endian, clamped to what follows), the head
 * (L bytes), then any number of steps: u32 word W; bit 31 set: drop subtree
 * W & 0x3FFFFFFF; else u32 length N (clamped) and N bytes added as subtree
 * W & 0x3FFFFFFF: the stored bytes as they are, or with bit 30 set, a raw blob
 * that the target deflates first (ms_subtree_deflate), so that mutations reach
 * the blob's own checks behind zlib.
 *
 * Besides the sanitizers, the target checks the partial index's contract and
 * aborts when it is broken: a refused head leaves no archive and a one-line
 * error; a refused subtree leaves the subtrees and bytes held as they were,
 * with a one-line error; an added subtree is held; after every step each cell
 * (of the first 1024) is held or not consistently (a held cell has its
 * parent held, prefixes that grow and stay within the stored lengths; a cell
 * not held reads NULL and prefix 0); a partial archive never has an index
 * blob or payloads.
 *
 * tests/test_fuzz_replay.c includes this file to replay tests/corpus/subtree/
 * in `make test`; it then calls ms_fuzz_subtree_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive.h"
#include "ms_subtree.h"

#define MS_FUZZ_SUBTREE_CHECK(cond)                                                            \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_subtree: contract broken: %s (%s:%d)\n", #cond, __FILE__,   \
                    __LINE__);                                                                 \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

static uint32_t ms_fuzz_subtree_u32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void ms_fuzz_subtree_check_cells(const ms_archive *a)
{
    const ms_archive_header *h = ms_archive_get_header(a);
    MS_FUZZ_SUBTREE_CHECK(ms_archive_get_cell(a, h->cell_count) == NULL);
    size_t size;
    MS_FUZZ_SUBTREE_CHECK(ms_archive_index_bytes(a, &size) == NULL && size == 0);
    MS_FUZZ_SUBTREE_CHECK(ms_archive_get_cell(a, 0) != NULL); /* the root subtree stays */
    for (uint32_t cell = 0; cell < h->cell_count && cell < 1024; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        if (!c) {
            MS_FUZZ_SUBTREE_CHECK(ms_archive_geometry_prefix(a, cell, 30) == 0);
            MS_FUZZ_SUBTREE_CHECK(ms_archive_apo_prefix(a, cell, 30, NULL) == 0);
            continue;
        }
        MS_FUZZ_SUBTREE_CHECK(cell == 0 || ms_archive_get_cell(a, c->parent) != NULL);
        uint32_t previous = 0;
        for (unsigned bits = 0; bits <= 24; ++bits) {
            uint32_t p = ms_archive_geometry_prefix(a, cell, bits);
            MS_FUZZ_SUBTREE_CHECK(p >= previous && p <= c->geometry_length);
            previous = p;
        }
        previous = 0;
        for (unsigned level = 0; level <= 34; ++level) {
            uint32_t p = ms_archive_apo_prefix(a, cell, level, NULL);
            MS_FUZZ_SUBTREE_CHECK(p >= previous && p <= c->apo_length);
            previous = p;
        }
        MS_FUZZ_SUBTREE_CHECK(ms_archive_geometry(a, cell, &size) == NULL);
    }
}

/* Returns true when the head and every subtree added were accepted. */
static bool ms_fuzz_subtree_one(const uint8_t *data, size_t size)
{
    if (size < 4)
        return false;
    size_t head_size = ms_fuzz_subtree_u32(data);
    data += 4, size -= 4;
    if (head_size > size)
        head_size = size;
    ms_archive *a = NULL;
    ms_error err;
    ms_error_clear(&err);
    if (ms_archive_open_head(data, head_size, "fuzz", &a, &err) != MS_OK) {
        MS_FUZZ_SUBTREE_CHECK(a == NULL);
        MS_FUZZ_SUBTREE_CHECK(err.text[0] != '\0' && !strchr(err.text, '\n'));
        return false;
    }
    MS_FUZZ_SUBTREE_CHECK(a != NULL && ms_archive_is_partial(a));
    MS_FUZZ_SUBTREE_CHECK(ms_archive_subtrees_held(a) == 1 && ms_archive_subtree_held(a, 0));
    data += head_size, size -= head_size;
    bool all = true;
    ms_fuzz_subtree_check_cells(a);
    while (size >= 4) {
        uint32_t word = ms_fuzz_subtree_u32(data), id = word & 0x3FFFFFFFu;
        data += 4, size -= 4;
        if (word & 0x80000000u) {
            bool was = ms_archive_subtree_held(a, id);
            ms_archive_drop_subtree(a, id);
            MS_FUZZ_SUBTREE_CHECK(ms_archive_subtree_held(a, id) == (was && id == 0));
        } else {
            size_t n = size >= 4 ? ms_fuzz_subtree_u32(data) : 0;
            data += size >= 4 ? 4 : size, size -= size >= 4 ? 4 : size;
            if (n > size)
                n = size;
            size_t held = ms_archive_subtrees_held(a), bytes = ms_archive_index_bytes_held(a);
            bool was = ms_archive_subtree_held(a, id);
            ms_error_clear(&err);
            const uint8_t *stored = data;
            uint8_t *deflated = NULL;
            size_t stored_size = n;
            if ((word & 0x40000000u) &&
                ms_subtree_deflate(data, n, &deflated, &stored_size, &err) == MS_OK)
                stored = deflated;
            ms_status st = ms_archive_add_subtree(a, id, stored, stored_size, &err);
            free(deflated);
            if (st == MS_OK) {
                MS_FUZZ_SUBTREE_CHECK(ms_archive_subtree_held(a, id));
                MS_FUZZ_SUBTREE_CHECK(ms_archive_subtrees_held(a) == held + !was);
                MS_FUZZ_SUBTREE_CHECK(was == (ms_archive_index_bytes_held(a) == bytes));
            } else {
                all = false;
                MS_FUZZ_SUBTREE_CHECK(err.text[0] != '\0' && !strchr(err.text, '\n'));
                MS_FUZZ_SUBTREE_CHECK(ms_archive_subtrees_held(a) == held);
                MS_FUZZ_SUBTREE_CHECK(ms_archive_index_bytes_held(a) == bytes);
                MS_FUZZ_SUBTREE_CHECK(!ms_archive_subtree_held(a, id));
            }
            data += n, size -= n;
        }
        ms_fuzz_subtree_check_cells(a);
    }
    ms_archive_close(a);
    return all;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_subtree_one(data, size);
    return 0;
}
#endif
