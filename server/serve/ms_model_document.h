/* A model's documents, read the same way by both doors: its thumbnail
 * (DIR/NAME.thumb.png), its catalogue entry with the sidecar metadata as JSON
 * (the object GET /catalog lists for it) and its annotations
 * (DIR/NAME.annotations.json, as stored). The binary door's GET_DOCUMENT
 * (PROTOCOL.md 4.5b) and the HTTP door's /models/NAME/thumbnail, /metadata
 * and /annotations all read through ms_model_document_read, which asks
 * ms_access_document, and nothing else, whether the reader may have it
 * (docs/SECURITY.md). Reads the catalogue entry and at most one small file:
 * opens no archive, so a catalogue page of 100 pictures opens nothing.
 *
 * Only names that ms_model_name_valid accepts (the registry's lookup) reach
 * the file system, and only as DIR/NAME.thumb.png or DIR/NAME.annotations.json.
 * Thread-safety: as the registry's (the server's loop).
 */
#ifndef MS_MODEL_DOCUMENT_H
#define MS_MODEL_DOCUMENT_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"
#include "ms_registry.h"

/* A larger thumbnail is not one meshbake wrote. */
#define MS_MODEL_THUMBNAIL_MAX (256u << 10)
/* Annotations are served up to the protocol's document limit (1 MiB). */
#define MS_MODEL_ANNOTATIONS_MAX MS_PROTO_MAX_DOCUMENT

/* Why a document was not read: what each door answers. */
typedef enum ms_document_refusal {
    MS_DOCUMENT_REFUSED_NONE = 0,
    MS_DOCUMENT_NO_MODEL,   /* no such model (or a bad name): HTTP 404, UNKNOWN_MODEL */
    MS_DOCUMENT_ABSENT,     /* the model has none, or none this reader may see (a
                               thumbnail finer than the public preview): 404, NO_DOCUMENT */
    MS_DOCUMENT_TOO_LARGE,  /* the file is above its kind's limit: 500, INTERNAL */
    MS_DOCUMENT_FAILED      /* out of memory, or the file does not read: 500, INTERNAL */
} ms_document_refusal;

typedef struct ms_model_document {
    uint8_t *bytes;           /* malloc'd, length bytes (NULL when length is 0) */
    size_t length;
    const char *content_type; /* "image/png" or "application/json" */
    /* For a file: its inode, modification time (ns) and size, for an ETag;
     * all 0 for the metadata (built from the catalogue). */
    uint64_t inode, mtime_ns, size;
} ms_model_document;

/* The document of kind (ms_document_kind) of the model named name in the
 * registry r, whose archives are in dir. MS_OK with *out filled (free it with
 * ms_model_document_free); otherwise *refusal says why and err has one line
 * (e.g. "no thumbnail for this model"): MS_ERR_RANGE for NO_MODEL, ABSENT and
 * an undefined kind (ABSENT), MS_ERR_FORMAT for TOO_LARGE, MS_ERR_IO or
 * MS_ERR_NOMEM for FAILED. */
ms_status ms_model_document_read(const ms_registry *r, const char *dir, const char *name,
                                 int kind, ms_model_document *out,
                                 ms_document_refusal *refusal, ms_error *err);

/* The same for a catalogue entry at hand (its public_max_bits clamped to its
 * bits, as the registry's and an open model's are): meshexport's static site
 * reads a model's documents through this, under the same rule. */
ms_status ms_model_document_read_entry(const ms_catalog_entry *entry, const char *dir, int kind,
                                       ms_model_document *out, ms_document_refusal *refusal,
                                       ms_error *err);

void ms_model_document_free(ms_model_document *doc);

#endif
