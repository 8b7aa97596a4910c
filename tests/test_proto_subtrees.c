/* Protocol version 3 (protocol/ms_proto.h, PROTOCOL.md sections 3, 4.7, 4.10,
 * 4.11 and 12): the subtree index's fields byte for byte (the worked example),
 * their validation (stream INDEX, index_encoding SUBTREES, a subtree's single
 * step), the capabilities each version defines, and the negotiation of
 * versions 1, 2 and 3 with the rules that depend on it: a version-1 or
 * version-2 peer never gets encoding SUBTREES or stream INDEX. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_proto.h"

/* ---- Helpers ---- */

static size_t encode(const ms_proto_message *m, uint8_t *out, size_t capacity)
{
    size_t written = 0;
    ms_error err;
    if (ms_proto_encode(m, out, capacity, &written, &err) != MS_OK)
        fail_msg("encode %s: %s", ms_proto_type_name(m->type), err.text);
    return written;
}

/* Decodes one whole frame after a handshake; returns the status, the message
 * and the fault. */
static ms_status decode(ms_proto_role role, const uint8_t *frame, size_t size, ms_proto_message *msg,
                        ms_proto_fault *fault, ms_proto_decoder **dec)
{
    ms_proto_decoder_config config = {role, MS_PROTO_MIN_FRAME, role == MS_PROTO_ROLE_SERVER ? 16 : 0};
    assert_int_equal(ms_proto_decoder_new(&config, dec, NULL), MS_OK);
    /* Handshake: a peer's first frame. */
    uint8_t hello[512];
    ms_proto_message h = {0};
    if (role == MS_PROTO_ROLE_SERVER) {
        h.type = MS_PROTO_HELLO;
        h.body.hello = (ms_proto_hello){.min_version = 1, .max_version = 3,
                                        .max_frame = MS_PROTO_MIN_FRAME};
    } else {
        h.type = MS_PROTO_HELLO_REPLY;
        h.body.hello_reply = (ms_proto_hello_reply){
            .version = 3, .max_frame = MS_PROTO_MIN_FRAME, .max_batch = 16, .max_outstanding = 16,
            .max_queued_bytes = 1, .max_open_models = 1};
    }
    size_t n = encode(&h, hello, sizeof hello), consumed = 0;
    bool have = false;
    assert_int_equal(ms_proto_decoder_feed(*dec, hello, n, &consumed, msg, &have, fault, NULL), MS_OK);
    assert_true(have);
    memset(fault, 0, sizeof *fault);
    ms_status s = ms_proto_decoder_feed(*dec, frame, size, &consumed, msg, &have, fault, NULL);
    if (s == MS_OK) {
        assert_true(have);
        assert_int_equal(consumed, size);
    }
    return s;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v, p[1] = (uint8_t)(v >> 8), p[2] = (uint8_t)(v >> 16), p[3] = (uint8_t)(v >> 24);
}

/* A REQUEST_CELLS frame of one entry, built by hand (the encoder would refuse
 * the bad ones). */
static size_t raw_request(uint8_t *f, uint32_t first_id, uint32_t cell, uint8_t stream,
                          uint8_t unit, uint32_t a, uint32_t b)
{
    memset(f, 0, 12 + 8 + 16);
    put32(f, 8 + 16);
    f[4] = MS_PROTO_REQUEST_CELLS;
    put32(f + 8, first_id);
    put32(f + 12, 1); /* model handle */
    f[16] = 1;        /* count */
    put32(f + 20, cell);
    f[24] = stream;
    f[25] = unit;
    put32(f + 28, a);
    put32(f + 32, b);
    return 12 + 8 + 16;
}

/* ---- The worked example of section 12 ---- */

