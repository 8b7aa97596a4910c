/* A client that refuses what breaks the protocol (issue 32, items 6 and 9).
 *
 * A fake meshserve on loopback (one thread, one connection at a time, each
 * bounded to 5 s) serves the synthetic test archive's whole index and then
 * breaks the protocol one way per test: a PAYLOAD naming another cell than
 * requested, a PAYLOAD after its request's LAST, a PAYLOAD for a request id
 * never sent, a MODEL_OPENED whose cell count contradicts its index, a
 * HELLO_REPLY with a version outside the client's. Each time the client core
 * ends the connection with one exact line ("protocol violation: ..."), tells
 * the server so with a fatal ERROR of the exact code, and connects again (the
 * fake server counts the connections). meshload against such a server, and
 * against one that never answers, exits 1 with one line of error text.
 *
 * Item 9: a fake HTTP server announces a 10 GB Content-Length (and another
 * sends an endless chunked body): ms_http_get refuses past its bound with one
 * exact line, and meshload --baseline draco exits 1 with it, holding nothing
 * like the announced size. Runs from the repository root. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <math.h>
#include <stdint.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <unistd.h>
#include <zlib.h>
#include <event2/buffer.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_client_core.h"
#include "ms_http_get.h"
#include "ms_progress.h"
#include "ms_proto.h"
#include "ms_test.h"
#include "ms_test_core.h"

typedef enum {
    BREAK_WRONG_CELL,
    BREAK_AFTER_LAST,
    BREAK_NEVER_REQUESTED,
    BREAK_CELL_COUNT,
    BREAK_HELLO,
    BREAK_SILENT,
    BREAK_DOCUMENT /* a DOCUMENT for no GET_DOCUMENT, before the model's answer */
} break_kind;

typedef struct fake_server {
    int fd;
    break_kind kind;
    const ms_archive *archive;
    pthread_t thread;
    volatile int stop;
    volatile int connections;
    volatile uint16_t client_error;   /* the code of the last ERROR the client sent */
    char client_text[300];
    pthread_mutex_t lock;
} fake_server;

static int listen_loopback(uint16_t *port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    assert_true(fd >= 0);
    struct sockaddr_in sin = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    assert_int_equal(bind(fd, (struct sockaddr *)&sin, sizeof sin), 0);
    assert_int_equal(listen(fd, 16), 0);
    socklen_t len = sizeof sin;
    assert_int_equal(getsockname(fd, (struct sockaddr *)&sin, &len), 0);
    *port = ntohs(sin.sin_port);
    return fd;
}

static void send_frame(int fd, const ms_proto_message *m)
{
    static uint8_t out[MS_PROTO_HEADER_SIZE + (1u << 17)];
    size_t n = 0;
    if (ms_proto_encode(m, out, sizeof out, &n, NULL) == MS_OK)
        (void)!send(fd, out, n, MSG_NOSIGNAL); /* the client may have hung up */
}

static void send_payload(int fd, uint32_t id, uint32_t cell, uint32_t offset, uint32_t end,
                         const uint8_t *data, uint32_t length, bool last)
{
    ms_proto_message p = {.type = MS_PROTO_PAYLOAD, .request_id = id,
                          .flags = last ? MS_PROTO_FLAG_LAST : 0};
    p.body.payload = (ms_proto_payload){cell, MS_PROTO_STREAM_GEOMETRY, offset, end, data, length};
    send_frame(fd, &p);
}

static void answer_open(fake_server *f, int conn, uint32_t id)
{
    size_t size;
    const uint8_t *index = ms_archive_index_bytes(f->archive, &size);
    const ms_archive_header *h = ms_archive_get_header(f->archive);
    ms_proto_message r = {.type = MS_PROTO_MODEL_OPENED, .request_id = id};
    r.body.model_opened = (ms_proto_model_opened){
        .model_handle = 1,
        .cell_count = h->cell_count + (f->kind == BREAK_CELL_COUNT ? 7 : 0),
        .content_id = 42, .index_size = (uint32_t)size,
        .index_crc32 = (uint32_t)crc32_z(0L, index, size), .archive_version = 1,
        .geometry_steps = (uint8_t)h->bits, .permitted_geometry_steps = (uint8_t)h->bits,
        .index_encoding = MS_PROTO_INDEX_RAW};
    send_frame(conn, &r);
    ms_proto_message d = {.type = MS_PROTO_INDEX_DATA, .request_id = id, .flags = MS_PROTO_FLAG_LAST};
    d.body.index_data = (ms_proto_index_data){0, index, (uint32_t)size};
    send_frame(conn, &d);
}

