/* Incremental frame decoder (PROTOCOL.md sections 2, 4, 6 and 9): bytes in, in
 * any split; validated messages or a precise fault out. The header is checked
 * as soon as its 12 bytes are in, before any body byte is buffered; the body is
 * then parsed for structure (exact length, reserved fields, magic) and every
 * field is range-checked by ms_proto_check_message. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_proto.h"
#include "ms_proto_decode_internal.h"
#include "ms_proto_wire.h"

/* Buffers larger than this are released between frames. */
#define MS_PROTO_DECODER_KEEP (1u << 20)

ms_status ms_proto_decoder_new(const ms_proto_decoder_config *config, ms_proto_decoder **out,
                               ms_error *err)
{
    if (out)
        *out = NULL;
    if (!config || !out)
        return ms_error_set(err, MS_ERR_ARG, "decoder_new: NULL argument");
    if (config->role != MS_PROTO_ROLE_SERVER && config->role != MS_PROTO_ROLE_CLIENT)
        return ms_error_set(err, MS_ERR_ARG, "decoder_new: role %d is neither server nor client",
                            (int)config->role);
    if (config->max_frame < MS_PROTO_MIN_FRAME || config->max_frame > MS_PROTO_MAX_FRAME)
        return ms_error_set(err, MS_ERR_ARG, "decoder_new: max_frame %u outside [%u, %u]",
                            (unsigned)config->max_frame, MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME);
    if (config->role == MS_PROTO_ROLE_SERVER &&
        (config->max_batch < 1 || config->max_batch > MS_PROTO_MAX_BATCH))
        return ms_error_set(err, MS_ERR_ARG, "decoder_new: max_batch %u outside [1, %u]",
                            (unsigned)config->max_batch, MS_PROTO_MAX_BATCH);
    ms_proto_decoder *dec = calloc(1, sizeof *dec);
    if (!dec)
        return ms_error_set(err, MS_ERR_NOMEM, "decoder_new: out of memory");
    dec->config = *config;
    /* A client accepts every batch the protocol allows. */
    if (config->role == MS_PROTO_ROLE_CLIENT)
        dec->config.max_batch = MS_PROTO_MAX_BATCH;
    *out = dec;
    return MS_OK;
}

void ms_proto_decoder_free(ms_proto_decoder *dec)
{
    if (!dec)
        return;
    free(dec->body);
    free(dec->scratch);
    free(dec);
}

size_t ms_proto_decoder_buffered(const ms_proto_decoder *dec)
{
    return dec ? dec->header_have + dec->body_have : 0;
}

static ms_status status_of(uint16_t code)
{
    switch (code) {
    case MS_PROTO_E_MALFORMED_FRAME:
    case MS_PROTO_E_UNKNOWN_TYPE:
    case MS_PROTO_E_UNEXPECTED_MESSAGE:
        return MS_ERR_FORMAT;
    case MS_PROTO_E_FRAME_TOO_LARGE:
    case MS_PROTO_E_INTERNAL:
        return MS_ERR_NOMEM;
    default:
        return MS_ERR_RANGE;
    }
}

/* Records a fatal fault: the decoder refuses everything after it. */
static ms_status fail_fatal(ms_proto_decoder *dec, uint16_t code, uint64_t detail,
                            ms_proto_fault *fault, ms_error *err, const char *fmt, ...)
    __attribute__((format(printf, 6, 7)));

static ms_status fail_fatal(ms_proto_decoder *dec, uint16_t code, uint64_t detail,
                            ms_proto_fault *fault, ms_error *err, const char *fmt, ...)
{
    char text[MS_ERROR_TEXT_MAX - 128]; /* room for the prefix below */
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    dec->failed = true;
    dec->failure = (ms_proto_fault){code, true, dec->header_have == MS_PROTO_HEADER_SIZE
                                                    ? dec->header[4] : 0, 0, 0, detail};
    snprintf(dec->failure_text, sizeof dec->failure_text, "frame at byte %llu: %s: %s",
             (unsigned long long)dec->frame_start, ms_proto_error_name(code), text);
    if (fault)
        *fault = dec->failure;
    return ms_error_set(err, status_of(code), "%s", dec->failure_text);
}

static ms_status grow(void **buffer, size_t *capacity, size_t needed)
{
    if (needed <= *capacity)
        return MS_OK;
    void *p = realloc(*buffer, needed);
    if (!p)
        return MS_ERR_NOMEM;
    *buffer = p;
    *capacity = needed;
    return MS_OK;
}

