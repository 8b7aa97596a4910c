/* libFuzzer target on the protocol frame decoder (protocol/ms_proto_decode.c).
 *
 * Input: one control byte, then the byte stream a peer would send.
 *   bit 0     role of the decoder: 0 server (decodes client frames), 1 client
 *   bit 1     1: feed a valid HELLO (server) or HELLO_REPLY (client) first, so
 *             that the fuzzer reaches the post-handshake frames directly
 *   bits 2-7  0: feed the stream in one call; otherwise a seed for random
 *             chunk sizes (1 to 64 bytes), so that every split is exercised
 *
 * Besides the sanitizers, the target checks the decoder's contract and aborts
 * when it is broken: input is consumed in full unless a message or a fault
 * stops it; every message passes ms_proto_check_message and re-encodes to
 * exactly the bytes it was decoded from; non-fatal faults leave the decoder
 * usable and fatal ones make it refuse everything after; every fault can be
 * answered with an encodable ERROR frame; error texts are one line. Every
 * message also goes through ms_proto_check_negotiated as on a version-1
 * connection without capabilities and on a version-3 one with them all: it
 * must pass the latter, and refuse only with FIELD_OUT_OF_RANGE and an
 * encodable ERROR. Cell requests of stream INDEX resolve against a one-step
 * stream as the server's subtrees do.
 *
 * A ZLIB-encoded index (MODEL_OPENED then INDEX_DATA frames, client role) is
 * reassembled as the client does and inflated with ms_proto_index_inflate:
 * only its documented statuses may come out, and MS_OK only for a blob whose
 * CRC-32 matches. Declared sizes above 1 MiB are not inflated (speed).
 *
 * tests/test_protocol.c includes this file to replay tests/corpus/protocol/
 * in `make test`; it then calls ms_fuzz_protocol_one() directly. */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_proto.h"
#include "ms_proto_range.h"

#define MS_FUZZ_CHECK(cond)                                                                    \
    do {                                                                                       \
        if (!(cond)) {                                                                         \
            fprintf(stderr, "fuzz_protocol: contract broken: %s (%s:%d)\n", #cond, __FILE__,  \
                    __LINE__);                                                                 \
            abort();                                                                           \
        }                                                                                      \
    } while (0)

/* Encodes the frame a peer sends first, into out (room for 512 bytes). */
static size_t ms_fuzz_handshake_frame(bool client_role, uint8_t *out)
{
    ms_proto_message m;
    memset(&m, 0, sizeof m);
    if (client_role) {
        m.type = MS_PROTO_HELLO_REPLY;
        m.body.hello_reply = (ms_proto_hello_reply){
            .version = 3, .capabilities = MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB |
                                          MS_PROTO_CAP_INDEX_SUBTREES,
            .max_frame = MS_PROTO_MIN_FRAME,
            .max_batch = 64, .max_outstanding = 1024, .max_queued_bytes = 1u << 26,
            .idle_timeout_ms = 30000, .max_request_rate = 0, .max_open_models = 4,
            .server_name = "fuzz", .server_name_length = 4};
    } else {
        m.type = MS_PROTO_HELLO;
        m.body.hello = (ms_proto_hello){.min_version = 1, .max_version = 3,
                                        .capabilities = MS_PROTO_CAP_APO |
                                                        MS_PROTO_CAP_INDEX_ZLIB |
                                                        MS_PROTO_CAP_INDEX_SUBTREES,
                                        .max_frame = MS_PROTO_MIN_FRAME};
    }
    size_t written = 0;
    MS_FUZZ_CHECK(ms_proto_encode(&m, out, 512, &written, NULL) == MS_OK);
    return written;
}

/* Every decoded cell request also goes through the range resolver, against a
 * cell whose stream holds steps 7..9 (bytes 100, 250, 400), with full access
 * and with a preview of 9 steps out of 16. */