/* The first entry of the first REQUEST_CELLS, answered the wrong way. */
static void answer_cells(fake_server *f, int conn, const ms_proto_message *m)
{
    const ms_proto_cell_request *e = &m->body.request_cells.entries[0];
    uint32_t id = m->request_id, start = e->a, end = e->a + e->b;
    assert_int_equal(e->unit, MS_PROTO_UNIT_BYTES);
    size_t length;
    const uint8_t *bytes = ms_archive_geometry(f->archive, e->cell_id, &length);
    assert_true(end <= length && e->b <= (1u << 16));
    switch (f->kind) {
    case BREAK_WRONG_CELL: send_payload(conn, id, e->cell_id + 1, start, end, bytes + start, 1, false); break;
    case BREAK_AFTER_LAST:
        send_payload(conn, id, e->cell_id, start, end, bytes + start, e->b, true);
        send_payload(conn, id, e->cell_id, start, end, bytes + start, 1, false);
        break;
    case BREAK_NEVER_REQUESTED:
        send_payload(conn, id + m->body.request_cells.count + 100, e->cell_id, start, end,
                     bytes + start, 1, false);
        break;
    default: break;
    }
}

static void converse(fake_server *f, int conn)
{
    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config dc = {MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 64};
    assert_int_equal(ms_proto_decoder_new(&dc, &dec, NULL), MS_OK);
    uint8_t buf[16384];
    bool answered_cells = false;
    /* 8 s: longer than the client's 5 s answer time-out, which a silent server's
     * test waits for (at 5 s the two raced: one failure in five under load) */
    for (double until = ms_now_seconds() + 8.0; ms_now_seconds() < until && !f->stop;) {
        struct pollfd p = {conn, POLLIN, 0};
        if (poll(&p, 1, 50) <= 0)
            continue;
        ssize_t got = read(conn, buf, sizeof buf);
        if (got <= 0)
            break;
        for (size_t at = 0; at < (size_t)got;) {
            size_t used;
            ms_proto_message m;
            bool have;
            ms_proto_fault fault;
            if (ms_proto_decoder_feed(dec, buf + at, (size_t)got - at, &used, &m, &have, &fault,
                                      NULL) != MS_OK)
                goto done;
            at += used;
            if (!have || f->kind == BREAK_SILENT)
                continue;
            if (m.type == MS_PROTO_HELLO) {
                ms_proto_message r = {.type = MS_PROTO_HELLO_REPLY};
                r.body.hello_reply = (ms_proto_hello_reply){
                    .version = f->kind == BREAK_HELLO ? 9 : f->kind == BREAK_DOCUMENT ? 3 : 2,
                    .capabilities = MS_PROTO_CAP_APO,
                    .max_frame = MS_PROTO_MIN_FRAME, .max_batch = 64, .max_outstanding = 1024,
                    .max_queued_bytes = 1u << 26, .max_open_models = 4};
                send_frame(conn, &r);
            } else if (m.type == MS_PROTO_OPEN_MODEL && f->kind == BREAK_DOCUMENT) {
                static const uint8_t doc[] = "{}";
                ms_proto_message d = {.type = MS_PROTO_DOCUMENT, .request_id = 77,
                                      .flags = MS_PROTO_FLAG_LAST};
                d.body.document = (ms_proto_document){MS_DOCUMENT_ANNOTATIONS, 2, 0, doc, 2};
                send_frame(conn, &d);
            } else if (m.type == MS_PROTO_OPEN_MODEL) {
                answer_open(f, conn, m.request_id);
            } else if (m.type == MS_PROTO_REQUEST_CELLS && !answered_cells) {
                answered_cells = true;
                answer_cells(f, conn, &m);
            } else if (m.type == MS_PROTO_ERROR) {
                pthread_mutex_lock(&f->lock);
                f->client_error = m.body.error.code;
                snprintf(f->client_text, sizeof f->client_text, "%.*s",
                         (int)m.body.error.text_length, m.body.error.text);
                pthread_mutex_unlock(&f->lock);
            }
        }
    }
done:
    ms_proto_decoder_free(dec);
}

static void *fake_serve(void *arg)
{
    fake_server *f = arg;
    while (!f->stop) {
        struct pollfd p = {f->fd, POLLIN, 0};
        if (poll(&p, 1, 50) <= 0)
            continue;
        int conn = accept(f->fd, NULL, NULL);
        if (conn < 0)
            continue;
        f->connections++;
        converse(f, conn);
        close(conn);
    }
    return NULL;
}

