/* Inside a binary-protocol client connection (ms_client.h): its state and
 * the helpers that ms_client.c (connection, frames, requests) shares with
 * ms_client_document.c (documents). Private to client/core. */
#ifndef MS_CLIENT_INTERNAL_H
#define MS_CLIENT_INTERNAL_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_client.h"

struct bufferevent;
struct ev_token_bucket_cfg;

/* A request sent and not yet ended by its terminal frame (PROTOCOL.md 5):
 * what the server may answer. Kept in id order (ids come from one counter). */
typedef enum { PENDING_CELLS, PENDING_OPEN, PENDING_LIST, PENDING_DOCUMENT } pending_kind;
typedef struct pending {
    uint32_t id;
    uint32_t handle, cell;     /* CELLS: the handle, cell (subtree) id asked for */
    uint32_t start, end;       /* CELLS, BYTES: the range; STEPS: end from the first frame */
    uint32_t next;             /* the offset the next PAYLOAD must start at, once started */
    uint8_t kind, stream, unit; /* DOCUMENT: stream is the document kind */
    bool started;              /* a first PAYLOAD, or OPEN: MODEL_OPENED, came */
    bool done;                 /* its terminal frame came */
} pending;

struct ms_client {
    struct bufferevent *bev;
    const ms_client_handlers *handlers;
    void *arg;
    ms_proto_decoder *decoder; /* owned */
    ms_proto_hello_reply limits;
    uint32_t next_id;
    bool over;
    /* The index blob being received (one OPEN_MODEL at a time is reassembled;
     * others interleave only if the caller opens several at once, which the
     * server answers in order anyway). */
    uint32_t index_request;
    ms_proto_model_opened opened;
    uint8_t *index;         /* index_size bytes: the blob, received or inflated */
    uint32_t index_have;    /* bytes of INDEX_DATA received (the wire form's) */
    uint32_t index_wire;    /* the wire size of the last index handed over */
    uint8_t *index_zlib;    /* the compressed form as it arrives (ZLIB encoding) */
    bool ask_index_zlib;    /* offer CAP_INDEX_ZLIB in HELLO */
    bool ask_index_subtrees; /* offer CAP_INDEX_SUBTREES in HELLO */
    struct ev_token_bucket_cfg *rate;
    uint64_t bytes_read;
    pending *pending;          /* outstanding requests, ids ascending (done ones until compacted) */
    size_t pending_count, pending_cap, pending_done;
    /* The document being received (one at a time: the DOCUMENT frames of one
     * request are never interleaved with another's, PROTOCOL.md 4.5b). */
    uint32_t doc_request;      /* 0: none */
    uint8_t *doc;              /* doc_total bytes */
    uint32_t doc_total, doc_have;
    /* The handler of DOCUMENT frames, set by the first GET_DOCUMENT sent
     * (ms_client_document.c, which uses this file and is not used by it);
     * NULL: no document was asked for, a DOCUMENT frame is a violation. */
    void (*on_document)(ms_client *c, const ms_proto_message *m);
    /* ms_client_fetch_document waiting for request wait_id */
    uint32_t wait_id;
    bool waiting, wait_done, wait_timed_out;
    double wait_limit_s;       /* 0: MS_CLIENT_DOCUMENT_TIMEOUT_S */
    uint8_t *wait_bytes;
    size_t wait_length;
    char why[MS_ERROR_TEXT_MAX]; /* the wait's error, or why the connection ended */
};

/* Ends the connection (once): handlers->closed gets why. */
void ms_client_finish(ms_client *c, const char *why);
/* Encodes and queues msg; MS_ERR_IO once the connection is over. */
ms_status ms_client_send_message(ms_client *c, const ms_proto_message *msg, ms_error *err);
/* count consecutive request ids. */
uint32_t ms_client_take_ids(ms_client *c, uint32_t count);
/* The outstanding request id, or NULL (never sent, or ended). */
pending *ms_client_pending_find(ms_client *c, uint32_t id);
/* Records request id as outstanding; NULL when out of memory. */
pending *ms_client_pending_add(ms_client *c, uint32_t id);
void ms_client_pending_end(ms_client *c, pending *p);

#endif
