/* Encoders: one message struct to one frame (PROTOCOL.md sections 2 and 4).
 * Every message is validated with ms_proto_check_message first, so an encoder
 * never writes a frame that a conforming decoder would reject. */
#include <string.h>

#include "ms_proto.h"
#include "ms_proto_wire.h"

/* Body size of a message, without validation. Arithmetic is on size_t from
 * 16-bit counts, so it cannot overflow. */
static size_t body_size(const ms_proto_message *msg)
{
    switch ((ms_proto_type)msg->type) {
    case MS_PROTO_HELLO:
        return MS_PROTO_HELLO_FIXED + (size_t)msg->body.hello.token_length +
               msg->body.hello.agent_length;
    case MS_PROTO_HELLO_REPLY:
        return MS_PROTO_HELLO_REPLY_FIXED + (size_t)msg->body.hello_reply.server_name_length;
    case MS_PROTO_PING:
    case MS_PROTO_PONG:
        return MS_PROTO_PING_SIZE;
    case MS_PROTO_LIST_CATALOGUE:
        return 0;
    case MS_PROTO_LIST_PAGE:
        return MS_PROTO_LIST_PAGE_FIXED + (size_t)msg->body.list_page.query_length;
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE: {
        size_t size = msg->type == MS_PROTO_CATALOGUE ? MS_PROTO_CATALOGUE_FIXED
                                                      : MS_PROTO_CATALOGUE_PAGE_FIXED;
        const ms_proto_catalogue *cat = &msg->body.catalogue;
        for (uint32_t i = 0; cat->entries && i < cat->entry_count; ++i)
            size += MS_PROTO_CATALOGUE_ENTRY_FIXED + (size_t)cat->entries[i].name_length +
                    cat->entries[i].title_length;
        return size;
    }
    case MS_PROTO_GET_DOCUMENT:
        return MS_PROTO_GET_DOCUMENT_FIXED + (size_t)msg->body.get_document.name_length;
    case MS_PROTO_DOCUMENT:
        return MS_PROTO_DOCUMENT_FIXED + (size_t)msg->body.document.data_length;
    case MS_PROTO_OPEN_MODEL:
        return MS_PROTO_OPEN_MODEL_FIXED + (size_t)msg->body.open_model.name_length;
    case MS_PROTO_MODEL_OPENED:
        return MS_PROTO_MODEL_OPENED_SIZE;
    case MS_PROTO_CLOSE_MODEL:
        return MS_PROTO_CLOSE_MODEL_SIZE;
    case MS_PROTO_REQUEST_CELLS:
        return MS_PROTO_REQUEST_CELLS_FIXED +
               (size_t)msg->body.request_cells.count * MS_PROTO_CELL_REQUEST_SIZE;
    case MS_PROTO_CANCEL:
        return MS_PROTO_CANCEL_FIXED +
               (size_t)msg->body.cancel.range_count * MS_PROTO_CANCEL_RANGE_SIZE;
    case MS_PROTO_INDEX_DATA:
        return MS_PROTO_INDEX_DATA_FIXED + (size_t)msg->body.index_data.data_length;
    case MS_PROTO_PAYLOAD:
        return MS_PROTO_PAYLOAD_FIXED + (size_t)msg->body.payload.data_length;
    case MS_PROTO_ERROR:
        return MS_PROTO_ERROR_FIXED + (size_t)msg->body.error.text_length;
    case MS_PROTO_NONE:
        break;
    }
    return 0;
}

ms_status ms_proto_encoded_size(const ms_proto_message *msg, size_t *size, ms_error *err)
{
    if (!msg || !size)
        return ms_error_set(err, MS_ERR_ARG, "encoded_size: NULL argument");
    if (!ms_wire_type_lookup(msg->type))
        return ms_error_set(err, MS_ERR_ARG, "encoded_size: undefined type 0x%02x", msg->type);
    *size = MS_PROTO_HEADER_SIZE + body_size(msg);
    return MS_OK;
}

/* Copies length bytes from src (which may be NULL when length is 0). */
static uint8_t *put_bytes(uint8_t *p, const void *src, size_t length)
{
    if (length)
        memcpy(p, src, length);
    return p + length;
}

static void write_hello(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_hello *h = &msg->body.hello;
    memcpy(b, MS_PROTO_MAGIC, 4);
    ms_wire_put16(b + 4, h->min_version);
    ms_wire_put16(b + 6, h->max_version);
    ms_wire_put32(b + 8, h->capabilities);
    ms_wire_put32(b + 12, h->max_frame);
    ms_wire_put16(b + 16, h->token_length);
    ms_wire_put16(b + 18, h->agent_length);
    ms_wire_put32(b + 20, 0);
    uint8_t *p = put_bytes(b + MS_PROTO_HELLO_FIXED, h->token, h->token_length);
    put_bytes(p, h->agent, h->agent_length);
}

