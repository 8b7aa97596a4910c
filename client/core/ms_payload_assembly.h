/* Reassembly of PAYLOAD frames into the byte ranges a client asked for
 * (PROTOCOL.md section 4.11): per outstanding request, its frames must name
 * the requested cell and stream, come in increasing offset order, contiguous,
 * from the range's start, never past its end, and the frame with LAST must end
 * exactly at it. Anything else is a server bug, reported as MS_ERR_FORMAT (a
 * client then closes the connection: section 9).
 *
 * With keep_bytes the bytes of each range are gathered and handed over whole
 * when its LAST frame arrives (a decoder can also take them frame by frame
 * from the PAYLOAD messages themselves); without, only offsets are checked.
 *
 * Ownership: the assembly owns its buffers; a completed range's data stays
 * valid until the next call on the assembly. Thread-safety: one thread.
 */
#ifndef MS_PAYLOAD_ASSEMBLY_H
#define MS_PAYLOAD_ASSEMBLY_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"

typedef struct ms_payload_assembly ms_payload_assembly;

typedef struct ms_assembled_range {
    uint32_t request_id;
    uint32_t cell;
    uint8_t stream;        /* ms_proto_stream */
    uint32_t start, end;   /* byte range of the stream */
    const uint8_t *data;   /* end - start bytes with keep_bytes, else NULL */
} ms_assembled_range;

/* max_bytes bounds the bytes held for incomplete ranges (keep_bytes only);
 * MS_ERR_NOMEM beyond it. */
ms_status ms_payload_assembly_new(bool keep_bytes, size_t max_bytes, ms_payload_assembly **out,
                                  ms_error *err);
void ms_payload_assembly_free(ms_payload_assembly *assembly);

/* Registers an outstanding request. MS_ERR_ARG if the id is already pending. */
ms_status ms_payload_assembly_expect(ms_payload_assembly *assembly, uint32_t request_id,
                                     uint32_t cell, uint8_t stream, ms_error *err);

/* Takes one PAYLOAD frame. On MS_OK, *done tells whether the request is
 * complete; then *range describes it and the request is no longer pending. */
ms_status ms_payload_assembly_add(ms_payload_assembly *assembly, uint32_t request_id,
                                  const ms_proto_payload *payload, bool last, bool *done,
                                  ms_assembled_range *range, ms_error *err);

/* Drops a pending request (ended by an ERROR, or given up). No-op if unknown. */
void ms_payload_assembly_forget(ms_payload_assembly *assembly, uint32_t request_id);

/* Requests pending, and bytes held for them. */
size_t ms_payload_assembly_pending(const ms_payload_assembly *assembly);
size_t ms_payload_assembly_held_bytes(const ms_payload_assembly *assembly);

#endif
