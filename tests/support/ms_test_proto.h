/* A blocking, bounded-in-time binary-protocol client for tests of meshserve:
 * sends encoded messages or raw bytes, and receives decoded frames (strictly
 * validated, client role). Every receive waits at most a few seconds. */
#ifndef MS_TEST_PROTO_H
#define MS_TEST_PROTO_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_proto.h"

typedef struct ms_test_conn {
    int fd;
    ms_proto_decoder *decoder; /* owned */
    uint8_t buffer[65536];
    size_t have, used;
    bool eof;
} ms_test_conn;

/* Connects to 127.0.0.1:port. 0 on success. */
int ms_test_conn_open(ms_test_conn *conn, uint16_t port);
void ms_test_conn_close(ms_test_conn *conn);

/* Encodes and sends msg (fails the test when it does not encode). */
void ms_test_conn_send(ms_test_conn *conn, const ms_proto_message *msg);
/* Sends bytes verbatim. 0 on success. */
int ms_test_conn_send_raw(ms_test_conn *conn, const void *data, size_t size);

/* Receives the next frame into msg (pointers valid until the next receive).
 * Returns 1 for a message, 0 at end of stream, -1 on time-out, socket error or
 * a frame the decoder rejects. */
int ms_test_conn_recv(ms_test_conn *conn, ms_proto_message *msg, double timeout_seconds);

/* HELLO with token (may be NULL), versions 1..1 and CAP_APO, as a version-1
 * client sends it; receives HELLO_REPLY into reply (fails the test otherwise). */
void ms_test_conn_hello(ms_test_conn *conn, const char *token, ms_proto_hello_reply *reply);
/* The same with versions 1..max_version and the given capability bits. */
void ms_test_conn_hello_with(ms_test_conn *conn, const char *token, uint16_t max_version,
                             uint32_t capabilities, ms_proto_hello_reply *reply);

/* Receives frames until an ERROR; fails the test on time-out or end of stream.
 * Returns the error code and stores the header id and body. Skips other frames. */
uint16_t ms_test_conn_expect_error(ms_test_conn *conn, uint32_t *request_id,
                                   ms_proto_error_body *body);

/* OPEN_MODEL name with id; receives MODEL_OPENED and the index blob (malloc'd
 * into *index; inflated and CRC-checked when it came ZLIB-encoded, the head as
 * received and CRC-checked when SUBTREES, else as received). Returns the handle, 0 when the server answered with an ERROR
 * (whose code goes to *error_code). */
uint32_t ms_test_conn_open_model(ms_test_conn *conn, const char *name, uint32_t id,
                                 ms_proto_model_opened *opened, uint8_t **index,
                                 uint16_t *error_code);

/* REQUEST_CELLS of count entries on handle, ids first_id.. */
void ms_test_conn_send_batch(ms_test_conn *conn, uint32_t handle, uint32_t first_id,
                             const ms_proto_cell_request *entries, uint16_t count);

/* Reassembles the answers to requests first..first+count-1: data per id,
 * terminal frames counted, the error code of requests ended by an ERROR. */
typedef struct ms_test_answers {
    uint32_t first, count;
    uint8_t **data;
    uint32_t *length, *start, *end;
    uint16_t *error;
    unsigned *terminals;
    uint32_t *order; /* ids in the order their terminal frame came */
    uint32_t done;
} ms_test_answers;

/* Allocates the bookkeeping of requests first..first+count-1; _free releases it. */
void ms_test_answers_init(ms_test_answers *a, uint32_t first, uint32_t count);
void ms_test_answers_free(ms_test_answers *a);
/* Takes one frame (PAYLOAD or ERROR) into a; false when it is not about these
 * requests. Fails the test on a frame after a request's terminal frame, or
 * payload frames out of order. */
bool ms_test_answers_take(ms_test_answers *a, const ms_proto_message *m);
/* Receives until every request has its terminal frame (fails the test on a
 * time-out, end of stream or a fatal ERROR); each exactly one. */
void ms_test_answers_collect(ms_test_conn *conn, ms_test_answers *a);

#endif