typedef struct fixture {
    char dir[512], file[600], path_file[600];
    ms_archive *archive;
} fixture;

static int setup(void **state)
{
    fixture *x = calloc(1, sizeof *x);
    if (!x || !ms_test_tmpdir(x->dir, sizeof x->dir))
        return -1;
    /* a real bake (a bumpy sphere of 2,256 triangles), so that what the fake
     * server sends right decodes without a warning of its own */
    char off[600], bin[512], cmd[2000], out[4096];
    snprintf(off, sizeof off, "%s/sphere.off", x->dir);
    if (ms_test_write_bumpy_sphere(off, 1.0) != 0)
        return -1;
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s %s -o %s/archives --name fake --min-tris 200 2>&1", bin, off,
             x->dir);
    if (ms_test_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "%s\n", out);
        return -1;
    }
    snprintf(x->file, sizeof x->file, "%s/archives/fake.msa", x->dir);
    ms_error err;
    if (ms_archive_open(x->file, &x->archive, &err) != MS_OK)
        return -1;
    /* a path looking at the archive's cube from outside */
    const ms_archive_header *h = ms_archive_get_header(x->archive);
    double c[3];
    for (int a = 0; a < 3; ++a)
        c[a] = h->box_origin[a] + 0.5 * h->box_side;
    snprintf(x->path_file, sizeof x->path_file, "%s/look.cam", x->dir);
    char text[600];
    int n = snprintf(text, sizeof text,
                     "meshstream-camera-path 1\n0 %.9g %.9g %.9g %.9g %.9g %.9g 0 1 0 40\n"
                     "1 %.9g %.9g %.9g %.9g %.9g %.9g 0 1 0 40\n",
                     c[0], c[1], c[2] + 2 * h->box_side, c[0], c[1], c[2], c[0], c[1],
                     c[2] + 1.5 * h->box_side, c[0], c[1], c[2]);
    ms_test_write_file(x->path_file, text, (size_t)n);
    *state = x;
    return 0;
}

static int teardown(void **state)
{
    fixture *x = *state;
    ms_archive_close(x->archive);
    ms_test_rmdir(x->dir);
    free(x);
    return 0;
}

static void fake_start(fake_server *f, const fixture *x, break_kind kind, uint16_t *port)
{
    memset(f, 0, sizeof *f);
    f->kind = kind;
    f->archive = x->archive;
    pthread_mutex_init(&f->lock, NULL);
    f->fd = listen_loopback(port);
    assert_int_equal(pthread_create(&f->thread, NULL, fake_serve, f), 0);
}

static void fake_stop(fake_server *f)
{
    f->stop = 1;
    pthread_join(f->thread, NULL);
    close(f->fd);
    pthread_mutex_destroy(&f->lock);
}

/* A core against the fake server until it has connected twice (the
 * violation, then the reconnect) or 20 s; the last figures in *st. */
static void run_core(const fixture *x, uint16_t port, fake_server *f, ms_core_stats *st)
{
    ms_core_options o = {.host = "127.0.0.1", .port = port, .model = "fake", .agent = "test",
                         .tolerance_px = 1, .answer_timeout = 3, .give_up_seconds = 30};
    ms_core *core;
    ms_error err;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    const ms_archive_header *h = ms_archive_get_header(x->archive);
    double c[3], eye[3], up[3] = {0, 1, 0};
    for (int a = 0; a < 3; ++a)
        c[a] = eye[a] = h->box_origin[a] + 0.5 * h->box_side;
    eye[2] += 2 * h->box_side;
    ms_camera cam;
    assert_int_equal(ms_camera_look_at(eye, c, up, 40, 640, 480, 0.01 * h->box_side,
                                       10 * h->box_side, &cam, &err),
                     MS_OK);
    ms_core_set_camera(core, &cam);
    for (double until = ms_now_seconds() + 20; ms_now_seconds() < until && f->connections < 2;)
        ms_test_sleep_s(0.01);
    ms_core_get_stats(core, st);
    ms_core_stop(core);
}

static void expect_violation(break_kind kind, const char *what, uint16_t code, void **state)
{
    fixture *x = *state;
    fake_server f;
    uint16_t port;
    fake_start(&f, x, kind, &port);
    ms_core_stats st;
    run_core(x, port, &f, &st);
    fake_stop(&f);
    char want[400];
    snprintf(want, sizeof want, "connection lost: protocol violation: %s", what);
    assert_string_equal(st.warning, want);
    assert_true(f.connections >= 2); /* and it connected again */
    assert_int_equal(f.client_error, code);
    assert_string_equal(f.client_text, what);
    assert_false(st.view_complete);
    assert_int_equal(st.error[0], 0); /* not fatal: it goes on trying */
}

