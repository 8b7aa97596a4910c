/* meshserve serving the index in subtrees (protocol version 3, issue 24), end to
 * end on loopback through both doors: the head a version-3 client gets is the
 * archive's header and root subtree; every subtree by STEPS and by BYTES is
 * exactly the archive's stored bytes; ids that are not subtree ids are
 * UNKNOWN_CELL; subtree requests share the payloads' priorities, cancellation
 * and CLOSE_MODEL; version-1 and version-2 clients get the whole index and
 * cannot ask for subtrees; a preview (no token) reads every subtree and still
 * no full-precision geometry; the HTTP side door serves the same bytes with
 * ETag, 304, Range, 404 and 416 (protocol/PROTOCOL.md sections 3, 4.7, 4.10,
 * 11). Models: the synthetic "dragon" (n = 4, S = 1: three subtrees), "deep" (n = 2,
 * S = 2, six levels: subtrees on three levels) and "big" (65 cells of 256 KiB,
 * to keep the queue busy). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_subtree.h"
#include "ms_synthetic_archive.h"
#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_test_net.h"
#include "ms_test_proto.h"

#define TOKEN "subtree-token"
#define ALL_CAPS (MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB | MS_PROTO_CAP_INDEX_SUBTREES)
#define DEEP_PUBLIC_BITS 6

typedef struct fixture {
    char dir[512];
    char archives[600];
    pid_t pid;
    uint16_t port, http_port;
} fixture;

/* A catalogue entry for an archive written by the test helpers. */
static void add_entry(const char *dir, const char *name, uint32_t cells, unsigned n,
                      uint8_t public_max_bits)
{
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", name);
    e.source = (char *)"synthetic";
    ms_catalog_now(e.baked_at, sizeof e.baked_at);
    e.vertices = 1234, e.triangles = 2468, e.cells = cells;
    e.bits = 12, e.n = n, e.root_bits = n == 2 ? 4 : 7, e.min_triangles = 8000;
    e.apo = true, e.apo_lead = 3, e.apo_max_depth = 13, e.apo_tolerance = 0.1;
    e.public_max_bits = public_max_bits;
    ms_error err;
    if (ms_catalog_update(dir, &e, &err) != MS_OK)
        fail_msg("%s", err.text);
}

/* The deep synthetic archive as model `name`. */
static void add_deep_model(const char *dir, const char *name, uint32_t salt)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.msa", dir, name);
    ms_test_write_deep_archive(path, salt);
    add_entry(dir, name, MS_TEST_DEEP_ARCHIVE_CELLS, 2, DEEP_PUBLIC_BITS);
}

