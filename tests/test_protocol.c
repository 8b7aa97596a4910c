/* Wire protocol (protocol/ms_proto.h, PROTOCOL.md): the worked examples of the
 * spec byte for byte, round trips of every message type at its boundary values,
 * the decoder fed byte by byte and in random splits, every malformed frame
 * class giving its documented error, a bounded random-mutation loop, and the
 * replay of the regression corpus tests/corpus/protocol/. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dirent.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_proto.h"
#include "ms_proto_decode_internal.h"
#include "ms_test.h"

#define MS_FUZZ_NO_ENTRY_POINT
#include "fuzz/fuzz_protocol.c"

/* ---- Helpers ---- */

static uint64_t rng_state = 0x243F6A8885A308D3ull;

static uint64_t rng_next(void)
{
    rng_state ^= rng_state << 13;
    rng_state ^= rng_state >> 7;
    rng_state ^= rng_state << 17;
    return rng_state;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

static void put16(uint8_t *p, uint16_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

/* A raw frame header, to build frames the encoder would refuse. */
static void raw_header(uint8_t *p, uint32_t body_length, uint8_t type, uint8_t flags,
                       uint32_t request_id)
{
    put32(p, body_length);
    p[4] = type;
    p[5] = flags;
    p[6] = p[7] = 0;
    put32(p + 8, request_id);
}

static size_t encode(const ms_proto_message *m, uint8_t *out, size_t capacity)
{
    size_t written = 0;
    ms_error err;
    ms_status s = ms_proto_encode(m, out, capacity, &written, &err);
    if (s != MS_OK)
        fail_msg("encode %s: %s", ms_proto_type_name(m->type), err.text);
    size_t size = 0;
    assert_int_equal(ms_proto_encoded_size(m, &size, NULL), MS_OK);
    assert_int_equal(size, written);
    return written;
}

static ms_proto_hello default_hello(void)
{
    return (ms_proto_hello){.min_version = 1, .max_version = 1, .capabilities = MS_PROTO_CAP_APO,
                            .max_frame = MS_PROTO_MIN_FRAME, .agent = "test", .agent_length = 4};
}

static ms_proto_hello_reply default_reply(void)
{
    return (ms_proto_hello_reply){.version = 1, .capabilities = MS_PROTO_CAP_APO,
                                  .max_frame = 65536, .max_batch = 8, .max_outstanding = 64,
                                  .max_queued_bytes = 1u << 20, .idle_timeout_ms = 30000,
                                  .max_request_rate = 1000, .max_open_models = 4,
                                  .server_name = "meshserve/0.1", .server_name_length = 13};
}

/* A decoder of the given role, already past the handshake. */
static void ready_decoder(ms_proto_decoder **dec, ms_proto_role role, uint32_t max_frame,
                          uint32_t max_batch)
{
    ms_proto_decoder_config config = {role, max_frame, max_batch};
    assert_int_equal(ms_proto_decoder_new(&config, dec, NULL), MS_OK);
    ms_proto_message m;
    memset(&m, 0, sizeof m);
    if (role == MS_PROTO_ROLE_SERVER) {
        m.type = MS_PROTO_HELLO;
        m.body.hello = default_hello();
    } else {
        m.type = MS_PROTO_HELLO_REPLY;
        m.body.hello_reply = default_reply();
    }
    uint8_t frame[512];
    size_t size = encode(&m, frame, sizeof frame);
    size_t consumed;
    bool have;
    ms_proto_message out;
    assert_int_equal(ms_proto_decoder_feed(*dec, frame, size, &consumed, &out, &have, NULL, NULL),
                     MS_OK);
    assert_true(have);
    assert_int_equal(consumed, size);
}

/* Feeds one whole frame; returns the status, with msg/fault filled. */
static ms_status feed_all(ms_proto_decoder *dec, const uint8_t *frame, size_t size,
                          ms_proto_message *msg, bool *have, ms_proto_fault *fault,
                          size_t *consumed)
{
    ms_error err;
    size_t used = 0;
    memset(fault, 0, sizeof *fault);
    ms_status s = ms_proto_decoder_feed(dec, frame, size, &used, msg, have, fault, &err);
    if (consumed)
        *consumed = used;
    if (s != MS_OK) {
        assert_int_equal(err.code, s);
        assert_true(strlen(err.text) > 0);
        assert_null(strchr(err.text, '\n'));
    }
    return s;
}

/* Asserts that frame is rejected with code, fatality, and ids/detail. */
static void expect_fault(ms_proto_role role, uint32_t max_batch, const uint8_t *frame,
                         size_t size, uint16_t code, bool fatal, uint32_t request_id,
                         uint32_t request_count, uint64_t detail)
{
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, role, MS_PROTO_MIN_FRAME, max_batch);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have = true;
    ms_status s = feed_all(dec, frame, size, &msg, &have, &fault, NULL);
    assert_int_not_equal(s, MS_OK);
    assert_false(have);
    if (fault.code != code)
        fail_msg("expected %s, got %s", ms_proto_error_name(code), ms_proto_error_name(fault.code));
    assert_int_equal(fault.fatal, fatal);
    assert_int_equal(fault.request_id, request_id);
    assert_int_equal(fault.request_count, request_count);
    assert_int_equal(fault.detail, detail);
    if (!fatal) {
        /* The decoder goes on with the next frame. */
        uint8_t ping[20];
        ms_proto_message p = {.type = MS_PROTO_PING, .body.ping.opaque = 7};
        size_t n = encode(&p, ping, sizeof ping);
        assert_int_equal(feed_all(dec, ping, n, &msg, &have, &fault, NULL), MS_OK);
        assert_true(have);
        assert_int_equal(msg.type, MS_PROTO_PING);
        assert_int_equal(msg.body.ping.opaque, 7);
    } else {
        /* A failed decoder repeats its fault and takes nothing more. */
        uint8_t more[4] = {0};
        size_t consumed = 1;
        ms_proto_fault again;
        assert_int_equal(feed_all(dec, more, sizeof more, &msg, &have, &again, &consumed), s);
        assert_int_equal(consumed, 0);
        assert_int_equal(again.code, code);
    }
    ms_proto_decoder_free(dec);
}

/* ---- Field-by-field comparison of two messages ---- */

static void assert_bytes(const void *a, const void *b, size_t n)
{
    if (n)
        assert_memory_equal(a, b, n);
}

static void assert_same(const ms_proto_message *a, const ms_proto_message *b)
{
    assert_int_equal(a->type, b->type);
    assert_int_equal(a->flags, b->flags);
    assert_int_equal(a->request_id, b->request_id);
    switch (a->type) {
    case MS_PROTO_HELLO: {
        const ms_proto_hello *x = &a->body.hello, *y = &b->body.hello;
        assert_int_equal(x->min_version, y->min_version);
        assert_int_equal(x->max_version, y->max_version);
        assert_int_equal(x->capabilities, y->capabilities);
        assert_int_equal(x->max_frame, y->max_frame);
        assert_int_equal(x->token_length, y->token_length);
        assert_bytes(x->token, y->token, x->token_length);
        assert_int_equal(x->agent_length, y->agent_length);
        assert_bytes(x->agent, y->agent, x->agent_length);
        break;
    }
    case MS_PROTO_HELLO_REPLY: {
        const ms_proto_hello_reply *x = &a->body.hello_reply, *y = &b->body.hello_reply;
        assert_int_equal(x->version, y->version);
        assert_int_equal(x->server_flags, y->server_flags);
        assert_int_equal(x->capabilities, y->capabilities);
        assert_int_equal(x->max_frame, y->max_frame);
        assert_int_equal(x->max_batch, y->max_batch);
        assert_int_equal(x->max_outstanding, y->max_outstanding);
        assert_int_equal(x->max_queued_bytes, y->max_queued_bytes);
        assert_int_equal(x->idle_timeout_ms, y->idle_timeout_ms);
        assert_int_equal(x->max_request_rate, y->max_request_rate);
        assert_int_equal(x->max_open_models, y->max_open_models);
        assert_int_equal(x->server_name_length, y->server_name_length);
        assert_bytes(x->server_name, y->server_name, x->server_name_length);
        break;
    }
    case MS_PROTO_PING:
    case MS_PROTO_PONG:
        assert_int_equal(a->body.ping.opaque, b->body.ping.opaque);
        break;
    case MS_PROTO_LIST_CATALOGUE:
        break;
    case MS_PROTO_LIST_PAGE: {
        const ms_proto_list_page *x = &a->body.list_page, *y = &b->body.list_page;
        assert_int_equal(x->offset, y->offset);
        assert_int_equal(x->limit, y->limit);
        assert_int_equal(x->sort, y->sort);
        assert_int_equal(x->descending, y->descending);
        assert_int_equal(x->query_length, y->query_length);
        assert_bytes(x->query, y->query, x->query_length);
        break;
    }
    case MS_PROTO_CATALOGUE:
    case MS_PROTO_CATALOGUE_PAGE: {
        const ms_proto_catalogue *x = &a->body.catalogue, *y = &b->body.catalogue;
        assert_int_equal(x->entry_count, y->entry_count);
        assert_int_equal(x->total, y->total);
        for (unsigned i = 0; i < x->entry_count; ++i) {
            const ms_proto_catalogue_entry *e = &x->entries[i], *f = &y->entries[i];
            assert_int_equal(e->name_length, f->name_length);
            assert_bytes(e->name, f->name, e->name_length);
            assert_int_equal(e->geometry_steps, f->geometry_steps);
            assert_int_equal(e->apo_steps, f->apo_steps);
            assert_int_equal(e->permitted_geometry_steps, f->permitted_geometry_steps);
            assert_int_equal(e->permitted_apo_steps, f->permitted_apo_steps);
            assert_int_equal(e->title_length, f->title_length);
            assert_bytes(e->title, f->title, e->title_length);
            assert_int_equal(e->cell_count, f->cell_count);
            assert_int_equal(e->content_id, f->content_id);
            assert_int_equal(e->archive_bytes, f->archive_bytes);
        }
        break;
    }
    case MS_PROTO_OPEN_MODEL:
        assert_int_equal(a->body.open_model.name_length, b->body.open_model.name_length);
        assert_bytes(a->body.open_model.name, b->body.open_model.name,
                     a->body.open_model.name_length);
        break;
    case MS_PROTO_MODEL_OPENED: {
        const ms_proto_model_opened *x = &a->body.model_opened, *y = &b->body.model_opened;
        assert_int_equal(x->model_handle, y->model_handle);
        assert_int_equal(x->cell_count, y->cell_count);
        assert_int_equal(x->content_id, y->content_id);
        assert_int_equal(x->index_size, y->index_size);
        assert_int_equal(x->index_crc32, y->index_crc32);
        assert_int_equal(x->archive_version, y->archive_version);
        assert_int_equal(x->geometry_steps, y->geometry_steps);
        assert_int_equal(x->apo_steps, y->apo_steps);
        assert_int_equal(x->permitted_geometry_steps, y->permitted_geometry_steps);
        assert_int_equal(x->permitted_apo_steps, y->permitted_apo_steps);
        assert_int_equal(x->index_encoding, y->index_encoding);
        break;
    }
    case MS_PROTO_CLOSE_MODEL:
        assert_int_equal(a->body.close_model.model_handle, b->body.close_model.model_handle);
        break;
    case MS_PROTO_REQUEST_CELLS: {
        const ms_proto_request_cells *x = &a->body.request_cells, *y = &b->body.request_cells;
        assert_int_equal(x->model_handle, y->model_handle);
        assert_int_equal(x->count, y->count);
        for (unsigned i = 0; i < x->count; ++i) {
            assert_int_equal(x->entries[i].cell_id, y->entries[i].cell_id);
            assert_int_equal(x->entries[i].stream, y->entries[i].stream);
            assert_int_equal(x->entries[i].unit, y->entries[i].unit);
            assert_int_equal(x->entries[i].priority, y->entries[i].priority);
            assert_int_equal(x->entries[i].a, y->entries[i].a);
            assert_int_equal(x->entries[i].b, y->entries[i].b);
        }
        break;
    }
    case MS_PROTO_CANCEL: {
        const ms_proto_cancel *x = &a->body.cancel, *y = &b->body.cancel;
        assert_int_equal(x->flags, y->flags);
        assert_int_equal(x->range_count, y->range_count);
        for (unsigned i = 0; i < x->range_count; ++i) {
            assert_int_equal(x->ranges[i].first_id, y->ranges[i].first_id);
            assert_int_equal(x->ranges[i].count, y->ranges[i].count);
        }
        break;
    }
    case MS_PROTO_INDEX_DATA:
        assert_int_equal(a->body.index_data.offset, b->body.index_data.offset);
        assert_int_equal(a->body.index_data.data_length, b->body.index_data.data_length);
        assert_bytes(a->body.index_data.data, b->body.index_data.data,
                     a->body.index_data.data_length);
        break;
    case MS_PROTO_PAYLOAD: {
        const ms_proto_payload *x = &a->body.payload, *y = &b->body.payload;
        assert_int_equal(x->cell_id, y->cell_id);
        assert_int_equal(x->stream, y->stream);
        assert_int_equal(x->offset, y->offset);
        assert_int_equal(x->end, y->end);
        assert_int_equal(x->data_length, y->data_length);
        assert_bytes(x->data, y->data, x->data_length);
        break;
    }
    case MS_PROTO_GET_DOCUMENT:
        assert_int_equal(a->body.get_document.kind, b->body.get_document.kind);
        assert_int_equal(a->body.get_document.name_length, b->body.get_document.name_length);
        assert_bytes(a->body.get_document.name, b->body.get_document.name,
                     a->body.get_document.name_length);
        break;
    case MS_PROTO_DOCUMENT: {
        const ms_proto_document *x = &a->body.document, *y = &b->body.document;
        assert_int_equal(x->kind, y->kind);
        assert_int_equal(x->total_length, y->total_length);
        assert_int_equal(x->offset, y->offset);
        assert_int_equal(x->data_length, y->data_length);
        assert_bytes(x->data, y->data, x->data_length);
        break;
    }
    case MS_PROTO_ERROR: {
        const ms_proto_error_body *x = &a->body.error, *y = &b->body.error;
        assert_int_equal(x->code, y->code);
        assert_int_equal(x->fatal, y->fatal);
        assert_int_equal(x->request_count, y->request_count);
        assert_int_equal(x->detail, y->detail);
        assert_int_equal(x->text_length, y->text_length);
        assert_bytes(x->text, y->text, x->text_length);
        break;
    }
    default:
        fail_msg("unexpected type 0x%02x", a->type);
    }
}

/* ---- A set of messages covering every type at its boundary values ---- */

static char long_token[MS_PROTO_MAX_TOKEN + 1];
static char long_label[MS_PROTO_MAX_LABEL + 1];
static char long_name[MS_PROTO_MAX_MODEL_NAME + 1];
static char long_text[MS_PROTO_MAX_TEXT + 1];
static uint8_t blob[70000];
static ms_proto_cell_request big_batch[MS_PROTO_MAX_BATCH];
static ms_proto_id_range many_ranges[MS_PROTO_MAX_CANCEL_RANGES];
static ms_proto_catalogue_entry catalogue_entries[3];
static const ms_proto_cell_request subtree_requests[2] = {
    {.cell_id = 65, .stream = MS_PROTO_STREAM_INDEX, .unit = MS_PROTO_UNIT_STEPS, .priority = 1,
     .a = 0, .b = 0},
    {.cell_id = UINT32_MAX, .stream = MS_PROTO_STREAM_INDEX, .unit = MS_PROTO_UNIT_BYTES,
     .priority = 255, .a = 1000, .b = 24}};

static void fill_fixtures(void)
{
    for (size_t i = 0; i < MS_PROTO_MAX_TOKEN; ++i)
        long_token[i] = (char)(0x21 + i % 94);
    for (size_t i = 0; i < MS_PROTO_MAX_LABEL; ++i)
        long_label[i] = (char)(0x20 + i % 95);
    static const char ident[] = "ABCXYZabcxyz0189_-";
    for (size_t i = 0; i < MS_PROTO_MAX_MODEL_NAME; ++i)
        long_name[i] = ident[i % (sizeof ident - 1)];
    /* 256 bytes of text mixing 1- to 4-byte UTF-8 sequences: "é€😀a" repeated. */
    static const char mix[] = "\xC3\xA9\xE2\x82\xAC\xF0\x9F\x98\x80" "a";
    for (size_t i = 0; i + 10 <= MS_PROTO_MAX_TEXT; i += 10)
        memcpy(long_text + i, mix, 10);
    memcpy(long_text + 250, "abcdef", 6);
    for (size_t i = 0; i < sizeof blob; ++i)
        blob[i] = (uint8_t)(i * 131 + 7);
    for (size_t i = 0; i < MS_PROTO_MAX_BATCH; ++i) {
        bool steps = i % 2 == 0;
        big_batch[i] = (ms_proto_cell_request){
            .cell_id = i == 0 ? UINT32_MAX : (uint32_t)i * 977, .stream = (uint8_t)(i % 2 ? 1 : 0),
            .unit = steps ? MS_PROTO_UNIT_STEPS : MS_PROTO_UNIT_BYTES, .priority = (uint8_t)(i * 7),
            .a = steps ? (uint32_t)(i % 64) : (i == 1 ? UINT32_MAX - 1 : (uint32_t)i * 100),
            .b = steps ? 63 : 1};
    }
    big_batch[3].b = UINT32_MAX - big_batch[3].a; /* BYTES range ending at 2^32 - 1 */
    for (size_t i = 0; i < MS_PROTO_MAX_CANCEL_RANGES; ++i)
        many_ranges[i] = (ms_proto_id_range){(uint32_t)i * 1000 + 1, (uint32_t)i + 1};
    many_ranges[255] = (ms_proto_id_range){UINT32_MAX, 1};
    catalogue_entries[0] = (ms_proto_catalogue_entry){
        .name = "a", .name_length = 1, .geometry_steps = 1, .apo_steps = 0,
        .permitted_geometry_steps = 1, .permitted_apo_steps = 0, .cell_count = 1};
    catalogue_entries[1] = (ms_proto_catalogue_entry){
        .name = long_name, .name_length = 64, .geometry_steps = 64, .apo_steps = 64,
        .permitted_geometry_steps = 64, .permitted_apo_steps = 64, .title = long_text,
        .title_length = MS_PROTO_MAX_TEXT, .cell_count = MS_PROTO_MAX_CELLS,
        .content_id = UINT64_MAX, .archive_bytes = UINT64_MAX};
    catalogue_entries[2] = (ms_proto_catalogue_entry){
        .name = "dragon_871k", .name_length = 11, .geometry_steps = 16, .apo_steps = 9,
        .permitted_geometry_steps = 10, .permitted_apo_steps = 3, .title = "Stanford dragon",
        .title_length = 15, .cell_count = 4681, .content_id = 0x0123456789ABCDEFull,
        .archive_bytes = 12345678};
}

/* Builds message number i of the sample set; returns false past the end. */
static bool sample_message(unsigned i, ms_proto_message *m)
{
    memset(m, 0, sizeof *m);
    switch (i) {
    case 0: /* HELLO, smallest */
        m->type = MS_PROTO_HELLO;
        m->body.hello = (ms_proto_hello){.min_version = 1, .max_version = 1,
                                         .max_frame = MS_PROTO_MIN_FRAME};
        return true;
    case 1: /* HELLO, largest */
        m->type = MS_PROTO_HELLO;
        m->body.hello = (ms_proto_hello){.min_version = UINT16_MAX, .max_version = UINT16_MAX,
                                         .capabilities = UINT32_MAX, .max_frame = MS_PROTO_MAX_FRAME,
                                         .token = long_token, .token_length = MS_PROTO_MAX_TOKEN,
                                         .agent = long_label, .agent_length = MS_PROTO_MAX_LABEL};
        return true;
    case 2:
        m->type = MS_PROTO_HELLO_REPLY;
        m->body.hello_reply = (ms_proto_hello_reply){
            .version = 1, .max_frame = MS_PROTO_MIN_FRAME, .max_batch = 1, .max_outstanding = 1,
            .max_queued_bytes = 1, .idle_timeout_ms = 0, .max_open_models = 1};
        return true;
    case 3:
        m->type = MS_PROTO_HELLO_REPLY;
        m->body.hello_reply = (ms_proto_hello_reply){
            .version = UINT16_MAX, .server_flags = MS_PROTO_SERVER_TOKEN_ACCEPTED,
            .capabilities = UINT32_MAX, .max_frame = MS_PROTO_MAX_FRAME,
            .max_batch = MS_PROTO_MAX_BATCH, .max_outstanding = MS_PROTO_MAX_OUTSTANDING,
            .max_queued_bytes = MS_PROTO_MAX_QUEUED_BYTES,
            .idle_timeout_ms = MS_PROTO_MAX_IDLE_TIMEOUT_MS, .max_request_rate = UINT32_MAX,
            .max_open_models = MS_PROTO_MAX_OPEN_MODELS, .server_name = long_label,
            .server_name_length = MS_PROTO_MAX_LABEL};
        return true;
    case 4:
        m->type = MS_PROTO_PING;
        m->body.ping.opaque = UINT64_MAX;
        return true;
    case 5:
        m->type = MS_PROTO_PONG;
        m->body.ping.opaque = 0;
        return true;
    case 6:
        m->type = MS_PROTO_LIST_CATALOGUE;
        m->request_id = UINT32_MAX;
        return true;
    case 7: /* empty catalogue: one LAST frame with no entry */
        m->type = MS_PROTO_CATALOGUE;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 1;
        return true;
    case 8:
        m->type = MS_PROTO_CATALOGUE;
        m->request_id = 2;
        m->body.catalogue = (ms_proto_catalogue){catalogue_entries, 3, 0};
        return true;
    case 9:
        m->type = MS_PROTO_OPEN_MODEL;
        m->request_id = 1;
        m->body.open_model = (ms_proto_open_model){"x", 1};
        return true;
    case 10:
        m->type = MS_PROTO_OPEN_MODEL;
        m->request_id = UINT32_MAX;
        m->body.open_model = (ms_proto_open_model){long_name, MS_PROTO_MAX_MODEL_NAME};
        return true;
    case 11:
        m->type = MS_PROTO_MODEL_OPENED;
        m->request_id = 3;
        m->body.model_opened = (ms_proto_model_opened){
            .model_handle = 1, .cell_count = 1, .content_id = 0, .index_size = 1,
            .index_crc32 = 0, .archive_version = 1, .geometry_steps = 1, .apo_steps = 0,
            .permitted_geometry_steps = 1, .permitted_apo_steps = 0};
        return true;
    case 12:
        m->type = MS_PROTO_MODEL_OPENED;
        m->request_id = UINT32_MAX;
        m->body.model_opened = (ms_proto_model_opened){
            .model_handle = UINT32_MAX, .cell_count = MS_PROTO_MAX_CELLS,
            .content_id = UINT64_MAX, .index_size = MS_PROTO_MAX_INDEX_SIZE,
            .index_crc32 = UINT32_MAX, .archive_version = UINT16_MAX, .geometry_steps = 64,
            .apo_steps = 64, .permitted_geometry_steps = 64, .permitted_apo_steps = 64,
            .index_encoding = MS_PROTO_INDEX_ZLIB};
        return true;
    case 13:
        m->type = MS_PROTO_CLOSE_MODEL;
        m->body.close_model.model_handle = UINT32_MAX;
        return true;
    case 14: /* batch of one, at the top of the id space */
        m->type = MS_PROTO_REQUEST_CELLS;
        m->request_id = UINT32_MAX;
        m->body.request_cells = (ms_proto_request_cells){1, big_batch, 1};
        return true;
    case 15: /* the largest batch the protocol allows */
        m->type = MS_PROTO_REQUEST_CELLS;
        m->request_id = 1;
        m->body.request_cells = (ms_proto_request_cells){UINT32_MAX, big_batch, MS_PROTO_MAX_BATCH};
        return true;
    case 16:
        m->type = MS_PROTO_CANCEL;
        m->body.cancel = (ms_proto_cancel){MS_PROTO_CANCEL_ALL, NULL, 0};
        return true;
    case 17:
        m->type = MS_PROTO_CANCEL;
        m->body.cancel = (ms_proto_cancel){0, many_ranges, MS_PROTO_MAX_CANCEL_RANGES};
        return true;
    case 18:
        m->type = MS_PROTO_INDEX_DATA;
        m->request_id = 9;
        m->body.index_data = (ms_proto_index_data){0, blob, 1};
        return true;
    case 19: /* ends exactly at the 64 MiB index limit */
        m->type = MS_PROTO_INDEX_DATA;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 9;
        m->body.index_data =
            (ms_proto_index_data){MS_PROTO_MAX_INDEX_SIZE - 60000, blob, 60000};
        return true;
    case 20: /* empty range: one LAST frame with no data */
        m->type = MS_PROTO_PAYLOAD;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 5;
        m->body.payload = (ms_proto_payload){.cell_id = 0, .stream = 0, .offset = 0, .end = 0};
        return true;
    case 21:
        m->type = MS_PROTO_PAYLOAD;
        m->request_id = 6;
        m->body.payload = (ms_proto_payload){.cell_id = UINT32_MAX, .stream = 1, .offset = 100,
                                             .end = UINT32_MAX, .data = blob, .data_length = 65536};
        return true;
    case 22: /* last chunk ending at 2^32 - 1 */
        m->type = MS_PROTO_PAYLOAD;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 6;
        m->body.payload = (ms_proto_payload){.cell_id = 1, .stream = 1,
                                             .offset = UINT32_MAX - 1000, .end = UINT32_MAX,
                                             .data = blob, .data_length = 1000};
        return true;
    case 23:
        m->type = MS_PROTO_ERROR;
        m->body.error = (ms_proto_error_body){.code = MS_PROTO_E_SHUTTING_DOWN, .fatal = true};
        return true;
    case 24:
        m->type = MS_PROTO_ERROR;
        m->request_id = UINT32_MAX;
        m->body.error = (ms_proto_error_body){.code = MS_PROTO_E_INTERNAL, .fatal = false,
                                              .request_count = 1, .detail = UINT64_MAX,
                                              .text = long_text, .text_length = MS_PROTO_MAX_TEXT};
        return true;
    case 25:
        m->type = MS_PROTO_ERROR;
        m->request_id = 1;
        m->body.error = (ms_proto_error_body){.code = MS_PROTO_E_CANCELLED,
                                              .request_count = UINT32_MAX, .text = "cancelled",
                                              .text_length = 9};
        return true;
    case 26: /* section 9.1: connection level, the handle in detail */
        m->type = MS_PROTO_ERROR;
        m->body.error = (ms_proto_error_body){.code = MS_PROTO_E_MODEL_CHANGED, .detail = 7,
                                              .text = "model changed", .text_length = 13};
        return true;
    case 27: /* version 3: the index head (section 4.7) */
        m->type = MS_PROTO_MODEL_OPENED;
        m->request_id = 4;
        m->body.model_opened = (ms_proto_model_opened){
            .model_handle = 2, .cell_count = 1281, .content_id = 77, .index_size = 2000,
            .index_crc32 = 0xDEADBEEF, .archive_version = 3, .geometry_steps = 16,
            .apo_steps = 6, .permitted_geometry_steps = 10, .permitted_apo_steps = 6,
            .index_encoding = MS_PROTO_INDEX_SUBTREES};
        return true;
    case 28: /* version 3: subtrees by STEPS (the whole) and by BYTES (resuming) */
        m->type = MS_PROTO_REQUEST_CELLS;
        m->request_id = 40;
        m->body.request_cells = (ms_proto_request_cells){2, subtree_requests, 2};
        return true;
    case 30: /* version 3: a page of the catalogue, and its answer */
        m->type = MS_PROTO_LIST_PAGE;
        m->request_id = 41;
        m->body.list_page = (ms_proto_list_page){.offset = 200, .limit = 100,
                                                 .sort = MS_PROTO_SORT_DATE, .descending = 1,
                                                 .query = "Büste", .query_length = 6};
        return true;
    case 31:
        m->type = MS_PROTO_CATALOGUE_PAGE;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 41;
        m->body.catalogue = (ms_proto_catalogue){catalogue_entries, 3, 10000};
        return true;
    case 32: /* version 3: a model's document, and its answer in two frames */
        m->type = MS_PROTO_GET_DOCUMENT;
        m->request_id = 42;
        m->body.get_document = (ms_proto_get_document){MS_DOCUMENT_ANNOTATIONS, long_name,
                                                       MS_PROTO_MAX_MODEL_NAME};
        return true;
    case 33:
        m->type = MS_PROTO_DOCUMENT;
        m->request_id = 42;
        m->body.document = (ms_proto_document){.kind = MS_DOCUMENT_ANNOTATIONS,
                                               .total_length = MS_PROTO_MAX_DOCUMENT, .offset = 0,
                                               .data = blob, .data_length = 65536};
        return true;
    case 34:
        m->type = MS_PROTO_DOCUMENT;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 42;
        m->body.document = (ms_proto_document){.kind = MS_DOCUMENT_THUMBNAIL,
                                               .total_length = 1000, .offset = 700, .data = blob,
                                               .data_length = 300};
        return true;
    case 35: /* an empty document: one LAST frame with no data */
        m->type = MS_PROTO_DOCUMENT;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 43;
        m->body.document = (ms_proto_document){.kind = MS_DOCUMENT_METADATA};
        return true;
    case 29: /* version 3: a subtree's last chunk */
        m->type = MS_PROTO_PAYLOAD;
        m->flags = MS_PROTO_FLAG_LAST;
        m->request_id = 40;
        m->body.payload = (ms_proto_payload){.cell_id = 65, .stream = MS_PROTO_STREAM_INDEX,
                                             .offset = 0, .end = 300, .data = blob,
                                             .data_length = 300};
        return true;
    default:
        return false;
    }
}

static bool client_sends(uint8_t type)
{
    return type <= MS_PROTO_GET_DOCUMENT || type == MS_PROTO_PING || type == MS_PROTO_PONG ||
           type == MS_PROTO_ERROR;
}

/* ---- Tests ---- */

static void test_spec_examples(void **state)
{
    (void)state;
    uint8_t out[128];
    /* PING */
    static const uint8_t ping[] = {0x08, 0, 0, 0, 0x40, 0, 0, 0, 0, 0, 0, 0,
                                   0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01};
    ms_proto_message m = {.type = MS_PROTO_PING, .body.ping.opaque = 0x0102030405060708ull};
    assert_int_equal(encode(&m, out, sizeof out), sizeof ping);
    assert_memory_equal(out, ping, sizeof ping);
    /* REQUEST_CELLS */
    static const uint8_t request[] = {
        0x28, 0, 0, 0, 0x05, 0, 0, 0, 0x10, 0, 0, 0, 0x01, 0, 0, 0, 0x02, 0, 0, 0,
        0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0x09, 0, 0, 0,
        0x45, 0x23, 0x01, 0, 0x01, 0x01, 0x05, 0, 0x00, 0x10, 0, 0, 0x00, 0x02, 0, 0};
    ms_proto_cell_request entries[2] = {
        {.cell_id = 0, .stream = MS_PROTO_STREAM_GEOMETRY, .unit = MS_PROTO_UNIT_STEPS,
         .priority = 0, .a = 0, .b = 9},
        {.cell_id = 0x12345, .stream = MS_PROTO_STREAM_APO, .unit = MS_PROTO_UNIT_BYTES,
         .priority = 5, .a = 4096, .b = 512}};
    m = (ms_proto_message){.type = MS_PROTO_REQUEST_CELLS, .request_id = 0x10,
                           .body.request_cells = {1, entries, 2}};
    assert_int_equal(encode(&m, out, sizeof out), sizeof request);
    assert_memory_equal(out, request, sizeof request);
    /* ERROR */
    static const uint8_t error[] = {0x1e, 0, 0, 0, 0x7f, 0, 0, 0, 0x11, 0, 0, 0, 0x0f, 0, 0, 0,
                                    0x01, 0, 0, 0, 0x45, 0x23, 0x01, 0, 0, 0, 0, 0, 0x0c, 0,
                                    'n', 'o', ' ', 's', 'u', 'c', 'h', ' ', 'c', 'e', 'l', 'l'};
    m = (ms_proto_message){.type = MS_PROTO_ERROR, .request_id = 0x11,
                           .body.error = {.code = MS_PROTO_E_UNKNOWN_CELL, .request_count = 1,
                                          .detail = 0x12345, .text = "no such cell",
                                          .text_length = 12}};
    assert_int_equal(encode(&m, out, sizeof out), sizeof error);
    assert_memory_equal(out, error, sizeof error);

    /* And they decode back to the same messages. */
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 16);
    ms_proto_message got;
    ms_proto_fault fault;
    bool have;
    assert_int_equal(feed_all(dec, request, sizeof request, &got, &have, &fault, NULL), MS_OK);
    assert_true(have);
    ms_proto_message want = {.type = MS_PROTO_REQUEST_CELLS, .request_id = 0x10,
                             .body.request_cells = {1, entries, 2}};
    assert_same(&want, &got);
    ms_proto_decoder_free(dec);
    ready_decoder(&dec, MS_PROTO_ROLE_CLIENT, MS_PROTO_MIN_FRAME, 0);
    assert_int_equal(feed_all(dec, error, sizeof error, &got, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_same(&m, &got);
    ms_proto_decoder_free(dec);
}

static void test_roundtrip_every_type(void **state)
{
    (void)state;
    fill_fixtures();
    static uint8_t frame[MS_PROTO_HEADER_SIZE + 70000];
    bool seen[256] = {false};
    ms_proto_message m;
    for (unsigned i = 0; sample_message(i, &m); ++i) {
        seen[m.type] = true;
        size_t size = encode(&m, frame, sizeof frame);
        ms_proto_role role = client_sends(m.type) ? MS_PROTO_ROLE_SERVER : MS_PROTO_ROLE_CLIENT;
        ms_proto_decoder *dec = NULL;
        if (m.type == MS_PROTO_HELLO || m.type == MS_PROTO_HELLO_REPLY) {
            ms_proto_decoder_config config = {role, MS_PROTO_MAX_FRAME, MS_PROTO_MAX_BATCH};
            assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
        } else {
            ready_decoder(&dec, role, MS_PROTO_MAX_FRAME, MS_PROTO_MAX_BATCH);
        }
        ms_proto_message got;
        ms_proto_fault fault;
        bool have = false;
        size_t consumed = 0;
        ms_status s = feed_all(dec, frame, size, &got, &have, &fault, &consumed);
        if (s != MS_OK)
            fail_msg("sample %u (%s) rejected: %s", i, ms_proto_type_name(m.type),
                     ms_proto_error_name(fault.code));
        assert_true(have);
        assert_int_equal(consumed, size);
        assert_same(&m, &got);
        assert_int_equal(ms_proto_decoder_buffered(dec), 0);
        assert_int_equal(ms_proto_decoder_finish(dec, NULL, NULL), MS_OK);
        ms_proto_decoder_free(dec);
    }
    static const uint8_t all_types[] = {
        MS_PROTO_HELLO, MS_PROTO_LIST_CATALOGUE, MS_PROTO_OPEN_MODEL, MS_PROTO_CLOSE_MODEL,
        MS_PROTO_REQUEST_CELLS, MS_PROTO_CANCEL, MS_PROTO_PING, MS_PROTO_PONG, MS_PROTO_ERROR,
        MS_PROTO_HELLO_REPLY, MS_PROTO_CATALOGUE, MS_PROTO_MODEL_OPENED, MS_PROTO_INDEX_DATA,
        MS_PROTO_PAYLOAD, MS_PROTO_LIST_PAGE, MS_PROTO_CATALOGUE_PAGE, MS_PROTO_GET_DOCUMENT,
        MS_PROTO_DOCUMENT};
    for (size_t i = 0; i < sizeof all_types; ++i)
        if (!seen[all_types[i]])
            fail_msg("no round trip for %s", ms_proto_type_name(all_types[i]));
}

/* The encoder refuses values one step outside each range. */
static void test_encoder_refuses_out_of_range(void **state)
{
    (void)state;
    fill_fixtures();
    uint8_t out[512];
    size_t written;
    ms_proto_message m;
    ms_error err;
    ms_proto_fault fault;
#define REFUSE(field_setup, want_code)                                                       \
    do {                                                                                \
        field_setup;                                                                    \
        assert_int_not_equal(ms_proto_encode(&m, out, sizeof out, &written, &err), MS_OK); \
        assert_int_not_equal(ms_proto_check_message(&m, MS_PROTO_MAX_BATCH, &fault, NULL), MS_OK); \
        assert_int_equal(fault.code, want_code);                                        \
    } while (0)
    REFUSE((sample_message(0, &m), m.body.hello.min_version = 0), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(0, &m), m.body.hello.max_frame = MS_PROTO_MIN_FRAME - 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(1, &m), m.body.hello.max_frame = MS_PROTO_MAX_FRAME + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(1, &m), m.body.hello.token_length = MS_PROTO_MAX_TOKEN + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(1, &m), m.body.hello.token = "a b", m.body.hello.token_length = 3),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(3, &m), m.body.hello_reply.max_batch = MS_PROTO_MAX_BATCH + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(2, &m), m.body.hello_reply.idle_timeout_ms = 999),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(3, &m), m.body.hello_reply.max_queued_bytes = MS_PROTO_MAX_QUEUED_BYTES + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(9, &m), m.body.open_model.name = "a.b", m.body.open_model.name_length = 3),
           MS_PROTO_E_BAD_MODEL_NAME);
    REFUSE((sample_message(12, &m), m.body.model_opened.cell_count = MS_PROTO_MAX_CELLS + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(11, &m), m.body.model_opened.permitted_geometry_steps = 2),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(12, &m), m.body.model_opened.index_encoding = MS_PROTO_INDEX_SUBTREES + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(14, &m), m.request_id = 0), MS_PROTO_E_MALFORMED_FRAME);
    REFUSE((sample_message(6, &m), m.flags = MS_PROTO_FLAG_LAST), MS_PROTO_E_MALFORMED_FRAME);
    REFUSE((sample_message(4, &m), m.request_id = 1), MS_PROTO_E_MALFORMED_FRAME);
    REFUSE((sample_message(16, &m), m.body.cancel.range_count = 1,
            m.body.cancel.ranges = many_ranges), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(20, &m), m.flags = 0), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(22, &m), m.body.payload.end -= 1), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(19, &m), m.body.index_data.offset += 1), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(23, &m), m.body.error.fatal = false), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(25, &m), m.request_id = 2), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(24, &m), m.body.error.text = "a\tb", m.body.error.text_length = 3),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(24, &m), m.body.error.code = MS_PROTO_E_LAST + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    /* MODEL_CHANGED is never fatal */
    REFUSE((sample_message(26, &m), m.body.error.fatal = true), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    /* documents: the kind, the name, the range, LAST where the document ends */
    REFUSE((sample_message(32, &m), m.body.get_document.kind = 0), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(32, &m), m.body.get_document.kind = MS_DOCUMENT_LAST + 1),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(32, &m), m.body.get_document.name = "a/b",
            m.body.get_document.name_length = 3), MS_PROTO_E_BAD_MODEL_NAME);
    REFUSE((sample_message(32, &m), m.request_id = 0), MS_PROTO_E_MALFORMED_FRAME);
    REFUSE((sample_message(34, &m), m.body.document.kind = 4), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(34, &m), m.body.document.total_length = MS_PROTO_MAX_DOCUMENT + 1,
            m.body.document.offset = MS_PROTO_MAX_DOCUMENT + 1 - 300),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(34, &m), m.body.document.offset = 701), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(34, &m), m.flags = 0), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(33, &m), m.flags = MS_PROTO_FLAG_LAST), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    REFUSE((sample_message(35, &m), m.body.document.total_length = 5),
           MS_PROTO_E_FIELD_OUT_OF_RANGE);