static void test_payload_for_another_cell(void **state)
{
    expect_violation(BREAK_WRONG_CELL,
                     "PAYLOAD for request 2 names cell 1 stream 0; it asked for cell 0 stream 0",
                     MS_PROTO_E_FIELD_OUT_OF_RANGE, state);
}

static void test_payload_after_last(void **state)
{
    expect_violation(BREAK_AFTER_LAST,
                     "PAYLOAD for request 2, which is not an outstanding cell request",
                     MS_PROTO_E_UNEXPECTED_MESSAGE, state);
}

static void test_payload_never_requested(void **state)
{
    /* the first batch has one entry per wanted range: its size sets the id */
    fixture *x = *state;
    fake_server f;
    uint16_t port;
    fake_start(&f, x, BREAK_NEVER_REQUESTED, &port);
    ms_core_stats st;
    run_core(x, port, &f, &st);
    fake_stop(&f);
    unsigned id;
    assert_int_equal(sscanf(st.warning, "connection lost: protocol violation: PAYLOAD for request %u,", &id), 1);
    assert_true(id >= 2 + 1 + 100);
    char want[300];
    snprintf(want, sizeof want,
             "connection lost: protocol violation: PAYLOAD for request %u, which is not an "
             "outstanding cell request", id);
    assert_string_equal(st.warning, want);
    assert_true(f.connections >= 2);
    assert_int_equal(f.client_error, MS_PROTO_E_UNEXPECTED_MESSAGE);
}

static void test_document_never_requested(void **state)
{
    expect_violation(BREAK_DOCUMENT,
                     "DOCUMENT for request 77 out of order, or for no document request",
                     MS_PROTO_E_UNEXPECTED_MESSAGE, state);
}

static void test_model_opened_lies_about_cells(void **state)
{
    fixture *x = *state;
    char what[120];
    uint32_t cells = ms_archive_get_header(x->archive)->cell_count;
    snprintf(what, sizeof what, "MODEL_OPENED says %u cells, its index %u", cells + 7, cells);
    expect_violation(BREAK_CELL_COUNT, what, MS_PROTO_E_FIELD_OUT_OF_RANGE, state);
}

static void test_hello_reply_out_of_range(void **state)
{
    expect_violation(BREAK_HELLO, "server chose protocol version 9, outside our 1..3",
                     MS_PROTO_E_FIELD_OUT_OF_RANGE, state);
}

/* meshload: a failure is one line of text, never an empty error. */
static void meshload_against(const fixture *x, break_kind kind, const char *want_line)
{
    fake_server f;
    uint16_t port;
    fake_start(&f, x, kind, &port);
    char bin[512], cmd[1600], out[4096], want[600];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd,
             "timeout 60 %s --server 127.0.0.1:%u --model fake --path %s --duration 7 2>&1 "
             ">/dev/null", bin, port, x->path_file);
    int status = ms_test_run(cmd, out, sizeof out);
    fake_stop(&f);
    assert_int_equal(status, 1);
    /* a line that starts so (a silent server's seconds vary in the last digit) */
    snprintf(want, sizeof want, "meshload: client 0: %s", want_line);
    if (strncmp(out, want, strlen(want)) != 0 || !strchr(out, '\n') || strchr(out, '\n')[1])
        fail_msg("meshload said '%s', not one line starting '%s'", out, want);
    if (kind == BREAK_HELLO)
        assert_string_equal(out + strlen(want), "\n");
    else
        assert_string_equal(strchr(out, '\n') - 3, " s)\n");
}

static void test_meshload_says_why(void **state)
{
    fixture *x = *state;
    meshload_against(x, BREAK_HELLO,
                     "the model did not open in time (connection lost: protocol violation: "
                     "server chose protocol version 9, outside our 1..3)");
    meshload_against(x, BREAK_SILENT,
                     "the model did not open in time (connection lost: the server sent nothing "
                     "for 5.");
}

/* --- item 9: bounded HTTP bodies ------------------------------------------- */

typedef struct fake_http {
    int fd;
    bool chunked;
    pthread_t thread;
    volatile int stop;
    volatile uint64_t sent; /* body bytes the client took */
} fake_http;

