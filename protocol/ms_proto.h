/* The meshstream wire protocol, versions 1, 2 and 3: message structs, encoders, and an
 * incremental frame decoder with strict validation. protocol/PROTOCOL.md is the
 * normative specification; the numbers of sections quoted here are its sections.
 *
 * Pure code: no I/O, no global mutable state, no threads. Encoding functions are
 * thread-safe. A decoder object is used by one thread at a time; distinct
 * decoder objects are independent.
 *
 * Errors follow common/util/ms_error.h: functions return an ms_status and fill an
 * optional ms_error with one line of text. Decoding also fills an ms_proto_fault
 * with the wire error code (section 9) to send to the peer, whether it is fatal,
 * and which request ids it ends, so that a server can answer every bad frame
 * with the documented ERROR frame.
 */
#ifndef MS_PROTO_H
#define MS_PROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

/* ---- Constants (section numbers refer to PROTOCOL.md) ---- */

#define MS_PROTO_VERSION 3u                 /* the highest version this code speaks */
#define MS_PROTO_MIN_VERSION 1u             /* the lowest version this code speaks */
#define MS_PROTO_HEADER_SIZE 12u            /* frame header bytes (section 2) */
#define MS_PROTO_MIN_FRAME 16384u           /* least max_frame; pre-handshake limit */
#define MS_PROTO_MAX_FRAME 16777216u        /* greatest max_frame (16 MiB) */
#define MS_PROTO_MAX_BATCH 4096u            /* greatest max_batch */
#define MS_PROTO_MAX_OUTSTANDING 1048576u   /* greatest max_outstanding */
#define MS_PROTO_MAX_QUEUED_BYTES (1ull << 40)
#define MS_PROTO_MIN_IDLE_TIMEOUT_MS 1000u
#define MS_PROTO_MAX_IDLE_TIMEOUT_MS 86400000u
#define MS_PROTO_MAX_OPEN_MODELS 1024u
#define MS_PROTO_MAX_TOKEN 256u             /* token bytes, 0x21..0x7E */
#define MS_PROTO_MAX_LABEL 64u              /* agent / server name, 0x20..0x7E */
#define MS_PROTO_MAX_MODEL_NAME 64u         /* [A-Za-z0-9_-]{1,64} */
#define MS_PROTO_MAX_TEXT 256u              /* error text, catalogue title: UTF-8 */
#define MS_PROTO_MAX_CANCEL_RANGES 256u
#define MS_PROTO_MAX_CELLS (1u << 26)       /* greatest cell_count */
#define MS_PROTO_MAX_INDEX_SIZE (64u << 20) /* greatest header + index blob */
#define MS_PROTO_MAX_STEPS 64u              /* greatest geometry/APO step count */
#define MS_PROTO_MAX_STEP 63u               /* greatest step number in a request */
#define MS_PROTO_PAYLOAD_CHUNK 65536u       /* advised payload data per frame */

/* Fixed parts of the bodies, in bytes (section 4). */
#define MS_PROTO_HELLO_FIXED 24u
#define MS_PROTO_HELLO_REPLY_FIXED 48u
#define MS_PROTO_PING_SIZE 8u
#define MS_PROTO_OPEN_MODEL_FIXED 4u
#define MS_PROTO_CLOSE_MODEL_SIZE 4u
#define MS_PROTO_REQUEST_CELLS_FIXED 8u
#define MS_PROTO_CELL_REQUEST_SIZE 16u
#define MS_PROTO_CANCEL_FIXED 4u
#define MS_PROTO_CANCEL_RANGE_SIZE 8u
#define MS_PROTO_ERROR_FIXED 18u
#define MS_PROTO_CATALOGUE_FIXED 4u
#define MS_PROTO_LIST_PAGE_FIXED 12u        /* version 3: LIST_PAGE before its query */
#define MS_PROTO_CATALOGUE_PAGE_FIXED 8u    /* version 3: CATALOGUE_PAGE before its entries */
#define MS_PROTO_MAX_PAGE 1000u             /* entries one LIST_PAGE asks for */
#define MS_PROTO_MAX_PAGE_QUERY 64u         /* bytes of a LIST_PAGE text filter */
#define MS_PROTO_GET_DOCUMENT_FIXED 4u       /* version 3: GET_DOCUMENT before its name */
#define MS_PROTO_DOCUMENT_FIXED 12u          /* version 3: DOCUMENT before its data */
#define MS_PROTO_MAX_DOCUMENT (1u << 20)     /* bytes of one document (1 MiB) */
#define MS_PROTO_CATALOGUE_ENTRY_FIXED 32u
#define MS_PROTO_MODEL_OPENED_SIZE 32u
#define MS_PROTO_INDEX_DATA_FIXED 4u
#define MS_PROTO_PAYLOAD_FIXED 16u

