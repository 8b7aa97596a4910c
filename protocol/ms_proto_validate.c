/* Validation shared by the encoder and the decoder: the type table, names of
 * types and error codes, identifier and text checks, and the range check of
 * every field of every message (PROTOCOL.md sections 2 to 5 and 9). */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "ms_proto.h"
#include "ms_proto_wire.h"

static const ms_wire_type_info type_table[] = {
    {MS_PROTO_HELLO, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_ZERO, 0, MS_PROTO_HELLO_FIXED,
     MS_PROTO_HELLO_FIXED + MS_PROTO_MAX_TOKEN + MS_PROTO_MAX_LABEL, "HELLO"},
    {MS_PROTO_LIST_CATALOGUE, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_NONZERO, 0, 0, 0, "LIST_CATALOGUE"},
    {MS_PROTO_LIST_PAGE, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_NONZERO, 0, MS_PROTO_LIST_PAGE_FIXED,
     MS_PROTO_LIST_PAGE_FIXED + MS_PROTO_MAX_PAGE_QUERY, "LIST_PAGE"},
    {MS_PROTO_GET_DOCUMENT, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_NONZERO, 0,
     MS_PROTO_GET_DOCUMENT_FIXED + 1, MS_PROTO_GET_DOCUMENT_FIXED + MS_PROTO_MAX_MODEL_NAME,
     "GET_DOCUMENT"},
    {MS_PROTO_OPEN_MODEL, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_NONZERO, 0, MS_PROTO_OPEN_MODEL_FIXED + 1,
     MS_PROTO_OPEN_MODEL_FIXED + MS_PROTO_MAX_MODEL_NAME, "OPEN_MODEL"},
    {MS_PROTO_CLOSE_MODEL, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_ZERO, 0, MS_PROTO_CLOSE_MODEL_SIZE,
     MS_PROTO_CLOSE_MODEL_SIZE, "CLOSE_MODEL"},
    {MS_PROTO_REQUEST_CELLS, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_NONZERO, 0,
     MS_PROTO_REQUEST_CELLS_FIXED, MS_WIRE_BODY_UNBOUNDED, "REQUEST_CELLS"},
    {MS_PROTO_CANCEL, MS_WIRE_FROM_CLIENT, MS_WIRE_ID_ZERO, 0, MS_PROTO_CANCEL_FIXED,
     MS_PROTO_CANCEL_FIXED + MS_PROTO_MAX_CANCEL_RANGES * MS_PROTO_CANCEL_RANGE_SIZE, "CANCEL"},
    {MS_PROTO_PING, MS_WIRE_FROM_BOTH, MS_WIRE_ID_ZERO, 0, MS_PROTO_PING_SIZE, MS_PROTO_PING_SIZE,
     "PING"},
    {MS_PROTO_PONG, MS_WIRE_FROM_BOTH, MS_WIRE_ID_ZERO, 0, MS_PROTO_PING_SIZE, MS_PROTO_PING_SIZE,
     "PONG"},
    {MS_PROTO_ERROR, MS_WIRE_FROM_BOTH, MS_WIRE_ID_ANY, 0, MS_PROTO_ERROR_FIXED,
     MS_PROTO_ERROR_FIXED + MS_PROTO_MAX_TEXT, "ERROR"},
    {MS_PROTO_HELLO_REPLY, MS_WIRE_FROM_SERVER, MS_WIRE_ID_ZERO, 0, MS_PROTO_HELLO_REPLY_FIXED,
     MS_PROTO_HELLO_REPLY_FIXED + MS_PROTO_MAX_LABEL, "HELLO_REPLY"},
    {MS_PROTO_CATALOGUE, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 1, MS_PROTO_CATALOGUE_FIXED,
     MS_WIRE_BODY_UNBOUNDED, "CATALOGUE"},
    {MS_PROTO_MODEL_OPENED, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 0, MS_PROTO_MODEL_OPENED_SIZE,
     MS_PROTO_MODEL_OPENED_SIZE, "MODEL_OPENED"},
    {MS_PROTO_INDEX_DATA, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 1, MS_PROTO_INDEX_DATA_FIXED + 1,
     MS_WIRE_BODY_UNBOUNDED, "INDEX_DATA"},
    {MS_PROTO_PAYLOAD, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 1, MS_PROTO_PAYLOAD_FIXED,
     MS_WIRE_BODY_UNBOUNDED, "PAYLOAD"},
    {MS_PROTO_CATALOGUE_PAGE, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 1,
     MS_PROTO_CATALOGUE_PAGE_FIXED, MS_WIRE_BODY_UNBOUNDED, "CATALOGUE_PAGE"},
    {MS_PROTO_DOCUMENT, MS_WIRE_FROM_SERVER, MS_WIRE_ID_NONZERO, 1, MS_PROTO_DOCUMENT_FIXED,
     MS_WIRE_BODY_UNBOUNDED, "DOCUMENT"},
};

const ms_wire_type_info *ms_wire_type_lookup(uint8_t type)
{
    for (size_t i = 0; i < sizeof type_table / sizeof type_table[0]; ++i)
        if (type_table[i].type == type)
            return &type_table[i];
    return NULL;
}

const char *ms_proto_type_name(uint8_t type)
{
    const ms_wire_type_info *info = ms_wire_type_lookup(type);
    return info ? info->name : "?";
}

