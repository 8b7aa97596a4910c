/* Reading stored subtrees: private to common/archive's archive files
 * (ms_subtree_read.c). */
#ifndef MS_SUBTREE_READ_H
#define MS_SUBTREE_READ_H

#include "ms_archive_internal.h"
#include "ms_subtree.h"

/* A raw subtree blob, inflated and checked on its own. */
typedef struct ms_subtree_blob {
    uint32_t id, count, table_words;
    uint8_t *raw; /* malloc'd, raw_size bytes */
    size_t raw_size;
    const uint8_t *ids, *records, *tables; /* inside raw */
} ms_subtree_blob;

/* Inflates a stored subtree into exactly the room its header declares (after
 * checking that against the archive header h, the depth and the stored size),
 * then checks the CRC and that the member ids ascend from id inside the
 * archive. `where` starts every error line. */
ms_status ms_subtree_blob_read(const char *where, const ms_archive_header *h, unsigned levels,
                               uint32_t id, const uint8_t *stored, size_t stored_size,
                               ms_subtree_blob *blob, ms_error *err);
void ms_subtree_blob_free(ms_subtree_blob *blob);

/* A record held outside the blob, or NULL. */
typedef const ms_archive_cell *(*ms_cell_lookup)(const void *context, uint32_t cell);

/* Decodes the members into cells (blob->count) and checks them: the first
 * group (the root, or the n^3 children of a held cell ending a band, found
 * through `held`), every other member a child of a member inside the band, the
 * children of every member inside the band all present, each record by the
 * rules of ms_archive_check_record with its tables in the blob's own words,
 * and the tables filling those words exactly. */
ms_status ms_subtree_blob_check(const char *where, const ms_archive_header *h, unsigned levels,
                                uint64_t payload_size, const ms_subtree_blob *blob,
                                ms_cell_lookup held, const void *context, ms_archive_cell *cells,
                                ms_error *err);

#endif