/* The four bytes HELLO and HELLO_REPLY start with. */
#define MS_PROTO_MAGIC "MSTP"

/* Header flag bits. */
#define MS_PROTO_FLAG_LAST 0x01u
/* Capability bits (section 3). */
#define MS_PROTO_CAP_APO 0x00000001u
/* Version 2: the index blob may be sent zlib-compressed (section 4.7). */
#define MS_PROTO_CAP_INDEX_ZLIB 0x00000002u
/* Version 3: the index may be sent as its head (archive header + root subtree)
 * and the rest of it requested by subtree, as stream INDEX (sections 4.7, 4.10). */
#define MS_PROTO_CAP_INDEX_SUBTREES 0x00000004u
/* Version 3: per-vertex colour streams (stream COLOUR, section 4.10). */
#define MS_PROTO_CAP_COLOUR 0x00000008u
/* HELLO_REPLY server_flags bits. */
#define MS_PROTO_SERVER_TOKEN_ACCEPTED 0x0001u
/* CANCEL flags bits. */
#define MS_PROTO_CANCEL_ALL 0x0001u
/* ERROR flags bits. */
#define MS_PROTO_ERROR_FATAL 0x01u

typedef enum ms_proto_type {
    MS_PROTO_NONE = 0x00, /* no message (decoder: nothing complete yet) */
    MS_PROTO_HELLO = 0x01,
    MS_PROTO_LIST_CATALOGUE = 0x02,
    MS_PROTO_OPEN_MODEL = 0x03,
    MS_PROTO_CLOSE_MODEL = 0x04,
    MS_PROTO_REQUEST_CELLS = 0x05,
    MS_PROTO_CANCEL = 0x06,
    MS_PROTO_LIST_PAGE = 0x07,          /* version 3 */
    MS_PROTO_GET_DOCUMENT = 0x08,       /* version 3 */
    MS_PROTO_PING = 0x40,
    MS_PROTO_PONG = 0x41,
    MS_PROTO_ERROR = 0x7F,
    MS_PROTO_HELLO_REPLY = 0x81,
    MS_PROTO_CATALOGUE = 0x82,
    MS_PROTO_MODEL_OPENED = 0x83,
    MS_PROTO_INDEX_DATA = 0x84,
    MS_PROTO_PAYLOAD = 0x85,
    MS_PROTO_CATALOGUE_PAGE = 0x86,     /* version 3 */
    MS_PROTO_DOCUMENT = 0x87            /* version 3 */
} ms_proto_type;

/* The documents of a model (GET_DOCUMENT's kind, version 3, section 4.5b);
 * the same numbers on both sides and at both doors. */
typedef enum ms_document_kind {
    MS_DOCUMENT_THUMBNAIL = 1,   /* the PNG meshbake drew (DIR/NAME.thumb.png) */
    MS_DOCUMENT_METADATA = 2,    /* the model's catalogue entry as JSON, as /catalog lists it */
    MS_DOCUMENT_ANNOTATIONS = 3  /* DIR/NAME.annotations.json as stored, at most 1 MiB */
} ms_document_kind;
#define MS_DOCUMENT_FIRST 1
#define MS_DOCUMENT_LAST 3
/* "thumbnail", "metadata", "annotations" (the HTTP door's path), or "?". */
const char *ms_document_kind_name(int kind);