/* Section 2: header checks in their documented order. */
static ms_status check_header(ms_proto_decoder *dec, ms_proto_fault *fault, ms_error *err)
{
    const uint8_t *h = dec->header;
    uint32_t body_length = ms_wire_get32(h);
    uint8_t type = h[4], flags = h[5];
    uint16_t reserved = ms_wire_get16(h + 6);
    uint32_t request_id = ms_wire_get32(h + 8);
    bool server = dec->config.role == MS_PROTO_ROLE_SERVER;

    if (reserved != 0)
        return fail_fatal(dec, MS_PROTO_E_MALFORMED_FRAME, 0, fault, err,
                          "reserved header field 0x%04x is not 0", reserved);
    if (flags & ~MS_PROTO_FLAG_LAST)
        return fail_fatal(dec, MS_PROTO_E_MALFORMED_FRAME, 0, fault, err,
                          "undefined header flag bits 0x%02x", flags & ~MS_PROTO_FLAG_LAST);
    const ms_wire_type_info *info = ms_wire_type_lookup(type);
    if (!info)
        return fail_fatal(dec, MS_PROTO_E_UNKNOWN_TYPE, type, fault, err,
                          "undefined message type 0x%02x", type);
    if (!(info->sender & (server ? MS_WIRE_FROM_CLIENT : MS_WIRE_FROM_SERVER)))
        return fail_fatal(dec, MS_PROTO_E_UNEXPECTED_MESSAGE, type, fault, err,
                          "%s is never sent by a %s", info->name, server ? "client" : "server");
    if (dec->peer_closed)
        return fail_fatal(dec, MS_PROTO_E_UNEXPECTED_MESSAGE, type, fault, err,
                          "%s after a fatal ERROR", info->name);
    if (!dec->handshake_done) {
        bool allowed = server ? type == MS_PROTO_HELLO
                              : type == MS_PROTO_HELLO_REPLY || type == MS_PROTO_ERROR;
        if (!allowed)
            return fail_fatal(dec, MS_PROTO_E_UNEXPECTED_MESSAGE, type, fault, err,
                              "%s before the handshake (expected %s)", info->name,
                              server ? "HELLO" : "HELLO_REPLY");
    } else if (type == MS_PROTO_HELLO || type == MS_PROTO_HELLO_REPLY) {
        return fail_fatal(dec, MS_PROTO_E_UNEXPECTED_MESSAGE, type, fault, err,
                          "second %s", info->name);
    }
    if (body_length > dec->config.max_frame)
        return fail_fatal(dec, MS_PROTO_E_FRAME_TOO_LARGE, dec->config.max_frame, fault, err,
                          "%s body of %u bytes above max_frame %u", info->name,
                          (unsigned)body_length, (unsigned)dec->config.max_frame);
    ms_error header_err;
    if (ms_wire_check_header(info, flags, request_id, body_length, dec->config.max_frame,
                             &header_err) != MS_OK)
        return fail_fatal(dec, MS_PROTO_E_MALFORMED_FRAME, 0, fault, err, "%s", header_err.text);
    dec->body_length = body_length;
    if (grow((void **)&dec->body, &dec->body_capacity, body_length ? body_length : 1) != MS_OK)
        return fail_fatal(dec, MS_PROTO_E_INTERNAL, 0, fault, err,
                          "cannot allocate %u bytes for a frame body", (unsigned)body_length);
    return MS_OK;
}

/* A malformed body: the text to why, MALFORMED_FRAME as the code (each
 * parse_* below has dec, msg, why and why_size). */
#define MALFORMED(...) (snprintf(why, why_size, __VA_ARGS__), MS_PROTO_E_MALFORMED_FRAME)

