/* The protocol decoder's state, behind the opaque ms_proto_decoder of
 * ms_proto.h: for ms_proto_decode.c and for white-box tests that check how much
 * memory the decoder keeps. Nothing else reads these fields. */
#ifndef MS_PROTO_DECODE_INTERNAL_H
#define MS_PROTO_DECODE_INTERNAL_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_proto.h"

struct ms_proto_decoder {
    ms_proto_decoder_config config;
    bool handshake_done;    /* first frame (HELLO / HELLO_REPLY) seen */
    bool peer_closed;       /* a fatal ERROR was received: nothing may follow */
    bool failed;            /* a fatal fault happened; failure/failure_text repeat it */
    ms_proto_fault failure;
    char failure_text[MS_ERROR_TEXT_MAX];
    uint8_t header[MS_PROTO_HEADER_SIZE];
    size_t header_have;     /* bytes of header buffered */
    uint32_t body_length;   /* of the current frame, once the header is complete */
    uint8_t *body;          /* owned; grown up to body_length only */
    size_t body_capacity;
    size_t body_have;
    void *scratch;          /* owned; decoded arrays (batch entries, ...) */
    size_t scratch_capacity;
    uint64_t stream_offset; /* bytes consumed since creation, for error texts */
    uint64_t frame_start;   /* stream offset of the current frame */
};

#endif