/* Wire error codes (section 9). */
typedef enum ms_proto_error_code {
    MS_PROTO_E_MALFORMED_FRAME = 1,
    MS_PROTO_E_FRAME_TOO_LARGE = 2,
    MS_PROTO_E_UNKNOWN_TYPE = 3,
    MS_PROTO_E_UNEXPECTED_MESSAGE = 4,
    MS_PROTO_E_UNSUPPORTED_VERSION = 5,
    MS_PROTO_E_FIELD_OUT_OF_RANGE = 6,
    MS_PROTO_E_BATCH_TOO_LARGE = 7,
    MS_PROTO_E_TOO_MANY_OUTSTANDING = 8,
    MS_PROTO_E_RATE_LIMITED = 9,
    MS_PROTO_E_QUEUE_FULL = 10,
    MS_PROTO_E_DUPLICATE_REQUEST_ID = 11,
    MS_PROTO_E_BAD_MODEL_NAME = 12,
    MS_PROTO_E_UNKNOWN_MODEL = 13,
    MS_PROTO_E_TOO_MANY_MODELS = 14,
    MS_PROTO_E_UNKNOWN_CELL = 15,
    MS_PROTO_E_RANGE_NOT_SATISFIABLE = 16,
    MS_PROTO_E_FORBIDDEN = 17,
    MS_PROTO_E_CANCELLED = 18,
    MS_PROTO_E_IDLE_TIMEOUT = 19,
    MS_PROTO_E_TOO_MANY_CONNECTIONS = 20,
    MS_PROTO_E_SHUTTING_DOWN = 21,
    MS_PROTO_E_INTERNAL = 22,
    /* Server only, never fatal, request_id 0, detail = a model handle: a
     * rescan replaced or removed that handle's model; the handle is closed and
     * every request outstanding on it ended (section 9). */
    MS_PROTO_E_MODEL_CHANGED = 23,
    /* Version 3, never fatal, detail = the kind asked for: the model has no
     * such document, or none this reader may see (section 4.5b). */
    MS_PROTO_E_NO_DOCUMENT = 24
} ms_proto_error_code;
#define MS_PROTO_E_FIRST 1
#define MS_PROTO_E_LAST 24

/* Whether an error code is fatal (the FATAL column of section 9). */
typedef enum ms_proto_fatality {
    MS_PROTO_FATAL_NEVER = 0,
    MS_PROTO_FATAL_ALWAYS = 1,
    MS_PROTO_FATAL_EITHER = 2
} ms_proto_fatality;

typedef enum ms_proto_stream {
    MS_PROTO_STREAM_GEOMETRY = 0,
    MS_PROTO_STREAM_APO = 1,
    /* Version 3, with CAP_INDEX_SUBTREES: the stored (zlib) bytes of one index
     * subtree; cell_id is the subtree id, the stream has exactly one step. */
    MS_PROTO_STREAM_INDEX = 2,
    /* Version 3, with CAP_COLOUR: a cell's colour stream (docs/ARCHIVE.md,
     * "Colour streams"); steps are precision bits, as geometry's. */
    MS_PROTO_STREAM_COLOUR = 3
} ms_proto_stream;

/* How INDEX_DATA carries the index blob (MODEL_OPENED index_encoding). */
typedef enum ms_proto_index_encoding {
    MS_PROTO_INDEX_RAW = 0, /* the blob itself */
    MS_PROTO_INDEX_ZLIB = 1, /* one zlib (RFC 1950) stream, shorter than the blob */
    /* Version 3, with CAP_INDEX_SUBTREES: the index head (a version-3 archive
     * header and the root subtree's stored bytes), sent as is; the other
     * subtrees are requested with stream INDEX. */
    MS_PROTO_INDEX_SUBTREES = 2
} ms_proto_index_encoding;

typedef enum ms_proto_unit {
    MS_PROTO_UNIT_STEPS = 0, /* precision bits (geometry) or octree levels (APO) */
    MS_PROTO_UNIT_BYTES = 1
} ms_proto_unit;

/* ---- Message bodies. Strings are (pointer, length), never NUL-terminated.
 * In a decoded message every pointer points into the decoder's memory (valid
 * until the next call on that decoder); for encoding they point to the
 * caller's memory, which is only read. ---- */