static void test_spec_example(void **state)
{
    (void)state;
    uint8_t out[128];
    /* MODEL_OPENED with the index head. */
    static const uint8_t opened[] = {
        0x20, 0, 0, 0, 0x83, 0, 0, 0, 0x03, 0, 0, 0,
        0x01, 0, 0, 0, 0x01, 0x05, 0, 0,
        0x88, 0x77, 0x66, 0x55, 0x44, 0x33, 0x22, 0x11,
        0xa4, 0x09, 0, 0, 0x0d, 0xf0, 0xfe, 0xca,
        0x03, 0, 0x11, 0x06, 0x11, 0x06, 0x02, 0};
    ms_proto_message m = {.type = MS_PROTO_MODEL_OPENED, .request_id = 3};
    m.body.model_opened = (ms_proto_model_opened){
        .model_handle = 1, .cell_count = 1281, .content_id = 0x1122334455667788ull,
        .index_size = 2468, .index_crc32 = 0xCAFEF00Du, .archive_version = 3,
        .geometry_steps = 17, .apo_steps = 6, .permitted_geometry_steps = 17,
        .permitted_apo_steps = 6, .index_encoding = MS_PROTO_INDEX_SUBTREES};
    assert_int_equal(encode(&m, out, sizeof out), sizeof opened);
    assert_memory_equal(out, opened, sizeof opened);
    ms_proto_decoder *dec = NULL;
    ms_proto_message got;
    ms_proto_fault fault;
    assert_int_equal(decode(MS_PROTO_ROLE_CLIENT, opened, sizeof opened, &got, &fault, &dec), MS_OK);
    assert_int_equal(got.body.model_opened.index_encoding, MS_PROTO_INDEX_SUBTREES);
    assert_int_equal(got.body.model_opened.index_size, 2468);
    ms_proto_decoder_free(dec);

    /* Two subtrees: 0x41 whole (STEPS 0..0), and 0x1041 resumed at byte 1024. */
    static const uint8_t request[] = {
        0x28, 0, 0, 0, 0x05, 0, 0, 0, 0x20, 0, 0, 0,
        0x01, 0, 0, 0, 0x02, 0, 0, 0,
        0x41, 0, 0, 0, 0x02, 0x00, 0x03, 0, 0, 0, 0, 0, 0, 0, 0, 0,
        0x41, 0x10, 0, 0, 0x02, 0x01, 0x03, 0, 0x00, 0x04, 0, 0, 0xf4, 0x01, 0, 0};
    const ms_proto_cell_request entries[2] = {
        {.cell_id = 0x41, .stream = MS_PROTO_STREAM_INDEX, .unit = MS_PROTO_UNIT_STEPS,
         .priority = 3, .a = 0, .b = 0},
        {.cell_id = 0x1041, .stream = MS_PROTO_STREAM_INDEX, .unit = MS_PROTO_UNIT_BYTES,
         .priority = 3, .a = 1024, .b = 500}};
    m = (ms_proto_message){.type = MS_PROTO_REQUEST_CELLS, .request_id = 0x20,
                           .body.request_cells = {1, entries, 2}};
    assert_int_equal(encode(&m, out, sizeof out), sizeof request);
    assert_memory_equal(out, request, sizeof request);
    assert_int_equal(decode(MS_PROTO_ROLE_SERVER, request, sizeof request, &got, &fault, &dec),
                     MS_OK);
    assert_int_equal(got.body.request_cells.count, 2);
    assert_int_equal(got.body.request_cells.entries[0].stream, MS_PROTO_STREAM_INDEX);
    assert_int_equal(got.body.request_cells.entries[1].a, 1024);
    ms_proto_decoder_free(dec);

    /* The answer to the first: one PAYLOAD of stream 2 with LAST (723 bytes). */
    static const uint8_t payload_head[] = {
        0xe3, 0x02, 0, 0, 0x85, 0x01, 0, 0, 0x20, 0, 0, 0,
        0x41, 0, 0, 0, 0x02, 0, 0, 0, 0, 0, 0, 0, 0xd3, 0x02, 0, 0};
    static uint8_t data[723], frame[800];
    for (size_t i = 0; i < sizeof data; ++i)
        data[i] = (uint8_t)(i * 7);
    m = (ms_proto_message){.type = MS_PROTO_PAYLOAD, .flags = MS_PROTO_FLAG_LAST,
                           .request_id = 0x20};
    m.body.payload = (ms_proto_payload){.cell_id = 0x41, .stream = MS_PROTO_STREAM_INDEX,
                                        .offset = 0, .end = 723, .data = data,
                                        .data_length = 723};
    assert_int_equal(encode(&m, frame, sizeof frame), sizeof payload_head + 723);
    assert_memory_equal(frame, payload_head, sizeof payload_head);
    assert_memory_equal(frame + sizeof payload_head, data, sizeof data);
}