static void *http_serve(void *arg)
{
    fake_http *h = arg;
    while (!h->stop) {
        struct pollfd p = {h->fd, POLLIN, 0};
        if (poll(&p, 1, 50) <= 0)
            continue;
        int conn = accept(h->fd, NULL, NULL);
        if (conn < 0)
            continue;
        char request[4096];
        (void)!read(conn, request, sizeof request);
        const char *head = h->chunked
                               ? "HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\n\r\n"
                               : "HTTP/1.1 200 OK\r\nContent-Length: 10737418240\r\n\r\n";
        (void)!send(conn, head, strlen(head), MSG_NOSIGNAL);
        static char chunk[65536 + 32];
        size_t n = 65536;
        int k = h->chunked ? snprintf(chunk, sizeof chunk, "%zx\r\n", n) : 0;
        memset(chunk + k, 'x', n);
        if (h->chunked)
            memcpy(chunk + k + n, "\r\n", 2);
        size_t frame = (size_t)k + n + (h->chunked ? 2 : 0);
        /* bytes until the client hangs up: at most 64 MiB and 10 s */
        for (double until = ms_now_seconds() + 10; ms_now_seconds() < until && !h->stop &&
                                                   h->sent < (64u << 20);) {
            ssize_t w = send(conn, chunk, frame, MSG_NOSIGNAL);
            if (w <= 0)
                break;
            h->sent += (uint64_t)w;
        }
        close(conn);
    }
    return NULL;
}

static void http_start(fake_http *h, bool chunked, uint16_t *port)
{
    memset(h, 0, sizeof *h);
    h->chunked = chunked;
    h->fd = listen_loopback(port);
    assert_int_equal(pthread_create(&h->thread, NULL, http_serve, h), 0);
}

static void http_stop(fake_http *h)
{
    h->stop = 1;
    pthread_join(h->thread, NULL);
    close(h->fd);
}

static void test_http_body_bounded(void **state)
{
    (void)state;
    for (int chunked = 0; chunked < 2; ++chunked) {
        fake_http h;
        uint16_t port;
        http_start(&h, chunked, &port);
        struct evbuffer *body = evbuffer_new();
        ms_http_get_options o = {.host = "127.0.0.1", .port = port, .path = "/models/m/draco",
                                 .timeout_s = 20, .max_body = 1u << 20};
        int status = -1;
        ms_error err;
        assert_int_equal(ms_http_get(&o, body, &status, &err), MS_ERR_RANGE);
        http_stop(&h);
        char want[200];
        snprintf(want, sizeof want,
                 "127.0.0.1:%u: the answer's body is larger than the 1048576-byte maximum", port);
        assert_string_equal(err.text, want);
        assert_int_equal(status, 0);
        assert_true(evbuffer_get_length(body) <= (1u << 20));
        evbuffer_free(body);
    }
}

/* meshload --baseline draco: the default bound (1 GiB) refuses a 10 GB
 * Content-Length before reading the body: one line, exit 1. */
static void test_meshload_baseline_bounded(void **state)
{
    (void)state;
    fake_http h;
    uint16_t port;
    http_start(&h, false, &port);
    char bin[512], cmd[1600], out[4096], want[600];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd,
             "timeout 60 %s --baseline draco --server 127.0.0.1:%u --model fake 2>&1 >/dev/null",
             bin, port);
    int status = ms_test_run(cmd, out, sizeof out);
    http_stop(&h);
    assert_int_equal(status, 1);
    snprintf(want, sizeof want,
             "meshload: client 0: 127.0.0.1:%u: the answer's body is larger than the "
             "1073741824-byte maximum\n", port);
    assert_string_equal(out, want);
    assert_true(h.sent < (64u << 20)); /* it hung up instead of reading on */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_payload_for_another_cell, setup, teardown),
        cmocka_unit_test_setup_teardown(test_payload_after_last, setup, teardown),
        cmocka_unit_test_setup_teardown(test_payload_never_requested, setup, teardown),
        cmocka_unit_test_setup_teardown(test_model_opened_lies_about_cells, setup, teardown),
        cmocka_unit_test_setup_teardown(test_document_never_requested, setup, teardown),
        cmocka_unit_test_setup_teardown(test_hello_reply_out_of_range, setup, teardown),
        cmocka_unit_test_setup_teardown(test_meshload_says_why, setup, teardown),
        cmocka_unit_test(test_http_body_bounded),
        cmocka_unit_test(test_meshload_baseline_bounded),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