typedef struct ms_proto_hello {
    uint16_t min_version, max_version; /* 1 <= min <= max */
    uint32_t capabilities;             /* MS_PROTO_CAP_* bits; unknown bits allowed */
    uint32_t max_frame;                /* [MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME] */
    const char *token;                 /* token_length bytes in 0x21..0x7E */
    uint16_t token_length;             /* [0, MS_PROTO_MAX_TOKEN] */
    const char *agent;                 /* agent_length bytes in 0x20..0x7E */
    uint16_t agent_length;             /* [0, MS_PROTO_MAX_LABEL] */
} ms_proto_hello;

typedef struct ms_proto_hello_reply {
    uint16_t version;           /* >= 1 */
    uint16_t server_flags;      /* MS_PROTO_SERVER_* bits only */
    uint32_t capabilities;
    uint32_t max_frame;         /* [MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME] */
    uint32_t max_batch;         /* [1, MS_PROTO_MAX_BATCH] */
    uint32_t max_outstanding;   /* [1, MS_PROTO_MAX_OUTSTANDING] */
    uint64_t max_queued_bytes;  /* [1, MS_PROTO_MAX_QUEUED_BYTES] */
    uint32_t idle_timeout_ms;   /* 0 or [MIN_IDLE_TIMEOUT_MS, MAX_IDLE_TIMEOUT_MS] */
    uint32_t max_request_rate;  /* requests per second, 0 = unlimited */
    uint16_t max_open_models;   /* [1, MS_PROTO_MAX_OPEN_MODELS] */
    const char *server_name;    /* 0x20..0x7E */
    uint16_t server_name_length; /* [0, MS_PROTO_MAX_LABEL] */
} ms_proto_hello_reply;

typedef struct ms_proto_ping {
    uint64_t opaque; /* echoed by PONG */
} ms_proto_ping;

typedef struct ms_proto_catalogue_entry {
    const char *name;          /* model name, [A-Za-z0-9_-] */
    uint8_t name_length;       /* [1, 64] */
    uint8_t geometry_steps;    /* [1, 64] */
    uint8_t apo_steps;         /* [0, 64] */
    uint8_t permitted_geometry_steps; /* [1, geometry_steps] */
    uint8_t permitted_apo_steps;      /* [0, apo_steps] */
    const char *title;         /* UTF-8 text, no control characters */
    uint16_t title_length;     /* [0, MS_PROTO_MAX_TEXT] */
    uint32_t cell_count;       /* [1, MS_PROTO_MAX_CELLS] */
    uint64_t content_id;
    uint64_t archive_bytes;
} ms_proto_catalogue_entry;

typedef struct ms_proto_catalogue {
    const ms_proto_catalogue_entry *entries;
    uint16_t entry_count; /* 0 only with MS_PROTO_FLAG_LAST */
    uint32_t total;       /* CATALOGUE_PAGE only: the models the page's filter matches */
} ms_proto_catalogue;

/* LIST_PAGE's sort keys (version 3, section 4.11). */
typedef enum ms_proto_page_sort {
    MS_PROTO_SORT_NAME = 0,
    MS_PROTO_SORT_SIZE = 1,      /* archive bytes */
    MS_PROTO_SORT_DATE = 2,      /* bake time */
    MS_PROTO_SORT_TRIANGLES = 3,
    MS_PROTO_SORT_LAST = MS_PROTO_SORT_TRIANGLES
} ms_proto_page_sort;

/* One page of the catalogue (version 3): entries [offset, offset + limit) of
 * the models whose name, source, title or description contains query (ASCII
 * case-insensitively; empty: every model), in sort order. */
typedef struct ms_proto_list_page {
    uint32_t offset;
    uint16_t limit;         /* [1, MS_PROTO_MAX_PAGE] */
    uint8_t sort;           /* ms_proto_page_sort */
    uint8_t descending;     /* 0 or 1 */
    const char *query;      /* UTF-8 text, no control characters */
    uint8_t query_length;   /* [0, MS_PROTO_MAX_PAGE_QUERY] */
} ms_proto_list_page;