/* ---- Field ranges ---- */

static void test_stream_index_validation(void **state)
{
    (void)state;
    uint8_t f[64];
    ms_proto_decoder *dec = NULL;
    ms_proto_message got;
    ms_proto_fault fault;
    /* STEPS 0..0 and any BYTES range: valid. */
    size_t n = raw_request(f, 9, 65, MS_PROTO_STREAM_INDEX, MS_PROTO_UNIT_STEPS, 0, 0);
    assert_int_equal(decode(MS_PROTO_ROLE_SERVER, f, n, &got, &fault, &dec), MS_OK);
    assert_int_equal(got.body.request_cells.entries[0].cell_id, 65);
    ms_proto_decoder_free(dec);
    n = raw_request(f, 9, 65, MS_PROTO_STREAM_INDEX, MS_PROTO_UNIT_BYTES, 7, 100);
    assert_int_equal(decode(MS_PROTO_ROLE_SERVER, f, n, &got, &fault, &dec), MS_OK);
    ms_proto_decoder_free(dec);
    /* A subtree has one step: STEPS beyond step 0 is out of range, naming the
     * first field that is not 0; not fatal, the request ends. */
    const struct {
        uint32_t a, b;
        uint64_t detail;
    } bad_steps[] = {{0, 1, 8 + 12}, {0, 63, 8 + 12}, {1, 1, 8 + 8}, {5, 9, 8 + 8}};
    for (size_t i = 0; i < sizeof bad_steps / sizeof *bad_steps; ++i) {
        n = raw_request(f, 9, 65, MS_PROTO_STREAM_INDEX, MS_PROTO_UNIT_STEPS, bad_steps[i].a,
                        bad_steps[i].b);
        assert_int_equal(decode(MS_PROTO_ROLE_SERVER, f, n, &got, &fault, &dec), MS_ERR_RANGE);
        assert_int_equal(fault.code, MS_PROTO_E_FIELD_OUT_OF_RANGE);
        assert_false(fault.fatal);
        assert_int_equal(fault.request_id, 9);
        assert_int_equal(fault.request_count, 1);
        assert_int_equal(fault.detail, bad_steps[i].detail);
        ms_proto_decoder_free(dec);
    }
    /* Stream 4 is undefined (3 is COLOUR). */
    n = raw_request(f, 9, 65, MS_PROTO_STREAM_COLOUR + 1, MS_PROTO_UNIT_STEPS, 0, 0);
    assert_int_equal(decode(MS_PROTO_ROLE_SERVER, f, n, &got, &fault, &dec), MS_ERR_RANGE);
    assert_int_equal(fault.detail, 8 + 4);
    ms_proto_decoder_free(dec);

    /* PAYLOAD of stream 2: valid; stream 4: fatal to the client. */
    ms_proto_message m = {.type = MS_PROTO_PAYLOAD, .flags = MS_PROTO_FLAG_LAST, .request_id = 5};
    m.body.payload = (ms_proto_payload){.cell_id = 65, .stream = MS_PROTO_STREAM_INDEX,
                                        .offset = 3, .end = 3};
    n = encode(&m, f, sizeof f);
    assert_int_equal(decode(MS_PROTO_ROLE_CLIENT, f, n, &got, &fault, &dec), MS_OK);
    assert_int_equal(got.body.payload.stream, MS_PROTO_STREAM_INDEX);
    ms_proto_decoder_free(dec);
    f[12 + 4] = MS_PROTO_STREAM_COLOUR + 1;
    assert_int_equal(decode(MS_PROTO_ROLE_CLIENT, f, n, &got, &fault, &dec), MS_ERR_RANGE);
    assert_true(fault.fatal);
    assert_int_equal(fault.detail, 4);
    ms_proto_decoder_free(dec);

    /* The encoder refuses what the decoder refuses. */
    const ms_proto_cell_request two_steps = {.cell_id = 65, .stream = MS_PROTO_STREAM_INDEX,
                                             .unit = MS_PROTO_UNIT_STEPS, .a = 0, .b = 1};
    m = (ms_proto_message){.type = MS_PROTO_REQUEST_CELLS, .request_id = 1,
                           .body.request_cells = {1, &two_steps, 1}};
    size_t written;
    assert_int_equal(ms_proto_encode(&m, f, sizeof f, &written, NULL), MS_ERR_RANGE);
}