static void ms_fuzz_resolve(const ms_proto_request_cells *batch)
{
    static const uint32_t ends[] = {100, 250, 400}, subtree_end[] = {300};
    const ms_proto_stream_steps steps = {7, 3, ends}, subtree = {0, 1, subtree_end};
    const ms_proto_stream_access accesses[2] = {{16, 16}, {16, 9}}, whole = {1, 1};
    for (uint32_t i = 0; i < batch->count; ++i) {
        const ms_proto_cell_request *r = &batch->entries[i];
        const bool index = r->stream == MS_PROTO_STREAM_INDEX;
        ms_proto_fault fault;
        ms_status s = ms_proto_check_cell_id(r->cell_id, 1000, &fault, NULL);
        MS_FUZZ_CHECK(s == (r->cell_id < 1000 ? MS_OK : MS_ERR_RANGE));
        for (int k = 0; k < 2; ++k) {
            ms_proto_byte_range out = {0, 0};
            memset(&fault, 0, sizeof fault);
            s = ms_proto_resolve_range(r, index ? &subtree : &steps, index ? &whole : &accesses[k],
                                       &out, &fault, NULL);
            if (s == MS_OK) {
                MS_FUZZ_CHECK(out.begin <= out.end && out.end <= (index ? 300u : 400u));
                /* A subtree by STEPS is the whole of it (validation allows 0..0 only). */
                MS_FUZZ_CHECK(!index || r->unit != MS_PROTO_UNIT_STEPS ||
                              (out.begin == 0 && out.end == 300));
            } else {
                MS_FUZZ_CHECK(s == MS_ERR_RANGE);
                MS_FUZZ_CHECK(fault.code == MS_PROTO_E_RANGE_NOT_SATISFIABLE ||
                              (fault.code == MS_PROTO_E_FORBIDDEN && k == 1 && !index));
            }
        }
    }
}

static bool ms_fuzz_one_line(const char *text)
{
    return text[0] != '\0' && strchr(text, '\n') == NULL && strchr(text, '\r') == NULL;
}

/* The negotiated rules (ms_proto_check_negotiated) on a decoded message: all
 * pass on version 3 with every capability (except a HELLO_REPLY's own version
 * and bits, checked against themselves); on version 1 without any, a refusal
 * is FIELD_OUT_OF_RANGE with a one-line text and an encodable ERROR. */
static void ms_fuzz_negotiated(const ms_proto_message *msg, uint8_t *scratch)
{
    const uint32_t all = ms_proto_version_capabilities(MS_PROTO_VERSION);
    if (msg->type != MS_PROTO_HELLO_REPLY)
        MS_FUZZ_CHECK(ms_proto_check_negotiated(msg, MS_PROTO_VERSION, all, NULL, NULL) == MS_OK);
    ms_proto_fault fault;
    memset(&fault, 0, sizeof fault);
    ms_error err;
    ms_error_clear(&err);
    ms_status s = ms_proto_check_negotiated(msg, 1, 0, &fault, &err);
    if (s == MS_OK)
        return;
    MS_FUZZ_CHECK(s == MS_ERR_RANGE && fault.code == MS_PROTO_E_FIELD_OUT_OF_RANGE);
    MS_FUZZ_CHECK(ms_fuzz_one_line(err.text));
    MS_FUZZ_CHECK((fault.request_id == 0) == (fault.request_count == 0));
    ms_proto_message answer;
    ms_proto_error_from_fault(&fault, err.text, &answer);
    size_t written = 0;
    MS_FUZZ_CHECK(ms_proto_encode(&answer, scratch, MS_PROTO_HEADER_SIZE + MS_PROTO_MIN_FRAME,
                                  &written, NULL) == MS_OK);
}

/* A compressed index being reassembled (at most one at a time). */
typedef struct ms_fuzz_index {
    ms_proto_model_opened opened;
    uint32_t request_id;
    uint8_t *wire;
    size_t have;
    bool active;
} ms_fuzz_index;

#define MS_FUZZ_MAX_INFLATE (1u << 20)

