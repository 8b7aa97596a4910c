/* Writing protocol frames into a libevent output buffer.
 *
 * Control messages are encoded (and so validated) by ms_proto_encode and
 * copied. Frames that carry archive bytes (PAYLOAD, INDEX_DATA) are written as
 * a small copied head followed by a reference to the archive mapping: the bytes
 * are never copied in user space, and the model stays mapped (one reference
 * held) until libevent has written them and calls the release.
 *
 * Thread-safety: the loop's thread only.
 */
#ifndef MS_FRAME_OUT_H
#define MS_FRAME_OUT_H

#include <stdbool.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"

struct evbuffer;
struct ms_model;

/* Encodes msg into out. MS_ERR_RANGE/FORMAT when msg is invalid (our bug),
 * MS_ERR_NOMEM when the buffer cannot grow. */
ms_status ms_frame_out_message(struct evbuffer *out, const ms_proto_message *msg, ms_error *err);

/* An ERROR frame; request_count 0 makes it connection-level (request_id 0).
 * FATAL is set when fatal is true (the sender closes after it: any error in
 * answer to a HELLO, for instance) or when the code is always fatal. */
ms_status ms_frame_out_error(struct evbuffer *out, uint16_t code, bool fatal, uint32_t request_id,
                             uint32_t request_count, uint64_t detail, const char *text,
                             ms_error *err);

/* A PAYLOAD frame whose data[0..length) lies in model's mapping. *in_flight
 * (the server's transfers_in_flight) counts references not yet written. */
ms_status ms_frame_out_payload(struct evbuffer *out, uint32_t request_id, uint32_t cell,
                               uint8_t stream, uint32_t offset, uint32_t end, bool last,
                               const uint8_t *data, uint32_t length, struct ms_model *model,
                               uint64_t *in_flight, ms_error *err);

/* An INDEX_DATA frame whose data[0..length) lies in model's mapping. */
ms_status ms_frame_out_index_data(struct evbuffer *out, uint32_t request_id, uint32_t offset,
                                  bool last, const uint8_t *data, uint32_t length,
                                  struct ms_model *model, uint64_t *in_flight, ms_error *err);

#endif