/* One document of a model (version 3, section 4.5b). */
typedef struct ms_proto_get_document {
    uint8_t kind;        /* ms_document_kind */
    const char *name;    /* the model's name, [A-Za-z0-9_-], else MS_PROTO_E_BAD_MODEL_NAME */
    uint8_t name_length; /* [1, 64] */
} ms_proto_get_document;

/* A chunk of a document (version 3, section 4.5b): data is the document's
 * bytes [offset, offset + data_length) of total_length; LAST on the frame
 * that ends it. */
typedef struct ms_proto_document {
    uint8_t kind;           /* ms_document_kind, the request's */
    uint32_t total_length;  /* [0, MS_PROTO_MAX_DOCUMENT] */
    uint32_t offset;        /* offset + data_length <= total_length */
    const uint8_t *data;
    uint32_t data_length;   /* 0 only for an empty document */
} ms_proto_document;

typedef struct ms_proto_open_model {
    const char *name;    /* [A-Za-z0-9_-], else MS_PROTO_E_BAD_MODEL_NAME */
    uint8_t name_length; /* [1, 64] */
} ms_proto_open_model;

typedef struct ms_proto_model_opened {
    uint32_t model_handle;   /* >= 1 */
    uint32_t cell_count;     /* [1, MS_PROTO_MAX_CELLS] */
    uint64_t content_id;
    uint32_t index_size;     /* [1, MS_PROTO_MAX_INDEX_SIZE] bytes of the blob (decoded), or
                              * with SUBTREES of the head */
    uint32_t index_crc32;    /* zlib crc32 of the whole blob (decoded), or of the head */
    uint8_t index_encoding;  /* ms_proto_index_encoding; ZLIB only with CAP_INDEX_ZLIB,
                              * SUBTREES only with CAP_INDEX_SUBTREES */
    uint16_t archive_version; /* >= 1: of the blob (1), or with SUBTREES of the head's header */
    uint8_t geometry_steps, apo_steps;                     /* as in the catalogue */
    uint8_t permitted_geometry_steps, permitted_apo_steps; /* as in the catalogue */
} ms_proto_model_opened;

typedef struct ms_proto_close_model {
    uint32_t model_handle; /* >= 1 */
} ms_proto_close_model;

/* One entry of a REQUEST_CELLS batch (section 4.10). */
typedef struct ms_proto_cell_request {
    uint32_t cell_id; /* stream INDEX: the subtree id */
    uint8_t stream;   /* ms_proto_stream */
    uint8_t unit;     /* ms_proto_unit */
    uint8_t priority; /* lower is sooner; ties FIFO */
    /* unit STEPS: a = first step, b = last step, a <= b <= MS_PROTO_MAX_STEP;
     * stream INDEX: a = b = 0 (a subtree is one step).
     * unit BYTES: a = byte offset, b = byte length >= 1, a + b <= UINT32_MAX. */
    uint32_t a, b;
} ms_proto_cell_request;

typedef struct ms_proto_request_cells {
    uint32_t model_handle; /* >= 1 */
    const ms_proto_cell_request *entries; /* entry i has request id first + i */
    uint16_t count;        /* [1, max_batch] */
} ms_proto_request_cells;

typedef struct ms_proto_id_range {
    uint32_t first_id; /* >= 1 */
    uint32_t count;    /* >= 1, first_id + count - 1 <= UINT32_MAX */
} ms_proto_id_range;

typedef struct ms_proto_cancel {
    uint16_t flags;    /* MS_PROTO_CANCEL_ALL or 0 */
    const ms_proto_id_range *ranges;
    uint16_t range_count; /* [0, 256]; 0 if and only if CANCEL_ALL */
} ms_proto_cancel;

/* A chunk of a model's header + cell index blob (section 4.8). */
typedef struct ms_proto_index_data {
    uint32_t offset;        /* offset + data_length <= MS_PROTO_MAX_INDEX_SIZE */
    const uint8_t *data;
    uint32_t data_length;   /* >= 1 */
} ms_proto_index_data;