#undef REFUSE
    /* Too small a buffer: nothing written, size needed reported. */
    sample_message(4, &m);
    assert_int_equal(ms_proto_encode(&m, out, 19, &written, NULL), MS_ERR_ARG);
    assert_int_equal(written, 20);
}

/* A stream of every sample, fed byte by byte and in random splits. */
static void check_stream_splits(ms_proto_role role, size_t max_chunk, unsigned rounds)
{
    fill_fixtures();
    static uint8_t stream[600000];
    size_t total = 0;
    ms_proto_message m, expected[64];
    unsigned count = 0;
    /* Handshake frame first, then every sample the other side sends. */
    memset(&m, 0, sizeof m);
    if (role == MS_PROTO_ROLE_SERVER) {
        m.type = MS_PROTO_HELLO;
        m.body.hello = default_hello();
    } else {
        m.type = MS_PROTO_HELLO_REPLY;
        m.body.hello_reply = default_reply();
    }
    expected[count++] = m;
    total += encode(&m, stream + total, sizeof stream - total);
    /* Fatal ERRORs last: nothing may follow one. */
    for (int fatal_pass = 0; fatal_pass < 2; ++fatal_pass)
        for (unsigned i = 0; sample_message(i, &m); ++i) {
            if (m.type == MS_PROTO_HELLO || m.type == MS_PROTO_HELLO_REPLY)
                continue;
            if (client_sends(m.type) != (role == MS_PROTO_ROLE_SERVER))
                continue;
            bool fatal = m.type == MS_PROTO_ERROR && m.body.error.fatal;
            if (fatal != (fatal_pass == 1))
                continue;
            expected[count++] = m;
            total += encode(&m, stream + total, sizeof stream - total);
        }
    for (unsigned round = 0; round < rounds; ++round) {
        ms_proto_decoder *dec = NULL;
        ms_proto_decoder_config config = {role, MS_PROTO_MAX_FRAME, MS_PROTO_MAX_BATCH};
        assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
        size_t pos = 0;
        unsigned got = 0;
        while (pos < total) {
            size_t chunk = max_chunk == 1 ? 1 : 1 + (size_t)(rng_next() % max_chunk);
            if (chunk > total - pos)
                chunk = total - pos;
            size_t end = pos + chunk;
            while (pos < end) {
                ms_proto_message msg;
                ms_proto_fault fault;
                bool have;
                size_t consumed;
                ms_status s = feed_all(dec, stream + pos, end - pos, &msg, &have, &fault,
                                       &consumed);
                if (s != MS_OK)
                    fail_msg("split round %u: fault %s at %zu", round,
                             ms_proto_error_name(fault.code), pos);
                assert_true(consumed > 0);
                pos += consumed;
                if (have) {
                    assert_true(got < count);
                    assert_same(&expected[got], &msg);
                    ++got;
                }
            }
        }
        assert_int_equal(got, count);
        assert_int_equal(ms_proto_decoder_finish(dec, NULL, NULL), MS_OK);
        ms_proto_decoder_free(dec);
    }
}

