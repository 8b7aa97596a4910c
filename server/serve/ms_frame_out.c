/* Frame writing for the binary door: see ms_frame_out.h. */
#include "ms_frame_out.h"

#include <event2/buffer.h>
#include <stdlib.h>
#include <string.h>

#include "ms_registry.h"

ms_status ms_frame_out_message(struct evbuffer *out, const ms_proto_message *msg, ms_error *err)
{
    uint8_t small[1024];
    size_t size;
    ms_status st = ms_proto_encoded_size(msg, &size, err);
    if (st != MS_OK)
        return st;
    uint8_t *buf = size <= sizeof small ? small : malloc(size);
    if (!buf)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a %zu-byte frame", size);
    size_t written;
    st = ms_proto_encode(msg, buf, size, &written, err);
    if (st == MS_OK && evbuffer_add(out, buf, written) != 0)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the output buffer");
    if (buf != small)
        free(buf);
    return st;
}

ms_status ms_frame_out_error(struct evbuffer *out, uint16_t code, bool fatal, uint32_t request_id,
                             uint32_t request_count, uint64_t detail, const char *text,
                             ms_error *err)
{
    ms_proto_fault fault = {0};
    fault.code = code;
    fault.fatal = fatal || ms_proto_error_fatality(code) == MS_PROTO_FATAL_ALWAYS;
    fault.request_id = request_count ? request_id : 0;
    fault.request_count = request_count;
    fault.detail = detail;
    ms_proto_message msg;
    ms_proto_error_from_fault(&fault, text, &msg);
    return ms_frame_out_message(out, &msg, err);
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v, p[1] = (uint8_t)(v >> 8), p[2] = (uint8_t)(v >> 16), p[3] = (uint8_t)(v >> 24);
}

/* Frame header of section 2. */
static void put_header(uint8_t *p, uint32_t body_length, uint8_t type, bool last, uint32_t id)
{
    put32(p, body_length);
    p[4] = type;
    p[5] = last ? MS_PROTO_FLAG_LAST : 0;
    p[6] = p[7] = 0;
    put32(p + 8, id);
}

typedef struct held_model {
    struct ms_model *model;
    uint64_t *in_flight;
} held_model;

static void release_held(const void *data, size_t length, void *extra)
{
    (void)data, (void)length;
    held_model *h = extra;
    --*h->in_flight;
    ms_model_unref(h->model);
    free(h);
}

/* Appends head[0..head_length) copied, then data by reference. */
static ms_status add_with_reference(struct evbuffer *out, const uint8_t *head, size_t head_length,
                                    const uint8_t *data, uint32_t length, struct ms_model *model,
                                    uint64_t *in_flight, ms_error *err)
{
    held_model *h = NULL;
    if (length) {
        h = malloc(sizeof *h);
        if (!h)
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for a transfer");
        h->model = model;
        h->in_flight = in_flight;
    }
    if (evbuffer_add(out, head, head_length) != 0) {
        free(h);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the output buffer");
    }
    if (!length)
        return MS_OK;
    ms_model_ref(model);
    ++*in_flight;
    if (evbuffer_add_reference(out, data, length, release_held, h) != 0) {
        release_held(NULL, 0, h);
        /* The head went out without its data: the stream is broken; the caller
         * closes the connection. */
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the output buffer");
    }
    return MS_OK;
}

ms_status ms_frame_out_payload(struct evbuffer *out, uint32_t request_id, uint32_t cell,
                               uint8_t stream, uint32_t offset, uint32_t end, bool last,
                               const uint8_t *data, uint32_t length, struct ms_model *model,
                               uint64_t *in_flight, ms_error *err)
{
    uint8_t head[MS_PROTO_HEADER_SIZE + MS_PROTO_PAYLOAD_FIXED];
    put_header(head, MS_PROTO_PAYLOAD_FIXED + length, MS_PROTO_PAYLOAD, last, request_id);
    uint8_t *b = head + MS_PROTO_HEADER_SIZE;
    put32(b, cell);
    b[4] = stream, b[5] = b[6] = b[7] = 0;
    put32(b + 8, offset);
    put32(b + 12, end);
    return add_with_reference(out, head, sizeof head, data, length, model, in_flight, err);
}

ms_status ms_frame_out_index_data(struct evbuffer *out, uint32_t request_id, uint32_t offset,
                                  bool last, const uint8_t *data, uint32_t length,
                                  struct ms_model *model, uint64_t *in_flight, ms_error *err)
{
    uint8_t head[MS_PROTO_HEADER_SIZE + MS_PROTO_INDEX_DATA_FIXED];
    put_header(head, MS_PROTO_INDEX_DATA_FIXED + length, MS_PROTO_INDEX_DATA, last, request_id);
    put32(head + MS_PROTO_HEADER_SIZE, offset);
    return add_with_reference(out, head, sizeof head, data, length, model, in_flight, err);
}