typedef struct ms_proto_payload {
    uint32_t cell_id;        /* stream INDEX: the subtree id */
    uint8_t stream;          /* ms_proto_stream */
    uint32_t offset;         /* byte offset in the cell stream of data[0] */
    uint32_t end;            /* end of the request's range: offset + data_length <= end */
    const uint8_t *data;
    uint32_t data_length;    /* 0 only with MS_PROTO_FLAG_LAST; with LAST, offset + data_length == end */
} ms_proto_payload;

typedef struct ms_proto_error_body {
    uint16_t code;          /* ms_proto_error_code */
    bool fatal;             /* must match ms_proto_error_fatality(code) */
    uint32_t request_count; /* 0 if and only if the frame's request_id is 0 */
    uint64_t detail;
    const char *text;       /* UTF-8 text, one line */
    uint16_t text_length;   /* [0, MS_PROTO_MAX_TEXT] */
} ms_proto_error_body;

/* One message: the frame header fields plus the body of its type. */
typedef struct ms_proto_message {
    uint8_t type;        /* ms_proto_type */
    uint8_t flags;       /* MS_PROTO_FLAG_LAST where the type allows it */
    uint32_t request_id; /* section 5 */
    union {
        ms_proto_hello hello;
        ms_proto_hello_reply hello_reply;
        ms_proto_ping ping;                 /* PING and PONG */
        ms_proto_catalogue catalogue;       /* CATALOGUE and CATALOGUE_PAGE */
        ms_proto_list_page list_page;
        ms_proto_get_document get_document;
        ms_proto_document document;
        ms_proto_open_model open_model;
        ms_proto_model_opened model_opened;
        ms_proto_close_model close_model;
        ms_proto_request_cells request_cells;
        ms_proto_cancel cancel;
        ms_proto_index_data index_data;
        ms_proto_payload payload;
        ms_proto_error_body error;
    } body;
} ms_proto_message;

/* What a receiver must answer to a rejected frame (section 9). */
typedef struct ms_proto_fault {
    uint16_t code;          /* ms_proto_error_code */
    bool fatal;             /* true: send the ERROR, then close */
    uint8_t frame_type;     /* type byte of the offending frame, 0 if none */
    uint32_t request_id;    /* first request id the error ends, 0 = connection level */
    uint32_t request_count; /* 0 when request_id is 0 */
    uint64_t detail;        /* the code's detail value */
} ms_proto_fault;

/* ---- Names and small helpers (ms_proto_validate.c) ---- */

/* "HELLO", "PAYLOAD", ...; "?" for an undefined type. */
const char *ms_proto_type_name(uint8_t type);
/* "MALFORMED_FRAME", ...; "?" for an undefined code. */
const char *ms_proto_error_name(uint16_t code);
/* Fatality of a defined code; MS_PROTO_FATAL_ALWAYS for an undefined one. */
ms_proto_fatality ms_proto_error_fatality(uint16_t code);

/* True when name[0..length) is a model name ([A-Za-z0-9_-]{1,64}). Otherwise,
 * if bad_offset is non-NULL, stores the offset of the first bad byte (length
 * itself when the length is 0 or above 64). */
bool ms_proto_model_name_valid(const char *name, size_t length, size_t *bad_offset);
/* True for well-formed UTF-8 without control characters (section 1). */
bool ms_proto_text_valid(const uint8_t *text, size_t length);

/* Version negotiation (section 3): the highest version in both ranges. Returns
 * MS_ERR_UNSUPPORTED when the ranges do not intersect (or one is empty). */
ms_status ms_proto_choose_version(uint16_t client_min, uint16_t client_max, uint16_t server_min,
                                  uint16_t server_max, uint16_t *chosen);

/* The capability bits a protocol version defines (section 3): CAP_APO from
 * version 1, CAP_INDEX_ZLIB from 2, CAP_INDEX_SUBTREES from 3; 0 for version
 * 0. A server grants (client's bits & its own & this), never more. */
uint32_t ms_proto_version_capabilities(uint16_t version);