static void test_byte_by_byte(void **state)
{
    (void)state;
    check_stream_splits(MS_PROTO_ROLE_SERVER, 1, 1);
    check_stream_splits(MS_PROTO_ROLE_CLIENT, 1, 1);
}

static void test_random_splits(void **state)
{
    (void)state;
    check_stream_splits(MS_PROTO_ROLE_SERVER, 7, 20);
    check_stream_splits(MS_PROTO_ROLE_CLIENT, 7, 20);
    check_stream_splits(MS_PROTO_ROLE_SERVER, 5000, 20);
    check_stream_splits(MS_PROTO_ROLE_CLIENT, 70000, 20);
}

/* ---- Malformed frame classes (PROTOCOL.md sections 2 and 9) ---- */

static void test_bad_length(void **state)
{
    (void)state;
    uint8_t f[64] = {0};
    /* Above the receiver's max_frame: refused from the header alone. */
    raw_header(f, MS_PROTO_MIN_FRAME + 1, MS_PROTO_PAYLOAD, 0, 1);
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 12, MS_PROTO_E_FRAME_TOO_LARGE, true, 0, 0,
                 MS_PROTO_MIN_FRAME);
    raw_header(f, UINT32_MAX, MS_PROTO_REQUEST_CELLS, 0, 1);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12, MS_PROTO_E_FRAME_TOO_LARGE, true, 0, 0,
                 MS_PROTO_MIN_FRAME);
    /* Outside the type's bounds. */
    raw_header(f, 7, MS_PROTO_PING, 0, 0);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 19, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 1, MS_PROTO_LIST_CATALOGUE, 0, 1);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 13, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    /* Body length disagreeing with the counts inside it. */
    raw_header(f, 8 + 16, MS_PROTO_REQUEST_CELLS, 0, 1);
    put32(f + 12, 1);
    put16(f + 16, 2); /* says 2 entries, carries 1 */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12 + 24, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 18 + 3, MS_PROTO_ERROR, 0, 0);
    memset(f + 12, 0, 21);
    put16(f + 12, MS_PROTO_E_CANCELLED);
    put16(f + 12 + 16, 4); /* text_length 4, 3 bytes present */
    memcpy(f + 30, "abc", 3);
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 33, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
}

