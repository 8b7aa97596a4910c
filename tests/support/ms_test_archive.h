/* A synthetic archive for tests of everything that serves or reads archives:
 * 129 cells (the root, its 64 children, and the 64 children of cell 5), p = 12,
 * n = 4, p_r = 7, with deterministic payload bytes (ms_test_archive_fill) and
 * APO chunks on cells whose number is not a multiple of 3. */
#ifndef MS_TEST_ARCHIVE_H
#define MS_TEST_ARCHIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_catalog.h"

#define MS_TEST_ARCHIVE_CELLS 129u

ms_archive_header ms_test_archive_header(void);
void ms_test_archive_fill(uint8_t *buf, uint32_t length, uint32_t seed);
uint32_t ms_test_archive_geometry_length(uint32_t cell); /* payload bytes */
uint32_t ms_test_archive_apo_levels(uint32_t cell);      /* 0 = no chunk; 40 bytes a level */
/* The surface error table given to a cell with `window` bits (every fourth
 * cell from cell 1: hundredths of the half-diagonal between 50 and 99); false
 * for the others, which get the writer's default (100 at every bit). */
bool ms_test_archive_error_table(uint32_t cell, unsigned window, uint8_t *table);

/* Writes the archive at path (fails the test on error). `salt` changes every
 * payload byte, to tell two versions of a model apart. */
void ms_test_write_archive(const char *path, uint32_t salt);

/* A deeper one for the subtree tests: n = 2, p = 12, p_r = 4, six levels
 * (the root splits; below it the first and the last cell of every group of 8
 * split, down to level 5): 1 + 8 + 16 + 32 + 64 + 128 cells, the same payload
 * rules. */
#define MS_TEST_DEEP_ARCHIVE_CELLS 249u
void ms_test_write_deep_archive(const char *path, uint32_t salt);

/* --- File images and index blobs (docs/ARCHIVE.md), for tests that take them
 * apart. An image's raw index comes through the reader (its subtrees are many
 * streams); they fail the test on any error; every buffer they return is
 * malloc'd. */

/* The raw index of an image (*raw_size bytes). */
uint8_t *ms_test_archive_raw_index(const uint8_t *file, size_t size, size_t *raw_size);
/* Recomputes the header CRC (bytes 124..127) of an image or a blob. */
void ms_test_archive_seal(uint8_t *file);
/* The index blob of an image (ms_archive_index_bytes) with `raw` as its raw
 * index and the header saying raw size raw_size and index CRC index_crc; the
 * file size follows and the header CRC is redone. Open it with
 * ms_archive_open_index: the same checks as a file's index. */
uint8_t *ms_test_archive_blob(const uint8_t *file, size_t size, const uint8_t *raw,
                              size_t raw_size, uint32_t index_crc, size_t *out_size);
/* ms_test_archive_blob with the CRC of `raw`: a consistent blob whose raw
 * index is `raw`, so only the structural checks can refuse it. */
uint8_t *ms_test_archive_blob_with_index(const uint8_t *file, size_t size, const uint8_t *raw,
                                         size_t raw_size, size_t *out_size);

/* Writes DIR/NAME.msa and adds NAME to DIR/catalog.json. */
void ms_test_add_model(const char *dir, const char *name, uint32_t salt, uint8_t public_max_bits);

#endif
