/* A model's documents through both doors (PROTOCOL.md 4.5b, docs/DEPLOY.md):
 * the thumbnail, the metadata and the annotations read by the binary door's
 * GET_DOCUMENT (through the client library: ms_client_fetch_document and
 * ms_client_fetch_document_at) and by the HTTP door's /models/NAME/thumbnail,
 * /metadata and /annotations are the same bytes, the file's where there is
 * one; a thumbnail finer than the public preview is refused by both; an absent
 * document, an unknown model and an oversized sidecar get one line each; bad
 * kinds, bad names, a version-2 connection and a truncated frame get the
 * protocol's errors and the server keeps serving; no archive is opened. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <event2/event.h>
#include <jansson.h>

#include "ms_catalog.h"
#include "ms_client.h"
#include "ms_test.h"
#include "ms_test_net.h"
#include "ms_test_proto.h"

typedef struct fixture {
    char dir[512], archives[600];
    pid_t pid;
    uint16_t port, http;
    uint8_t *notes; /* full's annotations */
    size_t notes_size;
} fixture;

static void bake(const char *bake_bin, const char *ply, const char *archives, const char *args)
{
    char cmd[16384], out[4096];
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --threads 2 %s", bake_bin, ply, archives, args);
    if (ms_test_run(cmd, out, sizeof out) != 0)
        fail_msg("%s: %s", cmd, out);
}

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    assert_int_equal(mkdir(f->archives, 0755), 0);
    char ply[700], gen[4096], bake_bin[4096], cmd[9000], out[4096], path[800];
    snprintf(ply, sizeof ply, "%s/demo.ply", f->dir);
    ms_test_bin_path(gen, sizeof gen, "meshgen");
    ms_test_bin_path(bake_bin, sizeof bake_bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s -o '%s' --triangles 20000", gen, ply);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    bake(bake_bin, ply, f->archives, "--name full");
    bake(bake_bin, ply, f->archives, "--name shown --public-bits 7");
    snprintf(path, sizeof path, "%s/meta.json", f->dir);
    const char *meta = "{\"title\": \"<img src=x onerror=alert(1)>\", \"creator\": \"A. "
                       "Canova\", \"description\": \"Carrara marble, \\u00e9t\\u00e9 1998\"}";
    ms_test_write_file(path, meta, strlen(meta));
    char args[900];
    snprintf(args, sizeof args, "--name withheld --public-bits 6 --metadata '%s'", path);
    bake(bake_bin, ply, f->archives, args);
    /* a preview coarser than the picture (a hand edit): the picture is withheld */
    ms_catalog c;
    ms_error err;
    assert_int_equal(ms_catalog_load(f->archives, &c, &err), MS_OK);
    ms_catalog_entry e = *ms_catalog_find(&c, "withheld");
    assert_true(e.thumbnail_bits >= 2);
    e.public_max_bits = (uint8_t)(e.thumbnail_bits - 1);
    assert_int_equal(ms_catalog_update(f->archives, &e, &err), MS_OK);
    ms_catalog_free(&c);
    /* annotations: full's over several frames (200 kB), shown's above 1 MiB,
     * withheld has none */
    f->notes_size = 200000;
    f->notes = malloc(f->notes_size);
    memcpy(f->notes, "{\"notes\": \"", 11);
    for (size_t i = 11; i < f->notes_size - 2; ++i)
        f->notes[i] = (uint8_t)('a' + i % 26);
    memcpy(f->notes + f->notes_size - 2, "\"}", 2);
    snprintf(path, sizeof path, "%s/full.annotations.json", f->archives);
    ms_test_write_file(path, f->notes, f->notes_size);
    size_t big = (1u << 20) + 1;
    char *huge = malloc(big);
    memset(huge, ' ', big);
    snprintf(path, sizeof path, "%s/shown.annotations.json", f->archives);
    ms_test_write_file(path, huge, big);
    free(huge);

    char port_file[700], log[700];
    snprintf(port_file, sizeof port_file, "%s/ports", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    f->pid = ms_test_meshserve_start(f->archives, NULL, 0, port_file, log, &f->port, &f->http);
    assert_true(f->pid > 0);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    if (f->pid > 0)
        assert_int_equal(ms_test_stop(f->pid, SIGTERM, 10.0), 0);
    ms_test_rmdir(f->dir);
    free(f->notes);
    free(f);
    return 0;
}

static ms_client_options options_of(const fixture *f, uint32_t max_frame)
{
    return (ms_client_options){.host = "127.0.0.1", .port = f->port, .agent = "test_documents",
                               .max_frame = max_frame};
}

/* GET path: the status and, with want_type, the Content-Type asserted. */
static void get(const fixture *f, const char *path, int status, const char *want_type,
                ms_test_http_response *r)
{
    assert_int_equal(ms_test_http_get(f->http, path, NULL, r), 0);
    if (r->status != status)
        fail_msg("GET %s: status %d, expected %d: %s", path, r->status, status, (char *)r->body);
    char value[128];
    if (want_type)
        assert_string_equal(ms_test_http_header(r, "Content-Type", value, sizeof value), want_type);
}

/* The binary door's document (one connection of its own) against the HTTP
 * door's and, where given, the file's bytes. */
static void same_both_doors(const fixture *f, const char *model, int kind, const char *path,
                            const char *type, const uint8_t *file, size_t file_size)
{
    ms_client_options o = options_of(f, 0);
    uint8_t *bytes;
    size_t length;
    ms_error err;
    if (ms_client_fetch_document_at(&o, 10.0, model, kind, &bytes, &length, &err) != MS_OK)
        fail_msg("%s of %s: %s", ms_document_kind_name(kind), model, err.text);
    ms_test_http_response r;
    get(f, path, 200, type, &r);
    assert_int_equal(r.body_length, length);
    assert_memory_equal(r.body, bytes, length);
    if (file) {
        assert_int_equal(length, file_size);
        assert_memory_equal(bytes, file, file_size);
    }
    ms_test_http_free(&r);
    free(bytes);
}

/* A refusal through both doors: the binary door's one line and the HTTP
 * door's status and line. */
static void refused_both_doors(const fixture *f, const char *model, int kind, const char *path,
                               const char *binary_line, int status, const char *http_line)
{
    ms_client_options o = options_of(f, 0);
    uint8_t *bytes = (uint8_t *)"x";
    size_t length = 7;
    ms_error err;
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, model, kind, &bytes, &length, &err),
                     MS_ERR_IO);
    assert_null(bytes);
    assert_int_equal(length, 0);
    assert_string_equal(err.text, binary_line);
    ms_test_http_response r;
    get(f, path, status, NULL, &r);
    assert_string_equal((char *)r.body, http_line);
    ms_test_http_free(&r);
}

