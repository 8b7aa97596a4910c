/* libFuzzer target on the archive index reader (common/archive/ms_archive.c,
 * ms_archive_open_index): the index blob a client receives from the server
 * (OPEN_MODEL's INDEX_DATA), or the static tree's models/NAME.index.
 *
 * Input: the blob. Besides the sanitizers, the target checks the reader's
 * contract and aborts when it is broken: a blob accepted has a header whose
 * cell count matches the cells it answers for; every cell's geometry prefix
 * grows with the precision and stays within the stored length, and so do
 * every APO prefix with the level and every colour prefix with the precision
 * (none without colour); an index-only archive has no payload
 * bytes; a refused blob leaves no archive and a one-line error.
 *
 * tests/test_fuzz_replay.c includes this file to replay
 * tests/corpus/archive_index/ in `make test`; it then calls
 * ms_fuzz_archive_index_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_archive.h"

#define MS_FUZZ_INDEX_CHECK(cond)                                                              \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_archive_index: contract broken: %s (%s:%d)\n", #cond,       \
                    __FILE__, __LINE__);                                                       \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* Returns true when the blob was accepted. */
static bool ms_fuzz_archive_index_one(const uint8_t *data, size_t size)
{
    ms_archive *a = NULL;
    ms_error err;
    ms_error_clear(&err);
    if (ms_archive_open_index(data, size, "fuzz", &a, &err) != MS_OK) {
        MS_FUZZ_INDEX_CHECK(a == NULL);
        MS_FUZZ_INDEX_CHECK(err.text[0] != '\0' && !strchr(err.text, '\n'));
        return false;
    }
    MS_FUZZ_INDEX_CHECK(a != NULL);
    const ms_archive_header *h = ms_archive_get_header(a);
    MS_FUZZ_INDEX_CHECK(ms_archive_get_cell(a, h->cell_count) == NULL);
    for (uint32_t cell = 0; cell < h->cell_count && cell < 4096; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        MS_FUZZ_INDEX_CHECK(c != NULL);
        uint32_t previous = 0;
        for (unsigned bits = 0; bits <= 64; ++bits) {
            uint32_t p = ms_archive_geometry_prefix(a, cell, bits);
            MS_FUZZ_INDEX_CHECK(p >= previous && p <= c->geometry_length);
            previous = p;
        }
        previous = 0;
        for (unsigned level = 0; level <= 40; ++level) {
            uint32_t p = ms_archive_apo_prefix(a, cell, level, NULL);
            MS_FUZZ_INDEX_CHECK(p >= previous && p <= c->apo_length);
            previous = p;
        }
        previous = 0;
        for (unsigned bits = 0; bits <= 64; ++bits) {
            uint32_t p = ms_archive_colour_prefix(a, cell, bits);
            MS_FUZZ_INDEX_CHECK(p >= previous && p <= ms_archive_colour_length(a, cell));
            MS_FUZZ_INDEX_CHECK(h->has_colour || p == 0);
            previous = p;
        }
        size_t length;
        MS_FUZZ_INDEX_CHECK(ms_archive_geometry(a, cell, &length) == NULL);
        MS_FUZZ_INDEX_CHECK(ms_archive_apo(a, cell, &length) == NULL);
        MS_FUZZ_INDEX_CHECK(ms_archive_colour(a, cell, &length) == NULL);
    }
    size_t blob_size;
    MS_FUZZ_INDEX_CHECK(ms_archive_index_bytes(a, &blob_size) != NULL && blob_size > 0);
    ms_archive_close(a);
    return true;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_archive_index_one(data, size);
    return 0;
}
#endif