static int start_server(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    assert_int_equal(mkdir(f->archives, 0755), 0);
    ms_test_add_model(f->archives, "dragon", 2, 8);
    add_deep_model(f->archives, "deep", 3);
    ms_synthetic_spec big = {1, 12, 256u << 10, 0, 1, 5, 12};
    ms_error err;
    if (ms_synthetic_archive_write(f->archives, "big", &big, &err) != MS_OK)
        fail_msg("%s", err.text);
    char config[700], port_file[700], log[700];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    FILE *c = fopen(config, "w");
    fprintf(c, "token = " TOKEN "\nhttp_rate = 100000\n");
    fclose(c);
    snprintf(port_file, sizeof port_file, "%s/ports", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    const char *extra[] = {"--config", config, NULL};
    f->pid = ms_test_meshserve_start(f->archives, extra, 0, port_file, log, &f->port, &f->http_port);
    if (!f->pid)
        fail_msg("meshserve did not start (see %s)", log);
    *state = f;
    return 0;
}

/* SIGTERM: a clean exit, which under the sanitizers also means no leak. */
static int stop_server(void **state)
{
    fixture *f = *state;
    int status = ms_test_stop(f->pid, SIGTERM, 15.0);
    ms_test_rmdir(f->dir);
    free(f);
    if (status != 0)
        fail_msg("meshserve did not exit cleanly after SIGTERM");
    return 0;
}

static ms_archive *open_archive(const fixture *f, const char *name)
{
    char path[800];
    snprintf(path, sizeof path, "%s/%s.msa", f->archives, name);
    ms_archive *a;
    ms_error err;
    if (ms_archive_open(path, &a, &err) != MS_OK)
        fail_msg("%s", err.text);
    return a;
}

/* A version-3 connection that was granted everything it asked for. */
static void connect_v3(const fixture *f, ms_test_conn *c, const char *token)
{
    assert_int_equal(ms_test_conn_open(c, f->port), 0);
    ms_proto_hello_reply reply;
    ms_test_conn_hello_with(c, token, 3, ALL_CAPS, &reply);
    assert_int_equal(reply.version, 3);
    assert_int_equal(reply.capabilities, ALL_CAPS);
}

static void subtree_ids(const ms_archive *a, uint32_t **ids, size_t *count)
{
    ms_error err;
    if (ms_subtree_list(a, ms_archive_subtree_levels(a), ids, count, &err) != MS_OK)
        fail_msg("%s", err.text);
}

static ms_proto_cell_request subtree_entry(uint32_t id, uint8_t unit, uint8_t priority, uint32_t a,
                                           uint32_t b)
{
    ms_proto_cell_request e = {id, MS_PROTO_STREAM_INDEX, unit, priority, a, b};
    return e;
}

/* Sends one single-entry batch and returns its ERROR's code and detail. */
static uint16_t single_error(ms_test_conn *c, uint32_t handle, uint32_t id,
                             ms_proto_cell_request e, uint64_t *detail)
{
    ms_test_conn_send_batch(c, handle, id, &e, 1);
    uint32_t got_id;
    ms_proto_error_body body;
    uint16_t code = ms_test_conn_expect_error(c, &got_id, &body);
    assert_int_equal(got_id, id);
    assert_false(body.fatal);
    *detail = body.detail;
    return code;
}

/* Two REQUEST_CELLS frames in one write, so that the server reads them
 * together, before its scheduler sends a byte. */
static void send_two_batches(ms_test_conn *c, uint32_t handle, uint32_t first_a,
                             const ms_proto_cell_request *a, uint16_t count_a, uint32_t first_b,
                             const ms_proto_cell_request *b, uint16_t count_b)
{
    size_t capacity = 2 * MS_PROTO_HEADER_SIZE + 2 * MS_PROTO_REQUEST_CELLS_FIXED +
                      ((size_t)count_a + count_b) * MS_PROTO_CELL_REQUEST_SIZE;
    uint8_t *frames = malloc(capacity);
    ms_proto_message m = {.type = MS_PROTO_REQUEST_CELLS, .request_id = first_a};
    m.body.request_cells = (ms_proto_request_cells){handle, a, count_a};
    size_t first_size, second_size;
    assert_int_equal(ms_proto_encode(&m, frames, capacity, &first_size, NULL), MS_OK);
    m.request_id = first_b;
    m.body.request_cells = (ms_proto_request_cells){handle, b, count_b};
    assert_int_equal(ms_proto_encode(&m, frames + first_size, capacity - first_size, &second_size,
                                     NULL),
                     MS_OK);
    assert_int_equal(ms_test_conn_send_raw(c, frames, first_size + second_size), 0);
    free(frames);
}

/* --- Binary door ------------------------------------------------------------ */

/* A version-3 client gets the head: the version-3 header of the model and the
 * root subtree, whose bytes are ms_archive_subtree(a, 0); the client's reader
 * opens it; content_id and cell_count are the whole index's. */
static void test_head_is_root_subtree(void **state)
{
    fixture *f = *state;
    const char *models[] = {"deep", "dragon"};
    for (size_t k = 0; k < 2; ++k) {
        ms_archive *a = open_archive(f, models[k]);
        size_t head_size, root_size;
        const uint8_t *head = ms_archive_index_head(a, &head_size);
        const uint8_t *root = ms_archive_subtree(a, 0, &root_size);
        assert_non_null(head);
        assert_non_null(root);
        assert_int_equal(head_size, MS_ARCHIVE_HEADER_SIZE + root_size);

        ms_test_conn c;
        connect_v3(f, &c, NULL);
        ms_proto_model_opened o;
        uint8_t *got;
        assert_true(ms_test_conn_open_model(&c, models[k], 1, &o, &got, NULL) >= 1);
        assert_int_equal(o.index_encoding, MS_PROTO_INDEX_SUBTREES);
        assert_int_equal(o.archive_version, MS_ARCHIVE_VERSION);
        assert_int_equal(o.index_size, head_size);
        assert_int_equal(o.index_crc32, (uint32_t)crc32_z(0L, head, head_size));
        assert_int_equal(o.cell_count, ms_archive_get_header(a)->cell_count);
        assert_memory_equal(got, head, head_size);
        assert_memory_equal(got + MS_ARCHIVE_HEADER_SIZE, root, root_size);
        ms_archive *partial;
        ms_error err;
        if (ms_archive_open_head(got, o.index_size, models[k], &partial, &err) != MS_OK)
            fail_msg("%s: %s", models[k], err.text);
        assert_true(ms_archive_is_partial(partial));
        assert_int_equal(ms_archive_subtree_levels(partial), ms_archive_subtree_levels(a));
        ms_archive_close(partial);
        free(got);
        ms_test_conn_close(&c);

        /* The same content id as a version-2 client's whole index. */
        assert_int_equal(ms_test_conn_open(&c, f->port), 0);
        ms_test_conn_hello_with(&c, NULL, 2, ALL_CAPS, NULL);
        ms_proto_model_opened whole;
        assert_true(ms_test_conn_open_model(&c, models[k], 1, &whole, NULL, NULL) >= 1);
        assert_int_equal(whole.index_encoding, MS_PROTO_INDEX_ZLIB);
        assert_true(whole.content_id == o.content_id);
        ms_test_conn_close(&c);
        ms_archive_close(a);
    }
    /* The deep model really has subtrees below subtrees (S = 2, six levels). */
    ms_archive *a = open_archive(f, "deep");
    assert_int_equal(ms_archive_subtree_levels(a), 2);
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    assert_true(count >= 5);
    const ms_archive_cell *last = ms_archive_get_cell(a, ids[count - 1]);
    assert_non_null(last);
    assert_int_equal(last->level, 4);
    free(ids);
    ms_archive_close(a);
}

/* Versions 1 and 2 keep working: the whole index (RAW, ZLIB), never the head,
 * and a request of stream INDEX is FIELD_OUT_OF_RANGE for its whole batch, as
 * is one from a version-3 client that did not ask for CAP_INDEX_SUBTREES. */
static void test_older_clients_get_whole_index(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "deep");
    size_t blob_size;
    const uint8_t *blob = ms_archive_index_bytes(a, &blob_size);
    const struct {
        uint16_t max_version;
        uint32_t asked, granted;
        uint8_t encoding;
    } cases[] = {
        {1, ALL_CAPS, MS_PROTO_CAP_APO, MS_PROTO_INDEX_RAW},
        {2, ALL_CAPS, MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB, MS_PROTO_INDEX_ZLIB},
        {3, MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB, MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB,
         MS_PROTO_INDEX_ZLIB},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        ms_test_conn c;
        assert_int_equal(ms_test_conn_open(&c, f->port), 0);
        ms_proto_hello_reply reply;
        ms_test_conn_hello_with(&c, TOKEN, cases[i].max_version, cases[i].asked, &reply);
        assert_int_equal(reply.version, cases[i].max_version);
        assert_int_equal(reply.capabilities, cases[i].granted);
        ms_proto_model_opened o;
        uint8_t *index;
        uint32_t handle = ms_test_conn_open_model(&c, "deep", 1, &o, &index, NULL);
        assert_true(handle >= 1);
        assert_int_equal(o.index_encoding, cases[i].encoding);
        assert_int_equal(o.archive_version, MS_ARCHIVE_BLOB_VERSION);
        assert_int_equal(o.index_size, blob_size);
        assert_memory_equal(index, blob, blob_size);
        free(index);
        /* Geometry first, then a subtree: the whole batch is refused, naming
         * the second entry's stream field; nothing else comes for it. */
        ms_proto_cell_request e[2] = {{0, MS_PROTO_STREAM_GEOMETRY, MS_PROTO_UNIT_STEPS, 0, 0, 3},
                                      subtree_entry(0, MS_PROTO_UNIT_STEPS, 0, 0, 0)};
        ms_test_conn_send_batch(&c, handle, 10, e, 2);
        uint32_t id;
        ms_proto_error_body body;
        assert_int_equal(ms_test_conn_expect_error(&c, &id, &body), MS_PROTO_E_FIELD_OUT_OF_RANGE);
        assert_int_equal(id, 10);
        assert_int_equal(body.request_count, 2);
        assert_false(body.fatal);
        assert_int_equal(body.detail, MS_PROTO_REQUEST_CELLS_FIXED + MS_PROTO_CELL_REQUEST_SIZE + 4);
        /* The connection goes on: the geometry alone is served. */
        ms_test_answers ans;
        ms_test_conn_send_batch(&c, handle, 20, e, 1);
        ms_test_answers_init(&ans, 20, 1);
        ms_test_answers_collect(&c, &ans);
        assert_int_equal(ans.error[0], 0);
        ms_test_answers_free(&ans);
        ms_test_conn_close(&c);
    }
    ms_archive_close(a);
}

