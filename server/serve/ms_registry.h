/* The models a server offers: the catalogue of an archive directory and, for
 * the models asked for, their archives, opened (mapped and validated) on first
 * request and closed again when the registry alone holds them and more than
 * its limit are open.
 *
 * A scan (ms_registry_scan) reads DIR/catalog.json and stats each model's
 * file, nothing more: start and rescan cost no archive reading, so a server of
 * 10,000 models answers at once and holds only their catalogue entries. A
 * model's archive is opened by ms_registry_find, at its first request; one that
 * does not open is warned about once and treated as absent until a rescan
 * finds its file changed (`meshbake --list` checks every archive ahead of
 * time). A rescan (SIGHUP) reuses the open archive of every model whose file
 * did not change (same inode, size and modification time) and whose catalogue
 * entry did not change either (a new public_max_bits takes effect at the
 * rescan; an open binary-protocol handle keeps the grant it was given). An open
 * model whose file changed is opened again during the rescan, so that a broken
 * replacement keeps its previous, verified version, with a warning: publish a
 * new version by writing it aside and renaming it over the old. Each model is
 * reference-counted: after a rescan the server closes every handle on a model
 * that was removed or replaced (ERROR MODEL_CHANGED,
 * ms_serve_conn_models_changed), and the frames already queued keep their
 * mapping alive until they are sent.
 *
 * Only names that ms_model_name_valid accepts ever reach the file system, and
 * only as DIR/NAME.msa. A catalogue entry whose archive file is missing is
 * skipped with a one-line warning (reported through the callback), not fatal.
 *
 * Thread-safety: none (reference counts are not atomic, and a find may open
 * or close archives); use from one thread (the server's event loop).
 */
#ifndef MS_REGISTRY_H
#define MS_REGISTRY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_error.h"

typedef struct ms_model {
    unsigned refs;
    ms_catalog_entry entry; /* entry.source owned */
    ms_archive *archive;
    uint8_t max_apo_levels; /* most APO levels stored in any cell (0: no APO) */
    uint32_t index_crc32;   /* zlib crc32 of the index blob (ms_archive_index_bytes) */
    /* The index blob as one zlib stream, sent to clients that negotiated
     * CAP_INDEX_ZLIB (compressed once, at load); NULL when it does not shrink. */
    uint8_t *index_zlib;
    size_t index_zlib_size;
    /* The index head (ms_archive_index_head: a version-3 header and the root
     * subtree), sent to clients that negotiated CAP_INDEX_SUBTREES, and its
     * CRC-32; owned by the archive. NULL when it could not be built (out of
     * memory, or above the protocol's index limit): such clients then get the
     * whole index like the others. */
    const uint8_t *index_head;
    size_t index_head_size;
    uint32_t index_head_crc32;
    uint64_t content_id;    /* FNV-1a 64 of the index blob, which holds every payload CRC */
    char *file_path;        /* DIR/NAME.msa, owned */
    uint64_t file_inode, file_size;
    int64_t file_mtime_ns;
    /* Per cell, what ms_model_check_payload found (MS_PAYLOAD_* bits), so that
     * each payload's CRC is computed once, on first use. */
    uint16_t *payload_checks;
    /* /metrics counters of this model, both doors: requests received for it
     * (opens, cell requests, HTTP answers) and payload bytes sent. Carried
     * over to the new version when a rescan replaces the model. */
    uint64_t requests, bytes_sent;
} ms_model;

enum {
    MS_PAYLOAD_GEOMETRY_CHECKED = 1,
    MS_PAYLOAD_GEOMETRY_BAD = 2,
    MS_PAYLOAD_APO_CHECKED = 4,
    MS_PAYLOAD_APO_BAD = 8,
    MS_PAYLOAD_GEOMETRY_GONE = 16, /* reported: the file shrank under it */
    MS_PAYLOAD_APO_GONE = 32,
    MS_PAYLOAD_COLOUR_CHECKED = 64,
    MS_PAYLOAD_COLOUR_BAD = 128,
    MS_PAYLOAD_COLOUR_GONE = 256,
};