static void test_unknown_type(void **state)
{
    (void)state;
    uint8_t f[12];
    static const uint8_t undefined[] = {0x00, 0x09, 0x3F, 0x42, 0x7E, 0x80, 0x88, 0xFF};
    for (size_t i = 0; i < sizeof undefined; ++i) {
        raw_header(f, 0, undefined[i], 0, 0);
        expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12, MS_PROTO_E_UNKNOWN_TYPE, true, 0, 0,
                     undefined[i]);
        expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 12, MS_PROTO_E_UNKNOWN_TYPE, true, 0, 0,
                     undefined[i]);
    }
}

static void test_unexpected_message(void **state)
{
    (void)state;
    uint8_t f[512];
    /* Wrong direction. */
    raw_header(f, 16, MS_PROTO_PAYLOAD, MS_PROTO_FLAG_LAST, 1);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12, MS_PROTO_E_UNEXPECTED_MESSAGE, true, 0, 0,
                 MS_PROTO_PAYLOAD);
    raw_header(f, 0, MS_PROTO_LIST_CATALOGUE, 0, 1);
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 12, MS_PROTO_E_UNEXPECTED_MESSAGE, true, 0, 0,
                 MS_PROTO_LIST_CATALOGUE);
    /* A second hello. */
    ms_proto_message m = {.type = MS_PROTO_HELLO, .body.hello = default_hello()};
    size_t n = encode(&m, f, sizeof f);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_UNEXPECTED_MESSAGE, true, 0, 0,
                 MS_PROTO_HELLO);
    /* Anything but HELLO first (server), anything but HELLO_REPLY or ERROR first (client). */
    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config config = {MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8};
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have;
    raw_header(f, 8, MS_PROTO_PING, 0, 0);
    assert_int_equal(feed_all(dec, f, 20, &msg, &have, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_UNEXPECTED_MESSAGE);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);

    config = (ms_proto_decoder_config){MS_PROTO_ROLE_CLIENT, MS_PROTO_MIN_FRAME, 0};
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
    m = (ms_proto_message){.type = MS_PROTO_ERROR,
                           .body.error = {.code = MS_PROTO_E_TOO_MANY_CONNECTIONS, .fatal = true}};
    n = encode(&m, f, sizeof f);
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_int_equal(msg.body.error.code, MS_PROTO_E_TOO_MANY_CONNECTIONS);
    /* Nothing may follow a fatal ERROR. */
    n = encode(&(ms_proto_message){.type = MS_PROTO_HELLO_REPLY, .body.hello_reply = default_reply()},
               f, sizeof f);
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_UNEXPECTED_MESSAGE);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);
    /* A non-fatal ERROR cannot come first. */
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
    m = (ms_proto_message){.type = MS_PROTO_ERROR,
                           .body.error = {.code = MS_PROTO_E_RATE_LIMITED, .detail = 100}};
    n = encode(&m, f, sizeof f);
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_UNEXPECTED_MESSAGE);
    assert_int_equal(fault.detail, MS_PROTO_ERROR);
    ms_proto_decoder_free(dec);
    /* A PONG before HELLO_REPLY. */
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
    raw_header(f, 8, MS_PROTO_PONG, 0, 0);
    assert_int_equal(feed_all(dec, f, 20, &msg, &have, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_UNEXPECTED_MESSAGE);
    ms_proto_decoder_free(dec);
    /* After a fatal ERROR from the client, the server decoder accepts nothing. */
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    m = (ms_proto_message){.type = MS_PROTO_ERROR,
                           .body.error = {.code = MS_PROTO_E_MALFORMED_FRAME, .fatal = true}};
    n = encode(&m, f, sizeof f);
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    raw_header(f, 8, MS_PROTO_PING, 0, 0);
    assert_int_equal(feed_all(dec, f, 20, &msg, &have, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_UNEXPECTED_MESSAGE);
    ms_proto_decoder_free(dec);
}

static void test_header_rules(void **state)
{
    (void)state;
    uint8_t f[32] = {0};
    raw_header(f, 8, MS_PROTO_PING, 0, 0);
    f[6] = 1; /* reserved */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 20, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 8, MS_PROTO_PING, 0x04, 0); /* undefined flag */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 20, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 8, MS_PROTO_PING, MS_PROTO_FLAG_LAST, 0); /* LAST where not allowed */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 20, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 8, MS_PROTO_PING, 0, 5); /* request id must be 0 */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 20, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 0, MS_PROTO_LIST_CATALOGUE, 0, 0); /* request id must not be 0 */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    raw_header(f, 16, MS_PROTO_PAYLOAD, 0, 0);
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 12, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
}