/* The rules of a message that depend on what the connection negotiated
 * (section 3), to apply after ms_proto_check_message (the decoder) by the side
 * that knows the negotiated version and the granted capabilities:
 *   HELLO_REPLY    capabilities only among those version defines;
 *   MODEL_OPENED   index_encoding ZLIB needs CAP_INDEX_ZLIB, SUBTREES needs
 *                  CAP_INDEX_SUBTREES;
 *   REQUEST_CELLS  an entry of stream APO needs CAP_APO, of stream INDEX
 *                  CAP_INDEX_SUBTREES (the fault names the whole batch);
 *   PAYLOAD        stream APO needs CAP_APO, stream INDEX CAP_INDEX_SUBTREES.
 * For HELLO_REPLY, version and capabilities are the reply's own. Returns MS_OK
 * or MS_ERR_RANGE with fault (if non-NULL) FIELD_OUT_OF_RANGE, detail = the
 * offset of the field in the body, the request ids it ends, fatal left false
 * (a client treats every fault in a server frame as fatal, section 9). Other
 * types: MS_OK. Pure; thread-safe. */
ms_status ms_proto_check_negotiated(const ms_proto_message *msg, uint16_t version,
                                    uint32_t capabilities, ms_proto_fault *fault, ms_error *err);

/* Checks every field range and cross-field rule of msg, header fields
 * included, exactly as a receiver would (max_batch: the batch limit to apply,
 * MS_PROTO_MAX_BATCH for the protocol's own). Returns MS_OK, or MS_ERR_RANGE /
 * MS_ERR_FORMAT with fault (if non-NULL) set to the wire error: code, detail
 * (field offset in the body for FIELD_OUT_OF_RANGE) and the request ids the
 * error ends. fault->fatal is left false; the decoder decides it by role. */
ms_status ms_proto_check_message(const ms_proto_message *msg, uint32_t max_batch,
                                 ms_proto_fault *fault, ms_error *err);

/* Fills out as an ERROR message describing fault, with text (may be NULL) cut
 * to at most MS_PROTO_MAX_TEXT bytes on a UTF-8 boundary. out->body.error.text
 * points into text, which must outlive out. */
void ms_proto_error_from_fault(const ms_proto_fault *fault, const char *text,
                               ms_proto_message *out);

/* ---- Encoding (ms_proto_encode.c) ---- */

/* Size in bytes of the whole frame (header included) msg encodes to. Does not
 * validate; returns MS_ERR_ARG for an undefined type. */
ms_status ms_proto_encoded_size(const ms_proto_message *msg, size_t *size, ms_error *err);

/* Validates msg with ms_proto_check_message(msg, MS_PROTO_MAX_BATCH) and writes
 * its frame to out[0..capacity). On success *written is the frame size. Errors:
 * MS_ERR_RANGE / MS_ERR_FORMAT (invalid message, nothing written), MS_ERR_ARG
 * (NULL argument, or capacity too small: *written is then the size needed). */
ms_status ms_proto_encode(const ms_proto_message *msg, uint8_t *out, size_t capacity,
                          size_t *written, ms_error *err);

/* ---- The index blob's wire encoding (ms_proto_index.c, section 4.8) ---- */

/* Compresses blob[0..size) into one zlib stream (level 9). On MS_OK, *encoded
 * is a malloc'd buffer the caller frees, of *encoded_size bytes. Returns
 * MS_ERR_RANGE (nothing allocated) when the stream would not be shorter than
 * the blob, in which case the blob is to be sent raw; MS_ERR_ARG for a size of
 * 0 or above MS_PROTO_MAX_INDEX_SIZE; MS_ERR_NOMEM. */
ms_status ms_proto_index_deflate(const uint8_t *blob, size_t size, uint8_t **encoded,
                                 size_t *encoded_size, ms_error *err);

/* Inflates a ZLIB-encoded index into out[0..declared_size) and checks the
 * CRC-32 of the result, never writing past out + declared_size (a stream that
 * would inflate further is rejected, not followed). The declared size comes
 * from MODEL_OPENED and is checked first. Errors, each with one line of text:
 *   MS_ERR_RANGE    declared_size 0 or above MS_PROTO_MAX_INDEX_SIZE, or
 *                   encoded_size 0 or not below declared_size;
 *   MS_ERR_FORMAT   not a zlib stream, truncated (input ends before the
 *                   stream), inflating to more or to fewer bytes than
 *                   declared, or bytes after the end of the stream;
 *   MS_ERR_CORRUPT  the inflated blob fails index_crc32;
 *   MS_ERR_NOMEM    zlib's own state could not be allocated.
 * out holds garbage after an error. Thread-safe. */