static void write_hello_reply(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_hello_reply *r = &msg->body.hello_reply;
    memcpy(b, MS_PROTO_MAGIC, 4);
    ms_wire_put16(b + 4, r->version);
    ms_wire_put16(b + 6, r->server_flags);
    ms_wire_put32(b + 8, r->capabilities);
    ms_wire_put32(b + 12, r->max_frame);
    ms_wire_put32(b + 16, r->max_batch);
    ms_wire_put32(b + 20, r->max_outstanding);
    ms_wire_put64(b + 24, r->max_queued_bytes);
    ms_wire_put32(b + 32, r->idle_timeout_ms);
    ms_wire_put32(b + 36, r->max_request_rate);
    ms_wire_put16(b + 40, r->max_open_models);
    ms_wire_put16(b + 42, r->server_name_length);
    ms_wire_put32(b + 44, 0);
    put_bytes(b + MS_PROTO_HELLO_REPLY_FIXED, r->server_name, r->server_name_length);
}

static void write_catalogue(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_catalogue *cat = &msg->body.catalogue;
    ms_wire_put16(b, cat->entry_count);
    ms_wire_put16(b + 2, 0);
    uint8_t *p = b + MS_PROTO_CATALOGUE_FIXED;
    if (msg->type == MS_PROTO_CATALOGUE_PAGE) {
        ms_wire_put32(b + 4, cat->total);
        p = b + MS_PROTO_CATALOGUE_PAGE_FIXED;
    }
    for (uint32_t i = 0; i < cat->entry_count; ++i) {
        const ms_proto_catalogue_entry *e = &cat->entries[i];
        p[0] = e->name_length;
        p[1] = e->geometry_steps;
        p[2] = e->apo_steps;
        p[3] = e->permitted_geometry_steps;
        p[4] = e->permitted_apo_steps;
        p[5] = 0;
        ms_wire_put16(p + 6, e->title_length);
        ms_wire_put32(p + 8, e->cell_count);
        ms_wire_put32(p + 12, 0);
        ms_wire_put64(p + 16, e->content_id);
        ms_wire_put64(p + 24, e->archive_bytes);
        p = put_bytes(p + MS_PROTO_CATALOGUE_ENTRY_FIXED, e->name, e->name_length);
        p = put_bytes(p, e->title, e->title_length);
    }
}

static void write_list_page(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_list_page *l = &msg->body.list_page;
    ms_wire_put32(b, l->offset);
    ms_wire_put16(b + 4, l->limit);
    b[6] = l->sort;
    b[7] = l->descending;
    b[8] = l->query_length;
    b[9] = 0;
    ms_wire_put16(b + 10, 0);
    put_bytes(b + MS_PROTO_LIST_PAGE_FIXED, l->query, l->query_length);
}

static void write_model_opened(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_model_opened *m = &msg->body.model_opened;
    ms_wire_put32(b, m->model_handle);
    ms_wire_put32(b + 4, m->cell_count);
    ms_wire_put64(b + 8, m->content_id);
    ms_wire_put32(b + 16, m->index_size);
    ms_wire_put32(b + 20, m->index_crc32);
    ms_wire_put16(b + 24, m->archive_version);
    b[26] = m->geometry_steps;
    b[27] = m->apo_steps;
    b[28] = m->permitted_geometry_steps;
    b[29] = m->permitted_apo_steps;
    b[30] = m->index_encoding;
    b[31] = 0;
}

static void write_request_cells(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_request_cells *r = &msg->body.request_cells;
    ms_wire_put32(b, r->model_handle);
    ms_wire_put16(b + 4, r->count);
    ms_wire_put16(b + 6, 0);
    uint8_t *p = b + MS_PROTO_REQUEST_CELLS_FIXED;
    for (uint32_t i = 0; i < r->count; ++i, p += MS_PROTO_CELL_REQUEST_SIZE) {
        const ms_proto_cell_request *e = &r->entries[i];
        ms_wire_put32(p, e->cell_id);
        p[4] = e->stream;
        p[5] = e->unit;
        p[6] = e->priority;
        p[7] = 0;
        ms_wire_put32(p + 8, e->a);
        ms_wire_put32(p + 12, e->b);
    }
}

static void write_cancel(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_cancel *k = &msg->body.cancel;
    ms_wire_put16(b, k->range_count);
    ms_wire_put16(b + 2, k->flags);
    uint8_t *p = b + MS_PROTO_CANCEL_FIXED;
    for (uint32_t i = 0; i < k->range_count; ++i, p += MS_PROTO_CANCEL_RANGE_SIZE) {
        ms_wire_put32(p, k->ranges[i].first_id);
        ms_wire_put32(p + 4, k->ranges[i].count);
    }
}

static void write_payload(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_payload *p = &msg->body.payload;
    ms_wire_put32(b, p->cell_id);
    b[4] = p->stream;
    b[5] = b[6] = b[7] = 0;
    ms_wire_put32(b + 8, p->offset);
    ms_wire_put32(b + 12, p->end);
    put_bytes(b + MS_PROTO_PAYLOAD_FIXED, p->data, p->data_length);
}