static const struct {
    const char *name;
    ms_proto_fatality fatality;
} error_table[MS_PROTO_E_LAST + 1] = {
    [MS_PROTO_E_MALFORMED_FRAME] = {"MALFORMED_FRAME", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_FRAME_TOO_LARGE] = {"FRAME_TOO_LARGE", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_UNKNOWN_TYPE] = {"UNKNOWN_TYPE", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_UNEXPECTED_MESSAGE] = {"UNEXPECTED_MESSAGE", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_UNSUPPORTED_VERSION] = {"UNSUPPORTED_VERSION", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_FIELD_OUT_OF_RANGE] = {"FIELD_OUT_OF_RANGE", MS_PROTO_FATAL_EITHER},
    [MS_PROTO_E_BATCH_TOO_LARGE] = {"BATCH_TOO_LARGE", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_TOO_MANY_OUTSTANDING] = {"TOO_MANY_OUTSTANDING", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_RATE_LIMITED] = {"RATE_LIMITED", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_QUEUE_FULL] = {"QUEUE_FULL", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_DUPLICATE_REQUEST_ID] = {"DUPLICATE_REQUEST_ID", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_BAD_MODEL_NAME] = {"BAD_MODEL_NAME", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_UNKNOWN_MODEL] = {"UNKNOWN_MODEL", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_TOO_MANY_MODELS] = {"TOO_MANY_MODELS", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_UNKNOWN_CELL] = {"UNKNOWN_CELL", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_RANGE_NOT_SATISFIABLE] = {"RANGE_NOT_SATISFIABLE", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_FORBIDDEN] = {"FORBIDDEN", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_CANCELLED] = {"CANCELLED", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_IDLE_TIMEOUT] = {"IDLE_TIMEOUT", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_TOO_MANY_CONNECTIONS] = {"TOO_MANY_CONNECTIONS", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_SHUTTING_DOWN] = {"SHUTTING_DOWN", MS_PROTO_FATAL_ALWAYS},
    [MS_PROTO_E_INTERNAL] = {"INTERNAL", MS_PROTO_FATAL_EITHER},
    [MS_PROTO_E_MODEL_CHANGED] = {"MODEL_CHANGED", MS_PROTO_FATAL_NEVER},
    [MS_PROTO_E_NO_DOCUMENT] = {"NO_DOCUMENT", MS_PROTO_FATAL_NEVER},
};

const char *ms_proto_error_name(uint16_t code)
{
    if (code < MS_PROTO_E_FIRST || code > MS_PROTO_E_LAST)
        return "?";
    return error_table[code].name;
}

const char *ms_document_kind_name(int kind)
{
    static const char *const names[] = {"?", "thumbnail", "metadata", "annotations"};
    return kind >= MS_DOCUMENT_FIRST && kind <= MS_DOCUMENT_LAST ? names[kind] : "?";
}

ms_proto_fatality ms_proto_error_fatality(uint16_t code)
{
    if (code < MS_PROTO_E_FIRST || code > MS_PROTO_E_LAST)
        return MS_PROTO_FATAL_ALWAYS;
    return error_table[code].fatality;
}

bool ms_proto_model_name_valid(const char *name, size_t length, size_t *bad_offset)
{
    if (length == 0 || length > MS_PROTO_MAX_MODEL_NAME || !name) {
        if (bad_offset)
            *bad_offset = length;
        return false;
    }
    for (size_t i = 0; i < length; ++i) {
        unsigned char c = (unsigned char)name[i];
        bool ok = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                  c == '_' || c == '-';
        if (!ok) {
            if (bad_offset)
                *bad_offset = i;
            return false;
        }
    }
    return true;
}

bool ms_proto_text_valid(const uint8_t *text, size_t length)
{
    size_t i = 0;
    while (i < length) {
        uint8_t c = text[i];
        if (c < 0x80) {
            if (c < 0x20 || c == 0x7F)
                return false;
            ++i;
            continue;
        }
        size_t extra;
        uint32_t cp;
        if (c >= 0xC2 && c <= 0xDF) {
            extra = 1;
            cp = c & 0x1Fu;
        } else if (c >= 0xE0 && c <= 0xEF) {
            extra = 2;
            cp = c & 0x0Fu;
        } else if (c >= 0xF0 && c <= 0xF4) {
            extra = 3;
            cp = c & 0x07u;
        } else {
            return false; /* continuation byte first, overlong lead C0/C1, or F5..FF */
        }
        if (length - i <= extra)
            return false;
        for (size_t k = 1; k <= extra; ++k) {
            uint8_t cc = text[i + k];
            if ((cc & 0xC0) != 0x80)
                return false;
            cp = cp << 6 | (cc & 0x3Fu);
        }
        if ((extra == 2 && cp < 0x800) || (extra == 3 && cp < 0x10000) || cp > 0x10FFFF ||
            (cp >= 0xD800 && cp <= 0xDFFF))
            return false;
        if (cp >= 0x80 && cp <= 0x9F) /* C1 controls */
            return false;
        i += extra + 1;
    }
    return true;
}

ms_status ms_proto_choose_version(uint16_t client_min, uint16_t client_max, uint16_t server_min,
                                  uint16_t server_max, uint16_t *chosen)
{
    if (client_min == 0 || client_min > client_max || server_min == 0 || server_min > server_max)
        return MS_ERR_UNSUPPORTED;
    uint16_t high = client_max < server_max ? client_max : server_max;
    uint16_t low = client_min > server_min ? client_min : server_min;
    if (high < low)
        return MS_ERR_UNSUPPORTED;
    if (chosen)
        *chosen = high;
    return MS_OK;
}

static bool ascii_in(const char *s, size_t length, unsigned char low, unsigned char high,
                     size_t *bad)
{
    for (size_t i = 0; i < length; ++i) {
        unsigned char c = (unsigned char)s[i];
        if (c < low || c > high) {
            *bad = i;
            return false;
        }
    }
    return true;
}