/* Every subtree of both models by STEPS 0..0, then parts of each by BYTES:
 * exactly the stored bytes; a range past the end is RANGE_NOT_SATISFIABLE
 * with the stored size as detail. */
static void test_every_subtree_by_steps_and_bytes(void **state)
{
    fixture *f = *state;
    const char *models[] = {"deep", "dragon"};
    for (size_t k = 0; k < 2; ++k) {
        ms_archive *a = open_archive(f, models[k]);
        uint32_t *ids;
        size_t count;
        subtree_ids(a, &ids, &count);
        assert_true(count >= 3 && count <= 512);
        ms_test_conn c;
        connect_v3(f, &c, TOKEN);
        uint32_t handle = ms_test_conn_open_model(&c, models[k], 1, NULL, NULL, NULL);
        ms_proto_cell_request *e = calloc(2 * count, sizeof *e);
        for (size_t i = 0; i < count; ++i)
            e[i] = subtree_entry(ids[i], MS_PROTO_UNIT_STEPS, (uint8_t)(i % 7), 0, 0);
        ms_test_conn_send_batch(&c, handle, 100, e, (uint16_t)count);
        ms_test_answers ans;
        ms_test_answers_init(&ans, 100, (uint32_t)count);
        ms_test_answers_collect(&c, &ans);
        for (size_t i = 0; i < count; ++i) {
            size_t size;
            const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
            assert_non_null(stored);
            assert_int_equal(ans.error[i], 0);
            assert_int_equal(ans.start[i], 0);
            assert_int_equal(ans.end[i], size);
            assert_int_equal(ans.length[i], size);
            assert_memory_equal(ans.data[i], stored, size);
        }
        ms_test_answers_free(&ans);

        /* BYTES: a middle part and the last byte of each. */
        for (size_t i = 0; i < count; ++i) {
            size_t size;
            ms_archive_subtree(a, ids[i], &size);
            uint32_t from = (uint32_t)size / 3, length = (uint32_t)size / 2 ? (uint32_t)size / 2 : 1;
            e[2 * i] = subtree_entry(ids[i], MS_PROTO_UNIT_BYTES, 3, from, length);
            e[2 * i + 1] = subtree_entry(ids[i], MS_PROTO_UNIT_BYTES, 3, (uint32_t)size - 1, 1);
        }
        ms_test_conn_send_batch(&c, handle, 5000, e, (uint16_t)(2 * count));
        ms_test_answers_init(&ans, 5000, (uint32_t)(2 * count));
        ms_test_answers_collect(&c, &ans);
        for (size_t i = 0; i < count; ++i) {
            size_t size;
            const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
            for (int part = 0; part < 2; ++part) {
                size_t j = 2 * i + (size_t)part;
                assert_int_equal(ans.error[j], 0);
                assert_int_equal(ans.start[j], e[j].a);
                assert_int_equal(ans.end[j], e[j].a + e[j].b);
                assert_int_equal(ans.length[j], e[j].b);
                assert_memory_equal(ans.data[j], stored + e[j].a, e[j].b);
            }
        }
        ms_test_answers_free(&ans);

        /* The frames themselves: stream 2, the subtree id as cell_id. */
        size_t size;
        ms_archive_subtree(a, ids[count - 1], &size);
        e[0] = subtree_entry(ids[count - 1], MS_PROTO_UNIT_STEPS, 0, 0, 0);
        ms_test_conn_send_batch(&c, handle, 9000, e, 1);
        ms_proto_message m;
        do {
            assert_int_equal(ms_test_conn_recv(&c, &m, 5.0), 1);
            assert_int_equal(m.type, MS_PROTO_PAYLOAD);
            assert_int_equal(m.request_id, 9000);
            assert_int_equal(m.body.payload.stream, MS_PROTO_STREAM_INDEX);
            assert_int_equal(m.body.payload.cell_id, ids[count - 1]);
            assert_int_equal(m.body.payload.end, size);
        } while (!(m.flags & MS_PROTO_FLAG_LAST));

        /* Past the end. */
        uint64_t detail;
        assert_int_equal(single_error(&c, handle, 9100,
                                      subtree_entry(ids[0], MS_PROTO_UNIT_BYTES, 0,
                                                    (uint32_t)size + 1000, 1),
                                      &detail),
                         MS_PROTO_E_RANGE_NOT_SATISFIABLE);
        ms_archive_subtree(a, ids[0], &size);
        assert_int_equal(detail, size);
        free(e);
        free(ids);
        ms_test_conn_close(&c);
        ms_archive_close(a);
    }
}

