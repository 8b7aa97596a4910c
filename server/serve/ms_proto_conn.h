/* One binary-protocol connection of meshserve: its socket (a bufferevent), the
 * incremental decoder, the handshake, the open models, the request queue and
 * the per-connection limits (outstanding requests, queued bytes, request rate,
 * idle time-out). ms_proto_conn.c moves bytes (input, output, closing);
 * ms_proto_requests.c answers every message a client may send.
 *
 * Memory per connection is bounded: input is read only while the output
 * buffer holds less than MS_PROTO_CONN_OUTPUT_LIMIT bytes, the decoder holds at
 * most one frame (max_frame, at most 64 KiB + 8: the largest batch), payload chunks are added only while the output
 * holds less than MS_PROTO_CONN_HIGH_WATER, and the queue is bounded by
 * max_outstanding. Payload bytes are references into the archive mapping.
 *
 * Private to server/: the door (ms_proto_door.c) creates and frees
 * connections; everything runs on the loop's thread.
 */
#ifndef MS_PROTO_CONN_H
#define MS_PROTO_CONN_H

#include <event2/util.h>
#include <stdbool.h>
#include <stdint.h>

#include "ms_access.h"
#include "ms_fair_scheduler.h"
#include "ms_proto.h"
#include "ms_request_queue.h"

struct bufferevent;
struct ms_server;
struct ms_model;
struct ms_registry;

#define MS_PROTO_CONN_HIGH_WATER (256u << 10)   /* stop adding payload chunks */
#define MS_PROTO_CONN_LOW_WATER (128u << 10)    /* resume (write callback) */
#define MS_PROTO_CONN_OUTPUT_LIMIT (1u << 20)   /* stop reading input */
#define MS_PROTO_CONN_MAX_OPEN_MODELS 64u
#define MS_PROTO_CONN_LINGER_SECONDS 2.0        /* wait for the peer's EOF after a fatal error */
#define MS_PROTO_CONN_HANDSHAKE_SECONDS 10u     /* most time from accept to HELLO */

/* What the door shares with its connections. */
typedef struct ms_serve_door_shared {
    struct ms_server *server;
    ms_fair_scheduler scheduler;
    bool draining;
    /* Limits announced in HELLO_REPLY, derived once from the config. */
    ms_proto_hello_reply limits;
    double send_timeout_s; /* config send_timeout: most time without send progress */
} ms_serve_door_shared;

typedef struct ms_open_model {
    uint32_t handle;        /* 0 = free slot */
    struct ms_model *model; /* one reference held */
    ms_access grant;        /* what this connection may read of it, fixed at open */
} ms_open_model;

typedef enum ms_conn_state {
    MS_CONN_AWAIT_HELLO,
    MS_CONN_READY,
    MS_CONN_CLOSING, /* fatal ERROR queued: flushing, then lingering for EOF */
} ms_conn_state;

typedef struct ms_serve_conn {
    ms_fair_link link;               /* first: the scheduler hands it back */
    struct ms_serve_conn *prev, *next; /* the door's list of connections */
    ms_serve_door_shared *door;
    struct bufferevent *bev;
    ms_conn_state state;
    bool rejected;                   /* over the connection limit: not counted */
    bool write_shut;                 /* shutdown(SHUT_WR) done */
    bool peer_eof;                   /* the peer shut down its side */
    bool reading_paused;             /* output over MS_PROTO_CONN_OUTPUT_LIMIT */
    ms_proto_decoder *decoder;       /* owned */
    uint32_t client_max_frame;
    uint16_t version;                /* negotiated (HELLO_REPLY) */
    uint32_t capabilities;           /* granted */
    bool token_accepted;
    ms_open_model models[MS_PROTO_CONN_MAX_OPEN_MODELS];
    uint32_t next_handle;
    ms_request_queue queue;
    double rate_tokens, rate_updated;
    double last_frame_at, closing_since;
    /* When the output buffer last shrank (the peer read), or last filled from
     * empty: a connection with bytes waiting and no progress for
     * send_timeout_s is a slow reader, dropped by the sweep. */
    double last_send_progress;
    /* For the access log (ms_server_access_log), written as the connection is freed. */
    char peer[64];                   /* "ADDRESS:PORT" */
    double opened_at;
    uint64_t requests, bytes_sent;   /* requests received, payload bytes sent */
    uint16_t fatal_code;             /* the fatal ERROR that closed it; 0: none */
    char model_names[256];           /* every model opened, comma separated (cut at the size) */
} ms_serve_conn;

/* Takes fd; creates the bufferevent and starts reading. NULL on failure (fd
 * closed). A rejected connection gets ERROR TOO_MANY_CONNECTIONS and closes. */
ms_serve_conn *ms_serve_conn_new(ms_serve_door_shared *door, evutil_socket_t fd, bool rejected);

/* Frees everything the connection holds (queued requests, model references,
 * buffers; payload references already in the output buffer are released by
 * libevent as the buffer is freed). */
void ms_serve_conn_free(ms_serve_conn *conn);

/* Sends a fatal ERROR and starts the lingering close. */
void ms_serve_conn_fail(ms_serve_conn *conn, uint16_t code, uint64_t detail, const char *text);

/* Sends an ERROR ending requests request_id .. request_id + count - 1 (count
 * 0: connection level); an always-fatal code goes through ms_serve_conn_fail. */
void ms_serve_conn_send_error(ms_serve_conn *conn, uint16_t code, uint32_t request_id,
                              uint32_t count, uint64_t detail, const char *text);
/* Encodes and queues a control message. */
void ms_serve_conn_send_message(ms_serve_conn *conn, const ms_proto_message *msg);
/* Closes without a word: stops answering, flushes what is queued, shuts down
 * writing and waits (a while) for the peer's end of stream. */
void ms_serve_conn_start_closing(ms_serve_conn *conn);
/* The output buffer refused bytes: close without another word. */
void ms_serve_conn_broken(ms_serve_conn *conn);

/* Answers one decoded message (ms_proto_requests.c). */
void ms_serve_conn_handle_message(ms_serve_conn *conn, const ms_proto_message *msg);

/* After a rescan (ms_proto_requests.c): every open handle whose model is no
 * longer registry's model of that name with the same content_id (replaced or
 * removed) loses its queued requests (no CANCELLED each) and is closed, and
 * the client gets ERROR MODEL_CHANGED (request_id 0, detail = the handle).
 * Payload frames already in the output buffer stay whole. Handles of
 * unchanged models see nothing. */
void ms_serve_conn_models_changed(ms_serve_conn *conn, const struct ms_registry *registry);

/* The scheduler's callback: sends one payload chunk. */
bool ms_serve_conn_send_chunk(ms_fair_link *link, void *arg);

/* One non-blocking attempt to write what the output buffer holds (before a
 * forced close). */
void ms_serve_conn_flush_now(ms_serve_conn *conn);

/* Periodic check (idle time-out, linger time-out). Returns false when the
 * connection must be freed now. */
bool ms_serve_conn_sweep(ms_serve_conn *conn, double now);

/* Drain: stop reading; close at once if nothing is queued. */
void ms_serve_conn_drain(ms_serve_conn *conn);

/* Called by the connection when it is finished: the door unlinks and frees it. */
void ms_serve_door_connection_done(ms_serve_door_shared *door, ms_serve_conn *conn);

#endif