static void test_hello_errors_are_fatal(void **state)
{
    (void)state;
    uint8_t f[512];
    ms_proto_message m = {.type = MS_PROTO_HELLO, .body.hello = default_hello()};
    size_t n = encode(&m, f, sizeof f);
    ms_proto_decoder_config config = {MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8};
    struct {
        size_t at;
        uint8_t value;
        uint16_t code;
        uint64_t detail;
    } cases[] = {
        {12 + 0, 'X', MS_PROTO_E_MALFORMED_FRAME, 0},       /* magic */
        {12 + 20, 1, MS_PROTO_E_MALFORMED_FRAME, 0},        /* reserved */
        {12 + 4, 0, MS_PROTO_E_FIELD_OUT_OF_RANGE, 4},      /* min_version 0 */
        {12 + 13, 0, MS_PROTO_E_FIELD_OUT_OF_RANGE, 12},    /* max_frame 0x0000?? < 16384 */
        {12 + 24, '\n', MS_PROTO_E_FIELD_OUT_OF_RANGE, 24}, /* agent byte */
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; ++i) {
        uint8_t g[512];
        memcpy(g, f, n);
        g[cases[i].at] = cases[i].value;
        if (cases[i].at == 12 + 13)
            g[12 + 12] = 0, g[12 + 14] = 0, g[12 + 15] = 0;
        ms_proto_decoder *dec = NULL;
        assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_OK);
        ms_proto_message msg;
        ms_proto_fault fault;
        bool have;
        assert_int_not_equal(feed_all(dec, g, n, &msg, &have, &fault, NULL), MS_OK);
        if (fault.code != cases[i].code)
            fail_msg("case %zu: expected %s, got %s", i, ms_proto_error_name(cases[i].code),
                     ms_proto_error_name(fault.code));
        assert_true(fault.fatal);
        assert_int_equal(fault.detail, cases[i].detail);
        ms_proto_decoder_free(dec);
    }
}

/* Builds a REQUEST_CELLS frame with count entries all equal to e. */
static size_t raw_batch(uint8_t *f, uint32_t first_id, uint32_t handle, uint16_t count,
                        ms_proto_cell_request e)
{
    raw_header(f, 8 + 16u * count, MS_PROTO_REQUEST_CELLS, 0, first_id);
    put32(f + 12, handle);
    put16(f + 16, count);
    put16(f + 18, 0);
    for (unsigned i = 0; i < count; ++i) {
        uint8_t *p = f + 20 + 16 * i;
        put32(p, e.cell_id);
        p[4] = e.stream;
        p[5] = e.unit;
        p[6] = e.priority;
        p[7] = 0;
        put32(p + 8, e.a);
        put32(p + 12, e.b);
    }
    return 20 + 16u * count;
}

static void test_out_of_range_fields(void **state)
{
    (void)state;
    static uint8_t f[12 + 8 + 16 * 64];
    const ms_proto_cell_request good = {.cell_id = 3, .stream = 0, .unit = 0, .a = 0, .b = 5};
    ms_proto_cell_request e;
    size_t n;
    /* Not fatal in a client's frame: the ERROR names the whole batch. */
    e = good, e.stream = MS_PROTO_STREAM_COLOUR + 1;
    n = raw_batch(f, 100, 1, 3, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 3, 8 + 4);
    e = good, e.unit = 9;
    n = raw_batch(f, 100, 1, 3, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 3, 8 + 5);
    e = good, e.a = 6, e.b = 5; /* last step before first */
    n = raw_batch(f, 100, 1, 2, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 2, 8 + 12);
    e = good, e.a = 64, e.b = 64;
    n = raw_batch(f, 100, 1, 1, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 1, 8 + 8);
    e = good, e.unit = MS_PROTO_UNIT_BYTES, e.a = 10, e.b = 0;
    n = raw_batch(f, 100, 1, 1, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 1, 8 + 12);
    e = good, e.unit = MS_PROTO_UNIT_BYTES, e.a = 10, e.b = UINT32_MAX - 9;
    n = raw_batch(f, 100, 1, 1, e);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 1, 8 + 12);
    n = raw_batch(f, 100, 0, 1, good); /* model handle 0 */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 100, 1, 0);
    n = raw_batch(f, 100, 1, 0, good); /* empty batch: no id to name */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 0, 0, 4);
    n = raw_batch(f, UINT32_MAX, 1, 2, good); /* ids wrap */
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 0, 0, 4);
    /* Second entry bad: detail is its offset. */
    n = raw_batch(f, 7, 1, 2, good);
    f[12 + 8 + 16 + 4] = 5;
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 7, 2,
                 8 + 16 + 4);
    /* Reserved byte of an entry: malformed, fatal. */
    n = raw_batch(f, 7, 1, 1, good);
    f[12 + 8 + 7] = 1;
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);

    /* CANCEL with a bad range: connection-level, not fatal. */
    raw_header(f, 12, MS_PROTO_CANCEL, 0, 0);
    put16(f + 12, 1);
    put16(f + 14, 0);
    put32(f + 16, 0);
    put32(f + 20, 1);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 24, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 0, 0, 4);
    put16(f + 14, MS_PROTO_CANCEL_ALL); /* CANCEL_ALL with ranges */
    put32(f + 16, 1);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 24, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 0, 0, 0);
    /* CLOSE_MODEL of handle 0. */
    raw_header(f, 4, MS_PROTO_CLOSE_MODEL, 0, 0);
    put32(f + 12, 0);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 16, MS_PROTO_E_FIELD_OUT_OF_RANGE, false, 0, 0, 0);

    /* In a server's frame every error is fatal to the client. */
    raw_header(f, 16 + 4, MS_PROTO_PAYLOAD, 0, 9);
    memset(f + 12, 0, 20);
    put32(f + 12 + 8, 10); /* offset 10 */
    put32(f + 12 + 12, 12); /* end 12, but 4 data bytes */
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 32, MS_PROTO_E_FIELD_OUT_OF_RANGE, true, 0, 0, 12);
    raw_header(f, 32, MS_PROTO_MODEL_OPENED, 0, 9);
    memset(f + 12, 0, 32);
    put32(f + 12, 1);
    put32(f + 16, 1);
    put32(f + 28, 1);
    f[12 + 24] = 1;
    f[12 + 26] = 65; /* geometry_steps above 64 */
    f[12 + 28] = 1;
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 44, MS_PROTO_E_FIELD_OUT_OF_RANGE, true, 0, 0, 26);
    /* index_encoding: 0, 1 (version 2) and 2 (version 3) only; the byte after
     * it is reserved. */
    f[12 + 26] = 1;
    f[12 + 30] = MS_PROTO_INDEX_SUBTREES + 1;
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 44, MS_PROTO_E_FIELD_OUT_OF_RANGE, true, 0, 0, 30);
    f[12 + 30] = MS_PROTO_INDEX_ZLIB;
    f[12 + 31] = 1;
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 44, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    /* ERROR frame whose fatal flag contradicts its code. */
    raw_header(f, 18, MS_PROTO_ERROR, 0, 0);
    memset(f + 12, 0, 18);
    put16(f + 12, MS_PROTO_E_IDLE_TIMEOUT);
    expect_fault(MS_PROTO_ROLE_CLIENT, 0, f, 30, MS_PROTO_E_FIELD_OUT_OF_RANGE, true, 0, 0, 2);
}