static void test_both_doors_agree(void **state)
{
    fixture *f = *state;
    char path[800];
    size_t size;
    snprintf(path, sizeof path, "%s/full.thumb.png", f->archives);
    unsigned char *png = ms_test_read_file(path, &size);
    assert_true(size > 1000);
    same_both_doors(f, "full", MS_DOCUMENT_THUMBNAIL, "/models/full/thumbnail", "image/png", png,
                    size);
    free(png);
    same_both_doors(f, "shown", MS_DOCUMENT_THUMBNAIL, "/models/shown/thumbnail", "image/png",
                    NULL, 0);
    same_both_doors(f, "full", MS_DOCUMENT_ANNOTATIONS, "/models/full/annotations",
                    "application/json", f->notes, f->notes_size);
    same_both_doors(f, "withheld", MS_DOCUMENT_METADATA, "/models/withheld/metadata",
                    "application/json", NULL, 0);
    same_both_doors(f, "full", MS_DOCUMENT_METADATA, "/models/full/metadata", "application/json",
                    NULL, 0);

    /* the metadata is the object /catalog lists for the model */
    ms_client_options o = options_of(f, 0);
    uint8_t *bytes;
    size_t length;
    ms_error err;
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "withheld", MS_DOCUMENT_METADATA,
                                                 &bytes, &length, &err),
                     MS_OK);
    json_error_t jerr;
    json_t *meta = json_loadb((const char *)bytes, length, 0, &jerr);
    free(bytes);
    assert_non_null(meta);
    assert_string_equal(json_string_value(json_object_get(meta, "title")),
                        "<img src=x onerror=alert(1)>");
    assert_string_equal(json_string_value(json_object_get(meta, "creator")), "A. Canova");
    assert_string_equal(json_string_value(json_object_get(meta, "description")),
                        "Carrara marble, \xc3\xa9t\xc3\xa9 1998");
    assert_true(json_is_false(json_object_get(meta, "thumbnail")));
    ms_test_http_response r;
    get(f, "/catalog?q=withheld", 200, "application/json", &r);
    json_t *page = json_loads((char *)r.body, 0, &jerr);
    ms_test_http_free(&r);
    assert_non_null(page);
    assert_true(json_equal(meta, json_array_get(json_object_get(page, "models"), 0)));
    json_decref(page);
    json_decref(meta);

    uint64_t open_models = 99;
    assert_int_equal(ms_test_metric(f->http, "meshstream_open_models", &open_models), 0);
    assert_int_equal(open_models, 0); /* documents open no archive */
}