ms_status ms_wire_check_header(const ms_wire_type_info *info, uint8_t flags, uint32_t request_id,
                               uint32_t body_length, uint32_t max_frame, ms_error *err)
{
    if (flags & ~MS_PROTO_FLAG_LAST)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: undefined flag bits 0x%02x set", info->name,
                            flags & ~MS_PROTO_FLAG_LAST);
    if ((flags & MS_PROTO_FLAG_LAST) && !info->last_allowed)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: LAST flag not allowed on this type",
                            info->name);
    if (info->id_rule == MS_WIRE_ID_ZERO && request_id != 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: request id must be 0, got %u", info->name,
                            (unsigned)request_id);
    if (info->id_rule == MS_WIRE_ID_NONZERO && request_id == 0)
        return ms_error_set(err, MS_ERR_FORMAT, "%s: request id must not be 0", info->name);
    uint32_t max_body = info->max_body == MS_WIRE_BODY_UNBOUNDED ? max_frame : info->max_body;
    if (body_length < info->min_body || body_length > max_body)
        return ms_error_set(err, MS_ERR_FORMAT,
                            "%s: body length %u outside [%u, %u] for this type", info->name,
                            (unsigned)body_length, (unsigned)info->min_body, (unsigned)max_body);
    return MS_OK;
}

/* ---- Field ranges ---- */

typedef struct check_ctx {
    const ms_proto_message *msg;
    const char *type_name;
    uint32_t ids_first;  /* the request ids a fault on this frame ends */
    uint32_t ids_count;
    ms_proto_fault *fault;
    ms_error *err;
} check_ctx;