ms_status ms_proto_index_inflate(const uint8_t *encoded, size_t encoded_size,
                                 uint32_t declared_size, uint32_t index_crc32, uint8_t *out,
                                 ms_error *err);

/* ---- Decoding (ms_proto_decode.c) ---- */

typedef enum ms_proto_role {
    MS_PROTO_ROLE_SERVER = 1, /* decodes what clients send */
    MS_PROTO_ROLE_CLIENT = 2  /* decodes what servers send */
} ms_proto_role;

typedef struct ms_proto_decoder_config {
    ms_proto_role role;
    uint32_t max_frame; /* largest body this side accepts (what its hello announces) */
    uint32_t max_batch; /* server: largest batch accepted; client: ignored (use 0) */
} ms_proto_decoder_config;

/* Incremental decoder: opaque. One per byte stream (connection); it buffers
 * at most one incomplete frame and the decoded arrays of the last message.
 *
 * Ownership: ms_proto_decoder_new gives the caller the decoder, which owns all
 * its buffers; ms_proto_decoder_free releases them. A decoded message borrows
 * the decoder's memory until the next call on that decoder.
 *
 * Thread-safety: a decoder is used by one thread at a time; distinct decoders
 * are independent (no shared state). */
typedef struct ms_proto_decoder ms_proto_decoder;

/* Creates a decoder for config (copied) in *out; allocates only the handle,
 * buffers grow with the frames fed. config->max_frame must be in
 * [MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME] and, for a server, max_batch in
 * [1, MS_PROTO_MAX_BATCH]; a role that is neither server nor client, or a
 * NULL argument, is MS_ERR_ARG too; MS_ERR_NOMEM when the handle cannot be
 * allocated. *out is NULL after any error. */
ms_status ms_proto_decoder_new(const ms_proto_decoder_config *config, ms_proto_decoder **out,
                               ms_error *err);

/* Releases the decoder and its buffers; NULL is a no-op. */
void ms_proto_decoder_free(ms_proto_decoder *dec);

/* Feeds bytes as they arrive, in any split. Consumes input until one frame is
 * complete or the input is exhausted; *consumed says how many bytes were used,
 * so call again with the rest.
 *
 * Returns MS_OK with *have_message true when msg holds a validated message (its
 * pointers borrow decoder memory until the next call on dec), or with
 * *have_message false when all input was consumed without completing a frame.
 *
 * Returns an error status when a frame is rejected: fault says what to answer
 * (section 9) and err has one line of text. If fault->fatal is false the frame
 * was consumed whole and decoding can continue after it; if true, the decoder
 * is failed and every later call returns the same fault, consuming nothing.
 * Status: MS_ERR_FORMAT (malformed, unknown or unexpected type),
 * MS_ERR_NOMEM (frame too large, or memory exhausted: INTERNAL),
 * MS_ERR_RANGE (field out of range, batch too large, bad model name).
 *
 * Memory: the body buffer grows to the frame's declared body length only after
 * that length passed every header check (at most max_frame); decoded arrays
 * are bounded by the same length and by max_batch. */
ms_status ms_proto_decoder_feed(ms_proto_decoder *dec, const uint8_t *data, size_t size,
                                size_t *consumed, ms_proto_message *msg, bool *have_message,
                                ms_proto_fault *fault, ms_error *err);

/* To call at end of stream: MS_OK when no partial frame is buffered, else a
 * fatal MALFORMED_FRAME fault (truncated frame). */
ms_status ms_proto_decoder_finish(ms_proto_decoder *dec, ms_proto_fault *fault, ms_error *err);

/* Bytes of an incomplete frame currently buffered (header and body); 0 for
 * NULL. */
size_t ms_proto_decoder_buffered(const ms_proto_decoder *dec);

#endif