/* Ids that are not subtree ids, even existing cells, are UNKNOWN_CELL with the
 * id as detail, each ending only its own entry; a subtree has step 0 only. */
static void test_unknown_subtree_ids(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "deep");
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    const uint32_t cells = ms_archive_get_header(a)->cell_count;
    uint32_t not_subtrees[4] = {1, cells - 1, cells, UINT32_MAX};
    for (size_t i = 0; i < count; ++i) /* 1 is in the root subtree; the last cell is a leaf */
        assert_true(ids[i] != 1 && ids[i] != cells - 1);
    ms_test_conn c;
    connect_v3(f, &c, TOKEN);
    uint32_t handle = ms_test_conn_open_model(&c, "deep", 1, NULL, NULL, NULL);
    for (size_t i = 0; i < 4; ++i) {
        uint64_t detail;
        assert_int_equal(single_error(&c, handle, (uint32_t)(10 + i),
                                      subtree_entry(not_subtrees[i], MS_PROTO_UNIT_STEPS, 0, 0, 0),
                                      &detail),
                         MS_PROTO_E_UNKNOWN_CELL);
        assert_int_equal(detail, not_subtrees[i]);
    }
    /* Mixed with good ones, only the bad entries end in an error. */
    ms_proto_cell_request e[3] = {subtree_entry(ids[1], MS_PROTO_UNIT_STEPS, 0, 0, 0),
                                  subtree_entry(1, MS_PROTO_UNIT_BYTES, 0, 0, 4),
                                  subtree_entry(ids[2], MS_PROTO_UNIT_STEPS, 0, 0, 0)};
    ms_test_conn_send_batch(&c, handle, 50, e, 3);
    ms_test_answers ans;
    ms_test_answers_init(&ans, 50, 3);
    ms_test_answers_collect(&c, &ans);
    assert_int_equal(ans.error[0], 0);
    assert_int_equal(ans.error[1], MS_PROTO_E_UNKNOWN_CELL);
    assert_int_equal(ans.error[2], 0);
    ms_test_answers_free(&ans);
    /* STEPS 0..1 of a subtree: out of range, the whole batch, not fatal. */
    uint8_t frame[12 + 8 + 16] = {0};
    frame[0] = 8 + 16, frame[4] = MS_PROTO_REQUEST_CELLS, frame[8] = 60;
    frame[12] = (uint8_t)handle, frame[16] = 1;
    frame[20] = (uint8_t)ids[1], frame[21] = (uint8_t)(ids[1] >> 8);
    frame[24] = MS_PROTO_STREAM_INDEX, frame[32] = 1; /* b = 1 */
    assert_int_equal(ms_test_conn_send_raw(&c, frame, sizeof frame), 0);
    uint32_t id;
    ms_proto_error_body body;
    assert_int_equal(ms_test_conn_expect_error(&c, &id, &body), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_int_equal(id, 60);
    assert_false(body.fatal);
    assert_int_equal(body.detail, 8 + 12);
    free(ids);
    ms_test_conn_close(&c);
    ms_archive_close(a);
}

