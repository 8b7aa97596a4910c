/* Resolving a cell request to a byte range (PROTOCOL.md section 4.10): step
 * clamping, byte-range checks and preview access, so that the server and the
 * HTTP side door answer every request the same way. Pure functions, no state,
 * thread-safe. */
#ifndef MS_PROTO_RANGE_H
#define MS_PROTO_RANGE_H

#include <stdint.h>

#include "ms_error.h"
#include "ms_proto.h"

/* One stream (geometry or APO) of one cell, as the cell index describes it.
 * The stream holds steps first_step .. first_step + step_count - 1 (its
 * window); step_ends[i] is the byte offset at which step first_step + i is
 * complete, non-decreasing, and step_ends[step_count - 1] is the stream size.
 * step_count 0 is an empty stream. Borrowed, only read. */
typedef struct ms_proto_stream_steps {
    uint32_t first_step;      /* [0, MS_PROTO_MAX_STEP] */
    uint32_t step_count;      /* [0, MS_PROTO_MAX_STEPS - first_step] */
    const uint32_t *step_ends;
} ms_proto_stream_steps;

/* What a connection may read of one stream of a model (MODEL_OPENED). */
typedef struct ms_proto_stream_access {
    uint8_t model_steps;     /* geometry_steps or apo_steps of the model */
    uint8_t permitted_steps; /* permitted_*_steps of this connection, <= model_steps */
} ms_proto_stream_access;

/* A resolved byte range [begin, end) of a cell stream; begin == end is empty. */
typedef struct ms_proto_byte_range {
    uint32_t begin, end;
} ms_proto_byte_range;

/* MS_OK when cell_id < cell_count; otherwise MS_ERR_RANGE with fault =
 * UNKNOWN_CELL (detail: the cell id). fault->request_id/count are left 0 for
 * the caller to fill with the entry's id. */
ms_status ms_proto_check_cell_id(uint32_t cell_id, uint32_t cell_count, ms_proto_fault *fault,
                                 ms_error *err);

/* Maps a validated request entry (unit, a, b) on the stream described by steps
 * to a byte range, applying the clamping of STEPS, the bounds of BYTES
 * (RANGE_NOT_SATISFIABLE, detail: stream size) and preview access (FORBIDDEN,
 * detail: permitted steps). Errors: MS_ERR_RANGE with fault set as above;
 * MS_ERR_CORRUPT (fault INTERNAL) when the step table is inconsistent;
 * MS_ERR_ARG for NULL arguments or an entry that fails validation. */
ms_status ms_proto_resolve_range(const ms_proto_cell_request *request,
                                 const ms_proto_stream_steps *steps,
                                 const ms_proto_stream_access *access, ms_proto_byte_range *out,
                                 ms_proto_fault *fault, ms_error *err);

#endif
