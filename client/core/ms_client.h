/* A binary-protocol client connection on a libevent loop (protocol/PROTOCOL.md):
 * connect, HELLO (versions 1..3, offering CAP_APO, CAP_INDEX_ZLIB and on request
 * CAP_INDEX_SUBTREES), OPEN_MODEL
 * (the index blob reassembled, inflated if compressed, and CRC-checked),
 * REQUEST_CELLS batches with consecutive request ids, CANCEL, PING; incoming
 * frames are strictly validated (any bad server frame closes the connection)
 * and handed to the caller's handlers. Used by meshloadgen, the client core,
 * and (ms_client_fetch_catalogue) by front ends listing a server's models.
 *
 * Ownership: ms_client_free releases everything; it may be called from inside
 * a handler only from `closed` (after which no handler runs). Pointers passed
 * to handlers are valid during the call only. Thread-safety: the loop's thread.
 */
#ifndef MS_CLIENT_H
#define MS_CLIENT_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"

struct event_base;
typedef struct ms_client ms_client;

typedef struct ms_client_handlers {
    /* HELLO_REPLY received: requests may be sent (they may also be sent before). */
    void (*ready)(ms_client *client, const ms_proto_hello_reply *reply, void *arg);
    /* OPEN_MODEL answered: the whole index blob, CRC-checked (and inflated
     * first when it came compressed), or with opened->index_encoding
     * SUBTREES the index head (index_size bytes, CRC-checked). */
    void (*model_opened)(ms_client *client, uint32_t request_id, const ms_proto_model_opened *opened,
                         const uint8_t *index, void *arg);
    /* One PAYLOAD frame (frames of one request come in order, contiguous). */
    void (*payload)(ms_client *client, uint32_t request_id, const ms_proto_payload *payload,
                    bool last, void *arg);
    /* A non-fatal ERROR ending requests first_id .. first_id + count - 1
     * (count 0: a connection-level error such as UNKNOWN_MODEL for a handle,
     * or MODEL_CHANGED: error->detail's handle is closed and every request
     * outstanding on it ended). */
    void (*request_error)(ms_client *client, uint32_t first_id, uint32_t count,
                          const ms_proto_error_body *error, void *arg);
    void (*pong)(ms_client *client, uint64_t opaque, void *arg);
    /* One CATALOGUE frame of the answer to request_id (last: the final one). */
    void (*catalogue)(ms_client *client, uint32_t request_id, const ms_proto_catalogue *catalogue,
                      bool last, void *arg);
    /* The connection is over: why is one line (a fatal ERROR's text, a
     * protocol violation, a socket error, or "closed"). */
    void (*closed)(ms_client *client, const char *why, void *arg);
    /* The whole document asked for by ms_client_request_document (kind:
     * ms_document_kind): length bytes, valid during the call. A refusal comes
     * to request_error (NO_DOCUMENT, UNKNOWN_MODEL, ...). */
    void (*document)(ms_client *client, uint32_t request_id, uint8_t kind, const uint8_t *bytes,
                     size_t length, void *arg);
} ms_client_handlers;

typedef struct ms_client_options {
    const char *host;     /* numeric IPv4/IPv6 address */
    uint16_t port;
    const char *token;    /* NULL = none */
    const char *agent;    /* e.g. "meshloadgen/0.1" */
    uint32_t max_frame;   /* largest body accepted; 0 = 1 MiB */
    bool raw_index;       /* do not offer CAP_INDEX_ZLIB: the index comes uncompressed */
    bool index_subtrees;  /* offer CAP_INDEX_SUBTREES (version 3): when granted, OPEN_MODEL
                             may answer with the index head (index_encoding SUBTREES),
                             handed to model_opened as is, CRC-checked; the subtrees are
                             then requested as stream INDEX */
} ms_client_options;

/* Starts connecting; HELLO is queued at once. MS_ERR_ARG for a bad address,
 * MS_ERR_IO/NOMEM otherwise. handlers and arg must outlive the client. */
ms_status ms_client_connect(struct event_base *base, const ms_client_options *options,
                            const ms_client_handlers *handlers, void *arg, ms_client **client,
                            ms_error *err);
void ms_client_free(ms_client *client);

