#include "ms_test_proto.h"

#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>
#include <zlib.h>
#include <cmocka.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

int ms_test_conn_open(ms_test_conn *c, uint16_t port)
{
    memset(c, 0, sizeof *c);
    c->fd = socket(AF_INET, SOCK_STREAM, 0);
    if (c->fd < 0)
        return -1;
    struct timeval tv = {5, 0};
    setsockopt(c->fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(c->fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
        close(c->fd);
        c->fd = -1;
        return -1;
    }
    ms_proto_decoder_config config = {MS_PROTO_ROLE_CLIENT, MS_PROTO_MAX_FRAME, 0};
    if (ms_proto_decoder_new(&config, &c->decoder, NULL) != MS_OK)
        return -1;
    return 0;
}

void ms_test_conn_close(ms_test_conn *c)
{
    if (c->fd >= 0)
        close(c->fd);
    c->fd = -1;
    ms_proto_decoder_free(c->decoder);
    c->decoder = NULL;
}

int ms_test_conn_send_raw(ms_test_conn *c, const void *data, size_t size)
{
    const uint8_t *p = data;
    while (size) {
        ssize_t n = send(c->fd, p, size, MSG_NOSIGNAL);
        if (n <= 0)
            return -1;
        p += n;
        size -= (size_t)n;
    }
    return 0;
}

void ms_test_conn_send(ms_test_conn *c, const ms_proto_message *msg)
{
    size_t size;
    ms_error err;
    if (ms_proto_encoded_size(msg, &size, &err) != MS_OK)
        fail_msg("encode: %s", err.text);
    uint8_t *buf = malloc(size);
    size_t written;
    if (ms_proto_encode(msg, buf, size, &written, &err) != MS_OK)
        fail_msg("encode: %s", err.text);
    if (ms_test_conn_send_raw(c, buf, written) != 0)
        fail_msg("send failed: %s", strerror(errno));
    free(buf);
}

int ms_test_conn_recv(ms_test_conn *c, ms_proto_message *msg, double timeout)
{
    double deadline = now_seconds() + timeout;
    for (;;) {
        while (c->used < c->have) {
            size_t consumed;
            bool have;
            ms_proto_fault fault;
            ms_error err;
            ms_status st = ms_proto_decoder_feed(c->decoder, c->buffer + c->used,
                                                 c->have - c->used, &consumed, msg, &have,
                                                 &fault, &err);
            c->used += consumed;
            if (st != MS_OK) {
                print_error("client decoder: %s\n", err.text);
                return -1;
            }
            if (have)
                return 1;
        }
        c->used = c->have = 0;
        if (c->eof)
            return 0;
        double left = deadline - now_seconds();
        if (left <= 0)
            return -1;
        struct pollfd p = {c->fd, POLLIN, 0};
        int r = poll(&p, 1, (int)(left * 1000) + 1);
        if (r <= 0)
            continue;
        ssize_t n = recv(c->fd, c->buffer, sizeof c->buffer, 0);
        if (n < 0)
            return errno == ECONNRESET ? 0 : -1;
        if (n == 0)
            c->eof = true;
        c->have = (size_t)n;
    }
}

void ms_test_conn_hello(ms_test_conn *c, const char *token, ms_proto_hello_reply *reply)
{
    ms_test_conn_hello_with(c, token, 1, MS_PROTO_CAP_APO, reply);
}

void ms_test_conn_hello_with(ms_test_conn *c, const char *token, uint16_t max_version,
                             uint32_t capabilities, ms_proto_hello_reply *reply)
{
    ms_proto_message m = {.type = MS_PROTO_HELLO};
    m.body.hello.min_version = 1;
    m.body.hello.max_version = max_version;
    m.body.hello.capabilities = capabilities;
    m.body.hello.max_frame = 1u << 20;
    m.body.hello.token = token;
    m.body.hello.token_length = token ? (uint16_t)strlen(token) : 0;
    m.body.hello.agent = "ms-test/1";
    m.body.hello.agent_length = 9;
    ms_test_conn_send(c, &m);
    ms_proto_message r;
    if (ms_test_conn_recv(c, &r, 5.0) != 1 || r.type != MS_PROTO_HELLO_REPLY)
        fail_msg("no HELLO_REPLY (type 0x%02x)", r.type);
    if (reply)
        *reply = r.body.hello_reply;
}

uint16_t ms_test_conn_expect_error(ms_test_conn *c, uint32_t *request_id, ms_proto_error_body *body)
{
    ms_proto_message m;
    for (;;) {
        int r = ms_test_conn_recv(c, &m, 5.0);
        if (r != 1)
            fail_msg("expected an ERROR frame, got %s", r == 0 ? "end of stream" : "nothing");
        if (m.type == MS_PROTO_ERROR)
            break;
    }
    if (request_id)
        *request_id = m.request_id;
    if (body)
        *body = m.body.error;
    return m.body.error.code;
}

uint32_t ms_test_conn_open_model(ms_test_conn *c, const char *name, uint32_t id,
                                 ms_proto_model_opened *opened, uint8_t **index,
                                 uint16_t *error_code)
{
    ms_proto_message m = {.type = MS_PROTO_OPEN_MODEL, .request_id = id};
    m.body.open_model.name = name;
    m.body.open_model.name_length = (uint8_t)strlen(name);
    ms_test_conn_send(c, &m);
    if (ms_test_conn_recv(c, &m, 5.0) != 1)
        fail_msg("no answer to OPEN_MODEL");
    if (m.type == MS_PROTO_ERROR) {
        if (error_code)
            *error_code = m.body.error.code;
        return 0;
    }
    assert_int_equal(m.type, MS_PROTO_MODEL_OPENED);
    assert_int_equal(m.request_id, id);
    ms_proto_model_opened o = m.body.model_opened;
    if (opened)
        *opened = o;
    uint8_t *blob = malloc(o.index_size);
    uint32_t have = 0;
    for (bool last = false; !last;) {
        if (ms_test_conn_recv(c, &m, 5.0) != 1)
            fail_msg("index data missing");
        assert_int_equal(m.type, MS_PROTO_INDEX_DATA);
        assert_int_equal(m.body.index_data.offset, have);
        assert_true(have + m.body.index_data.data_length <= o.index_size);
        memcpy(blob + have, m.body.index_data.data, m.body.index_data.data_length);
        have += m.body.index_data.data_length;
        last = m.flags & MS_PROTO_FLAG_LAST;
    }
    if (o.index_encoding == MS_PROTO_INDEX_ZLIB) {
        uint8_t *inflated = malloc(o.index_size);
        ms_error err;
        if (ms_proto_index_inflate(blob, have, o.index_size, o.index_crc32, inflated, &err) !=
            MS_OK)
            fail_msg("compressed index: %s", err.text);
        free(blob);
        blob = inflated;
        have = o.index_size;
    }
    assert_int_equal(have, o.index_size);
    if (o.index_encoding == MS_PROTO_INDEX_SUBTREES &&
        (uint32_t)crc32_z(0L, blob, have) != o.index_crc32)
        fail_msg("index head: CRC-32 mismatch");
    if (index)
        *index = blob;
    else
        free(blob);
    return o.model_handle;
}

void ms_test_conn_send_batch(ms_test_conn *c, uint32_t handle, uint32_t first_id,
                       const ms_proto_cell_request *entries, uint16_t count)
{
    ms_proto_message m = {.type = MS_PROTO_REQUEST_CELLS, .request_id = first_id};
    m.body.request_cells.model_handle = handle;
    m.body.request_cells.entries = entries;
    m.body.request_cells.count = count;
    ms_test_conn_send(c, &m);
}



void ms_test_answers_init(ms_test_answers *a, uint32_t first, uint32_t count)
{
    memset(a, 0, sizeof *a);
    a->first = first, a->count = count;
    a->data = calloc(count, sizeof *a->data);
    a->length = calloc(count, sizeof *a->length);
    a->start = calloc(count, sizeof *a->start);
    a->end = calloc(count, sizeof *a->end);
    a->error = calloc(count, sizeof *a->error);
    a->terminals = calloc(count, sizeof *a->terminals);
    a->order = calloc(count, sizeof *a->order);
}

void ms_test_answers_free(ms_test_answers *a)
{
    for (uint32_t i = 0; i < a->count; ++i)
        free(a->data[i]);
    free(a->data), free(a->length), free(a->start), free(a->end), free(a->error);
    free(a->terminals), free(a->order);
}

/* Takes one frame into a; returns false when it is not about these requests. */
bool ms_test_answers_take(ms_test_answers *a, const ms_proto_message *m)
{
    if (m->request_id < a->first || m->request_id - a->first >= a->count)
        return false;
    uint32_t k = m->request_id - a->first;
    if (m->type == MS_PROTO_ERROR) {
        uint32_t n = m->body.error.request_count;
        for (uint32_t j = 0; j < n && k + j < a->count; ++j) {
            if (a->terminals[k + j]++ == 0)
                a->order[a->done++] = m->request_id + j;
            a->error[k + j] = m->body.error.code;
        }
        return true;
    }
    assert_int_equal(m->type, MS_PROTO_PAYLOAD);
    if (a->terminals[k])
        fail_msg("frame for request %u after its terminal frame", m->request_id);
    const ms_proto_payload *p = &m->body.payload;
    if (!a->data[k]) {
        a->data[k] = malloc(p->end + 1);
        a->start[k] = p->offset;
        a->end[k] = p->end;
    }
    assert_int_equal(p->end, a->end[k]);
    assert_int_equal(p->offset, a->start[k] + a->length[k]); /* contiguous, in order */
    memcpy(a->data[k] + a->length[k], p->data, p->data_length);
    a->length[k] += p->data_length;
    if (m->flags & MS_PROTO_FLAG_LAST) {
        a->terminals[k]++;
        a->order[a->done++] = m->request_id;
    }
    return true;
}

void ms_test_answers_collect(ms_test_conn *c, ms_test_answers *a)
{
    ms_proto_message m;
    while (a->done < a->count) {
        int r = ms_test_conn_recv(c, &m, 10.0);
        if (r != 1)
            fail_msg("%u of %u requests answered, then %s", a->done, a->count,
                     r == 0 ? "end of stream" : "time-out");
        if (m.type == MS_PROTO_ERROR && m.body.error.fatal)
            fail_msg("fatal error %s: %.*s", ms_proto_error_name(m.body.error.code),
                     (int)m.body.error.text_length, m.body.error.text);
        ms_test_answers_take(a, &m);
    }
    for (uint32_t i = 0; i < a->count; ++i)
        assert_int_equal(a->terminals[i], 1);
}