static void ms_fuzz_index_message(ms_fuzz_index *x, const ms_proto_message *msg)
{
    if (msg->type == MS_PROTO_MODEL_OPENED) {
        free(x->wire);
        memset(x, 0, sizeof *x);
        x->opened = msg->body.model_opened;
        x->request_id = msg->request_id;
        x->active = x->opened.index_encoding == MS_PROTO_INDEX_ZLIB &&
                    x->opened.index_size <= MS_FUZZ_MAX_INFLATE;
        return;
    }
    const ms_proto_index_data *d = &msg->body.index_data;
    if (msg->type != MS_PROTO_INDEX_DATA || !x->active || msg->request_id != x->request_id ||
        d->offset != x->have || (uint64_t)d->offset + d->data_length >= x->opened.index_size) {
        x->active = false;
        return;
    }
    uint8_t *grown = realloc(x->wire, x->have + d->data_length);
    MS_FUZZ_CHECK(grown != NULL);
    x->wire = grown;
    memcpy(x->wire + x->have, d->data, d->data_length);
    x->have += d->data_length;
    if (!(msg->flags & MS_PROTO_FLAG_LAST))
        return;
    uint8_t *out = malloc(x->opened.index_size);
    MS_FUZZ_CHECK(out != NULL);
    ms_error err;
    ms_status s = ms_proto_index_inflate(x->wire, x->have, x->opened.index_size,
                                         x->opened.index_crc32, out, &err);
    MS_FUZZ_CHECK(s == MS_OK || s == MS_ERR_FORMAT || s == MS_ERR_CORRUPT || s == MS_ERR_RANGE);
    MS_FUZZ_CHECK(s == MS_OK || ms_fuzz_one_line(err.text));
    free(out);
    x->active = false;
}


/* Runs one input; returns the number of messages decoded and, if first_fault
 * is non-NULL, the code of the first fault (0 if none), for tests. */