/* LIST_PAGE's ranges, its layout, and the negotiated version (section 4.11). */
static void test_catalogue_page_rules(void **state)
{
    (void)state;
    uint8_t f[12 + 12 + 80];
    struct {
        uint32_t offset;
        uint16_t limit;
        uint8_t sort, descending, query_length, reserved;
        const char *query;
        uint16_t code;
        uint64_t detail;
    } cases[] = {
        {0, 0, 0, 0, 0, 0, "", MS_PROTO_E_FIELD_OUT_OF_RANGE, 4},
        {0, 1001, 0, 0, 0, 0, "", MS_PROTO_E_FIELD_OUT_OF_RANGE, 4},
        {0, 10, 4, 0, 0, 0, "", MS_PROTO_E_FIELD_OUT_OF_RANGE, 6},
        {0, 10, 0, 2, 0, 0, "", MS_PROTO_E_FIELD_OUT_OF_RANGE, 7},
        {0, 10, 0, 0, 65, 0, "", MS_PROTO_E_MALFORMED_FRAME, 0},
        {0, 10, 0, 0, 2, 0, "a\n", MS_PROTO_E_FIELD_OUT_OF_RANGE, 12},
        {0, 10, 0, 0, 2, 0, "\xC3\x28", MS_PROTO_E_FIELD_OUT_OF_RANGE, 12},
        {0, 10, 0, 0, 0, 1, "", MS_PROTO_E_MALFORMED_FRAME, 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        size_t q = strlen(cases[i].query), body = 12 + q;
        if (cases[i].query_length == 65) /* a length the body does not hold */
            body = 12 + 64, q = 64;
        raw_header(f, (uint32_t)body, MS_PROTO_LIST_PAGE, 0, 9);
        memset(f + 12, 0, body);
        put32(f + 12, cases[i].offset);
        put16(f + 16, cases[i].limit);
        f[18] = cases[i].sort;
        f[19] = cases[i].descending;
        f[20] = cases[i].query_length;
        f[21] = cases[i].reserved;
        memcpy(f + 24, cases[i].query, strlen(cases[i].query));
        bool malformed = cases[i].code == MS_PROTO_E_MALFORMED_FRAME;
        expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12 + body, cases[i].code, malformed,
                     malformed ? 0 : 9, malformed ? 0 : 1, cases[i].detail);
    }
    /* a page needs version 3 */
    ms_proto_message m = {.type = MS_PROTO_LIST_PAGE, .request_id = 5};
    m.body.list_page = (ms_proto_list_page){.limit = 10, .query = ""};
    ms_proto_fault fault;
    assert_int_equal(ms_proto_check_negotiated(&m, 3, 0, &fault, NULL), MS_OK);
    assert_int_equal(ms_proto_check_negotiated(&m, 2, 0, &fault, NULL), MS_ERR_RANGE);
    assert_int_equal(fault.code, MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_int_equal(fault.request_id, 5);
    /* a page's answer cannot count fewer models than it carries */
    m = (ms_proto_message){.type = MS_PROTO_CATALOGUE_PAGE, .request_id = 5,
                           .flags = MS_PROTO_FLAG_LAST};
    fill_fixtures();
    m.body.catalogue = (ms_proto_catalogue){catalogue_entries, 3, 2};
    assert_int_equal(ms_proto_check_message(&m, MS_PROTO_MAX_BATCH, &fault, NULL), MS_ERR_RANGE);
    assert_int_equal(fault.detail, 4);
}

static void test_oversized_batch(void **state)
{
    (void)state;
    static uint8_t f[12 + 8 + 16 * 1024];
    const ms_proto_cell_request good = {.cell_id = 3, .stream = 1, .unit = 0, .a = 0, .b = 63};
    size_t n = raw_batch(f, 1000, 1, 9, good);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, n, MS_PROTO_E_BATCH_TOO_LARGE, false, 1000, 9, 8);
    n = raw_batch(f, 1, 1, 8, good); /* exactly max_batch is fine */
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have;
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_int_equal(msg.body.request_cells.count, 8);
    ms_proto_decoder_free(dec);
    /* Above the protocol's 4096 but within max_frame: still BATCH_TOO_LARGE,
     * and nothing is allocated for the entries. */
    static uint8_t huge[12 + 8 + 16 * 5000];
    n = raw_batch(huge, 1, 1, 5000, good);
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, 1u << 20, MS_PROTO_MAX_BATCH);
    assert_int_equal(feed_all(dec, huge, n, &msg, &have, &fault, NULL), MS_ERR_RANGE);
    assert_int_equal(fault.code, MS_PROTO_E_BATCH_TOO_LARGE);
    assert_false(fault.fatal);
    assert_int_equal(fault.request_id, 1);
    assert_int_equal(fault.request_count, 5000);
    assert_int_equal(fault.detail, MS_PROTO_MAX_BATCH);
    assert_int_equal(dec->scratch_capacity, 0);
    ms_proto_decoder_free(dec);
}

static void test_unknown_cell_decodes(void **state)
{
    (void)state;
    /* The decoder cannot know a model's cell count: a request for a cell that
     * does not exist decodes, and the server answers UNKNOWN_CELL (section
     * 4.10) with detail = the cell id. Check that ERROR round trips. */
    uint8_t f[64];
    const ms_proto_cell_request far = {.cell_id = UINT32_MAX, .stream = 0, .unit = 0, .a = 0, .b = 0};
    size_t n = raw_batch(f, 1, 1, 1, far);
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have;
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_OK);
    assert_int_equal(msg.body.request_cells.entries[0].cell_id, UINT32_MAX);
    ms_proto_decoder_free(dec);
    ms_proto_fault unknown = {.code = MS_PROTO_E_UNKNOWN_CELL, .request_id = 1,
                              .request_count = 1, .detail = UINT32_MAX};
    ms_proto_message answer;
    ms_proto_error_from_fault(&unknown, "no cell 4294967295 in model", &answer);
    n = encode(&answer, f, sizeof f);
    ready_decoder(&dec, MS_PROTO_ROLE_CLIENT, MS_PROTO_MIN_FRAME, 0);
    assert_int_equal(feed_all(dec, f, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_int_equal(msg.body.error.code, MS_PROTO_E_UNKNOWN_CELL);
    assert_false(msg.body.error.fatal);
    assert_int_equal(msg.request_id, 1);
    assert_int_equal(msg.body.error.detail, UINT32_MAX);
    ms_proto_decoder_free(dec);
}

static void test_path_like_model_names(void **state)
{
    (void)state;
    static const struct {
        const char *name;
        size_t length;
        size_t bad;
    } names[] = {
        {"../etc/passwd", 13, 0}, {"models/bunny", 12, 6}, {"..", 2, 0},
        {"bunny.msa", 9, 5},      {"/bunny", 6, 0},        {"a\\b", 3, 1},
        {"bun ny", 6, 3},         {"bunny\0x", 7, 5},      {"caf\xC3\xA9", 5, 3},
        {"~root", 5, 0},          {"%2e%2e", 6, 0},
    };
    uint8_t f[128];
    for (size_t i = 0; i < sizeof names / sizeof names[0]; ++i) {
        raw_header(f, 4 + (uint32_t)names[i].length, MS_PROTO_OPEN_MODEL, 0, 42);
        f[12] = (uint8_t)names[i].length;
        f[13] = f[14] = f[15] = 0;
        memcpy(f + 16, names[i].name, names[i].length);
        expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 16 + names[i].length, MS_PROTO_E_BAD_MODEL_NAME,
                     false, 42, 1, names[i].bad);
        size_t bad = 99;
        assert_false(ms_proto_model_name_valid(names[i].name, names[i].length, &bad));
        assert_int_equal(bad, names[i].bad);
    }
    assert_true(ms_proto_model_name_valid("Stanford_bunny-2", 16, NULL));
    /* A name longer than 64 bytes makes the body longer than OPEN_MODEL allows. */
    raw_header(f, 4 + 65, MS_PROTO_OPEN_MODEL, 0, 42);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 12, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
    /* name_length disagreeing with the body. */
    raw_header(f, 4 + 5, MS_PROTO_OPEN_MODEL, 0, 42);
    f[12] = 4;
    f[13] = f[14] = f[15] = 0;
    memcpy(f + 16, "bunny", 5);
    expect_fault(MS_PROTO_ROLE_SERVER, 8, f, 21, MS_PROTO_E_MALFORMED_FRAME, true, 0, 0, 0);
}

static void test_garbage_after_valid_frame(void **state)
{
    (void)state;
    uint8_t f[64];
    ms_proto_message m = {.type = MS_PROTO_PING, .body.ping.opaque = 1};
    size_t n = encode(&m, f, sizeof f);
    /* Twelve 0xFF bytes: the reserved header field is not zero. */
    memset(f + n, 0xFF, 12);
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have;
    size_t consumed;
    assert_int_equal(feed_all(dec, f, n + 12, &msg, &have, &fault, &consumed), MS_OK);
    assert_true(have);
    assert_int_equal(consumed, n);
    assert_int_equal(feed_all(dec, f + n, 12, &msg, &have, &fault, &consumed), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_MALFORMED_FRAME);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);

    /* An HTTP request where a frame should be. */
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    const char *http = "GET /catalogue HTTP/1.1\r\n\r\n";
    assert_int_not_equal(feed_all(dec, (const uint8_t *)http, strlen(http), &msg, &have, &fault,
                                  NULL), MS_OK);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);

    /* A few stray bytes, then end of stream: truncated frame. */
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    memcpy(f + n, "\x01\x02\x03", 3);
    assert_int_equal(feed_all(dec, f, n + 3, &msg, &have, &fault, &consumed), MS_OK);
    assert_int_equal(consumed, n);
    assert_int_equal(feed_all(dec, f + n, 3, &msg, &have, &fault, &consumed), MS_OK);
    assert_false(have);
    assert_int_equal(consumed, 3);
    assert_int_equal(ms_proto_decoder_buffered(dec), 3);
    assert_int_equal(ms_proto_decoder_finish(dec, &fault, NULL), MS_ERR_FORMAT);
    assert_int_equal(fault.code, MS_PROTO_E_MALFORMED_FRAME);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);

    /* A frame cut in its body. */
    ready_decoder(&dec, MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 8);
    assert_int_equal(feed_all(dec, f, n - 1, &msg, &have, &fault, &consumed), MS_OK);
    assert_false(have);
    assert_int_equal(ms_proto_decoder_finish(dec, &fault, NULL), MS_ERR_FORMAT);
    ms_proto_decoder_free(dec);
}

