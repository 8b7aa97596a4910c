/* The cell index in subtrees (docs/ARCHIVE.md, "Subtrees"; the design of
 * issue 24).
 *
 * An archive has a subtree depth S (levels per subtree, 1..8). The root
 * subtree, id 0, holds cell 0 and its descendants at levels 1 .. S-1; every
 * other subtree starts at the n^3 children of a cell p at level kS - 1 (k >= 1)
 * and holds them and their descendants at levels kS+1 .. kS+S-1; its id is
 * p.first_child, the smallest id of its members. Every record lies in exactly
 * one subtree.
 *
 * A subtree travels as a raw blob (header, member ids, records with table_first
 * rebased to the blob's own table words, table words; CRC32) compressed as one
 * zlib stream with fixed parameters, so the stored bytes of a subtree depend
 * only on the model and S.
 *
 * Server side: ms_archive_open computes the subtree ids of an archive (the
 * file's S; ms_subtree_default_levels for an archive opened from an index
 * blob); a file's stored subtrees are served as they are in the file, those of
 * a blob's archive are deflated on first request and kept in the ms_archive
 * until it is closed.
 *
 * Client side: ms_archive_open_head makes a partial archive from the index
 * head (header + root subtree); ms_archive_add_subtree validates and adds
 * subtrees below the ones held, ms_archive_drop_subtree forgets them. On a
 * partial archive ms_archive_get_cell is NULL for a cell whose subtree is not
 * held, the prefix look-ups return 0 for it, ms_archive_index_bytes is NULL,
 * and a record's table_first is the one in its subtree's blob (an index into
 * that subtree's table words, not the file's).
 *
 * Thread-safety: on a whole archive every function here may be called from any
 * number of threads at once. A partial archive is changed by add/drop: the
 * caller serialises those with every other use of that archive.
 */
#ifndef MS_SUBTREE_H
#define MS_SUBTREE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_error.h"

/* The raw subtree blob. */
#define MS_SUBTREE_MAGIC "MSST"
#define MS_SUBTREE_VERSION 1u
#define MS_SUBTREE_HEADER_SIZE 24u
#define MS_SUBTREE_MIN_LEVELS 1u
#define MS_SUBTREE_MAX_LEVELS 8u

/* Subtree depth default for an nSP arity n: 1 for n >= 4 (a subtree is one
 * sibling group of 64 or 512 cells), 2 for n = 2 (8 + 64 cells). */
unsigned ms_subtree_default_levels(unsigned n);

/* On a whole archive (any file version; not a partial one): the subtree ids at
 * depth `levels` (1..8), ascending, in a malloc'd array the caller frees.
 * MS_ERR_ARG for levels outside 1..8 or a partial archive. */
ms_status ms_subtree_list(const ms_archive *a, unsigned levels, uint32_t **ids,
                          size_t *count, ms_error *err);

/* The member cell ids of subtree `id` at depth `levels`, ascending (malloc'd,
 * caller frees). MS_ERR_RANGE when id is not a subtree id at that depth. */
ms_status ms_subtree_members(const ms_archive *a, unsigned levels, uint32_t id,
                             uint32_t **members, size_t *count, ms_error *err);

/* Encodes one subtree's raw blob from a whole archive (malloc'd, caller frees).
 * MS_ERR_RANGE when id is not a subtree id at that depth. */
ms_status ms_subtree_encode(const ms_archive *a, unsigned levels, uint32_t id,
                            uint8_t **raw, size_t *size, ms_error *err);

/* One zlib stream of raw with the fixed parameters (level 9, window 15,
 * memLevel 8, Z_FILTERED): deterministic. Malloc'd, caller frees. */
ms_status ms_subtree_deflate(const uint8_t *raw, size_t size, uint8_t **stored,
                             size_t *stored_size, ms_error *err);