static void test_index_encoding_validation(void **state)
{
    (void)state;
    uint8_t f[64];
    ms_proto_message m = {.type = MS_PROTO_MODEL_OPENED, .request_id = 2};
    m.body.model_opened = (ms_proto_model_opened){
        .model_handle = 1, .cell_count = 9, .index_size = 200, .archive_version = 3,
        .geometry_steps = 4, .permitted_geometry_steps = 4,
        .index_encoding = MS_PROTO_INDEX_SUBTREES};
    size_t n = encode(&m, f, sizeof f);
    assert_int_equal(f[12 + 30], 2);
    ms_proto_decoder *dec = NULL;
    ms_proto_message got;
    ms_proto_fault fault;
    assert_int_equal(decode(MS_PROTO_ROLE_CLIENT, f, n, &got, &fault, &dec), MS_OK);
    ms_proto_decoder_free(dec);
    f[12 + 30] = MS_PROTO_INDEX_SUBTREES + 1;
    assert_int_equal(decode(MS_PROTO_ROLE_CLIENT, f, n, &got, &fault, &dec), MS_ERR_RANGE);
    assert_int_equal(fault.code, MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_int_equal(fault.detail, 30);
    assert_true(fault.fatal);
    ms_proto_decoder_free(dec);
}

/* ---- Versions and capabilities ---- */

static void test_version_capabilities(void **state)
{
    (void)state;
    assert_int_equal(MS_PROTO_VERSION, 3);
    assert_int_equal(MS_PROTO_MIN_VERSION, 1);
    assert_int_equal(MS_PROTO_CAP_INDEX_SUBTREES, 1u << 2);
    assert_int_equal(ms_proto_version_capabilities(0), 0);
    assert_int_equal(ms_proto_version_capabilities(1), MS_PROTO_CAP_APO);
    assert_int_equal(ms_proto_version_capabilities(2), MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB);
    const uint32_t all = MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB | MS_PROTO_CAP_INDEX_SUBTREES |
                         MS_PROTO_CAP_COLOUR;
    assert_int_equal(ms_proto_version_capabilities(3), all);
    /* A later version keeps them (it defines nothing more here). */
    assert_int_equal(ms_proto_version_capabilities(UINT16_MAX), all);
}

/* What a server of versions 1..3 that supports every capability grants: the
 * section 3 rule, as meshserve applies it. */
static void negotiate(uint16_t client_min, uint16_t client_max, uint32_t client_caps,
                      uint16_t *version, uint32_t *granted)
{
    assert_int_equal(ms_proto_choose_version(client_min, client_max, MS_PROTO_MIN_VERSION,
                                             MS_PROTO_VERSION, version),
                     MS_OK);
    *granted = client_caps & ms_proto_version_capabilities(*version);
}

static void test_negotiation_interplay(void **state)
{
    (void)state;
    const uint32_t apo = MS_PROTO_CAP_APO, zlib = MS_PROTO_CAP_INDEX_ZLIB,
                   subtrees = MS_PROTO_CAP_INDEX_SUBTREES, unknown = 0x80000000u;
    const struct {
        uint16_t min, max;
        uint32_t caps;
        uint16_t version;
        uint32_t granted;
    } cases[] = {
        {1, 1, apo | zlib | subtrees, 1, apo},                 /* version-1 client */
        {1, 2, apo | zlib | subtrees, 2, apo | zlib},          /* version-2 client, bits it cannot mean */
        {1, 2, apo | zlib, 2, apo | zlib},
        {1, 3, apo | zlib | subtrees, 3, apo | zlib | subtrees},
        {1, 3, apo | subtrees | unknown, 3, apo | subtrees},   /* subtrees without zlib */
        {3, 3, zlib, 3, zlib},                                 /* version 3 without subtrees */
        {2, 9, apo | zlib | subtrees, 3, apo | zlib | subtrees}, /* a future client */
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        uint16_t version;
        uint32_t granted;
        negotiate(cases[i].min, cases[i].max, cases[i].caps, &version, &granted);
        assert_int_equal(version, cases[i].version);
        assert_int_equal(granted, cases[i].granted);
        /* The reply is valid for the client to receive. */
        ms_proto_message reply = {.type = MS_PROTO_HELLO_REPLY};
        reply.body.hello_reply.version = version;
        reply.body.hello_reply.capabilities = granted;
        assert_int_equal(ms_proto_check_negotiated(&reply, version, granted, NULL, NULL), MS_OK);
    }
    uint16_t version;
    assert_int_equal(ms_proto_choose_version(4, 5, MS_PROTO_MIN_VERSION, MS_PROTO_VERSION, &version),
                     MS_ERR_UNSUPPORTED);
    /* A version-2 server talking to a version-3 client chooses 2. */
    assert_int_equal(ms_proto_choose_version(1, 3, 1, 2, &version), MS_OK);
    assert_int_equal(version, 2);
}

static void expect_refused(const ms_proto_message *m, uint16_t version, uint32_t caps,
                           uint32_t request_id, uint32_t request_count, uint64_t detail)
{
    ms_proto_fault fault;
    memset(&fault, 0xAB, sizeof fault);
    ms_error err;
    assert_int_equal(ms_proto_check_negotiated(m, version, caps, &fault, &err), MS_ERR_RANGE);
    assert_int_equal(fault.code, MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_false(fault.fatal);
    assert_int_equal(fault.frame_type, m->type);
    assert_int_equal(fault.request_id, request_id);
    assert_int_equal(fault.request_count, request_count);
    assert_int_equal(fault.detail, detail);
    assert_non_null(strstr(err.text, ms_proto_type_name(m->type)));
    assert_null(strchr(err.text, '\n'));
}

static void test_negotiated_rules(void **state)
{
    (void)state;
    const uint32_t v1 = ms_proto_version_capabilities(1), v2 = ms_proto_version_capabilities(2),
                   v3 = ms_proto_version_capabilities(3);
    /* HELLO_REPLY: bit 2 exists from version 3 on; bit 1 from version 2. */
    ms_proto_message reply = {.type = MS_PROTO_HELLO_REPLY};
    reply.body.hello_reply = (ms_proto_hello_reply){.version = 2, .capabilities = v3};
    expect_refused(&reply, 2, v3, 0, 0, 8);
    reply.body.hello_reply = (ms_proto_hello_reply){.version = 1, .capabilities = v2};
    expect_refused(&reply, 1, v2, 0, 0, 8);
    reply.body.hello_reply = (ms_proto_hello_reply){.version = 3, .capabilities = v3};
    assert_int_equal(ms_proto_check_negotiated(&reply, 3, v3, NULL, NULL), MS_OK);

    /* MODEL_OPENED: each encoding needs its capability, RAW none. */
    ms_proto_message opened = {.type = MS_PROTO_MODEL_OPENED, .request_id = 6};
    opened.body.model_opened.index_encoding = MS_PROTO_INDEX_SUBTREES;
    expect_refused(&opened, 2, v2, 0, 0, 30);
    expect_refused(&opened, 3, v3 & ~MS_PROTO_CAP_INDEX_SUBTREES, 0, 0, 30);
    assert_int_equal(ms_proto_check_negotiated(&opened, 3, MS_PROTO_CAP_INDEX_SUBTREES, NULL, NULL),
                     MS_OK);
    opened.body.model_opened.index_encoding = MS_PROTO_INDEX_ZLIB;
    expect_refused(&opened, 1, v1, 0, 0, 30);
    expect_refused(&opened, 3, MS_PROTO_CAP_INDEX_SUBTREES, 0, 0, 30);
    assert_int_equal(ms_proto_check_negotiated(&opened, 2, v2, NULL, NULL), MS_OK);
    opened.body.model_opened.index_encoding = MS_PROTO_INDEX_RAW;
    assert_int_equal(ms_proto_check_negotiated(&opened, 1, 0, NULL, NULL), MS_OK);

    /* REQUEST_CELLS: stream INDEX without CAP_INDEX_SUBTREES ends the whole
     * batch, naming the stream field of the first entry that needs it. */
    const ms_proto_cell_request entries[3] = {
        {.cell_id = 1, .stream = MS_PROTO_STREAM_GEOMETRY},
        {.cell_id = 2, .stream = MS_PROTO_STREAM_APO},
        {.cell_id = 65, .stream = MS_PROTO_STREAM_INDEX}};
    ms_proto_message batch = {.type = MS_PROTO_REQUEST_CELLS, .request_id = 100,
                              .body.request_cells = {1, entries, 3}};
    expect_refused(&batch, 2, v2, 100, 3, 8 + 2 * 16 + 4);
    expect_refused(&batch, 3, v3 & ~MS_PROTO_CAP_INDEX_SUBTREES, 100, 3, 8 + 2 * 16 + 4);
    expect_refused(&batch, 3, MS_PROTO_CAP_INDEX_SUBTREES, 100, 3, 8 + 1 * 16 + 4); /* APO first */
    assert_int_equal(ms_proto_check_negotiated(&batch, 3, v3, NULL, NULL), MS_OK);

    /* PAYLOAD: a server never sends stream INDEX (or APO) without its capability. */
    ms_proto_message payload = {.type = MS_PROTO_PAYLOAD, .flags = MS_PROTO_FLAG_LAST,
                                .request_id = 8};
    payload.body.payload.stream = MS_PROTO_STREAM_INDEX;
    expect_refused(&payload, 2, v2, 0, 0, 4);
    assert_int_equal(ms_proto_check_negotiated(&payload, 3, v3, NULL, NULL), MS_OK);
    payload.body.payload.stream = MS_PROTO_STREAM_APO;
    expect_refused(&payload, 3, MS_PROTO_CAP_INDEX_SUBTREES, 0, 0, 4);
    payload.body.payload.stream = MS_PROTO_STREAM_GEOMETRY;
    assert_int_equal(ms_proto_check_negotiated(&payload, 1, 0, NULL, NULL), MS_OK);

    /* Types without negotiated fields pass; a NULL message is an argument error. */
    ms_proto_message ping = {.type = MS_PROTO_PING};
    assert_int_equal(ms_proto_check_negotiated(&ping, 1, 0, NULL, NULL), MS_OK);
    assert_int_equal(ms_proto_check_negotiated(NULL, 3, v3, NULL, NULL), MS_ERR_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_spec_example),
        cmocka_unit_test(test_stream_index_validation),
        cmocka_unit_test(test_index_encoding_validation),
        cmocka_unit_test(test_version_capabilities),
        cmocka_unit_test(test_negotiation_interplay),
        cmocka_unit_test(test_negotiated_rules),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