static void test_error_from_fault(void **state)
{
    (void)state;
    /* Text is cut to 256 bytes, never inside a UTF-8 sequence. */
    char text[600];
    memset(text, 'a', 255);
    memcpy(text + 255, "\xE2\x82\xAC", 3);
    memset(text + 258, 'b', 100);
    text[358] = '\0';
    ms_proto_fault fault = {.code = MS_PROTO_E_QUEUE_FULL, .fatal = true, .request_id = 5,
                            .request_count = 2, .detail = 1u << 20};
    ms_proto_message m;
    ms_proto_error_from_fault(&fault, text, &m);
    assert_int_equal(m.body.error.text_length, 255);
    assert_false(m.body.error.fatal); /* QUEUE_FULL is never fatal */
    uint8_t out[512];
    encode(&m, out, sizeof out);
    fault = (ms_proto_fault){.code = MS_PROTO_E_MALFORMED_FRAME};
    ms_proto_error_from_fault(&fault, NULL, &m);
    assert_true(m.body.error.fatal);
    assert_int_equal(m.request_id, 0);
    encode(&m, out, sizeof out);
    /* Names and fatality table. */
    assert_string_equal(ms_proto_error_name(MS_PROTO_E_FORBIDDEN), "FORBIDDEN");
    assert_string_equal(ms_proto_error_name(0), "?");
    assert_string_equal(ms_proto_type_name(MS_PROTO_PAYLOAD), "PAYLOAD");
    for (uint16_t c = MS_PROTO_E_FIRST; c <= MS_PROTO_E_LAST; ++c)
        assert_string_not_equal(ms_proto_error_name(c), "?");
    assert_int_equal(MS_PROTO_E_MODEL_CHANGED, 23);
    assert_int_equal(MS_PROTO_E_NO_DOCUMENT, 24);
    assert_int_equal(MS_PROTO_E_LAST, MS_PROTO_E_NO_DOCUMENT);
    assert_string_equal(ms_proto_error_name(MS_PROTO_E_NO_DOCUMENT), "NO_DOCUMENT");
    assert_int_equal(ms_proto_error_fatality(MS_PROTO_E_NO_DOCUMENT), MS_PROTO_FATAL_NEVER);
    /* the document kinds are fixed: other programs rely on the numbers */
    assert_int_equal(MS_DOCUMENT_THUMBNAIL, 1);
    assert_int_equal(MS_DOCUMENT_METADATA, 2);
    assert_int_equal(MS_DOCUMENT_ANNOTATIONS, 3);
    assert_string_equal(ms_document_kind_name(MS_DOCUMENT_ANNOTATIONS), "annotations");
    assert_string_equal(ms_document_kind_name(4), "?");
    assert_string_equal(ms_proto_error_name(MS_PROTO_E_MODEL_CHANGED), "MODEL_CHANGED");
    assert_int_equal(ms_proto_error_fatality(MS_PROTO_E_MODEL_CHANGED), MS_PROTO_FATAL_NEVER);
}

static void test_version_choice_and_text(void **state)
{
    (void)state;
    uint16_t v = 0;
    assert_int_equal(ms_proto_choose_version(1, 3, 2, 5, &v), MS_OK);
    assert_int_equal(v, 3);
    assert_int_equal(ms_proto_choose_version(1, 1, 1, 1, &v), MS_OK);
    assert_int_equal(v, 1);
    assert_int_equal(ms_proto_choose_version(4, 5, 1, 3, &v), MS_ERR_UNSUPPORTED);
    assert_int_equal(ms_proto_choose_version(0, 5, 1, 3, &v), MS_ERR_UNSUPPORTED);
    assert_int_equal(ms_proto_choose_version(3, 2, 1, 3, &v), MS_ERR_UNSUPPORTED);
    assert_true(ms_proto_text_valid((const uint8_t *)"caf\xC3\xA9 \xF0\x9F\x98\x80", 10));
    assert_false(ms_proto_text_valid((const uint8_t *)"\xC0\xAF", 2));         /* overlong */
    assert_false(ms_proto_text_valid((const uint8_t *)"\xED\xA0\x80", 3));     /* surrogate */
    assert_false(ms_proto_text_valid((const uint8_t *)"\xF4\x90\x80\x80", 4)); /* > U+10FFFF */
    assert_false(ms_proto_text_valid((const uint8_t *)"\xE2\x82", 2));         /* truncated */
    assert_false(ms_proto_text_valid((const uint8_t *)"\xC2\x85", 2));         /* C1 control */
    assert_false(ms_proto_text_valid((const uint8_t *)"a\x7F", 2));
    assert_false(ms_proto_text_valid((const uint8_t *)"\x80", 1));
}

/* A large frame does not pin its buffer after the next frame starts. */
static void test_large_buffer_released(void **state)
{
    (void)state;
    fill_fixtures();
    static uint8_t frame[MS_PROTO_HEADER_SIZE + MS_PROTO_PAYLOAD_FIXED + (2u << 20)];
    static uint8_t big[2u << 20];
    ms_proto_message m = {.type = MS_PROTO_PAYLOAD, .flags = MS_PROTO_FLAG_LAST, .request_id = 3,
                          .body.payload = {.cell_id = 1, .offset = 0, .end = sizeof big,
                                           .data = big, .data_length = sizeof big}};
    size_t n = encode(&m, frame, sizeof frame);
    ms_proto_decoder *dec = NULL;
    ready_decoder(&dec, MS_PROTO_ROLE_CLIENT, MS_PROTO_MAX_FRAME, 0);
    ms_proto_message msg;
    ms_proto_fault fault;
    bool have;
    assert_int_equal(feed_all(dec, frame, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_int_equal(msg.body.payload.data_length, sizeof big);
    assert_true(dec->body_capacity >= sizeof big);
    ms_proto_message ping = {.type = MS_PROTO_PING, .body.ping.opaque = 2};
    n = encode(&ping, frame, sizeof frame);
    assert_int_equal(feed_all(dec, frame, n, &msg, &have, &fault, NULL), MS_OK);
    assert_true(have);
    assert_true(dec->body_capacity <= 1u << 20);
    ms_proto_decoder_free(dec);
}

static void test_decoder_init_arguments(void **state)
{
    (void)state;
    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config config = {MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME - 1, 8};
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_ERR_ARG);
    config = (ms_proto_decoder_config){MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 0};
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_ERR_ARG);
    config = (ms_proto_decoder_config){(ms_proto_role)7, MS_PROTO_MIN_FRAME, 8};
    assert_int_equal(ms_proto_decoder_new(&config, &dec, NULL), MS_ERR_ARG);
    assert_null(dec);
    assert_int_equal(ms_proto_decoder_new(NULL, &dec, NULL), MS_ERR_ARG);
    config.role = MS_PROTO_ROLE_CLIENT;
    assert_int_equal(ms_proto_decoder_new(&config, NULL, NULL), MS_ERR_ARG);
    ms_proto_decoder_free(NULL);
}

/* Mutations of valid streams, fed in random splits to both roles; the fuzz
 * target's contract checks run on every case. Bounded count. */
static void test_random_mutations(void **state)
{
    (void)state;
    fill_fixtures();
    static uint8_t base[4096], input[4200];
    unsigned cases = 0, with_message = 0;
    for (unsigned round = 0; round < 6000; ++round) {
        /* A small valid stream of 1 to 4 sample frames of one direction. */
        bool client_role = rng_next() & 1;
        size_t size = 0;
        unsigned frames = 1 + (unsigned)(rng_next() % 4);
        for (unsigned k = 0; k < frames; ++k) {
            ms_proto_message m;
            unsigned pick = (unsigned)(rng_next() % 27);
            if (!sample_message(pick, &m) || m.type == MS_PROTO_HELLO ||
                m.type == MS_PROTO_HELLO_REPLY ||
                client_sends(m.type) == client_role)
                continue;
            size_t need = 0;
            ms_proto_encoded_size(&m, &need, NULL);
            if (need > MS_PROTO_HEADER_SIZE + MS_PROTO_MIN_FRAME || size + need > sizeof base)
                continue;
            size += encode(&m, base + size, sizeof base - size);
        }
        /* Control byte: role, auto handshake, split seed. */
        input[0] = (uint8_t)((client_role ? 1 : 0) | 2 | (uint8_t)(rng_next() << 2));
        memcpy(input + 1, base, size);
        size_t n = 1 + size;
        unsigned mutations = (unsigned)(rng_next() % 4);
        for (unsigned k = 0; k < mutations && n > 1; ++k) {
            size_t at = 1 + (size_t)(rng_next() % (n - 1));
            switch (rng_next() % 5) {
            case 0: input[at] ^= (uint8_t)(1u << (rng_next() % 8)); break;
            case 1: input[at] = (uint8_t)rng_next(); break;
            case 2: n = at; break; /* truncate */
            case 3: /* insert a byte */
                if (n < sizeof input) {
                    memmove(input + at + 1, input + at, n - at);
                    input[at] = (uint8_t)rng_next();
                    ++n;
                }
                break;
            default: /* interesting boundary values in a length-like spot */
                input[at] = (uint8_t[]){0x00, 0xFF, 0x7F, 0x80, 0x01}[rng_next() % 5];
            }
        }
        if (ms_fuzz_protocol_one(input, n, NULL) > 0)
            ++with_message;
        ++cases;
    }
    assert_int_equal(cases, 6000);
    assert_true(with_message > 1000); /* the loop reaches real messages */
}

static void test_corpus_replay(void **state)
{
    (void)state;
    const char *dir_path = "tests/corpus/protocol";
    DIR *dir = opendir(dir_path);
    if (!dir)
        fail_msg("cannot open %s (run the tests from the repository root)", dir_path);
    unsigned files = 0, checked = 0;
    static uint8_t data[1 << 20];
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        if (entry->d_name[0] == '.' || strcmp(entry->d_name, "README.md") == 0)
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir_path, entry->d_name);
        FILE *f = fopen(path, "rb");
        assert_non_null(f);
        size_t n = fread(data, 1, sizeof data, f);
        fclose(f);
        uint16_t first_fault = 0;
        ms_fuzz_protocol_one(data, n, &first_fault);
        /* Seeds named ROLE-ok-... decode cleanly; ROLE-CODE-... fail with CODE
         * first. Other names (fuzzer finds) only need to run clean. */
        const char *dash = strchr(entry->d_name, '-');
        if (dash && (!strncmp(entry->d_name, "server-", 7) || !strncmp(entry->d_name, "client-", 7))) {
            const char *expect = dash + 1;
            if (!strncmp(expect, "ok-", 3)) {
                if (first_fault != 0)
                    fail_msg("%s: unexpected %s", entry->d_name, ms_proto_error_name(first_fault));
            } else {
                const char *got = ms_proto_error_name(first_fault);
                size_t len = strlen(got);
                if (strncmp(expect, got, len) != 0 || (expect[len] != '-' && expect[len] != '.'))
                    fail_msg("%s: got %s", entry->d_name, first_fault ? got : "no fault");
            }
            ++checked;
        }
        ++files;
    }
    closedir(dir);
    assert_true(files >= 20);
    assert_true(checked >= 20);
}


/* ---- Corpus seeds: MS_PROTO_WRITE_CORPUS=dir test_protocol writes them ---- */

static void write_seed(const char *dir, const char *name, uint8_t control, const uint8_t *a,
                       size_t a_size, const uint8_t *b, size_t b_size)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "wb");
    if (!f)
        fail_msg("cannot write %s", path);
    fputc(control, f);
    if (a_size)
        fwrite(a, 1, a_size, f);
    if (b_size)
        fwrite(b, 1, b_size, f);
    fclose(f);
}

/* A ZLIB-encoded index as MODEL_OPENED + INDEX_DATA frames (all valid frames:
 * the fuzz target inflates the stream), declared_delta bytes off the real size,
 * the CRC off by crc_xor, the stream cut by cut bytes or followed by trailing
 * junk, in one frame or two. */