static uint16_t parse_hello(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                            size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_hello *h = &msg->body.hello;
    if (memcmp(b, MS_PROTO_MAGIC, 4) != 0)
        return MALFORMED("HELLO: bad magic (not a meshstream client?)");
    if (ms_wire_get32(b + 20) != 0)
        return MALFORMED("HELLO: reserved field is not 0");
    h->min_version = ms_wire_get16(b + 4);
    h->max_version = ms_wire_get16(b + 6);
    h->capabilities = ms_wire_get32(b + 8);
    h->max_frame = ms_wire_get32(b + 12);
    h->token_length = ms_wire_get16(b + 16);
    h->agent_length = ms_wire_get16(b + 18);
    if ((size_t)MS_PROTO_HELLO_FIXED + h->token_length + h->agent_length != n)
        return MALFORMED("HELLO: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_HELLO_FIXED + h->token_length + h->agent_length);
    h->token = (const char *)b + MS_PROTO_HELLO_FIXED;
    h->agent = h->token + h->token_length;
    return 0;
}

static uint16_t parse_hello_reply(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                  size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_hello_reply *r = &msg->body.hello_reply;
    if (memcmp(b, MS_PROTO_MAGIC, 4) != 0)
        return MALFORMED("HELLO_REPLY: bad magic (not a meshstream server?)");
    if (ms_wire_get32(b + 44) != 0)
        return MALFORMED("HELLO_REPLY: reserved field is not 0");
    r->version = ms_wire_get16(b + 4);
    r->server_flags = ms_wire_get16(b + 6);
    r->capabilities = ms_wire_get32(b + 8);
    r->max_frame = ms_wire_get32(b + 12);
    r->max_batch = ms_wire_get32(b + 16);
    r->max_outstanding = ms_wire_get32(b + 20);
    r->max_queued_bytes = ms_wire_get64(b + 24);
    r->idle_timeout_ms = ms_wire_get32(b + 32);
    r->max_request_rate = ms_wire_get32(b + 36);
    r->max_open_models = ms_wire_get16(b + 40);
    r->server_name_length = ms_wire_get16(b + 42);
    if ((size_t)MS_PROTO_HELLO_REPLY_FIXED + r->server_name_length != n)
        return MALFORMED("HELLO_REPLY: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_HELLO_REPLY_FIXED + r->server_name_length);
    r->server_name = (const char *)b + MS_PROTO_HELLO_REPLY_FIXED;
    return 0;
}

static uint16_t parse_catalogue(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_catalogue *cat = &msg->body.catalogue;
    bool page = msg->type == MS_PROTO_CATALOGUE_PAGE;
    size_t fixed = page ? MS_PROTO_CATALOGUE_PAGE_FIXED : MS_PROTO_CATALOGUE_FIXED;
    cat->entry_count = ms_wire_get16(b);
    cat->total = page ? ms_wire_get32(b + 4) : 0;
    if (ms_wire_get16(b + 2) != 0)
        return MALFORMED("CATALOGUE: reserved field is not 0");
    /* Bound the count by the body before allocating for it. */
    if ((size_t)cat->entry_count * MS_PROTO_CATALOGUE_ENTRY_FIXED > n - fixed)
        return MALFORMED("CATALOGUE: %u entries cannot fit in %u bytes", cat->entry_count,
                         (unsigned)n);
    if (grow(&dec->scratch, &dec->scratch_capacity,
             (size_t)(cat->entry_count ? cat->entry_count : 1) *
                 sizeof(ms_proto_catalogue_entry)) != MS_OK) {
        snprintf(why, why_size, "CATALOGUE: cannot allocate %u entries", cat->entry_count);
        return MS_PROTO_E_INTERNAL;
    }
    ms_proto_catalogue_entry *entries = dec->scratch;
    size_t at = fixed;
    for (uint32_t i = 0; i < cat->entry_count; ++i) {
        if (n - at < MS_PROTO_CATALOGUE_ENTRY_FIXED)
            return MALFORMED("CATALOGUE: entry %u truncated", (unsigned)i);
        const uint8_t *p = b + at;
        ms_proto_catalogue_entry *e = &entries[i];
        if (p[5] != 0 || ms_wire_get32(p + 12) != 0)
            return MALFORMED("CATALOGUE: entry %u: reserved field is not 0", (unsigned)i);
        e->name_length = p[0];
        e->geometry_steps = p[1];
        e->apo_steps = p[2];
        e->permitted_geometry_steps = p[3];
        e->permitted_apo_steps = p[4];
        e->title_length = ms_wire_get16(p + 6);
        e->cell_count = ms_wire_get32(p + 8);
        e->content_id = ms_wire_get64(p + 16);
        e->archive_bytes = ms_wire_get64(p + 24);
        size_t strings = (size_t)e->name_length + e->title_length;
        if (n - at - MS_PROTO_CATALOGUE_ENTRY_FIXED < strings)
            return MALFORMED("CATALOGUE: entry %u: strings run past the body", (unsigned)i);
        e->name = (const char *)p + MS_PROTO_CATALOGUE_ENTRY_FIXED;
        e->title = e->name + e->name_length;
        at += MS_PROTO_CATALOGUE_ENTRY_FIXED + strings;
    }
    if (at != n)
        return MALFORMED("CATALOGUE: %zu bytes after the last entry", n - at);
    cat->entries = entries;
    return 0;
}

static uint16_t parse_list_page(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_list_page *l = &msg->body.list_page;
    l->offset = ms_wire_get32(b);
    l->limit = ms_wire_get16(b + 4);
    l->sort = b[6];
    l->descending = b[7];
    l->query_length = b[8];
    if (b[9] != 0 || ms_wire_get16(b + 10) != 0)
        return MALFORMED("LIST_PAGE: reserved field is not 0");
    if ((size_t)MS_PROTO_LIST_PAGE_FIXED + l->query_length != n)
        return MALFORMED("LIST_PAGE: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_LIST_PAGE_FIXED + l->query_length);
    l->query = (const char *)b + MS_PROTO_LIST_PAGE_FIXED;
    return 0;
}

static uint16_t parse_get_document(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                   size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_get_document *g = &msg->body.get_document;
    g->kind = b[0];
    g->name_length = b[1];
    if (ms_wire_get16(b + 2) != 0)
        return MALFORMED("GET_DOCUMENT: reserved field is not 0");
    if ((size_t)MS_PROTO_GET_DOCUMENT_FIXED + g->name_length != n)
        return MALFORMED("GET_DOCUMENT: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_GET_DOCUMENT_FIXED + g->name_length);
    g->name = (const char *)b + MS_PROTO_GET_DOCUMENT_FIXED;
    return 0;
}

static uint16_t parse_document(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                               size_t why_size)
{
    const uint8_t *b = dec->body;
    ms_proto_document *d = &msg->body.document;
    d->kind = b[0];
    if (b[1] != 0 || ms_wire_get16(b + 2) != 0)
        return MALFORMED("DOCUMENT: reserved field is not 0");
    d->total_length = ms_wire_get32(b + 4);
    d->offset = ms_wire_get32(b + 8);
    d->data = b + MS_PROTO_DOCUMENT_FIXED;
    d->data_length = dec->body_length - MS_PROTO_DOCUMENT_FIXED;
    return 0;
}

static uint16_t parse_open_model(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                 size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_open_model *o = &msg->body.open_model;
    o->name_length = b[0];
    if (b[1] || b[2] || b[3])
        return MALFORMED("OPEN_MODEL: reserved field is not 0");
    if ((size_t)MS_PROTO_OPEN_MODEL_FIXED + o->name_length != n)
        return MALFORMED("OPEN_MODEL: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_OPEN_MODEL_FIXED + o->name_length);
    o->name = (const char *)b + MS_PROTO_OPEN_MODEL_FIXED;
    return 0;
}

static uint16_t parse_model_opened(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                   size_t why_size)
{
    const uint8_t *b = dec->body;
    ms_proto_model_opened *m = &msg->body.model_opened;
    if (b[31] != 0)
        return MALFORMED("MODEL_OPENED: reserved field is not 0");
    m->model_handle = ms_wire_get32(b);
    m->cell_count = ms_wire_get32(b + 4);
    m->content_id = ms_wire_get64(b + 8);
    m->index_size = ms_wire_get32(b + 16);
    m->index_crc32 = ms_wire_get32(b + 20);
    m->archive_version = ms_wire_get16(b + 24);
    m->geometry_steps = b[26];
    m->apo_steps = b[27];
    m->permitted_geometry_steps = b[28];
    m->permitted_apo_steps = b[29];
    m->index_encoding = b[30];
    return 0;
}

static uint16_t parse_request_cells(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                    size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_request_cells *r = &msg->body.request_cells;
    r->model_handle = ms_wire_get32(b);
    r->count = ms_wire_get16(b + 4);
    r->entries = NULL;
    if (ms_wire_get16(b + 6) != 0)
        return MALFORMED("REQUEST_CELLS: reserved field is not 0");
    if ((size_t)MS_PROTO_REQUEST_CELLS_FIXED + (size_t)r->count * MS_PROTO_CELL_REQUEST_SIZE != n)
        return MALFORMED("REQUEST_CELLS: body length %u, layout says %zu for %u entries",
                         (unsigned)n,
                         (size_t)MS_PROTO_REQUEST_CELLS_FIXED +
                             (size_t)r->count * MS_PROTO_CELL_REQUEST_SIZE,
                         r->count);
    /* An oversized batch is refused by the range check (BATCH_TOO_LARGE)
     * without allocating anything for its entries. */
    if (r->count == 0 || r->count > dec->config.max_batch)
        return 0;
    if (grow(&dec->scratch, &dec->scratch_capacity,
             (size_t)r->count * sizeof(ms_proto_cell_request)) != MS_OK) {
        snprintf(why, why_size, "REQUEST_CELLS: cannot allocate %u entries", r->count);
        return MS_PROTO_E_INTERNAL;
    }
    ms_proto_cell_request *entries = dec->scratch;
    for (uint32_t i = 0; i < r->count; ++i) {
        const uint8_t *p = b + MS_PROTO_REQUEST_CELLS_FIXED + (size_t)i * MS_PROTO_CELL_REQUEST_SIZE;
        if (p[7] != 0)
            return MALFORMED("REQUEST_CELLS: entry %u: reserved field is not 0", (unsigned)i);
        entries[i].cell_id = ms_wire_get32(p);
        entries[i].stream = p[4];
        entries[i].unit = p[5];
        entries[i].priority = p[6];
        entries[i].a = ms_wire_get32(p + 8);
        entries[i].b = ms_wire_get32(p + 12);
    }
    r->entries = entries;
    return 0;
}

static uint16_t parse_cancel(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                             size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_cancel *k = &msg->body.cancel;
    k->range_count = ms_wire_get16(b);
    k->flags = ms_wire_get16(b + 2);
    k->ranges = NULL;
    if ((size_t)MS_PROTO_CANCEL_FIXED + (size_t)k->range_count * MS_PROTO_CANCEL_RANGE_SIZE != n)
        return MALFORMED("CANCEL: body length %u, layout says %zu for %u ranges", (unsigned)n,
                         (size_t)MS_PROTO_CANCEL_FIXED +
                             (size_t)k->range_count * MS_PROTO_CANCEL_RANGE_SIZE,
                         k->range_count);
    if (k->range_count == 0)
        return 0;
    if (grow(&dec->scratch, &dec->scratch_capacity,
             (size_t)k->range_count * sizeof(ms_proto_id_range)) != MS_OK) {
        snprintf(why, why_size, "CANCEL: cannot allocate %u ranges", k->range_count);
        return MS_PROTO_E_INTERNAL;
    }
    ms_proto_id_range *ranges = dec->scratch;
    for (uint32_t i = 0; i < k->range_count; ++i) {
        const uint8_t *p = b + MS_PROTO_CANCEL_FIXED + (size_t)i * MS_PROTO_CANCEL_RANGE_SIZE;
        ranges[i].first_id = ms_wire_get32(p);
        ranges[i].count = ms_wire_get32(p + 4);
    }
    k->ranges = ranges;
    return 0;
}

static uint16_t parse_payload(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                              size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_payload *p = &msg->body.payload;
    if (b[5] || b[6] || b[7])
        return MALFORMED("PAYLOAD: reserved field is not 0");
    p->cell_id = ms_wire_get32(b);
    p->stream = b[4];
    p->offset = ms_wire_get32(b + 8);
    p->end = ms_wire_get32(b + 12);
    p->data = b + MS_PROTO_PAYLOAD_FIXED;
    p->data_length = n - MS_PROTO_PAYLOAD_FIXED;
    return 0;
}

static uint16_t parse_error_body(ms_proto_decoder *dec, ms_proto_message *msg, char *why,
                                 size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    ms_proto_error_body *e = &msg->body.error;
    if ((b[2] & ~MS_PROTO_ERROR_FATAL) || b[3])
        return MALFORMED("ERROR: undefined flag bits or reserved field set");
    e->code = ms_wire_get16(b);
    e->fatal = (b[2] & MS_PROTO_ERROR_FATAL) != 0;
    e->request_count = ms_wire_get32(b + 4);
    e->detail = ms_wire_get64(b + 8);
    e->text_length = ms_wire_get16(b + 16);
    if ((size_t)MS_PROTO_ERROR_FIXED + e->text_length != n)
        return MALFORMED("ERROR: body length %u, layout says %zu", (unsigned)n,
                         (size_t)MS_PROTO_ERROR_FIXED + e->text_length);
    e->text = (const char *)b + MS_PROTO_ERROR_FIXED;
    return 0;
}

#undef MALFORMED

/* Structure of a complete body: exact length, magic, reserved fields. Fills
 * msg; arrays go to the decoder's scratch. On failure returns the error code
 * (MALFORMED_FRAME or INTERNAL) and writes a text to why. */
static uint16_t parse_body(ms_proto_decoder *dec, ms_proto_message *msg, char *why, size_t why_size)
{
    const uint8_t *b = dec->body;
    const uint32_t n = dec->body_length;
    switch ((ms_proto_type)msg->type) {
    case MS_PROTO_HELLO:
        return parse_hello(dec, msg, why, why_size);
    case MS_PROTO_HELLO_REPLY:
        return parse_hello_reply(dec, msg, why, why_size);
    case MS_PROTO_PING:
    case MS_PROTO_PONG:
        msg->body.ping.opaque = ms_wire_get64(b);
        return 0;
    case MS_PROTO_LIST_CATALOGUE:
        return 0;
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE:
        return parse_catalogue(dec, msg, why, why_size);
    case MS_PROTO_LIST_PAGE:
        return parse_list_page(dec, msg, why, why_size);
    case MS_PROTO_GET_DOCUMENT:
        return parse_get_document(dec, msg, why, why_size);
    case MS_PROTO_DOCUMENT:
        return parse_document(dec, msg, why, why_size);
    case MS_PROTO_OPEN_MODEL:
        return parse_open_model(dec, msg, why, why_size);
    case MS_PROTO_MODEL_OPENED:
        return parse_model_opened(dec, msg, why, why_size);
    case MS_PROTO_CLOSE_MODEL:
        msg->body.close_model.model_handle = ms_wire_get32(b);
        return 0;
    case MS_PROTO_REQUEST_CELLS:
        return parse_request_cells(dec, msg, why, why_size);
    case MS_PROTO_CANCEL:
        return parse_cancel(dec, msg, why, why_size);
    case MS_PROTO_INDEX_DATA: {
        ms_proto_index_data *d = &msg->body.index_data;
        d->offset = ms_wire_get32(b);
        d->data = b + MS_PROTO_INDEX_DATA_FIXED;
        d->data_length = n - MS_PROTO_INDEX_DATA_FIXED;
        return 0;
    }
    case MS_PROTO_PAYLOAD:
        return parse_payload(dec, msg, why, why_size);
    case MS_PROTO_ERROR:
        return parse_error_body(dec, msg, why, why_size);
    case MS_PROTO_NONE:
        break;
    }
    snprintf(why, why_size, "no parser for type 0x%02x", msg->type);
    return MS_PROTO_E_INTERNAL;
}

/* A complete frame is in header/body: parse, validate, decide fatality. */
static ms_status finish_frame(ms_proto_decoder *dec, ms_proto_message *msg, bool *have_message,
                              ms_proto_fault *fault, ms_error *err)
{
    memset(msg, 0, sizeof *msg);
    msg->type = dec->header[4];
    msg->flags = dec->header[5];
    msg->request_id = ms_wire_get32(dec->header + 8);
    char why[256];
    uint16_t code = parse_body(dec, msg, why, sizeof why);
    if (code != 0)
        return fail_fatal(dec, code, 0, fault, err, "%s", why);

    ms_proto_fault found;
    ms_error check_err;
    if (ms_proto_check_message(msg, dec->config.max_batch, &found, &check_err) != MS_OK) {
        bool server = dec->config.role == MS_PROTO_ROLE_SERVER;
        /* Section 9: a client trusts no bad server frame; any error in a HELLO
         * is fatal; otherwise range errors in a client's frame are not. */
        bool fatal = !server || msg->type == MS_PROTO_HELLO ||
                     ms_proto_error_fatality(found.code) == MS_PROTO_FATAL_ALWAYS;
        if (fatal)
            return fail_fatal(dec, found.code, found.detail, fault, err, "%s", check_err.text);
        found.fatal = false;
        if (fault)
            *fault = found;
        memset(msg, 0, sizeof *msg);
        return ms_error_set(err, status_of(found.code), "frame at byte %llu: %s: %s",
                            (unsigned long long)dec->frame_start,
                            ms_proto_error_name(found.code), check_err.text);
    }
    if (msg->type == MS_PROTO_ERROR && msg->body.error.fatal) {
        dec->peer_closed = true;
    } else if (msg->type == MS_PROTO_ERROR && !dec->handshake_done) {
        uint16_t error_code = msg->body.error.code;
        memset(msg, 0, sizeof *msg);
        return fail_fatal(dec, MS_PROTO_E_UNEXPECTED_MESSAGE, MS_PROTO_ERROR, fault, err,
                          "non-fatal ERROR %s before HELLO_REPLY", ms_proto_error_name(error_code));
    }
    if (msg->type == MS_PROTO_HELLO || msg->type == MS_PROTO_HELLO_REPLY)
        dec->handshake_done = true;
    *have_message = true;
    return MS_OK;
}

ms_status ms_proto_decoder_feed(ms_proto_decoder *dec, const uint8_t *data, size_t size,
                                size_t *consumed, ms_proto_message *msg, bool *have_message,
                                ms_proto_fault *fault, ms_error *err)
{
    if (!dec || (!data && size) || !consumed || !msg || !have_message)
        return ms_error_set(err, MS_ERR_ARG, "decoder_feed: NULL argument");
    *consumed = 0;
    *have_message = false;
    msg->type = MS_PROTO_NONE;
    if (dec->failed) {
        if (fault)
            *fault = dec->failure;
        return ms_error_set(err, status_of(dec->failure.code), "%s", dec->failure_text);
    }
    size_t used = 0;
    if (dec->header_have < MS_PROTO_HEADER_SIZE) {
        if (dec->header_have == 0 && dec->body_have == 0) {
            dec->frame_start = dec->stream_offset;
            /* Between frames: the previous message's borrow has ended, so a
             * buffer grown past MS_PROTO_DECODER_KEEP by one large frame is
             * released rather than kept for the connection's lifetime. */
            if (dec->body_capacity > MS_PROTO_DECODER_KEEP) {
                free(dec->body);
                dec->body = NULL;
                dec->body_capacity = 0;
            }
            if (dec->scratch_capacity > MS_PROTO_DECODER_KEEP) {
                free(dec->scratch);
                dec->scratch = NULL;
                dec->scratch_capacity = 0;
            }
        }
        size_t take = MS_PROTO_HEADER_SIZE - dec->header_have;
        if (take > size)
            take = size;
        if (take)
            memcpy(dec->header + dec->header_have, data, take);
        dec->header_have += take;
        used += take;
        dec->stream_offset += take;
        *consumed = used;
        if (dec->header_have < MS_PROTO_HEADER_SIZE)
            return MS_OK;
        ms_status status = check_header(dec, fault, err);
        if (status != MS_OK)
            return status;
    }
    size_t take = dec->body_length - dec->body_have;
    if (take > size - used)
        take = size - used;
    if (take)
        memcpy(dec->body + dec->body_have, data + used, take);
    dec->body_have += take;
    used += take;
    dec->stream_offset += take;
    *consumed = used;
    if (dec->body_have < dec->body_length)
        return MS_OK;
    /* The frame is complete and consumed, whatever its fate. */
    ms_status status = finish_frame(dec, msg, have_message, fault, err);
    dec->header_have = 0;
    dec->body_have = 0;
    return status;
}

ms_status ms_proto_decoder_finish(ms_proto_decoder *dec, ms_proto_fault *fault, ms_error *err)
{
    if (!dec)
        return ms_error_set(err, MS_ERR_ARG, "decoder_finish: NULL argument");
    if (dec->failed) {
        if (fault)
            *fault = dec->failure;
        return ms_error_set(err, status_of(dec->failure.code), "%s", dec->failure_text);
    }
    size_t pending = ms_proto_decoder_buffered(dec);
    if (pending == 0)
        return MS_OK;
    return fail_fatal(dec, MS_PROTO_E_MALFORMED_FRAME, 0, fault, err,
                      "truncated frame: end of stream after %zu of %zu bytes", pending,
                      dec->header_have == MS_PROTO_HEADER_SIZE
                          ? (size_t)MS_PROTO_HEADER_SIZE + dec->body_length
                          : (size_t)MS_PROTO_HEADER_SIZE);
}