static void test_refusals(void **state)
{
    fixture *f = *state;
    /* the preview rule: a picture finer than the public preview, for nobody */
    refused_both_doors(f, "withheld", MS_DOCUMENT_THUMBNAIL, "/models/withheld/thumbnail",
                       "document 'thumbnail' of withheld: NO_DOCUMENT no thumbnail for this model",
                       404, "error: no thumbnail for this model\n");
    refused_both_doors(f, "withheld", MS_DOCUMENT_ANNOTATIONS, "/models/withheld/annotations",
                       "document 'annotations' of withheld: NO_DOCUMENT no annotations for this "
                       "model",
                       404, "error: no annotations for this model\n");
    refused_both_doors(f, "nope", MS_DOCUMENT_METADATA, "/models/nope/metadata",
                       "document 'metadata' of nope: UNKNOWN_MODEL no such model", 404,
                       "error: no such model\n");
    refused_both_doors(f, "shown", MS_DOCUMENT_ANNOTATIONS, "/models/shown/annotations",
                       "document 'annotations' of shown: INTERNAL the model's annotations.json "
                       "file is above 1048576 bytes",
                       500, "error: the model's annotations.json file is above 1048576 bytes\n");
    ms_test_http_response r;
    get(f, "/models/..%2Ffull/annotations", 404, NULL, &r);
    ms_test_http_free(&r);
    /* the client refuses what it cannot send */
    ms_client_options o = options_of(f, 0);
    uint8_t *bytes;
    size_t length;
    ms_error err;
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "full", 0, &bytes, &length, &err),
                     MS_ERR_ARG);
    assert_string_equal(err.text, "document kind 0 undefined (1..3)");
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "../full", MS_DOCUMENT_METADATA,
                                                 &bytes, &length, &err),
                     MS_ERR_ARG);
    assert_string_equal(err.text, "'../full' is not a model name");
}

/* Several documents on one connection, in frames of a small max_frame. */
static void test_one_connection(void **state)
{
    fixture *f = *state;
    struct event_base *base = event_base_new();
    ms_client_options o = options_of(f, MS_PROTO_MIN_FRAME);
    static const ms_client_handlers none = {0};
    ms_client *client;
    ms_error err;
    assert_int_equal(ms_client_connect(base, &o, &none, NULL, &client, &err), MS_OK);
    for (int round = 0; round < 2; ++round) {
        uint8_t *bytes;
        size_t length;
        assert_int_equal(ms_client_fetch_document(client, "full", MS_DOCUMENT_ANNOTATIONS, &bytes,
                                                  &length, &err),
                         MS_OK);
        assert_int_equal(length, f->notes_size);
        assert_memory_equal(bytes, f->notes, length);
        free(bytes);
        assert_int_equal(ms_client_fetch_document(client, "withheld", MS_DOCUMENT_THUMBNAIL,
                                                  &bytes, &length, &err),
                         MS_ERR_IO);
        assert_null(bytes);
        assert_int_equal(ms_client_fetch_document(client, "full", MS_DOCUMENT_THUMBNAIL, &bytes,
                                                  &length, &err),
                         MS_OK);
        assert_true(length > 1000);
        assert_memory_equal(bytes, "\x89PNG", 4);
        free(bytes);
    }
    ms_client_free(client);
    event_base_free(base);
}

