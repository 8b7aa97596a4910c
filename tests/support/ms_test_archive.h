/* A synthetic archive for tests of everything that serves or reads archives:
 * 129 cells (the root, its 64 children, and the 64 children of cell 5), p = 12,
 * n = 4, p_r = 7, with deterministic payload bytes (ms_test_archive_fill) and
 * APO chunks on cells whose number is not a multiple of 3. */
#ifndef MS_TEST_ARCHIVE_H
#define MS_TEST_ARCHIVE_H

#include <stdint.h>

#include "ms_archive.h"
#include "ms_catalog.h"

#define MS_TEST_ARCHIVE_CELLS 129u

ms_archive_header ms_test_archive_header(void);
void ms_test_archive_fill(uint8_t *buf, uint32_t length, uint32_t seed);
uint32_t ms_test_archive_geometry_length(uint32_t cell); /* payload bytes */
uint32_t ms_test_archive_apo_levels(uint32_t cell);      /* 0 = no chunk; 40 bytes a level */

/* Writes the archive at path (fails the test on error). `salt` changes every
 * payload byte, to tell two versions of a model apart. */
void ms_test_write_archive(const char *path, uint32_t salt);

/* Writes DIR/NAME.msa and adds NAME to DIR/catalog.json. */
void ms_test_add_model(const char *dir, const char *name, uint32_t salt, uint8_t public_max_bits);

#endif