/* Subtree requests are scheduled with the payloads: a better priority
 * overtakes 16 MiB of queued geometry; CANCEL and CLOSE_MODEL end them. */
static void test_subtree_priority_and_cancel(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "big");
    const uint32_t cells = ms_archive_get_header(a)->cell_count;
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    assert_true(count >= 2);
    ms_test_conn c;
    connect_v3(f, &c, NULL);
    uint32_t handle = ms_test_conn_open_model(&c, "big", 1, NULL, NULL, NULL);
    ms_proto_cell_request *geometry = calloc(cells, sizeof *geometry);
    ms_proto_cell_request *subtrees = calloc(count, sizeof *subtrees);
    for (uint32_t i = 0; i < cells; ++i)
        geometry[i] = (ms_proto_cell_request){i, MS_PROTO_STREAM_GEOMETRY, MS_PROTO_UNIT_STEPS,
                                              100, 0, MS_PROTO_MAX_STEP};

    /* Priority: subtrees at 0 after all the geometry at 100. */
    for (size_t i = 0; i < count; ++i)
        subtrees[i] = subtree_entry(ids[i], MS_PROTO_UNIT_STEPS, 0, 0, 0);
    send_two_batches(&c, handle, 1000, geometry, (uint16_t)cells, 5000, subtrees,
                     (uint16_t)count);
    ms_test_answers payloads, index;
    ms_test_answers_init(&payloads, 1000, cells);
    ms_test_answers_init(&index, 5000, (uint32_t)count);
    uint32_t payloads_done_when_index_done = UINT32_MAX;
    while (payloads.done < cells || index.done < count) {
        ms_proto_message m;
        assert_int_equal(ms_test_conn_recv(&c, &m, 10.0), 1);
        if (!ms_test_answers_take(&index, &m))
            assert_true(ms_test_answers_take(&payloads, &m));
        if (index.done == count && payloads_done_when_index_done == UINT32_MAX)
            payloads_done_when_index_done = payloads.done;
    }
    /* Both batches arrived in one write, before the first chunk went out:
     * every subtree before any geometry. */
    assert_int_equal(payloads_done_when_index_done, 0);
    for (size_t i = 0; i < count; ++i)
        assert_int_equal(index.error[i], 0);
    ms_test_answers_free(&payloads);
    ms_test_answers_free(&index);

    /* CANCEL: subtrees queued behind 16 MiB at priority 255 never start. */
    for (uint32_t i = 0; i < cells; ++i)
        geometry[i].priority = 0;
    for (size_t i = 0; i < count; ++i)
        subtrees[i].priority = 255;
    ms_test_conn_send_batch(&c, handle, 10000, geometry, (uint16_t)cells);
    ms_test_conn_send_batch(&c, handle, 20000, subtrees, (uint16_t)count);
    ms_proto_message cancel = {.type = MS_PROTO_CANCEL};
    ms_proto_id_range range = {20000, (uint32_t)count};
    cancel.body.cancel = (ms_proto_cancel){0, &range, 1};
    ms_test_conn_send(&c, &cancel);
    ms_test_answers_init(&payloads, 10000, cells);
    ms_test_answers_init(&index, 20000, (uint32_t)count);
    while (payloads.done < cells || index.done < count) {
        ms_proto_message m;
        assert_int_equal(ms_test_conn_recv(&c, &m, 10.0), 1);
        if (!ms_test_answers_take(&index, &m))
            assert_true(ms_test_answers_take(&payloads, &m));
    }
    for (size_t i = 0; i < count; ++i) {
        assert_int_equal(index.error[i], MS_PROTO_E_CANCELLED);
        assert_int_equal(index.length[i], 0);
    }
    for (uint32_t i = 0; i < cells; ++i)
        assert_int_equal(payloads.error[i], 0);
    ms_test_answers_free(&payloads);
    ms_test_answers_free(&index);

    /* CLOSE_MODEL ends the subtree requests outstanding on the handle. */
    ms_test_conn_send_batch(&c, handle, 30000, geometry, (uint16_t)cells);
    ms_test_conn_send_batch(&c, handle, 40000, subtrees, (uint16_t)count);
    ms_proto_message close_msg = {.type = MS_PROTO_CLOSE_MODEL};
    close_msg.body.close_model.model_handle = handle;
    ms_test_conn_send(&c, &close_msg);
    ms_test_answers_init(&payloads, 30000, cells);
    ms_test_answers_init(&index, 40000, (uint32_t)count);
    while (payloads.done < cells || index.done < count) {
        ms_proto_message m;
        assert_int_equal(ms_test_conn_recv(&c, &m, 10.0), 1);
        if (!ms_test_answers_take(&index, &m))
            assert_true(ms_test_answers_take(&payloads, &m));
    }
    for (size_t i = 0; i < count; ++i)
        assert_int_equal(index.error[i], MS_PROTO_E_CANCELLED);
    ms_test_answers_free(&payloads);
    ms_test_answers_free(&index);
    free(geometry);
    free(subtrees);
    free(ids);
    ms_test_conn_close(&c);
    ms_archive_close(a);
}