typedef struct index_seed {
    const char *name;
    int declared_delta;
    uint32_t crc_xor;
    size_t cut, trailing;
    bool two_frames;
    uint8_t encoding;
} index_seed;

static void write_index_seed(const char *dir, const index_seed *x, const uint8_t *index_blob,
                             uint32_t index_blob_size, const uint8_t *z, size_t z_size)
{
    static uint8_t out[4][4096];
    size_t sizes[4] = {0}, frames = 0;
    ms_proto_message m = {.type = MS_PROTO_MODEL_OPENED, .request_id = 7};
    m.body.model_opened = (ms_proto_model_opened){
        .model_handle = 1, .cell_count = 1, .index_size = (uint32_t)((int)index_blob_size + x->declared_delta),
        .index_crc32 = (uint32_t)crc32_z(0L, index_blob, index_blob_size) ^ x->crc_xor, .archive_version = 1,
        .geometry_steps = 16, .permitted_geometry_steps = 16,
        .index_encoding = MS_PROTO_INDEX_ZLIB};
    uint8_t *f = out[frames];
    sizes[frames++] = encode(&m, f, sizeof out[0]);
    f[MS_PROTO_HEADER_SIZE + 30] = x->encoding; /* the encoder refuses a bad one */
    static uint8_t wire[4096];
    size_t wire_size = z_size - x->cut;
    memcpy(wire, z, wire_size);
    memset(wire + wire_size, 'x', x->trailing);
    wire_size += x->trailing;
    size_t split = x->two_frames ? wire_size / 2 : wire_size;
    for (size_t at = 0; at < wire_size; at = split, split = wire_size) {
        m = (ms_proto_message){.type = MS_PROTO_INDEX_DATA, .request_id = 7};
        m.flags = split == wire_size ? MS_PROTO_FLAG_LAST : 0;
        m.body.index_data = (ms_proto_index_data){(uint32_t)at, wire + at, (uint32_t)(split - at)};
        sizes[frames] = encode(&m, out[frames], sizeof out[0]);
        ++frames;
    }
    static uint8_t all[3 * 4096];
    size_t n = 0;
    for (size_t i = 0; i < frames; ++i)
        memcpy(all + n, out[i], sizes[i]), n += sizes[i];
    write_seed(dir, x->name, x->two_frames ? 3 | 0x14 : 3, all, n, NULL, 0);
}

static void write_index_seeds(const char *dir)
{
    static uint8_t index_blob[16000];
    for (size_t i = 0; i < sizeof index_blob; i += 80)
        index_blob[i] = (uint8_t)(i / 80), index_blob[i + 8] = (uint8_t)(i % 7);
    uint8_t *z;
    size_t z_size;
    assert_int_equal(ms_proto_index_deflate(index_blob, sizeof index_blob, &z, &z_size, NULL), MS_OK);
    assert_true(z_size < 2000);
    const index_seed seeds[] = {
        {"client-ok-index-zlib.bin", 0, 0, 0, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-two-frames.bin", 0, 0, 0, 0, true, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-truncated.bin", 0, 0, 3, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-crc-mismatch.bin", 0, 1, 0, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-declared-short.bin", -1, 0, 0, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-declared-long.bin", 1, 0, 0, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-trailing.bin", 0, 0, 0, 3, false, MS_PROTO_INDEX_ZLIB},
        {"client-ok-index-zlib-bomb.bin", -15000, 0, 0, 0, false, MS_PROTO_INDEX_ZLIB},
        {"client-FIELD_OUT_OF_RANGE-index-encoding.bin", 0, 0, 0, 0, false,
         MS_PROTO_INDEX_SUBTREES + 1},
    };
    for (size_t i = 0; i < sizeof seeds / sizeof *seeds; ++i)
        write_index_seed(dir, &seeds[i], index_blob, sizeof index_blob, z, z_size);
    free(z);
}

static void write_corpus(const char *dir)
{
    fill_fixtures();
    static uint8_t frame[MS_PROTO_HEADER_SIZE + 70000], hello[512];
    ms_proto_message m;
    char name[128];
    for (unsigned i = 0; sample_message(i, &m); ++i) {
        size_t need = 0;
        ms_proto_encoded_size(&m, &need, NULL);
        if (need > MS_PROTO_HEADER_SIZE + MS_PROTO_MIN_FRAME)
            continue;
        size_t n = encode(&m, frame, sizeof frame);
        bool client_role = !client_sends(m.type);
        bool handshake = m.type == MS_PROTO_HELLO || m.type == MS_PROTO_HELLO_REPLY;
        uint8_t control = (uint8_t)((client_role ? 1 : 0) | (handshake ? 0 : 2));
        snprintf(name, sizeof name, "%s-ok-%02u-%s.bin", client_role ? "client" : "server", i,
                 ms_proto_type_name(m.type));
        write_seed(dir, name, control, frame, n, NULL, 0);
        if (!handshake) { /* the same with an explicit handshake and split feeding */
            size_t h = ms_fuzz_handshake_frame(client_role, hello);
            snprintf(name, sizeof name, "%s-ok-%02u-%s-split.bin",
                     client_role ? "client" : "server", i, ms_proto_type_name(m.type));
            write_seed(dir, name, (uint8_t)((client_role ? 1 : 0) | 0x14), hello, h, frame, n);
        }
    }
    uint8_t f[2048] = {0};
    const ms_proto_cell_request good = {.cell_id = 3, .stream = 0, .unit = 0, .a = 0, .b = 5};
    ms_proto_cell_request e;
    size_t n;
    raw_header(f, UINT32_MAX, MS_PROTO_REQUEST_CELLS, 0, 1);
    write_seed(dir, "server-FRAME_TOO_LARGE.bin", 2, f, 12, NULL, 0);
    raw_header(f, 7, MS_PROTO_PING, 0, 0);
    write_seed(dir, "server-MALFORMED_FRAME-ping-length.bin", 2, f, 19, NULL, 0);
    raw_header(f, 0, 0x55, 0, 0);
    write_seed(dir, "server-UNKNOWN_TYPE.bin", 2, f, 12, NULL, 0);
    raw_header(f, 16, MS_PROTO_PAYLOAD, MS_PROTO_FLAG_LAST, 1);
    write_seed(dir, "server-UNEXPECTED_MESSAGE-payload.bin", 2, f, 28, NULL, 0);
    raw_header(f, 8, MS_PROTO_PING, 0, 0);
    write_seed(dir, "server-UNEXPECTED_MESSAGE-before-hello.bin", 0, f, 20, NULL, 0);
    raw_header(f, 8, MS_PROTO_PING, 0, 0);
    f[6] = 1;
    write_seed(dir, "server-MALFORMED_FRAME-reserved.bin", 2, f, 20, NULL, 0);
    f[6] = 0;
    n = raw_batch(f, 10, 1, 20, good);
    write_seed(dir, "server-BATCH_TOO_LARGE.bin", 2, f, n, NULL, 0);
    e = good, e.stream = MS_PROTO_STREAM_COLOUR + 1;
    n = raw_batch(f, 10, 1, 2, e);
    write_seed(dir, "server-FIELD_OUT_OF_RANGE-stream.bin", 2, f, n, NULL, 0);
    e = good, e.stream = MS_PROTO_STREAM_INDEX, e.a = 0, e.b = 1; /* a subtree has step 0 only */
    n = raw_batch(f, 10, 1, 1, e);
    write_seed(dir, "server-FIELD_OUT_OF_RANGE-subtree-steps.bin", 2, f, n, NULL, 0);
    e = good, e.unit = MS_PROTO_UNIT_BYTES, e.a = 5, e.b = UINT32_MAX;
    n = raw_batch(f, 10, 1, 1, e);
    write_seed(dir, "server-FIELD_OUT_OF_RANGE-bytes.bin", 2, f, n, NULL, 0);
    n = raw_batch(f, UINT32_MAX, 1, 2, good);
    write_seed(dir, "server-FIELD_OUT_OF_RANGE-id-wrap.bin", 2, f, n, NULL, 0);
    raw_header(f, 4 + 13, MS_PROTO_OPEN_MODEL, 0, 42);
    f[12] = 13;
    memcpy(f + 16, "../etc/passwd", 13);
    write_seed(dir, "server-BAD_MODEL_NAME.bin", 2, f, 29, NULL, 0);
    raw_header(f, 4 + 5, MS_PROTO_GET_DOCUMENT, 0, 43);
    f[12] = MS_DOCUMENT_LAST + 1, f[13] = 5;
    memcpy(f + 16, "model", 5);
    write_seed(dir, "server-FIELD_OUT_OF_RANGE-document-kind.bin", 2, f, 21, NULL, 0);
    f[12] = MS_DOCUMENT_ANNOTATIONS;
    write_seed(dir, "server-MALFORMED_FRAME-document-truncated.bin", 2, f, 19, NULL, 0);
    m = (ms_proto_message){.type = MS_PROTO_PING, .body.ping.opaque = 1};
    n = encode(&m, f, sizeof f);
    memset(f + n, 0xFF, 12);
    write_seed(dir, "server-MALFORMED_FRAME-garbage-after.bin", 2, f, n + 12, NULL, 0);
    write_seed(dir, "server-MALFORMED_FRAME-truncated.bin", 2, f, n + 5, NULL, 0);
    const char *http = "GET /catalogue HTTP/1.1\r\nHost: x\r\n\r\n";
    write_seed(dir, "server-MALFORMED_FRAME-http.bin", 0, (const uint8_t *)http, strlen(http),
               NULL, 0);
    raw_header(f, 16 + 4, MS_PROTO_PAYLOAD, 0, 9);
    memset(f + 12, 0, 20);
    put32(f + 12 + 8, 10);
    put32(f + 12 + 12, 12);
    write_seed(dir, "client-FIELD_OUT_OF_RANGE-payload-end.bin", 3, f, 32, NULL, 0);
    raw_header(f, 0, MS_PROTO_LIST_CATALOGUE, 0, 1);
    write_seed(dir, "client-UNEXPECTED_MESSAGE.bin", 3, f, 12, NULL, 0);
    write_index_seeds(dir);
}

int main(void)
{
    const char *corpus_dir = getenv("MS_PROTO_WRITE_CORPUS");
    if (corpus_dir) {
        write_corpus(corpus_dir);
        return 0;
    }
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spec_examples),
        cmocka_unit_test(test_roundtrip_every_type),
        cmocka_unit_test(test_encoder_refuses_out_of_range),
        cmocka_unit_test(test_byte_by_byte),
        cmocka_unit_test(test_random_splits),
        cmocka_unit_test(test_bad_length),
        cmocka_unit_test(test_unknown_type),
        cmocka_unit_test(test_unexpected_message),
        cmocka_unit_test(test_header_rules),
        cmocka_unit_test(test_hello_errors_are_fatal),
        cmocka_unit_test(test_out_of_range_fields),
        cmocka_unit_test(test_catalogue_page_rules),
        cmocka_unit_test(test_oversized_batch),
        cmocka_unit_test(test_unknown_cell_decodes),
        cmocka_unit_test(test_path_like_model_names),
        cmocka_unit_test(test_garbage_after_valid_frame),
        cmocka_unit_test(test_error_from_fault),
        cmocka_unit_test(test_version_choice_and_text),
        cmocka_unit_test(test_decoder_init_arguments),
        cmocka_unit_test(test_large_buffer_released),
        cmocka_unit_test(test_random_mutations),
        cmocka_unit_test(test_corpus_replay),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