/* The models of one scan of a directory, sorted by name: opaque, built by
 * ms_registry_scan, released by ms_registry_free. */
typedef struct ms_registry ms_registry;

/* Called with a one-line message for each model skipped or failing. */
typedef void (*ms_registry_warn_fn)(void *arg, const char *message);

/* Builds *out (the caller's, ms_registry_free) from DIR, keeping at most
 * max_open archives open that nobody but the registry holds (at least 1).
 * previous (may be NULL) lends its open archives and the models' counters. A
 * catalogue that cannot be read at all is an error (*out NULL); models whose
 * file is missing are warned about and skipped. warn (may be NULL) is also
 * called by later finds. */
ms_status ms_registry_scan(const char *dir, const ms_registry *previous, size_t max_open,
                           ms_registry **out, ms_registry_warn_fn warn, void *warn_arg,
                           ms_error *err);

/* Drops the registry's references (models still held elsewhere stay alive) and
 * frees it; NULL is a no-op. */
void ms_registry_free(ms_registry *registry);

/* The number of models, and model i's catalogue entry (0 <= i < count, by
 * name; public_max_bits clamped to bits), without opening anything. */
size_t ms_registry_count(const ms_registry *registry);
const ms_catalog_entry *ms_registry_entry(const ms_registry *registry, size_t i);

/* The model named name (validated first), its archive opened if it was not,
 * or NULL (no such model, or its archive does not open: warned once). Does not
 * take a reference: the model stays valid until the next find or scan unless
 * the caller takes one. Opening one may close the least recently used model
 * that only the registry holds. */
ms_model *ms_registry_find(ms_registry *registry, const char *name);

/* The catalogue entry of the model named name (validated first), or NULL;
 * opens nothing. */
const ms_catalog_entry *ms_registry_entry_named(const ms_registry *registry, const char *name);

/* The model named name if its archive is open, else NULL; opens nothing. */
ms_model *ms_registry_peek(const ms_registry *registry, const char *name);

/* Model i's open model, or NULL when it is not open (for per-model metrics of
 * the open models only). */
ms_model *ms_registry_open_model_at(const ms_registry *registry, size_t i);

/* The number of open archives (held by clients or kept for reuse). */
size_t ms_registry_open_count(const ms_registry *registry);

/* Closes the archives only the registry holds whose last find is idle_s or
 * more before now (ms_now_seconds). O(closed + held by clients). */
void ms_registry_close_idle(ms_registry *registry, double now, double idle_s);

/* Opens DIR/NAME.msa for the catalogue entry (copied; public_max_bits clamped
 * to the archive's bits) as a model holding one reference. Errors: MS_ERR_IO
 * (missing file), the archive reader's errors, MS_ERR_NOMEM. */
ms_status ms_model_open(const char *dir, const ms_catalog_entry *entry, ms_model **out,
                        ms_error *err);

/* Checks one payload of a cell (stream: MS_PROTO_STREAM_GEOMETRY, _APO or
 * _COLOUR: its geometry, APO chunk or colour stream)
 * against the CRC-32 in the index, the first time it is asked, and remembers
 * the answer. MS_OK when it is intact; MS_ERR_CORRUPT naming the cell and the
 * stream when not, with *first_report true only the first time (to log it
 * once); MS_ERR_RANGE for a cell that does not exist. Every call also checks
 * that the file under the mapping (same inode at file_path) still reaches past
 * the payload: a file truncated in place gives MS_ERR_IO ("the archive file
 * shrank"), never a read past its end (SIGBUS) or a silent short answer. */
ms_status ms_model_check_payload(ms_model *model, uint32_t cell, uint8_t stream,
                                 bool *first_report, ms_error *err);

void ms_model_ref(ms_model *model);
void ms_model_unref(ms_model *model);

#endif