/* A preview connection (no token) reads every subtree, and still no geometry
 * beyond the preview, by either door. */
static void test_preview_reads_subtrees_only(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "deep");
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    ms_test_conn c;
    connect_v3(f, &c, NULL);
    ms_proto_model_opened o;
    uint32_t handle = ms_test_conn_open_model(&c, "deep", 1, &o, NULL, NULL);
    assert_int_equal(o.permitted_geometry_steps, DEEP_PUBLIC_BITS + 1);
    assert_true(o.permitted_geometry_steps < o.geometry_steps);
    ms_proto_cell_request *e = calloc(count, sizeof *e);
    for (size_t i = 0; i < count; ++i)
        e[i] = subtree_entry(ids[i], MS_PROTO_UNIT_STEPS, 0, 0, 0);
    ms_test_conn_send_batch(&c, handle, 100, e, (uint16_t)count);
    ms_test_answers ans;
    ms_test_answers_init(&ans, 100, (uint32_t)count);
    ms_test_answers_collect(&c, &ans);
    for (size_t i = 0; i < count; ++i) {
        size_t size;
        const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
        assert_int_equal(ans.error[i], 0);
        assert_int_equal(ans.length[i], size);
        assert_memory_equal(ans.data[i], stored, size);
    }
    ms_test_answers_free(&ans);
    uint64_t detail;
    ms_proto_cell_request full = {0, MS_PROTO_STREAM_GEOMETRY, MS_PROTO_UNIT_STEPS, 0, 0,
                                  MS_PROTO_MAX_STEP};
    assert_int_equal(single_error(&c, handle, 500, full, &detail), MS_PROTO_E_FORBIDDEN);
    assert_int_equal(detail, DEEP_PUBLIC_BITS + 1);
    ms_test_conn_close(&c);

    /* HTTP without a token: the subtrees, not the full geometry. */
    char path[128];
    ms_test_http_response r;
    for (size_t i = 0; i < count; ++i) {
        snprintf(path, sizeof path, "/models/deep/subtrees/%u", ids[i]);
        assert_int_equal(ms_test_http_get(f->http_port, path, NULL, &r), 0);
        assert_int_equal(r.status, 200);
        size_t size;
        const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
        assert_int_equal(r.body_length, size);
        assert_memory_equal(r.body, stored, size);
        ms_test_http_free(&r);
    }
    /* A cell whose geometry goes beyond the preview: its full precision is 403. */
    uint32_t fine = 0;
    const uint32_t cells = ms_archive_get_header(a)->cell_count;
    while (fine < cells && ms_archive_get_cell(a, fine)->bits_max <= DEEP_PUBLIC_BITS)
        ++fine;
    assert_true(fine < cells);
    snprintf(path, sizeof path, "/models/deep/cells/%u/geometry?bits=12", fine);
    assert_int_equal(ms_test_http_get(f->http_port, path, NULL, &r), 0);
    assert_int_equal(r.status, 403);
    ms_test_http_free(&r);
    assert_int_equal(ms_test_http_get(f->http_port, path, "Authorization: Bearer " TOKEN "\r\n",
                                      &r),
                     0);
    assert_int_equal(r.status, 200);
    ms_test_http_free(&r);
    free(e);
    free(ids);
    ms_archive_close(a);
}

/* --- HTTP side door ------------------------------------------------------------ */

static void expect_status(const fixture *f, const char *path, const char *headers, int status)
{
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, path, headers, &r), 0);
    if (r.status != status)
        fail_msg("%s: %d, expected %d", path, r.status, status);
    ms_test_http_free(&r);
}