/* Each returns the request id(s) it used. MS_ERR_ARG for an invalid message
 * (bad name, count 0 or above the protocol's maximum), MS_ERR_NOMEM. */
ms_status ms_client_open_model(ms_client *client, const char *name, uint32_t *request_id,
                               ms_error *err);
/* Bytes the last index handed to model_opened took on the wire (compressed,
 * raw, or the head); 0 before the first. */
uint32_t ms_client_index_wire_bytes(const ms_client *client);
/* CLOSE_MODEL (PROTOCOL.md 4.9): the server ends every request outstanding on
 * the handle with ERROR CANCELLED; no other answer. */
/* The caller found a frame that breaks the protocol (a MODEL_OPENED whose
 * index contradicts it, say): sends the server a fatal ERROR code (detail)
 * with why, and ends the connection; `closed` then says
 * "protocol violation: WHY". The client itself ends a connection so on a
 * PAYLOAD, MODEL_OPENED, INDEX_DATA or CATALOGUE for a request that is not
 * outstanding (never sent, or ended: after LAST), or a PAYLOAD for another
 * cell or stream than its request's, or not contiguous from the request's
 * range. */
void ms_client_violation(ms_client *client, uint16_t code, uint64_t detail, const char *why);
ms_status ms_client_close_model(ms_client *client, uint32_t model_handle, ms_error *err);
ms_status ms_client_request_cells(ms_client *client, uint32_t model_handle,
                                  const ms_proto_cell_request *entries, uint16_t count,
                                  uint32_t *first_id, ms_error *err);
ms_status ms_client_cancel(ms_client *client, const ms_proto_id_range *ranges, uint16_t count,
                           ms_error *err);

/* One model of a server's catalogue (PROTOCOL.md 4.5), as a front end lists it. */
typedef struct ms_client_catalogue_entry {
    char name[MS_PROTO_MAX_MODEL_NAME + 1];    /* model name, NUL-terminated */
    char title[MS_PROTO_MAX_TEXT + 1];   /* the server's title (meshserve: "V vertices,
                                            T triangles"), NUL-terminated */
    uint8_t geometry_steps, apo_steps;   /* precision bits, APO levels (0: no APO) */
    uint8_t permitted_geometry_steps, permitted_apo_steps; /* what this token may read */
    uint32_t cell_count;
    uint64_t content_id;
    uint64_t archive_bytes;              /* size of the model's archive file */
} ms_client_catalogue_entry;

typedef struct ms_client_catalogue {
    ms_client_catalogue_entry *entries;  /* in the server's order: by name (a page: by
                                            its sort) */
    size_t count;
    size_t total;                        /* a page: the models its filter matches; a
                                            whole catalogue: count */
} ms_client_catalogue;

/* One page of a catalogue (protocol version 3, PROTOCOL.md 4.11). */
typedef struct ms_client_page_request {
    uint32_t offset;
    uint16_t limit;        /* 1 .. MS_PROTO_MAX_PAGE */
    uint8_t sort;          /* ms_proto_page_sort */
    bool descending;
    const char *query;     /* NULL or "": every model; else matched (ASCII case-insensitively)
                              in the name, source, title and description; at most 64 bytes */
} ms_client_page_request;

/* The models a server offers this token: connects to options->host:port
 * (token, agent, max_frame as for ms_client_connect), sends LIST_CATALOGUE,
 * gathers every CATALOGUE frame and closes. Blocks for at most timeout_s
 * seconds (0 = 5) on its own event loop, so it may run on any thread (a
 * viewer runs it before its window, or on a thread of its own). An empty
 * catalogue is MS_OK with count 0. Errors (one line naming the server):
 * MS_ERR_ARG for bad options, MS_ERR_IO for a refused or dropped connection,
 * an ERROR answer or the time-out, MS_ERR_NOMEM. The caller frees the result
 * with ms_client_catalogue_free (also safe on a zeroed or failed one). */
ms_status ms_client_fetch_catalogue(const ms_client_options *options, double timeout_s,
                                    ms_client_catalogue *catalogue, ms_error *err);
void ms_client_catalogue_free(ms_client_catalogue *catalogue);