static void write_error_body(const ms_proto_message *msg, uint8_t *b)
{
    const ms_proto_error_body *e = &msg->body.error;
    ms_wire_put16(b, e->code);
    b[2] = e->fatal ? MS_PROTO_ERROR_FATAL : 0;
    b[3] = 0;
    ms_wire_put32(b + 4, e->request_count);
    ms_wire_put64(b + 8, e->detail);
    ms_wire_put16(b + 16, e->text_length);
    put_bytes(b + MS_PROTO_ERROR_FIXED, e->text, e->text_length);
}

static void write_body(const ms_proto_message *msg, uint8_t *b)
{
    switch ((ms_proto_type)msg->type) {
    case MS_PROTO_HELLO:
        write_hello(msg, b);
        break;
    case MS_PROTO_HELLO_REPLY:
        write_hello_reply(msg, b);
        break;
    case MS_PROTO_PING:
    case MS_PROTO_PONG:
        ms_wire_put64(b, msg->body.ping.opaque);
        break;
    case MS_PROTO_LIST_CATALOGUE:
        break;
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE:
        write_catalogue(msg, b);
        break;
    case MS_PROTO_LIST_PAGE:
        write_list_page(msg, b);
        break;
    case MS_PROTO_GET_DOCUMENT: {
        const ms_proto_get_document *g = &msg->body.get_document;
        b[0] = g->kind;
        b[1] = g->name_length;
        ms_wire_put16(b + 2, 0);
        put_bytes(b + MS_PROTO_GET_DOCUMENT_FIXED, g->name, g->name_length);
        break;
    }
    case MS_PROTO_DOCUMENT: {
        const ms_proto_document *d = &msg->body.document;
        b[0] = d->kind;
        b[1] = 0;
        ms_wire_put16(b + 2, 0);
        ms_wire_put32(b + 4, d->total_length);
        ms_wire_put32(b + 8, d->offset);
        put_bytes(b + MS_PROTO_DOCUMENT_FIXED, d->data, d->data_length);
        break;
    }
    case MS_PROTO_OPEN_MODEL: {
        const ms_proto_open_model *o = &msg->body.open_model;
        b[0] = o->name_length;
        b[1] = b[2] = b[3] = 0;
        put_bytes(b + MS_PROTO_OPEN_MODEL_FIXED, o->name, o->name_length);
        break;
    }
    case MS_PROTO_MODEL_OPENED:
        write_model_opened(msg, b);
        break;
    case MS_PROTO_CLOSE_MODEL:
        ms_wire_put32(b, msg->body.close_model.model_handle);
        break;
    case MS_PROTO_REQUEST_CELLS:
        write_request_cells(msg, b);
        break;
    case MS_PROTO_CANCEL:
        write_cancel(msg, b);
        break;
    case MS_PROTO_INDEX_DATA: {
        const ms_proto_index_data *d = &msg->body.index_data;
        ms_wire_put32(b, d->offset);
        put_bytes(b + MS_PROTO_INDEX_DATA_FIXED, d->data, d->data_length);
        break;
    }
    case MS_PROTO_PAYLOAD:
        write_payload(msg, b);
        break;
    case MS_PROTO_ERROR:
        write_error_body(msg, b);
        break;
    case MS_PROTO_NONE:
        break;
    }
}

ms_status ms_proto_encode(const ms_proto_message *msg, uint8_t *out, size_t capacity,
                          size_t *written, ms_error *err)
{
    if (!msg || !out || !written)
        return ms_error_set(err, MS_ERR_ARG, "encode: NULL argument");
    *written = 0;
    ms_status status = ms_proto_check_message(msg, MS_PROTO_MAX_BATCH, NULL, err);
    if (status != MS_OK)
        return status;
    size_t body = body_size(msg);
    const ms_wire_type_info *info = ms_wire_type_lookup(msg->type);
    uint32_t max_body = info->max_body == MS_WIRE_BODY_UNBOUNDED ? MS_PROTO_MAX_FRAME
                                                                 : info->max_body;
    if (body > max_body)
        return ms_error_set(err, MS_ERR_RANGE, "encode: %s body of %zu bytes above %u", info->name,
                            body, (unsigned)max_body);
    if (capacity < MS_PROTO_HEADER_SIZE + body) {
        *written = MS_PROTO_HEADER_SIZE + body;
        return ms_error_set(err, MS_ERR_ARG, "encode: %s needs %zu bytes, buffer has %zu",
                            info->name, MS_PROTO_HEADER_SIZE + body, capacity);
    }
    ms_wire_put32(out, (uint32_t)body);
    out[4] = msg->type;
    out[5] = msg->flags;
    ms_wire_put16(out + 6, 0);
    ms_wire_put32(out + 8, msg->request_id);
    write_body(msg, out + MS_PROTO_HEADER_SIZE);
    *written = MS_PROTO_HEADER_SIZE + body;
    return MS_OK;
}
