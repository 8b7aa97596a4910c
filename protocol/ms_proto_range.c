/* Cell request to byte range (PROTOCOL.md section 4.10). */
#include <string.h>

#include "ms_proto_range.h"

static ms_status range_fault(ms_proto_fault *fault, uint16_t code, uint64_t detail)
{
    if (fault) {
        memset(fault, 0, sizeof *fault);
        fault->code = code;
        fault->detail = detail;
    }
    return code == MS_PROTO_E_INTERNAL ? MS_ERR_CORRUPT : MS_ERR_RANGE;
}

ms_status ms_proto_check_cell_id(uint32_t cell_id, uint32_t cell_count, ms_proto_fault *fault,
                                 ms_error *err)
{
    if (cell_id < cell_count)
        return MS_OK;
    ms_error_set(err, MS_ERR_RANGE, "cell %u does not exist (the model has %u cells)",
                 (unsigned)cell_id, (unsigned)cell_count);
    return range_fault(fault, MS_PROTO_E_UNKNOWN_CELL, cell_id);
}

/* end(s) for a step inside the window. */
static uint32_t step_end(const ms_proto_stream_steps *steps, uint32_t step)
{
    return steps->step_ends[step - steps->first_step];
}

ms_status ms_proto_resolve_range(const ms_proto_cell_request *request,
                                 const ms_proto_stream_steps *steps,
                                 const ms_proto_stream_access *access, ms_proto_byte_range *out,
                                 ms_proto_fault *fault, ms_error *err)
{
    if (!request || !steps || !access || !out || (steps->step_count && !steps->step_ends))
        return ms_error_set(err, MS_ERR_ARG, "resolve_range: NULL argument");
    if (request->unit > MS_PROTO_UNIT_BYTES ||
        (request->unit == MS_PROTO_UNIT_STEPS &&
         (request->a > request->b || request->b > MS_PROTO_MAX_STEP)) ||
        (request->unit == MS_PROTO_UNIT_BYTES &&
         (request->b == 0 || (uint64_t)request->a + request->b > UINT32_MAX)))
        return ms_error_set(err, MS_ERR_ARG, "resolve_range: request entry not validated");
    if (access->permitted_steps > access->model_steps)
        return ms_error_set(err, MS_ERR_ARG, "resolve_range: permitted %u above model steps %u",
                            access->permitted_steps, access->model_steps);
    /* The step table comes from the archive: check it before using it. */
    if (steps->first_step > MS_PROTO_MAX_STEP ||
        steps->step_count > MS_PROTO_MAX_STEPS - steps->first_step) {
        ms_error_set(err, MS_ERR_CORRUPT, "step window %u + %u outside [0, %u]",
                     (unsigned)steps->first_step, (unsigned)steps->step_count, MS_PROTO_MAX_STEP);
        return range_fault(fault, MS_PROTO_E_INTERNAL, 0);
    }
    for (uint32_t i = 1; i < steps->step_count; ++i)
        if (steps->step_ends[i] < steps->step_ends[i - 1]) {
            ms_error_set(err, MS_ERR_CORRUPT, "step table decreases at step %u",
                         (unsigned)(steps->first_step + i));
            return range_fault(fault, MS_PROTO_E_INTERNAL, 0);
        }
    const uint32_t size = steps->step_count ? steps->step_ends[steps->step_count - 1] : 0;
    const uint32_t last_step = steps->first_step + steps->step_count - 1; /* if step_count > 0 */
    const bool limited = access->permitted_steps < access->model_steps;

    if (request->unit == MS_PROTO_UNIT_BYTES) {
        uint64_t stop = (uint64_t)request->a + request->b;
        if (stop > size) {
            ms_error_set(err, MS_ERR_RANGE, "bytes [%u, %llu) outside the %u-byte stream",
                         (unsigned)request->a, (unsigned long long)stop, (unsigned)size);
            return range_fault(fault, MS_PROTO_E_RANGE_NOT_SATISFIABLE, size);
        }
        if (limited) {
            /* Bytes readable under the preview: up to end(permitted - 1). */
            uint32_t allowed = 0;
            if (access->permitted_steps > 0 && steps->step_count > 0 &&
                access->permitted_steps - 1u >= steps->first_step) {
                uint32_t top = access->permitted_steps - 1u;
                allowed = step_end(steps, top < last_step ? top : last_step);
            }
            if (stop > allowed) {
                ms_error_set(err, MS_ERR_RANGE, "bytes past %u need more than the %u permitted steps",
                             (unsigned)allowed, access->permitted_steps);
                return range_fault(fault, MS_PROTO_E_FORBIDDEN, access->permitted_steps);
            }
        }
        out->begin = request->a;
        out->end = (uint32_t)stop;
        return MS_OK;
    }

    if (limited && request->b >= access->permitted_steps) {
        ms_error_set(err, MS_ERR_RANGE, "step %u is beyond the %u permitted steps",
                     (unsigned)request->b, access->permitted_steps);
        return range_fault(fault, MS_PROTO_E_FORBIDDEN, access->permitted_steps);
    }
    if (steps->step_count == 0 || request->b < steps->first_step) {
        out->begin = out->end = 0; /* entirely before the window (or empty stream) */
        return MS_OK;
    }
    if (request->a > last_step) {
        out->begin = out->end = size; /* entirely past the window */
        return MS_OK;
    }
    uint32_t first = request->a > steps->first_step ? request->a : steps->first_step;
    uint32_t last = request->b < last_step ? request->b : last_step;
    out->begin = first == steps->first_step ? 0 : step_end(steps, first - 1);
    out->end = step_end(steps, last);
    return MS_OK;
}