static size_t ms_fuzz_protocol_one(const uint8_t *data, size_t size, uint16_t *first_fault)
{
    if (first_fault)
        *first_fault = 0;
    if (size == 0)
        return 0;
    const uint8_t control = data[0];
    const bool client_role = control & 1;
    ++data;
    --size;

    uint8_t prefix[512];
    size_t prefix_size = (control & 2) ? ms_fuzz_handshake_frame(client_role, prefix) : 0;
    uint8_t *stream = malloc(prefix_size + size + 1);
    MS_FUZZ_CHECK(stream != NULL);
    memcpy(stream, prefix, prefix_size);
    if (size)
        memcpy(stream + prefix_size, data, size);
    const size_t total = prefix_size + size;

    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config config = {client_role ? MS_PROTO_ROLE_CLIENT : MS_PROTO_ROLE_SERVER,
                                      MS_PROTO_MIN_FRAME, client_role ? 0 : 16};
    MS_FUZZ_CHECK(ms_proto_decoder_new(&config, &dec, NULL) == MS_OK);

    uint64_t rng = (uint64_t)(control >> 2) * 0x9E3779B97F4A7C15ull + 1;
    size_t pos = 0, frame_start = 0, messages = 0;
    bool dead = false;
    uint8_t *reencoded = malloc(MS_PROTO_HEADER_SIZE + MS_PROTO_MIN_FRAME);
    MS_FUZZ_CHECK(reencoded != NULL);
    ms_fuzz_index index = {0};

    while (pos < total && !dead) {
        size_t chunk = total - pos;
        if (control >> 2) {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            size_t want = 1 + (size_t)(rng % 64);
            if (want < chunk)
                chunk = want;
        }
        size_t chunk_pos = 0;
        while (chunk_pos < chunk) {
            size_t consumed = 12345;
            bool have = false;
            ms_proto_message msg;
            ms_proto_fault fault;
            ms_error err;
            ms_error_clear(&err);
            memset(&fault, 0, sizeof fault);
            ms_status s = ms_proto_decoder_feed(dec, stream + pos, chunk - chunk_pos, &consumed,
                                                &msg, &have, &fault, &err);
            MS_FUZZ_CHECK(consumed <= chunk - chunk_pos);
            pos += consumed;
            chunk_pos += consumed;
            if (s == MS_OK && !have) {
                MS_FUZZ_CHECK(chunk_pos == chunk); /* no message: all input taken */
                MS_FUZZ_CHECK(ms_proto_decoder_buffered(dec) > 0);
                continue;
            }
            if (s == MS_OK) {
                ++messages;
                MS_FUZZ_CHECK(msg.type != MS_PROTO_NONE);
                MS_FUZZ_CHECK(ms_proto_check_message(&msg, MS_PROTO_MAX_BATCH, NULL, NULL) ==
                              MS_OK);
                size_t written = 0;
                MS_FUZZ_CHECK(ms_proto_encode(&msg, reencoded, MS_PROTO_HEADER_SIZE +
                                              MS_PROTO_MIN_FRAME, &written, NULL) == MS_OK);
                MS_FUZZ_CHECK(written == pos - frame_start);
                MS_FUZZ_CHECK(memcmp(reencoded, stream + frame_start, written) == 0);
                if (msg.type == MS_PROTO_REQUEST_CELLS)
                    ms_fuzz_resolve(&msg.body.request_cells);
                ms_fuzz_negotiated(&msg, reencoded);
                if (client_role)
                    ms_fuzz_index_message(&index, &msg);
                frame_start = pos;
                continue;
            }
            /* A rejected frame. */
            if (first_fault && *first_fault == 0)
                *first_fault = fault.code;
            MS_FUZZ_CHECK(err.code == s && ms_fuzz_one_line(err.text));
            MS_FUZZ_CHECK(fault.code >= MS_PROTO_E_FIRST && fault.code <= MS_PROTO_E_LAST);
            MS_FUZZ_CHECK((fault.request_id == 0) == (fault.request_count == 0));
            ms_proto_message answer;
            ms_proto_error_from_fault(&fault, err.text, &answer);
            size_t written = 0;
            MS_FUZZ_CHECK(ms_proto_encode(&answer, reencoded, MS_PROTO_HEADER_SIZE +
                                          MS_PROTO_MIN_FRAME, &written, NULL) == MS_OK);
            MS_FUZZ_CHECK(answer.body.error.fatal == fault.fatal);
            if (fault.fatal) {
                MS_FUZZ_CHECK(ms_proto_error_fatality(fault.code) != MS_PROTO_FATAL_NEVER);
                ms_proto_fault again;
                size_t consumed_again = 1;
                MS_FUZZ_CHECK(ms_proto_decoder_feed(dec, stream + pos, total - pos,
                                                    &consumed_again, &msg, &have, &again,
                                                    NULL) == s);
                MS_FUZZ_CHECK(consumed_again == 0 && !have && again.code == fault.code);
                dead = true;
                break;
            }
            MS_FUZZ_CHECK(!client_role); /* a client treats every bad frame as fatal */
            MS_FUZZ_CHECK(ms_proto_error_fatality(fault.code) != MS_PROTO_FATAL_ALWAYS);
            MS_FUZZ_CHECK(ms_proto_decoder_buffered(dec) == 0);
            frame_start = pos;
        }
    }
    if (!dead) {
        ms_proto_fault fault;
        ms_status s = ms_proto_decoder_finish(dec, &fault, NULL);
        if (ms_proto_decoder_buffered(dec) == 0 && frame_start == pos) {
            MS_FUZZ_CHECK(s == MS_OK);
        } else {
            MS_FUZZ_CHECK(s == MS_ERR_FORMAT && fault.code == MS_PROTO_E_MALFORMED_FRAME &&
                          fault.fatal);
            if (first_fault && *first_fault == 0)
                *first_fault = fault.code;
        }
    }
    ms_proto_decoder_free(dec);
    free(index.wire);
    free(reencoded);
    free(stream);
    return messages;
}

#ifndef MS_FUZZ_NO_ENTRY_POINT
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    ms_fuzz_protocol_one(data, size, NULL);
    return 0;
}
#endif
