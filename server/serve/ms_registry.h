/* The models a server offers: the catalogue of an archive directory and each
 * model's archive, opened (mapped and validated) once.
 *
 * A registry snapshot is immutable. ms_registry_scan builds a new one from the
 * directory, reusing the already-open archive of every model whose file did not
 * change (same inode, size and modification time) and whose catalogue entry
 * did not change either (a new public_max_bits takes effect at the rescan; an
 * open binary-protocol handle keeps the grant it was given), so a rescan (SIGHUP) costs
 * little. Each model is reference-counted: after a rescan the server closes
 * every handle on a model that was removed or replaced (ERROR MODEL_CHANGED,
 * ms_serve_conn_models_changed), and the frames already queued keep their
 * mapping alive until they are sent.
 *
 * Only names that ms_model_name_valid accepts ever reach the file system, and
 * only as DIR/NAME.msa. A model whose file changed but no longer opens (a
 * broken replacement) keeps its previous, verified version, with a warning:
 * publish a new version by writing it aside and renaming it over the old. A catalogue entry whose archive is missing or invalid is
 * skipped with a one-line warning (reported through the callback), not fatal.
 *
 * Thread-safety: reference counts are not atomic; use from one thread (the
 * server's event loop).
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

/* The models of one scan of a directory, sorted by name, each held by one
 * reference: opaque, built by ms_registry_scan, released by ms_registry_free. */
typedef struct ms_registry ms_registry;

/* Called with a one-line message for each model skipped during a scan. */
typedef void (*ms_registry_warn_fn)(void *arg, const char *message);

/* Builds *out (the caller's, ms_registry_free) from DIR. previous (may be
 * NULL) lends its open archives. A catalogue that cannot be read at all is an
 * error (*out NULL); models that fail are warned about and skipped. */
ms_status ms_registry_scan(const char *dir, const ms_registry *previous, ms_registry **out,
                           ms_registry_warn_fn warn, void *warn_arg, ms_error *err);

/* Drops the registry's references (models still held elsewhere stay alive) and
 * frees it; NULL is a no-op. */
void ms_registry_free(ms_registry *registry);

/* The number of models, and model i (0 <= i < count, by name) without taking
 * a reference. */
size_t ms_registry_count(const ms_registry *registry);
ms_model *ms_registry_model(const ms_registry *registry, size_t i);

/* The model named name (validated first), or NULL. Does not take a reference. */
ms_model *ms_registry_find(const ms_registry *registry, const char *name);

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