/* On a whole archive: the stored (zlib) bytes of subtree `id`: a file's own
 * bytes, or for an archive opened from an index blob the ones deflated on the
 * first request and kept until ms_archive_close. NULL (and *stored_size 0) when id is
 * not a subtree id of the archive (the server answers "no such cell"), on a
 * partial archive, or when memory runs out. Thread-safe. */
const uint8_t *ms_archive_subtree(const ms_archive *a, uint32_t id, size_t *stored_size);

/* The archive's subtree depth S (the file's, the default for an archive opened
 * from an index blob, the head's on a partial archive). */
unsigned ms_archive_subtree_levels(const ms_archive *a);

/* Number of subtrees of the model (whole or partial archive). */
uint32_t ms_archive_subtree_count(const ms_archive *a);

/* The index head (docs/ARCHIVE.md): a 128-byte version-3 header followed by the
 * root subtree's stored bytes. The same bytes from a file and from its index
 * blob. Built on first request and kept until close; NULL
 * (size 0) on a partial archive or out of memory. Thread-safe. */
const uint8_t *ms_archive_index_head(const ms_archive *a, size_t *size);

/* --- Client: a partial index ------------------------------------------------ */

/* Validates the head (its header, then the root subtree in full) and makes a
 * partial archive holding the root subtree; name is used in errors. Payload
 * accessors behave as on ms_archive_open_index's archives. */
ms_status ms_archive_open_head(const uint8_t *head, size_t size, const char *name,
                               ms_archive **archive, ms_error *err);

/* Validates a stored subtree against the head and the records already held
 * (its id must be the first_child of a held cell at level kS-1: MS_ERR_RANGE
 * otherwise), then makes its records visible to ms_archive_get_cell and the
 * prefix look-ups. Adding a subtree already held is a no-op (MS_OK). Any
 * disagreement of the bytes (zlib, sizes, CRC, header fields, membership,
 * records, tables) is MS_ERR_FORMAT / MS_ERR_CORRUPT with one line naming the
 * subtree; the archive is then unchanged. MS_ERR_ARG on a whole archive. */
ms_status ms_archive_add_subtree(ms_archive *a, uint32_t id, const uint8_t *stored,
                                 size_t stored_size, ms_error *err);

/* Forgets a held subtree and every held subtree below it; their cells' records
 * read NULL again. Never the root subtree (id 0: nothing happens), nothing for
 * an id not held or a whole archive. */
void ms_archive_drop_subtree(ms_archive *a, uint32_t id);

/* The id of the subtree that holds cell's record (MS_ARCHIVE_NONE when the
 * record is not held or cell >= cell_count), and the id of the subtree that
 * holds its children's records (MS_ARCHIVE_NONE for a leaf or a cell not
 * held): cell's own subtree, or cell.first_child when cell ends a band of S
 * levels. Whole or partial archive. */
uint32_t ms_archive_subtree_of(const ms_archive *a, uint32_t cell);
uint32_t ms_archive_children_subtree(const ms_archive *a, uint32_t cell);

bool ms_archive_is_partial(const ms_archive *a);
/* Whether subtree id is held (always true for a subtree of a whole archive). */
bool ms_archive_subtree_held(const ms_archive *a, uint32_t id);
/* On a partial archive: the members of held subtree id, ascending, and their
 * records in the same order (table_first relative to the subtree's own table
 * words, as ms_archive_get_cell gives them). Owned by the archive, valid until
 * the subtree is dropped. False (and *count 0) when the archive is whole or the
 * subtree is not held. */
bool ms_archive_held_subtree(const ms_archive *a, uint32_t id, const uint32_t **ids,
                             const ms_archive_cell **records, size_t *count);
/* Subtrees held and their raw bytes (24 + 84 per record + 4 per table word,
 * summed), for the memory budget and the statistics. On a whole archive: every
 * subtree and the raw index size. */
size_t ms_archive_subtrees_held(const ms_archive *a);
size_t ms_archive_index_bytes_held(const ms_archive *a);

#endif
