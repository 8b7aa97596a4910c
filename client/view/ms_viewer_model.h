/* Where meshview's models come from: a meshserve server or a local archive
 * directory (DIR/catalog.json and DIR/NAME.msa, ms_catalog.h). Lists the models
 * for the catalogue screen and opens one model: checks that the source lists
 * it (so an unknown model or a server that is not there is one clear error
 * before any window opens) and says whether it has APO. The model's index is
 * not fetched here: its header and head (the records the index holds at open,
 * ms_core_opening) come from the stream's core once it opened the model
 * (ms_viewer_stream_open fills them in), so the index crosses the network
 * once, and by subtree where the server offers it (docs/CLIENT.md).
 *
 * Server: the list comes from ms_client_fetch_catalogue (LIST_CATALOGUE,
 * bounded by the time-out). Local: ms_catalog_load.
 *
 * Ownership: lists and models own their memory (_free / _close, both safe on
 * zeroed values). Errors: ms_status with one line naming the server or file:
 * MS_ERR_IO (no server, connection dropped, time-out), MS_ERR_RANGE (no such
 * model), MS_ERR_FORMAT (bad catalogue or archive), MS_ERR_NOMEM.
 * Thread-safety: none shared; each call runs its own event loop.
 */
#ifndef MS_VIEWER_MODEL_H
#define MS_VIEWER_MODEL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_client_core.h"
#include "ms_error.h"

typedef struct ms_viewer_source {
    const char *archive_dir; /* non-NULL: a local archive directory; else the server */
    const char *host;        /* numeric address */
    uint16_t port;
    const char *token;       /* NULL: none */
    double timeout_s;        /* for the server's answers; 0 = 5 */
} ms_viewer_source;

typedef struct ms_viewer_model_entry {
    char name[MS_MODEL_NAME_MAX + 1];
    uint64_t triangles;      /* 0 when the server does not say */
    uint64_t bytes;          /* archive size */
    bool apo;
    bool has_crease_angle;   /* the catalogue sets the model's crease angle (local
                                catalog.json only: the binary door does not carry it) */
    double crease_angle_deg;
    /* local catalog.json only (the binary door's listing carries neither): the
     * sidecar metadata (owned; NULL: none) and whether DIR/NAME.thumb.png was
     * made (ms_catalog_entry.has_thumbnail) */
    ms_metadata *metadata;
    bool has_thumbnail;
    /* a server's model: its documents, fetched once, when the catalogue first
     * shows its panel (by the screen's worker, ms_viewer_fetcher.h) */
    bool documents_fetched;
    uint8_t *thumbnail_png;  /* the PNG's bytes (owned); NULL: none */
    size_t thumbnail_png_size;
} ms_viewer_model_entry;

typedef struct ms_viewer_model_list {
    ms_viewer_model_entry *entries; /* by name */
    size_t count;
    /* ms_viewer_list_page's: the models the source offers that match query;
     * above count while a server's later pages are not fetched yet
     * (ms_viewer_list_more). 0 (or count) for a whole list. */
    size_t total;
    char query[65];                 /* the search text it was made with; "": none */
} ms_viewer_model_list;

/* Models a page of a server's catalogue brings (PROTOCOL.md 4.4a). */
#define MS_VIEWER_PAGE 200

ms_status ms_viewer_list_models(const ms_viewer_source *source, ms_viewer_model_list *list,
                                ms_error *err);
void ms_viewer_model_list_free(ms_viewer_model_list *list);

/* The catalogue screen's list (ms_viewer_pages.c): the models whose name,
 * title or description holds query (ASCII case-insensitively; NULL or "":
 * every model; at most 64 bytes, else MS_ERR_ARG), by name. From a server,
 * its first page only: LIST_PAGE with query as the server's text filter (the
 * server searches, also the source), MS_VIEWER_PAGE models, list->total the
 * models that match; a server below protocol version 3 lists everything and
 * meshview filters the names. From a local directory, the whole catalogue,
 * filtered here. Errors as ms_viewer_list_models. */
ms_status ms_viewer_list_page(const ms_viewer_source *source, const char *query,
                              ms_viewer_model_list *list, ms_error *err);

/* Appends the server's next page to list (the same query), when total says
 * there are more: MS_OK doing nothing otherwise (a local list is whole).
 * On an error list keeps what it had. */