/* Sends LIST_CATALOGUE (page NULL) or, on a connection that negotiated
 * version 3, LIST_PAGE for page, as request *request_id: the answer comes to
 * handlers->catalogue, frame by frame. MS_ERR_IO when the connection is
 * closed; the encoder's errors for a page outside the protocol's ranges. */
ms_status ms_client_list_catalogue(ms_client *client, const ms_client_page_request *page,
                                   uint32_t *request_id, ms_error *err);

/* ms_client_fetch_catalogue for one page: the server filters, sorts and cuts
 * (LIST_PAGE), so a front end shows the first page of a 10,000-model
 * collection without the whole list; catalogue->total says how many models
 * match. Errors as ms_client_fetch_catalogue, and MS_ERR_UNSUPPORTED when
 * the server speaks a protocol version below 4 (ask for the whole catalogue
 * instead), MS_ERR_ARG for a page outside the protocol's ranges. */
ms_status ms_client_fetch_catalogue_page(const ms_client_options *options, double timeout_s,
                                         const ms_client_page_request *page,
                                         ms_client_catalogue *catalogue, ms_error *err);

/* --- A model's documents (protocol version 3, PROTOCOL.md 4.5b) ---------- */

/* The longest ms_client_fetch_document waits for its answer, in seconds. */
#define MS_CLIENT_DOCUMENT_TIMEOUT_S 30

/* Sends GET_DOCUMENT for the document of kind (MS_DOCUMENT_THUMBNAIL, _METADATA
 * or _ANNOTATIONS, ms_proto.h) of the model named model, as request
 * *request_id: the answer comes to handlers->document whole, or a refusal to
 * request_error. MS_ERR_ARG for a bad name or kind, MS_ERR_UNSUPPORTED when
 * the server negotiated a version below 3, MS_ERR_IO when the connection is
 * closed. */
ms_status ms_client_request_document(ms_client *client, const char *model, int kind,
                                     uint32_t *request_id, ms_error *err);

/* The document of kind of the model named model, on this connection,
 * blocking: waits for the handshake if it has not completed, sends
 * GET_DOCUMENT and runs the connection's event loop (its other handlers run
 * as usual meanwhile) until the whole document has come, or a refusal, or at
 * most MS_CLIENT_DOCUMENT_TIMEOUT_S. On MS_OK *bytes (malloc'd, the caller
 * frees it; NULL for an empty document) holds *length bytes: the PNG, the
 * model's catalogue entry as JSON (the object GET /catalog lists: figures,
 * "thumbnail", and the sidecar's title, creator, date, licence, description, unit),
 * or DIR/NAME.annotations.json as stored (at most 1 MiB). Errors (one line):
 * MS_ERR_ARG for a bad name or kind, or when called from inside the
 * connection's own event loop (a handler: use ms_client_request_document
 * there); MS_ERR_UNSUPPORTED for a server below version 3; MS_ERR_IO for the
 * server's refusal ("NO_DOCUMENT no annotations for this model",
 * "UNKNOWN_MODEL no such model", ...), a closed connection or the time-out;
 * MS_ERR_NOMEM. The handlers must not free the client while this waits. */
ms_status ms_client_fetch_document(ms_client *client, const char *model, int kind,
                                   uint8_t **bytes, size_t *length, ms_error *err);

/* ms_client_fetch_document on a connection of its own (options as for
 * ms_client_fetch_catalogue; its own event loop, so it may run on any
 * thread), closed before it returns; timeout_s 0 = 5. */
ms_status ms_client_fetch_document_at(const ms_client_options *options, double timeout_s,
                                      const char *model, int kind, uint8_t **bytes,
                                      size_t *length, ms_error *err);

/* Throttles what this connection reads to bytes_per_second (a token bucket
 * refilled every 10 ms); 0 removes the limit. MS_ERR_NOMEM. */
ms_status ms_client_set_rate_limit(ms_client *client, double bytes_per_second, ms_error *err);

/* Bytes received from the server so far (every frame, index data included). */
uint64_t ms_client_bytes_read(const ms_client *client);

/* The server's HELLO_REPLY (zeros before it arrived). */
const ms_proto_hello_reply *ms_client_limits(const ms_client *client);

#endif