static void test_http_head_and_subtrees(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "deep");
    size_t head_size;
    const uint8_t *head = ms_archive_index_head(a, &head_size);
    ms_test_conn c;
    connect_v3(f, &c, NULL);
    ms_proto_model_opened o;
    ms_test_conn_open_model(&c, "deep", 1, &o, NULL, NULL);
    ms_test_conn_close(&c);

    /* The head: the binary door's bytes, public, with an ETag from the content id. */
    ms_test_http_response r;
    char value[256], etag[64];
    assert_int_equal(ms_test_http_get(f->http_port, "/models/deep/head", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, head_size);
    assert_memory_equal(r.body, head, head_size);
    snprintf(etag, sizeof etag, "\"%016llx-head\"", (unsigned long long)o.content_id);
    assert_string_equal(ms_test_http_header(&r, "ETag", value, sizeof value), etag);
    assert_string_equal(ms_test_http_header(&r, "Content-Type", value, sizeof value),
                        "application/octet-stream");
    assert_string_equal(ms_test_http_header(&r, "Cache-Control", value, sizeof value),
                        "public, max-age=3600");
    assert_string_equal(ms_test_http_header(&r, "Accept-Ranges", value, sizeof value), "bytes");
    ms_test_http_free(&r);
    char headers[256];
    snprintf(headers, sizeof headers, "If-None-Match: %s\r\n", etag);
    expect_status(f, "/models/deep/head", headers, 304);
    /* A token changes nothing: still public. */
    assert_int_equal(ms_test_http_get(f->http_port, "/models/deep/head",
                                      "Authorization: Bearer " TOKEN "\r\n", &r),
                     0);
    assert_int_equal(r.status, 200);
    assert_memory_equal(r.body, head, head_size);
    assert_string_equal(ms_test_http_header(&r, "Cache-Control", value, sizeof value),
                        "public, max-age=3600");
    ms_test_http_free(&r);
    /* Range on the head. */
    assert_int_equal(ms_test_http_get(f->http_port, "/models/deep/head", "Range: bytes=5-24\r\n", &r),
                     0);
    assert_int_equal(r.status, 206);
    assert_int_equal(r.body_length, 20);
    assert_memory_equal(r.body, head + 5, 20);
    char want_range[64];
    snprintf(want_range, sizeof want_range, "bytes 5-24/%zu", head_size);
    assert_string_equal(ms_test_http_header(&r, "Content-Range", value, sizeof value), want_range);
    ms_test_http_free(&r);
    snprintf(headers, sizeof headers, "Range: bytes=%zu-\r\n", head_size);
    expect_status(f, "/models/deep/head", headers, 416);
    /* HEAD: the length, no body. */
    const char *head_request = "HEAD /models/deep/head HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n";
    assert_int_equal(ms_test_http_raw(f->http_port, head_request, strlen(head_request), &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, 0);
    assert_int_equal(strtoull(ms_test_http_header(&r, "Content-Length", value, sizeof value), NULL,
                              10),
                     head_size);
    ms_test_http_free(&r);

    /* Every subtree, whole and by Range, each with its own ETag. */
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    char path[128], previous_etag[64] = "";
    for (size_t i = 0; i < count; ++i) {
        size_t size;
        const uint8_t *stored = ms_archive_subtree(a, ids[i], &size);
        snprintf(path, sizeof path, "/models/deep/subtrees/%u", ids[i]);
        assert_int_equal(ms_test_http_get(f->http_port, path, NULL, &r), 0);
        assert_int_equal(r.status, 200);
        assert_int_equal(r.body_length, size);
        assert_memory_equal(r.body, stored, size);
        snprintf(etag, sizeof etag, "\"%016llx-subtree-%u\"", (unsigned long long)o.content_id,
                 ids[i]);
        assert_string_equal(ms_test_http_header(&r, "ETag", value, sizeof value), etag);
        assert_string_not_equal(etag, previous_etag);
        snprintf(previous_etag, sizeof previous_etag, "%s", etag);
        ms_test_http_free(&r);
        assert_int_equal(ms_test_http_get(f->http_port, path, "Range: bytes=-10\r\n", &r), 0);
        assert_int_equal(r.status, 206);
        assert_int_equal(r.body_length, size < 10 ? size : 10);
        assert_memory_equal(r.body, stored + size - r.body_length, r.body_length);
        ms_test_http_free(&r);
        snprintf(headers, sizeof headers, "If-None-Match: %s\r\n", etag);
        expect_status(f, path, headers, 304);
        snprintf(headers, sizeof headers, "Range: bytes=%zu-\r\n", size);
        expect_status(f, path, headers, 416);
    }
    /* Not subtrees. */
    expect_status(f, "/models/deep/subtrees/1", NULL, 404);
    snprintf(path, sizeof path, "/models/deep/subtrees/%u", MS_TEST_DEEP_ARCHIVE_CELLS - 1);
    expect_status(f, path, NULL, 404);
    expect_status(f, "/models/deep/subtrees/4294967295", NULL, 404);
    expect_status(f, "/models/deep/subtrees/4294967296", NULL, 404);
    expect_status(f, "/models/deep/subtrees/x1", NULL, 404);
    expect_status(f, "/models/deep/subtrees/-1", NULL, 404);
    expect_status(f, "/models/deep/subtrees", NULL, 400); /* the subtrees route, without its list */
    expect_status(f, "/models/deep/subtrees/0/more", NULL, 404);
    expect_status(f, "/models/nosuch/head", NULL, 404);
    expect_status(f, "/models/nosuch/subtrees/0", NULL, 404);
    free(ids);
    ms_archive_close(a);
}

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

/* The subtrees route (docs/BROWSER.md, "The subtrees route"): several
 * subtrees in one answer, each the single route's bytes, an id that is no
 * subtree named per entry with no bytes, public whatever the token; a list
 * that is not one refused whole. */
static void test_http_subtrees_route(void **state)
{
    fixture *f = *state;
    ms_archive *a = open_archive(f, "deep");
    uint32_t *ids;
    size_t count;
    subtree_ids(a, &ids, &count);
    assert_true(count > 3);
    char path[2048];
    ms_test_http_response r;
    for (int with_token = 0; with_token < 2; ++with_token)
        for (size_t first = 0; first < count; first += 60) {
            /* up to 60 subtrees, then three ids that are none, one of them a cell's */
            size_t n = count - first < 60 ? count - first : 60;
            int at = snprintf(path, sizeof path, "/models/deep/subtrees?ids=");
            for (size_t i = 0; i < n; ++i)
                at += snprintf(path + at, sizeof path - (size_t)at, "%u,", ids[first + i]);
            snprintf(path + at, sizeof path - (size_t)at, "1,%u,4294967295", MS_TEST_DEEP_ARCHIVE_CELLS - 1);
            assert_int_equal(ms_test_http_get(f->http_port, path, with_token ? "Authorization: Bearer " TOKEN "\r\n" : NULL,
                                              &r), 0);
            assert_int_equal(r.status, 200);
            char value[64];
            assert_string_equal(ms_test_http_header(&r, "Cache-Control", value, sizeof value), "public, max-age=3600");
            assert_memory_equal(r.body, "MSS1", 4);
            assert_int_equal(le32(r.body + 4), n + 3);
            size_t pos = 8;
            for (size_t i = 0; i < n + 3; ++i) {
                assert_true(pos + 12 <= r.body_length);
                const uint8_t *e = r.body + pos;
                uint32_t id = le32(e), status = (uint32_t)e[4] | (uint32_t)e[5] << 8, length = le32(e + 8);
                assert_int_equal(e[6] | e[7], 0);
                pos += 12;
                assert_true(length <= r.body_length - pos);
                if (i < n) {
                    size_t size;
                    const uint8_t *stored = ms_archive_subtree(a, ids[first + i], &size);
                    assert_int_equal(id, ids[first + i]);
                    assert_int_equal(status, 200);
                    assert_int_equal(length, size);
                    assert_memory_equal(r.body + pos, stored, size);
                } else {
                    assert_int_equal(status, 404);
                    assert_int_equal(length, 0);
                }
                pos += length;
            }
            assert_int_equal(pos, r.body_length);
            ms_test_http_free(&r);
        }
    /* lists that are not one: refused whole, with one line */
    char many[1024] = "/models/deep/subtrees?ids=0";
    for (int k = 0; k < 64; ++k)
        strcat(many, ",0");
    const char *bad[] = {"/models/deep/subtrees?ids=", "/models/deep/subtrees?ids=0,,1", "/models/deep/subtrees?ids=x",
                         "/models/deep/subtrees?ids=0.1", "/models/deep/subtrees?ids=4294967296",
                         "/models/deep/subtrees?ids=0,", "/models/deep/subtrees?id=0", many};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        assert_int_equal(ms_test_http_get(f->http_port, bad[i], NULL, &r), 0);
        if (r.status != 400)
            fail_msg("%s: %d, expected 400", bad[i], r.status);
        assert_non_null(strstr((const char *)r.body, "ids= wants subtree ids"));
        ms_test_http_free(&r);
    }
    expect_status(f, "/models/nosuch/subtrees?ids=0", NULL, 404);
    free(ids);
    ms_archive_close(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_head_is_root_subtree),
        cmocka_unit_test(test_older_clients_get_whole_index),
        cmocka_unit_test(test_every_subtree_by_steps_and_bytes),
        cmocka_unit_test(test_unknown_subtree_ids),
        cmocka_unit_test(test_subtree_priority_and_cancel),
        cmocka_unit_test(test_preview_reads_subtrees_only),
        cmocka_unit_test(test_http_head_and_subtrees),
        cmocka_unit_test(test_http_subtrees_route),
    };
    return cmocka_run_group_tests(tests, start_server, stop_server);
}