ms_status ms_viewer_list_more(const ms_viewer_source *source, ms_viewer_model_list *list,
                              ms_error *err);

/* The entry of model name as the server lists it (a page searched for the
 * name), for a model not in the pages fetched so far: MS_ERR_RANGE when the
 * server does not list it. */
ms_status ms_viewer_list_lookup(const ms_viewer_source *source, const char *name,
                                ms_viewer_model_entry *entry, ms_error *err);

/* One server catalogue entry as a list entry (meshserve's title gives the
 * triangles). */
struct ms_client_catalogue_entry;
void ms_viewer_entry_from_server(const struct ms_client_catalogue_entry *e,
                                 ms_viewer_model_entry *d);

/* A server's model: its metadata and thumbnail through the binary door
 * (GET_DOCUMENT, PROTOCOL.md 4.5b: ms_client_fetch_document_at, one
 * connection, bounded by the source's time-out), once: entry->metadata (the
 * sidecar's fields of the METADATA document, checked as a sidecar is),
 * has_thumbnail (its "thumbnail"), and thumbnail_png (the THUMBNAIL document)
 * when it has one; documents_fetched is set even when they fail (no retry),
 * with the first failure's line in err and MS_ERR_IO (no server),
 * MS_ERR_FORMAT (a document that does not parse) or MS_ERR_NOMEM. A local
 * source, or an entry already fetched: MS_OK, nothing done. Blocks: the
 * catalogue screen fetches through its worker instead (ms_viewer_fetcher.h). */
ms_status ms_viewer_model_fetch_documents(const ms_viewer_source *source,
                                          ms_viewer_model_entry *entry, ms_error *err);

/* A server's METADATA document (bytes, length: the model's catalogue entry as
 * JSON) into entry: metadata (the sidecar's fields, checked as a sidecar is)
 * and has_thumbnail. MS_ERR_FORMAT (not a JSON object, or a field the
 * sidecar's rules refuse), MS_ERR_NOMEM. */
ms_status ms_viewer_entry_set_metadata(ms_viewer_model_entry *entry, const uint8_t *bytes,
                                       size_t length, ms_error *err);

typedef struct ms_viewer_model {
    char name[MS_MODEL_NAME_MAX + 1];
    char archive_path[4096];  /* local: DIR/NAME.msa; "" for a server */
    bool apo;                 /* the source lists the model with APO */
    bool has_crease_angle;    /* the source's catalogue sets its crease angle */
    double crease_angle_deg;
    /* the unit its sidecar metadata declares ("": none), when the listing
     * says (unit_known: a local catalog.json, or a server entry whose
     * documents were fetched); else ms_viewer_unit.h asks the server */
    char unit[MS_METADATA_UNIT_MAX + 1];
    bool unit_known;
    /* filled by ms_viewer_stream_open once the core opened the model: */
    ms_archive_header header;
    ms_core_opening index;    /* the head (by subtree) or the whole index, and the
                                 content bounds */
} ms_viewer_model;

/* The box the model's surface occupies: the content bounds its stream's
 * core worked out from the root before the model was first drawn
 * (ms_core_opening.content_lo / _hi: every vertex inside, within one root
 * quantum of their box on every side), by which a viewer places, frames and
 * picks it. Without them (an empty model, a root that did not decode in
 * time), the index held at open: the union of the cubes of the cells that
 * hold triangles and whose children it does not hold (with an index by
 * subtree, the head's deepest cells: up to a quarter of the model's cube
 * loose on a side), the whole cube when none does. */
void ms_viewer_model_bounds(const ms_viewer_model *model, double lo[3], double hi[3]);

/* Opens model `name` (a valid model name, else MS_ERR_ARG): MS_ERR_RANGE when
 * the source does not list it. Lists the source's models first (from a
 * server: one connection and a round trip). */
ms_status ms_viewer_model_open(const ms_viewer_source *source, const char *name,
                               ms_viewer_model *model, ms_error *err);
/* The same with the source's list in hand (ms_viewer_list_models; the
 * caller's, not freed here): reads no file and asks no server, so a scene
 * opens all its pieces from one listing. */
ms_status ms_viewer_model_open_listed(const ms_viewer_source *source,
                                      const ms_viewer_model_list *list, const char *name,
                                      ms_viewer_model *model, ms_error *err);
void ms_viewer_model_close(ms_viewer_model *model);

#endif
