/* Synthetic archives with realistic payload sizes, for load tests and
 * benchmarks of the servers (not for viewing: payload bytes are pseudo-random,
 * not decodable geometry). The tree is a complete nSP tree (n = 4) of `levels`
 * levels below the root; every cell has a geometry stream whose prefix table
 * grows with the precision bits, and (with APO) a chunk whose levels double in
 * size, like a breadth-first octree.
 *
 * Thread-safety: no shared state; one call writes one file.
 */
#ifndef MS_SYNTHETIC_ARCHIVE_H
#define MS_SYNTHETIC_ARCHIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"

typedef struct ms_synthetic_spec {
    unsigned levels;          /* nSP levels below the root: 0..3 (1, 65, 4161, 266305 cells) */
    unsigned bits;            /* p, 8..20; must exceed 7 + 2 * (levels - 1) */
    uint32_t geometry_bytes;  /* mean geometry payload per cell (each varies by +-25 %) */
    uint32_t apo_bytes;       /* mean APO chunk per cell; 0 = no APO */
    unsigned apo_levels;      /* APO levels per cell, 1..12 (ignored without APO) */
    uint32_t seed;            /* changes every payload byte */
    uint8_t public_max_bits;  /* catalogue preview precision */
} ms_synthetic_spec;

/* Number of cells of a complete tree of `levels` levels. */
uint32_t ms_synthetic_cell_count(unsigned levels);

/* Writes DIR/NAME.msa and adds NAME to DIR/catalog.json. MS_ERR_ARG for a spec
 * out of range, MS_ERR_IO/NOMEM from the writer. */
ms_status ms_synthetic_archive_write(const char *dir, const char *name,
                                     const ms_synthetic_spec *spec, ms_error *err);

#endif