/* Raw frames: the protocol's errors, each ending its request only, and the
 * server serving on. */
static void test_hostile_requests(void **state)
{
    fixture *f = *state;
    ms_test_conn conn;
    ms_proto_hello_reply reply;
    assert_int_equal(ms_test_conn_open(&conn, f->port), 0);
    ms_test_conn_hello_with(&conn, NULL, 3, MS_PROTO_CAP_APO, &reply);
    assert_int_equal(reply.version, 3);
    uint8_t frame[64] = {0};
    /* kind 9 */
    frame[0] = 8, frame[4] = MS_PROTO_GET_DOCUMENT, frame[8] = 5;
    frame[12] = 9, frame[13] = 4;
    memcpy(frame + 16, "full", 4);
    assert_int_equal(ms_test_conn_send_raw(&conn, frame, 20), 0);
    uint32_t id;
    ms_proto_error_body e;
    assert_int_equal(ms_test_conn_expect_error(&conn, &id, &e), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_int_equal(id, 5);
    assert_false(e.fatal);
    /* a name with a slash */
    frame[8] = 6, frame[12] = MS_DOCUMENT_METADATA;
    memcpy(frame + 16, "fu/l", 4);
    assert_int_equal(ms_test_conn_send_raw(&conn, frame, 20), 0);
    assert_int_equal(ms_test_conn_expect_error(&conn, &id, &e), MS_PROTO_E_BAD_MODEL_NAME);
    assert_int_equal(id, 6);
    assert_false(e.fatal);
    /* still serving this connection */
    ms_proto_message m = {.type = MS_PROTO_GET_DOCUMENT, .request_id = 7};
    m.body.get_document = (ms_proto_get_document){MS_DOCUMENT_METADATA, "full", 4};
    ms_test_conn_send(&conn, &m);
    ms_proto_message got;
    assert_int_equal(ms_test_conn_recv(&conn, &got, 5.0), 1);
    assert_int_equal(got.type, MS_PROTO_DOCUMENT);
    assert_int_equal(got.request_id, 7);
    assert_int_equal(got.flags, MS_PROTO_FLAG_LAST);
    assert_int_equal(got.body.document.kind, MS_DOCUMENT_METADATA);
    assert_int_equal(got.body.document.offset, 0);
    assert_int_equal(got.body.document.data_length, got.body.document.total_length);
    assert_memory_equal(got.body.document.data, "{\"apo\":", 7);
    /* a truncated frame, then the end of the stream */
    frame[8] = 8, frame[12] = MS_DOCUMENT_THUMBNAIL;
    memcpy(frame + 16, "full", 4);
    assert_int_equal(ms_test_conn_send_raw(&conn, frame, 17), 0);
    ms_test_conn_close(&conn);

    /* version 2 has no documents: FIELD_OUT_OF_RANGE, not fatal */
    assert_int_equal(ms_test_conn_open(&conn, f->port), 0);
    ms_test_conn_hello_with(&conn, NULL, 2, MS_PROTO_CAP_APO, &reply);
    assert_int_equal(reply.version, 2);
    m.request_id = 1;
    ms_test_conn_send(&conn, &m);
    assert_int_equal(ms_test_conn_expect_error(&conn, &id, &e), MS_PROTO_E_FIELD_OUT_OF_RANGE);
    assert_int_equal(id, 1);
    assert_false(e.fatal);
    const char *want = "GET_DOCUMENT: a document needs version 3 (version 2)";
    assert_int_equal(e.text_length, strlen(want));
    assert_memory_equal(e.text, want, e.text_length);
    ms_test_conn_close(&conn);

    /* the server kept serving */
    ms_client_options o = options_of(f, 0);
    uint8_t *bytes;
    size_t length;
    ms_error err;
    assert_int_equal(ms_client_fetch_document_at(&o, 10.0, "full", MS_DOCUMENT_THUMBNAIL, &bytes,
                                                 &length, &err),
                     MS_OK);
    free(bytes);
    ms_test_http_response r;
    get(f, "/healthz", 200, NULL, &r);
    ms_test_http_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_both_doors_agree),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_one_connection),
        cmocka_unit_test(test_hostile_requests),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