static ms_status fail(check_ctx *c, uint16_t code, uint64_t detail, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

static ms_status fail(check_ctx *c, uint16_t code, uint64_t detail, const char *fmt, ...)
{
    ms_status status = code == MS_PROTO_E_MALFORMED_FRAME ? MS_ERR_FORMAT : MS_ERR_RANGE;
    if (c->fault) {
        c->fault->code = code;
        c->fault->fatal = false;
        c->fault->frame_type = c->msg->type;
        c->fault->request_id = c->ids_first;
        c->fault->request_count = c->ids_count;
        c->fault->detail = detail;
    }
    if (c->err) {
        char text[MS_ERROR_TEXT_MAX];
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(text, sizeof text, fmt, ap);
        va_end(ap);
        ms_error_set(c->err, status, "%s: %s", c->type_name, text);
    }
    return status;
}

#define OUT_OF_RANGE(c, offset, ...) fail((c), MS_PROTO_E_FIELD_OUT_OF_RANGE, (offset), __VA_ARGS__)

static ms_status check_hello(check_ctx *c, const ms_proto_hello *h)
{
    size_t bad;
    if (h->min_version < 1)
        return OUT_OF_RANGE(c, 4, "min_version 0 (must be >= 1)");
    if (h->max_version < h->min_version)
        return OUT_OF_RANGE(c, 6, "max_version %u below min_version %u", h->max_version,
                            h->min_version);
    if (h->max_frame < MS_PROTO_MIN_FRAME || h->max_frame > MS_PROTO_MAX_FRAME)
        return OUT_OF_RANGE(c, 12, "max_frame %u outside [%u, %u]", (unsigned)h->max_frame,
                            MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME);
    if (h->token_length > MS_PROTO_MAX_TOKEN || (h->token_length && !h->token))
        return OUT_OF_RANGE(c, 16, "token_length %u above %u", h->token_length, MS_PROTO_MAX_TOKEN);
    if (h->agent_length > MS_PROTO_MAX_LABEL || (h->agent_length && !h->agent))
        return OUT_OF_RANGE(c, 18, "agent_length %u above %u", h->agent_length, MS_PROTO_MAX_LABEL);
    if (!ascii_in(h->token, h->token_length, 0x21, 0x7E, &bad))
        return OUT_OF_RANGE(c, MS_PROTO_HELLO_FIXED + bad,
                            "token byte %zu is not printable ASCII without space", bad);
    if (!ascii_in(h->agent, h->agent_length, 0x20, 0x7E, &bad))
        return OUT_OF_RANGE(c, MS_PROTO_HELLO_FIXED + h->token_length + bad,
                            "agent byte %zu is not printable ASCII", bad);
    return MS_OK;
}

static ms_status check_hello_reply(check_ctx *c, const ms_proto_hello_reply *r)
{
    size_t bad;
    if (r->version < 1)
        return OUT_OF_RANGE(c, 4, "version 0 (must be >= 1)");
    if (r->server_flags & ~MS_PROTO_SERVER_TOKEN_ACCEPTED)
        return OUT_OF_RANGE(c, 6, "undefined server_flags bits 0x%04x", r->server_flags);
    if (r->max_frame < MS_PROTO_MIN_FRAME || r->max_frame > MS_PROTO_MAX_FRAME)
        return OUT_OF_RANGE(c, 12, "max_frame %u outside [%u, %u]", (unsigned)r->max_frame,
                            MS_PROTO_MIN_FRAME, MS_PROTO_MAX_FRAME);
    if (r->max_batch < 1 || r->max_batch > MS_PROTO_MAX_BATCH)
        return OUT_OF_RANGE(c, 16, "max_batch %u outside [1, %u]", (unsigned)r->max_batch,
                            MS_PROTO_MAX_BATCH);
    if (r->max_outstanding < 1 || r->max_outstanding > MS_PROTO_MAX_OUTSTANDING)
        return OUT_OF_RANGE(c, 20, "max_outstanding %u outside [1, %u]",
                            (unsigned)r->max_outstanding, MS_PROTO_MAX_OUTSTANDING);
    if (r->max_queued_bytes < 1 || r->max_queued_bytes > MS_PROTO_MAX_QUEUED_BYTES)
        return OUT_OF_RANGE(c, 24, "max_queued_bytes %llu outside [1, 2^40]",
                            (unsigned long long)r->max_queued_bytes);
    if (r->idle_timeout_ms != 0 && (r->idle_timeout_ms < MS_PROTO_MIN_IDLE_TIMEOUT_MS ||
                                    r->idle_timeout_ms > MS_PROTO_MAX_IDLE_TIMEOUT_MS))
        return OUT_OF_RANGE(c, 32, "idle_timeout_ms %u outside 0 or [%u, %u]",
                            (unsigned)r->idle_timeout_ms, MS_PROTO_MIN_IDLE_TIMEOUT_MS,
                            MS_PROTO_MAX_IDLE_TIMEOUT_MS);
    if (r->max_open_models < 1 || r->max_open_models > MS_PROTO_MAX_OPEN_MODELS)
        return OUT_OF_RANGE(c, 40, "max_open_models %u outside [1, %u]", r->max_open_models,
                            MS_PROTO_MAX_OPEN_MODELS);
    if (r->server_name_length > MS_PROTO_MAX_LABEL || (r->server_name_length && !r->server_name))
        return OUT_OF_RANGE(c, 42, "name_length %u above %u", r->server_name_length,
                            MS_PROTO_MAX_LABEL);
    if (!ascii_in(r->server_name, r->server_name_length, 0x20, 0x7E, &bad))
        return OUT_OF_RANGE(c, MS_PROTO_HELLO_REPLY_FIXED + bad,
                            "server_name byte %zu is not printable ASCII", bad);
    return MS_OK;
}

static ms_status check_steps(check_ctx *c, size_t base, uint8_t geometry, uint8_t apo,
                             uint8_t permitted_geometry, uint8_t permitted_apo, const char *where)
{
    if (geometry < 1 || geometry > MS_PROTO_MAX_STEPS)
        return OUT_OF_RANGE(c, base, "%sgeometry_steps %u outside [1, %u]", where, geometry,
                            MS_PROTO_MAX_STEPS);
    if (apo > MS_PROTO_MAX_STEPS)
        return OUT_OF_RANGE(c, base + 1, "%sapo_steps %u above %u", where, apo, MS_PROTO_MAX_STEPS);
    if (permitted_geometry < 1 || permitted_geometry > geometry)
        return OUT_OF_RANGE(c, base + 2, "%spermitted_geometry_steps %u outside [1, %u]", where,
                            permitted_geometry, geometry);
    if (permitted_apo > apo)
        return OUT_OF_RANGE(c, base + 3, "%spermitted_apo_steps %u above apo_steps %u", where,
                            permitted_apo, apo);
    return MS_OK;
}

static ms_status check_catalogue(check_ctx *c, const ms_proto_catalogue *cat)
{
    if (cat->entry_count == 0 && !(c->msg->flags & MS_PROTO_FLAG_LAST))
        return OUT_OF_RANGE(c, 0, "entry_count 0 on a frame without LAST");
    if (cat->entry_count && !cat->entries)
        return OUT_OF_RANGE(c, 0, "entries missing");
    size_t offset = c->msg->type == MS_PROTO_CATALOGUE_PAGE ? MS_PROTO_CATALOGUE_PAGE_FIXED
                                                             : MS_PROTO_CATALOGUE_FIXED;
    if (c->msg->type == MS_PROTO_CATALOGUE_PAGE && cat->total < cat->entry_count)
        return OUT_OF_RANGE(c, 4, "total %u below the frame's %u entries", (unsigned)cat->total,
                            (unsigned)cat->entry_count);
    for (uint32_t i = 0; i < cat->entry_count; ++i) {
        const ms_proto_catalogue_entry *e = &cat->entries[i];
        char where[32];
        snprintf(where, sizeof where, "entry %u: ", (unsigned)i);
        size_t bad;
        if (!ms_proto_model_name_valid(e->name, e->name_length, &bad))
            return OUT_OF_RANGE(c, offset + MS_PROTO_CATALOGUE_ENTRY_FIXED + bad,
                                "%sname is not an identifier [A-Za-z0-9_-]{1,64} (byte %zu)", where,
                                bad);
        ms_status s = check_steps(c, offset + 1, e->geometry_steps, e->apo_steps,
                                  e->permitted_geometry_steps, e->permitted_apo_steps, where);
        if (s != MS_OK)
            return s;
        if (e->title_length > MS_PROTO_MAX_TEXT || (e->title_length && !e->title))
            return OUT_OF_RANGE(c, offset + 6, "%stitle_length %u above %u", where,
                                e->title_length, MS_PROTO_MAX_TEXT);
        if (!ms_proto_text_valid((const uint8_t *)e->title, e->title_length))
            return OUT_OF_RANGE(c, offset + MS_PROTO_CATALOGUE_ENTRY_FIXED + e->name_length,
                                "%stitle is not UTF-8 text without control characters", where);
        if (e->cell_count < 1 || e->cell_count > MS_PROTO_MAX_CELLS)
            return OUT_OF_RANGE(c, offset + 8, "%scell_count %u outside [1, %u]", where,
                                (unsigned)e->cell_count, MS_PROTO_MAX_CELLS);
        offset += MS_PROTO_CATALOGUE_ENTRY_FIXED + e->name_length + e->title_length;
    }
    return MS_OK;
}

static ms_status check_open_model(check_ctx *c, const ms_proto_open_model *o)
{
    size_t bad;
    if (!ms_proto_model_name_valid(o->name, o->name_length, &bad))
        return fail(c, MS_PROTO_E_BAD_MODEL_NAME, bad,
                    "model name is not an identifier [A-Za-z0-9_-]{1,64} (byte %zu of %u)", bad,
                    o->name_length);
    return MS_OK;
}

static ms_status check_model_opened(check_ctx *c, const ms_proto_model_opened *m)
{
    if (m->model_handle == 0)
        return OUT_OF_RANGE(c, 0, "model_handle 0");
    if (m->cell_count < 1 || m->cell_count > MS_PROTO_MAX_CELLS)
        return OUT_OF_RANGE(c, 4, "cell_count %u outside [1, %u]", (unsigned)m->cell_count,
                            MS_PROTO_MAX_CELLS);
    if (m->index_size < 1 || m->index_size > MS_PROTO_MAX_INDEX_SIZE)
        return OUT_OF_RANGE(c, 16, "index_size %u outside [1, %u]", (unsigned)m->index_size,
                            MS_PROTO_MAX_INDEX_SIZE);
    if (m->archive_version < 1)
        return OUT_OF_RANGE(c, 24, "archive_version 0");
    if (m->index_encoding > MS_PROTO_INDEX_SUBTREES)
        return OUT_OF_RANGE(c, 30, "index_encoding %u undefined", m->index_encoding);
    return check_steps(c, 26, m->geometry_steps, m->apo_steps, m->permitted_geometry_steps,
                       m->permitted_apo_steps, "");
}

static ms_status check_request_cells(check_ctx *c, const ms_proto_request_cells *r,
                                     uint32_t max_batch)
{
    if (r->model_handle == 0)
        return OUT_OF_RANGE(c, 0, "model_handle 0");
    if (r->count == 0)
        return OUT_OF_RANGE(c, 4, "empty batch (count 0)");
    if ((uint64_t)c->msg->request_id + r->count - 1 > UINT32_MAX)
        return OUT_OF_RANGE(c, 4, "request ids %u + %u wrap past 0xFFFFFFFF",
                            (unsigned)c->msg->request_id, r->count);
    if (r->count > max_batch)
        return fail(c, MS_PROTO_E_BATCH_TOO_LARGE, max_batch, "batch of %u entries above %u",
                    r->count, (unsigned)max_batch);
    if (!r->entries)
        return OUT_OF_RANGE(c, 8, "entries missing");
    for (uint32_t i = 0; i < r->count; ++i) {
        const ms_proto_cell_request *e = &r->entries[i];
        size_t base = MS_PROTO_REQUEST_CELLS_FIXED + (size_t)i * MS_PROTO_CELL_REQUEST_SIZE;
        if (e->stream > MS_PROTO_STREAM_COLOUR)
            return OUT_OF_RANGE(c, base + 4, "entry %u: stream %u (0 geometry, 1 APO, 2 index, 3 colour)",
                                (unsigned)i, e->stream);
        if (e->unit > MS_PROTO_UNIT_BYTES)
            return OUT_OF_RANGE(c, base + 5, "entry %u: unit %u (0 steps, 1 bytes)", (unsigned)i,
                                e->unit);
        if (e->unit == MS_PROTO_UNIT_STEPS) {
            if (e->a > MS_PROTO_MAX_STEP)
                return OUT_OF_RANGE(c, base + 8, "entry %u: first step %u above %u", (unsigned)i,
                                    (unsigned)e->a, MS_PROTO_MAX_STEP);
            if (e->b < e->a || e->b > MS_PROTO_MAX_STEP)
                return OUT_OF_RANGE(c, base + 12, "entry %u: last step %u outside [%u, %u]",
                                    (unsigned)i, (unsigned)e->b, (unsigned)e->a, MS_PROTO_MAX_STEP);
            /* A subtree is one step: STEPS on the index stream asks for all of it. */
            if (e->stream == MS_PROTO_STREAM_INDEX && e->b != 0)
                return OUT_OF_RANGE(c, base + (e->a ? 8 : 12),
                                    "entry %u: steps [%u, %u] of a subtree (it has step 0 only)",
                                    (unsigned)i, (unsigned)e->a, (unsigned)e->b);
        } else {
            if (e->b == 0)
                return OUT_OF_RANGE(c, base + 12, "entry %u: byte length 0", (unsigned)i);
            if ((uint64_t)e->a + e->b > UINT32_MAX)
                return OUT_OF_RANGE(c, base + 12, "entry %u: byte range %u + %u past 2^32 - 1",
                                    (unsigned)i, (unsigned)e->a, (unsigned)e->b);
        }
    }
    return MS_OK;
}

static ms_status check_cancel(check_ctx *c, const ms_proto_cancel *k)
{
    if (k->flags & ~MS_PROTO_CANCEL_ALL)
        return OUT_OF_RANGE(c, 2, "undefined flag bits 0x%04x", k->flags);
    if (k->range_count > MS_PROTO_MAX_CANCEL_RANGES)
        return OUT_OF_RANGE(c, 0, "range_count %u above %u", k->range_count,
                            MS_PROTO_MAX_CANCEL_RANGES);
    bool all = (k->flags & MS_PROTO_CANCEL_ALL) != 0;
    if (all != (k->range_count == 0))
        return OUT_OF_RANGE(c, 0, all ? "CANCEL_ALL with %u ranges" : "no range and no CANCEL_ALL%.0u",
                            k->range_count);
    if (k->range_count && !k->ranges)
        return OUT_OF_RANGE(c, 4, "ranges missing");
    for (uint32_t i = 0; i < k->range_count; ++i) {
        const ms_proto_id_range *r = &k->ranges[i];
        size_t base = MS_PROTO_CANCEL_FIXED + (size_t)i * MS_PROTO_CANCEL_RANGE_SIZE;
        if (r->first_id == 0)
            return OUT_OF_RANGE(c, base, "range %u: first id 0", (unsigned)i);
        if (r->count == 0 || (uint64_t)r->first_id + r->count - 1 > UINT32_MAX)
            return OUT_OF_RANGE(c, base + 4, "range %u: count %u invalid from id %u", (unsigned)i,
                                (unsigned)r->count, (unsigned)r->first_id);
    }
    return MS_OK;
}

static ms_status check_index_data(check_ctx *c, const ms_proto_index_data *d)
{
    if (d->data_length == 0 || !d->data)
        return OUT_OF_RANGE(c, 4, "no data");
    if ((uint64_t)d->offset + d->data_length > MS_PROTO_MAX_INDEX_SIZE)
        return OUT_OF_RANGE(c, 0, "offset %u + %u bytes past the %u-byte index limit",
                            (unsigned)d->offset, (unsigned)d->data_length, MS_PROTO_MAX_INDEX_SIZE);
    return MS_OK;
}

static ms_status check_payload(check_ctx *c, const ms_proto_payload *p)
{
    bool last = (c->msg->flags & MS_PROTO_FLAG_LAST) != 0;
    if (p->stream > MS_PROTO_STREAM_COLOUR)
        return OUT_OF_RANGE(c, 4, "stream %u (0 geometry, 1 APO, 2 index, 3 colour)", p->stream);
    if (p->data_length && !p->data)
        return OUT_OF_RANGE(c, 16, "data missing");
    uint64_t stop = (uint64_t)p->offset + p->data_length;
    if (stop > p->end)
        return OUT_OF_RANGE(c, 12, "data [%u, %llu) past the range end %u", (unsigned)p->offset,
                            (unsigned long long)stop, (unsigned)p->end);
    if (last && stop != p->end)
        return OUT_OF_RANGE(c, 12, "last frame ends at %llu, not at the range end %u",
                            (unsigned long long)stop, (unsigned)p->end);
    if (!last && p->data_length == 0)
        return OUT_OF_RANGE(c, 16, "empty data on a frame without LAST");
    return MS_OK;
}

static ms_status check_error(check_ctx *c, const ms_proto_error_body *e)
{
    if (e->code < MS_PROTO_E_FIRST || e->code > MS_PROTO_E_LAST)
        return OUT_OF_RANGE(c, 0, "undefined error code %u", e->code);
    ms_proto_fatality f = ms_proto_error_fatality(e->code);
    if ((f == MS_PROTO_FATAL_ALWAYS && !e->fatal) || (f == MS_PROTO_FATAL_NEVER && e->fatal))
        return OUT_OF_RANGE(c, 2, "%s must %sbe fatal", ms_proto_error_name(e->code),
                            e->fatal ? "not " : "");
    if ((c->msg->request_id == 0) != (e->request_count == 0))
        return OUT_OF_RANGE(c, 4, "request_count %u with request id %u", (unsigned)e->request_count,
                            (unsigned)c->msg->request_id);
    if ((uint64_t)c->msg->request_id + e->request_count - (e->request_count ? 1 : 0) > UINT32_MAX)
        return OUT_OF_RANGE(c, 4, "request ids %u + %u wrap past 0xFFFFFFFF",
                            (unsigned)c->msg->request_id, (unsigned)e->request_count);
    if (e->text_length > MS_PROTO_MAX_TEXT || (e->text_length && !e->text))
        return OUT_OF_RANGE(c, 16, "text_length %u above %u", e->text_length, MS_PROTO_MAX_TEXT);
    if (!ms_proto_text_valid((const uint8_t *)e->text, e->text_length))
        return OUT_OF_RANGE(c, 18, "text is not UTF-8 without control characters");
    return MS_OK;
}

static ms_status check_get_document(check_ctx *c, const ms_proto_get_document *g)
{
    if (g->kind < MS_DOCUMENT_FIRST || g->kind > MS_DOCUMENT_LAST)
        return OUT_OF_RANGE(c, 0, "document kind %u undefined (%u..%u)", g->kind,
                            MS_DOCUMENT_FIRST, MS_DOCUMENT_LAST);
    size_t bad;
    if (!ms_proto_model_name_valid(g->name, g->name_length, &bad))
        return fail(c, MS_PROTO_E_BAD_MODEL_NAME, bad,
                    "model name is not an identifier [A-Za-z0-9_-]{1,64} (byte %zu of %u)", bad,
                    g->name_length);
    return MS_OK;
}

static ms_status check_document(check_ctx *c, const ms_proto_document *d)
{
    bool last = (c->msg->flags & MS_PROTO_FLAG_LAST) != 0;
    if (d->kind < MS_DOCUMENT_FIRST || d->kind > MS_DOCUMENT_LAST)
        return OUT_OF_RANGE(c, 0, "document kind %u undefined (%u..%u)", d->kind,
                            MS_DOCUMENT_FIRST, MS_DOCUMENT_LAST);
    if (d->total_length > MS_PROTO_MAX_DOCUMENT)
        return OUT_OF_RANGE(c, 4, "total_length %u above %u", (unsigned)d->total_length,
                            MS_PROTO_MAX_DOCUMENT);
    if (d->data_length && !d->data)
        return OUT_OF_RANGE(c, MS_PROTO_DOCUMENT_FIXED, "data missing");
    if ((uint64_t)d->offset + d->data_length > d->total_length)
        return OUT_OF_RANGE(c, 8, "offset %u + %u bytes past the document's %u",
                            (unsigned)d->offset, (unsigned)d->data_length,
                            (unsigned)d->total_length);
    if (d->data_length == 0 && d->total_length != 0)
        return OUT_OF_RANGE(c, MS_PROTO_DOCUMENT_FIXED, "no data");
    if (last != ((uint64_t)d->offset + d->data_length == d->total_length))
        return OUT_OF_RANGE(c, 8, "LAST %s on a frame %s the document", last ? "set" : "not set",
                            last ? "that does not end" : "that ends");
    return MS_OK;
}

static ms_status check_list_page(check_ctx *c, const ms_proto_list_page *l)
{
    if (l->limit < 1 || l->limit > MS_PROTO_MAX_PAGE)
        return OUT_OF_RANGE(c, 4, "limit %u outside [1, %u]", l->limit, MS_PROTO_MAX_PAGE);
    if (l->sort > MS_PROTO_SORT_LAST)
        return OUT_OF_RANGE(c, 6, "sort %u undefined", l->sort);
    if (l->descending > 1)
        return OUT_OF_RANGE(c, 7, "descending %u is not 0 or 1", l->descending);
    if (l->query_length > MS_PROTO_MAX_PAGE_QUERY || (l->query_length && !l->query))
        return OUT_OF_RANGE(c, 8, "query_length %u above %u", l->query_length,
                            MS_PROTO_MAX_PAGE_QUERY);
    if (!ms_proto_text_valid((const uint8_t *)l->query, l->query_length))
        return OUT_OF_RANGE(c, MS_PROTO_LIST_PAGE_FIXED,
                            "query is not UTF-8 text without control characters");
    return MS_OK;
}

ms_status ms_proto_check_message(const ms_proto_message *msg, uint32_t max_batch,
                                 ms_proto_fault *fault, ms_error *err)
{
    if (!msg)
        return ms_error_set(err, MS_ERR_ARG, "no message");
    const ms_wire_type_info *info = ms_wire_type_lookup(msg->type);
    check_ctx c = {msg, info ? info->name : "?", 0, 0, fault, err};
    if (!info)
        return fail(&c, MS_PROTO_E_UNKNOWN_TYPE, msg->type, "undefined type 0x%02x", msg->type);
    /* The ids a rejection of this frame ends (section 4.10, 5). */
    if (msg->type == MS_PROTO_LIST_CATALOGUE || msg->type == MS_PROTO_LIST_PAGE ||
        msg->type == MS_PROTO_GET_DOCUMENT || msg->type == MS_PROTO_OPEN_MODEL) {
        c.ids_first = msg->request_id;
        c.ids_count = msg->request_id ? 1 : 0;
    } else if (msg->type == MS_PROTO_REQUEST_CELLS && msg->request_id != 0 &&
               msg->body.request_cells.count != 0 &&
               (uint64_t)msg->request_id + msg->body.request_cells.count - 1 <= UINT32_MAX) {
        c.ids_first = msg->request_id;
        c.ids_count = msg->body.request_cells.count;
    }
    ms_error header_err;
    if (ms_wire_check_header(info, msg->flags, msg->request_id, info->min_body, info->min_body,
                             &header_err) != MS_OK) {
        c.ids_first = c.ids_count = 0;
        return fail(&c, MS_PROTO_E_MALFORMED_FRAME, 0, "%s", header_err.text);
    }
    switch ((ms_proto_type)msg->type) {
    case MS_PROTO_HELLO: return check_hello(&c, &msg->body.hello);
    case MS_PROTO_HELLO_REPLY: return check_hello_reply(&c, &msg->body.hello_reply);
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE: return check_catalogue(&c, &msg->body.catalogue);
    case MS_PROTO_LIST_PAGE: return check_list_page(&c, &msg->body.list_page);
    case MS_PROTO_GET_DOCUMENT: return check_get_document(&c, &msg->body.get_document);
    case MS_PROTO_DOCUMENT: return check_document(&c, &msg->body.document);
    case MS_PROTO_OPEN_MODEL: return check_open_model(&c, &msg->body.open_model);
    case MS_PROTO_MODEL_OPENED: return check_model_opened(&c, &msg->body.model_opened);
    case MS_PROTO_CLOSE_MODEL:
        if (msg->body.close_model.model_handle == 0)
            return OUT_OF_RANGE(&c, 0, "model_handle 0");
        return MS_OK;
    case MS_PROTO_REQUEST_CELLS:
        return check_request_cells(&c, &msg->body.request_cells, max_batch);
    case MS_PROTO_CANCEL: return check_cancel(&c, &msg->body.cancel);
    case MS_PROTO_INDEX_DATA: return check_index_data(&c, &msg->body.index_data);
    case MS_PROTO_PAYLOAD: return check_payload(&c, &msg->body.payload);
    case MS_PROTO_ERROR: return check_error(&c, &msg->body.error);
    case MS_PROTO_LIST_CATALOGUE:
    case MS_PROTO_PING:
    case MS_PROTO_PONG:
    case MS_PROTO_NONE:
        break;
    }
    return MS_OK;
}

uint32_t ms_proto_version_capabilities(uint16_t version)
{
    uint32_t caps = 0;
    if (version >= 1)
        caps |= MS_PROTO_CAP_APO;
    if (version >= 2)
        caps |= MS_PROTO_CAP_INDEX_ZLIB;
    if (version >= 3)
        caps |= MS_PROTO_CAP_INDEX_SUBTREES | MS_PROTO_CAP_COLOUR;
    return caps;
}

/* The capability a stream needs (0: none). */
static uint32_t stream_capability(uint8_t stream)
{
    switch (stream) {
    case MS_PROTO_STREAM_APO: return MS_PROTO_CAP_APO;
    case MS_PROTO_STREAM_INDEX: return MS_PROTO_CAP_INDEX_SUBTREES;
    case MS_PROTO_STREAM_COLOUR: return MS_PROTO_CAP_COLOUR;
    default: return 0;
    }
}

static const char *capability_name(uint32_t capability)
{
    switch (capability) {
    case MS_PROTO_CAP_APO: return "CAP_APO";
    case MS_PROTO_CAP_INDEX_ZLIB: return "CAP_INDEX_ZLIB";
    case MS_PROTO_CAP_INDEX_SUBTREES: return "CAP_INDEX_SUBTREES";
    case MS_PROTO_CAP_COLOUR: return "CAP_COLOUR";
    default: return "an undefined capability";
    }
}

ms_status ms_proto_check_negotiated(const ms_proto_message *msg, uint16_t version,
                                    uint32_t capabilities, ms_proto_fault *fault, ms_error *err)
{
    if (!msg)
        return ms_error_set(err, MS_ERR_ARG, "no message");
    const ms_wire_type_info *info = ms_wire_type_lookup(msg->type);
    check_ctx c = {msg, info ? info->name : "?", 0, 0, fault, err};
    switch (msg->type) {
    case MS_PROTO_LIST_PAGE:
    case MS_PROTO_CATALOGUE_PAGE:
        c.ids_first = msg->request_id;
        c.ids_count = msg->request_id ? 1 : 0;
        if (version < 3)
            return OUT_OF_RANGE(&c, 0, "a catalogue page needs version 3 (version %u)", version);
        return MS_OK;
    case MS_PROTO_GET_DOCUMENT:
    case MS_PROTO_DOCUMENT:
        c.ids_first = msg->request_id;
        c.ids_count = msg->request_id ? 1 : 0;
        if (version < 3)
            return OUT_OF_RANGE(&c, 0, "a document needs version 3 (version %u)", version);
        return MS_OK;
    case MS_PROTO_HELLO_REPLY: {
        uint32_t undefined = msg->body.hello_reply.capabilities &
                             ~ms_proto_version_capabilities(msg->body.hello_reply.version);
        if (undefined)
            return OUT_OF_RANGE(&c, 8, "capabilities 0x%08x not defined in version %u",
                                (unsigned)undefined, msg->body.hello_reply.version);
        return MS_OK;
    }
    case MS_PROTO_MODEL_OPENED: {
        uint8_t encoding = msg->body.model_opened.index_encoding;
        uint32_t needed = encoding == MS_PROTO_INDEX_ZLIB       ? MS_PROTO_CAP_INDEX_ZLIB
                          : encoding == MS_PROTO_INDEX_SUBTREES ? MS_PROTO_CAP_INDEX_SUBTREES
                                                                : 0;
        if (needed & ~capabilities)
            return OUT_OF_RANGE(&c, 30, "index_encoding %u without %s (version %u)", encoding,
                                capability_name(needed), version);
        return MS_OK;
    }
    case MS_PROTO_REQUEST_CELLS: {
        const ms_proto_request_cells *r = &msg->body.request_cells;
        if (msg->request_id && r->count &&
            (uint64_t)msg->request_id + r->count - 1 <= UINT32_MAX) {
            c.ids_first = msg->request_id;
            c.ids_count = r->count;
        }
        for (uint32_t i = 0; r->entries && i < r->count; ++i) {
            uint32_t needed = stream_capability(r->entries[i].stream);
            if (needed & ~capabilities)
                return OUT_OF_RANGE(&c,
                                    MS_PROTO_REQUEST_CELLS_FIXED +
                                        (size_t)i * MS_PROTO_CELL_REQUEST_SIZE + 4,
                                    "entry %u: stream %u without %s (version %u)", (unsigned)i,
                                    r->entries[i].stream, capability_name(needed), version);
        }
        return MS_OK;
    }
    case MS_PROTO_PAYLOAD: {
        uint32_t needed = stream_capability(msg->body.payload.stream);
        if (needed & ~capabilities)
            return OUT_OF_RANGE(&c, 4, "stream %u without %s (version %u)",
                                msg->body.payload.stream, capability_name(needed), version);
        return MS_OK;
    }
    default: return MS_OK;
    }
}

void ms_proto_error_from_fault(const ms_proto_fault *fault, const char *text,
                               ms_proto_message *out)
{
    memset(out, 0, sizeof *out);
    out->type = MS_PROTO_ERROR;
    out->request_id = fault->request_count ? fault->request_id : 0;
    ms_proto_error_body *e = &out->body.error;
    e->code = fault->code;
    ms_proto_fatality f = ms_proto_error_fatality(fault->code);
    e->fatal = f == MS_PROTO_FATAL_ALWAYS || (f == MS_PROTO_FATAL_EITHER && fault->fatal);
    e->request_count = out->request_id ? fault->request_count : 0;
    e->detail = fault->detail;
    size_t length = text ? strlen(text) : 0;
    if (length > MS_PROTO_MAX_TEXT) {
        length = MS_PROTO_MAX_TEXT;
        /* Do not cut a UTF-8 sequence: back off over continuation bytes. */
        while (length > 0 && ((unsigned char)text[length] & 0xC0) == 0x80)
            --length;
    }
    e->text = text;
    e->text_length = (uint16_t)length;
}
