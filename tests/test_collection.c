/* An archive directory served as a collection (issue 20, item 4): 20 small
 * models, `meshbake --list` (the catalogue, every archive's checksums), and
 * models added, replaced (written aside, renamed over) and removed
 * (`meshbake --remove`) while meshserve serves the directory, each applied by
 * SIGHUP: an unchanged model is untouched (same content id, same ETag, its open
 * handle goes on and hears nothing), a replaced one opens with a new content
 * id and its new bytes, a removed one answers UNKNOWN_MODEL and 404; a
 * connection holding a replaced or removed model gets ERROR MODEL_CHANGED for
 * that handle (test_client_core: a core streaming it stops with
 * stats.model_changed; meshload then streams the new version).
 * Also the operations side (item 5): the access log (one JSON line per binary
 * connection and per HTTP answer), its reopening on SIGHUP, and /metrics
 * counters per model.
 * Runs from the repository root; needs meshserve and meshbake. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_archive.h"
#include "ms_proto.h"
#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_test_net.h"
#include "ms_test_proto.h"

#define MODELS 20

typedef struct fixture {
    char dir[512], archives[600], log[600], port_file[600];
    pid_t pid;
    uint16_t port, http_port;
} fixture;

static void model_name(char *out, size_t size, int i) { snprintf(out, size, "m%02d", i); }

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    snprintf(f->log, sizeof f->log, "%s/meshserve.log", f->dir);
    snprintf(f->port_file, sizeof f->port_file, "%s/ports", f->dir);
    if (mkdir(f->archives, 0755) != 0)
        return -1;
    for (int i = 0; i < MODELS; ++i) {
        char name[16];
        model_name(name, sizeof name, i);
        ms_test_add_model(f->archives, name, (uint32_t)i + 1, i % 4 == 0 ? 8 : 12);
    }
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    if (f->pid > 0)
        ms_test_stop(f->pid, SIGTERM, 15.0);
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* --list: every model, its figures and checksums; one damaged byte fails it. */
static void test_list_checks_every_archive(void **state)
{
    fixture *f = *state;
    char bin[512], cmd[1400];
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s --list %s --json", bin, f->archives);
    json_t *j = ms_test_run_json(cmd, 0);
    assert_int_equal(json_integer_value(json_object_get(j, "count")), MODELS);
    assert_int_equal(json_integer_value(json_object_get(j, "failed")), 0);
    json_t *models = json_object_get(j, "models");
    assert_int_equal(json_array_size(models), MODELS);
    for (int i = 0; i < MODELS; ++i) {
        json_t *m = json_array_get(models, (size_t)i);
        char name[16], path[700];
        model_name(name, sizeof name, i);
        assert_string_equal(json_string_value(json_object_get(m, "name")), name);
        assert_true(json_is_true(json_object_get(m, "ok")));
        assert_int_equal(json_integer_value(json_object_get(m, "cells")), MS_TEST_ARCHIVE_CELLS);
        assert_int_equal(json_integer_value(json_object_get(m, "public_bits")), i % 4 == 0 ? 8 : 12);
        snprintf(path, sizeof path, "%s/%s.msa", f->archives, name);
        struct stat st;
        assert_int_equal(stat(path, &st), 0);
        assert_int_equal(json_integer_value(json_object_get(m, "bytes")), st.st_size);
    }
    json_decref(j);

    /* the table form names each model */
    static char out[1 << 16];
    snprintf(cmd, sizeof cmd, "%s --list %s", bin, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "m19 "));
    assert_non_null(strstr(out, "8/12"));

    /* one payload byte of m07 flipped (in a copy of the directory) */
    char copy[700];
    snprintf(copy, sizeof copy, "%s/damaged", f->dir);
    snprintf(cmd, sizeof cmd, "cp -r %s %s", f->archives, copy);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    char victim[800];
    snprintf(victim, sizeof victim, "%s/m07.msa", copy);
    size_t size;
    uint8_t *bytes = ms_test_read_file(victim, &size);
    bytes[size - 10] ^= 0x40; /* the payload area ends the file */
    ms_test_write_file(victim, bytes, size);
    free(bytes);
    snprintf(cmd, sizeof cmd, "%s --list %s --json", bin, copy);
    j = ms_test_run_json(cmd, 1);
    assert_int_equal(json_integer_value(json_object_get(j, "failed")), 1);
    json_t *m07 = json_array_get(json_object_get(j, "models"), 7);
    assert_false(json_is_true(json_object_get(m07, "ok")));
    assert_non_null(strstr(json_string_value(json_object_get(m07, "error")), "checksum mismatch"));
    json_decref(j);

    /* usage errors */
    snprintf(cmd, sizeof cmd, "%s --list", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    snprintf(cmd, sizeof cmd, "%s --remove m01", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--remove needs -o ARCHIVE_DIR"));
}

typedef struct model_view {
    uint32_t handle;
    uint64_t content_id;
    uint16_t error;
} model_view;

static model_view open_model(ms_test_conn *c, const char *name, uint32_t id)
{
    model_view v = {0, 0, 0};
    ms_proto_model_opened opened;
    uint8_t *index = NULL;
    v.handle = ms_test_conn_open_model(c, name, id, &opened, &index, &v.error);
    if (v.handle)
        v.content_id = opened.content_id;
    free(index);
    return v;
}

/* The first cell's geometry over the side door: status, body, ETag. */
static int cell_answer(const fixture *f, const char *name, uint8_t **body, size_t *length,
                       char *etag, size_t etag_size)
{
    char path[128];
    snprintf(path, sizeof path, "/models/%s/cells/0/geometry", name);
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, path, NULL, &r), 0);
    int status = r.status;
    if (etag)
        ms_test_http_header(&r, "ETag", etag, etag_size);
    if (body) {
        *body = r.body;
        *length = r.body_length;
        r.body = NULL;
    }
    ms_test_http_free(&r);
    return status;
}

static void rescan(const fixture *f, const char *name_expected, bool present)
{
    assert_int_equal(kill(f->pid, SIGHUP), 0);
    /* the rescan is done when the catalogue says so */
    for (int tries = 0; tries < 200; ++tries) {
        ms_test_http_response r;
        assert_int_equal(ms_test_http_get(f->http_port, "/catalog", NULL, &r), 0);
        char quoted[80];
        snprintf(quoted, sizeof quoted, "\"%s\"", name_expected);
        bool there = r.body && strstr((const char *)r.body, quoted);
        ms_test_http_free(&r);
        if (there == present)
            return;
        usleep(25000);
    }
    fail_msg("the rescan did not apply (%s %s)", name_expected, present ? "added" : "removed");
}

/* Add, replace, remove while serving; each applied by SIGHUP. */
static void test_add_replace_remove_while_serving(void **state)
{
    fixture *f = *state;
    f->pid = ms_test_meshserve_start(f->archives, NULL, 0, f->port_file, f->log, &f->port,
                                     &f->http_port);
    assert_true(f->pid != 0);

    ms_test_conn c;
    assert_int_equal(ms_test_conn_open(&c, f->port), 0);
    ms_test_conn_hello(&c, NULL, NULL);
    model_view unchanged = open_model(&c, "m03", 1), replaced = open_model(&c, "m05", 2),
               removed = open_model(&c, "m09", 3);
    assert_true(unchanged.handle && replaced.handle && removed.handle);
    char etag_before[128], etag[128];
    uint8_t *before;
    size_t before_length;
    assert_int_equal(cell_answer(f, "m03", &before, &before_length, etag_before, sizeof etag_before), 200);

    /* add: written into the directory (file, then catalogue entry) */
    ms_test_add_model(f->archives, "m20", 21, 12);
    /* replace: written aside under a temporary name, renamed over */
    char aside[700], target[700];
    snprintf(aside, sizeof aside, "%s/m05.msa.new", f->archives);
    snprintf(target, sizeof target, "%s/m05.msa", f->archives);
    ms_test_write_archive(aside, 505);
    assert_int_equal(rename(aside, target), 0);
    /* remove: meshbake --remove */
    char baker[512], cmd[1400], out[1024];
    ms_test_bin_path(baker, sizeof baker, "meshbake");
    snprintf(cmd, sizeof cmd, "%s --remove m09 -o %s", baker, f->archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "model 'm09' removed"));
    snprintf(cmd, sizeof cmd, "%s/m09.msa", f->archives);
    assert_int_equal(access(cmd, F_OK), -1);
    rescan(f, "m20", true);

    /* The connection that held them: MODEL_CHANGED (never fatal, request id
     * 0, detail = the handle) for the replaced and the removed model, in
     * handle-table order, and nothing for the unchanged one. */
    uint32_t changed_handles[2] = {replaced.handle, removed.handle};
    for (int i = 0; i < 2; ++i) {
        ms_proto_message m;
        assert_int_equal(ms_test_conn_recv(&c, &m, 5.0), 1);
        assert_int_equal(m.type, MS_PROTO_ERROR);
        assert_int_equal(m.body.error.code, MS_PROTO_E_MODEL_CHANGED);
        assert_false(m.body.error.fatal);
        assert_int_equal(m.request_id, 0);
        assert_int_equal(m.body.error.request_count, 0);
        assert_int_equal(m.body.error.detail, changed_handles[i]);
    }
    ms_proto_message nothing;
    assert_int_equal(ms_test_conn_recv(&c, &nothing, 0.3), -1); /* time-out: nothing */
    /* reopened by name on the same connection: the new version, or UNKNOWN_MODEL */
    model_view reopened = open_model(&c, "m05", 5);
    assert_true(reopened.handle != 0 && reopened.handle != replaced.handle);
    assert_true(reopened.content_id != replaced.content_id);
    model_view reopened_gone = open_model(&c, "m09", 6);
    assert_int_equal(reopened_gone.handle, 0);
    assert_int_equal(reopened_gone.error, MS_PROTO_E_UNKNOWN_MODEL);

    /* the catalogue: 20 - 1 + 1 */
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/catalog", NULL, &r), 0);
    json_t *catalog = json_loads((const char *)r.body, 0, NULL);
    ms_test_http_free(&r);
    assert_non_null(catalog);
    json_t *list = json_is_array(catalog) ? catalog : json_object_get(catalog, "models");
    assert_int_equal(json_array_size(list), MODELS);
    json_decref(catalog);

    ms_test_conn d;
    assert_int_equal(ms_test_conn_open(&d, f->port), 0);
    ms_test_conn_hello(&d, NULL, NULL);
    /* unchanged: the same content id, ETag and bytes */
    model_view again = open_model(&d, "m03", 1);
    assert_true(again.handle != 0);
    assert_true(again.content_id == unchanged.content_id);
    uint8_t *after;
    size_t after_length;
    assert_int_equal(cell_answer(f, "m03", &after, &after_length, etag, sizeof etag), 200);
    assert_string_equal(etag, etag_before);
    assert_int_equal(after_length, before_length);
    assert_memory_equal(after, before, before_length);
    free(after);
    free(before);
    /* replaced: a new content id, and the new file's bytes */
    model_view fresh = open_model(&d, "m05", 2);
    assert_true(fresh.handle != 0);
    assert_true(fresh.content_id != replaced.content_id);
    assert_true(fresh.content_id == reopened.content_id);
    ms_archive *a;
    assert_int_equal(ms_archive_open(target, &a, NULL), MS_OK);
    size_t length;
    const uint8_t *want = ms_archive_geometry(a, 0, &length);
    assert_int_equal(cell_answer(f, "m05", &after, &after_length, NULL, 0), 200);
    assert_int_equal(after_length, length);
    assert_memory_equal(after, want, length);
    free(after);
    ms_archive_close(a);
    /* removed: UNKNOWN_MODEL and 404 */
    model_view gone = open_model(&d, "m09", 3);
    assert_int_equal(gone.handle, 0);
    assert_int_equal(gone.error, MS_PROTO_E_UNKNOWN_MODEL);
    assert_int_equal(cell_answer(f, "m09", NULL, NULL, NULL, 0), 404);
    /* added */
    model_view added = open_model(&d, "m20", 4);
    assert_true(added.handle != 0);
    assert_int_equal(cell_answer(f, "m20", NULL, NULL, NULL, 0), 200);
    /* the connection opened before the rescan still holds a working handle
     * on its unchanged model */
    model_view still = open_model(&c, "m03", 7);
    assert_true(still.handle != 0 && still.content_id == unchanged.content_id);
    ms_test_conn_close(&d);
    ms_test_conn_close(&c);

    /* the directory as --list sees it now */
    snprintf(cmd, sizeof cmd, "%s --list %s --json", baker, f->archives);
    json_t *j = ms_test_run_json(cmd, 0);
    assert_int_equal(json_integer_value(json_object_get(j, "count")), MODELS);
    assert_int_equal(json_integer_value(json_object_get(j, "failed")), 0);
    json_decref(j);
    assert_int_equal(ms_test_stop(f->pid, SIGTERM, 15.0), 0);
    f->pid = 0;
}

/* The lines of a file, as JSON objects, into an array (waits up to 10 s for
 * at least `want` lines: a connection's line is written as it is freed). */
static json_t *log_lines(const char *path, size_t want)
{
    json_t *lines = NULL;
    for (int tries = 0; tries < 400; ++tries) {
        json_decref(lines);
        lines = json_array();
        FILE *f = fopen(path, "r");
        char line[4096];
        while (f && fgets(line, sizeof line, f)) {
            json_error_t jerr;
            json_t *j = json_loads(line, 0, &jerr);
            if (!j)
                fail_msg("%s: a line that is not JSON: %s", path, line);
            json_array_append_new(lines, j);
        }
        if (f)
            fclose(f);
        if (json_array_size(lines) >= want)
            return lines;
        usleep(25000);
    }
    fail_msg("%s: %zu lines, not %zu", path, json_array_size(lines), want);
    return NULL;
}

static const char *field(json_t *line, const char *key)
{
    json_t *v = json_object_get(line, key);
    assert_true(json_is_string(v));
    return json_string_value(v);
}

static json_int_t number(json_t *line, const char *key)
{
    json_t *v = json_object_get(line, key);
    assert_true(json_is_integer(v));
    return json_integer_value(v);
}

static uint64_t metric(const fixture *f, const char *line_start)
{
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/metrics", NULL, &r), 0);
    const char *at = strstr((const char *)r.body, line_start);
    if (!at)
        fail_msg("/metrics has no '%s'", line_start);
    uint64_t v = strtoull(at + strlen(line_start), NULL, 10);
    ms_test_http_free(&r);
    return v;
}

static void test_access_log_and_model_metrics(void **state)
{
    fixture *f = *state;
    char config[700], log_path[700], rotated[720];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    snprintf(log_path, sizeof log_path, "%s/access.log", f->dir);
    snprintf(rotated, sizeof rotated, "%s.1", log_path);
    FILE *c = fopen(config, "w");
    fprintf(c, "access_log = %s\n", log_path);
    fclose(c);
    const char *extra[] = {"--config", config, NULL};
    f->pid = ms_test_meshserve_start(f->archives, extra, 0, f->port_file, f->log, &f->port,
                                     &f->http_port);
    assert_true(f->pid != 0);

    /* a binary connection that opens two models (and one twice), then leaves */
    ms_test_conn conn;
    assert_int_equal(ms_test_conn_open(&conn, f->port), 0);
    ms_test_conn_hello(&conn, NULL, NULL);
    assert_true(open_model(&conn, "m01", 1).handle != 0);
    assert_true(open_model(&conn, "m03", 2).handle != 0);
    assert_true(open_model(&conn, "m01", 3).handle != 0);
    ms_test_conn_close(&conn);
    /* an HTTP answer with a body, and a 404 */
    uint8_t *body;
    size_t length;
    assert_int_equal(cell_answer(f, "m02", &body, &length, NULL, 0), 200);
    free(body);
    assert_true(length > 0);
    assert_int_equal(cell_answer(f, "nope", NULL, NULL, NULL, 0), 404);

    json_t *lines = log_lines(log_path, 3);
    assert_int_equal(json_array_size(lines), 3);
    json_t *binary = NULL, *ok = NULL, *missing = NULL;
    for (size_t i = 0; i < 3; ++i) {
        json_t *l = json_array_get(lines, i);
        if (!strcmp(field(l, "door"), "binary"))
            binary = l;
        else if (!strcmp(field(l, "status"), "200"))
            ok = l;
        else
            missing = l;
    }
    assert_non_null(binary);
    assert_non_null(ok);
    assert_non_null(missing);
    assert_string_equal(field(binary, "model"), "m01,m03");
    assert_int_equal(number(binary, "requests"), 3);
    assert_int_equal(number(binary, "bytes"), 0); /* an index is not payload */
    assert_string_equal(field(binary, "status"), "ok");
    assert_int_equal(strncmp(field(binary, "client"), "127.0.0.1:", 10), 0);
    assert_true(json_is_real(json_object_get(binary, "seconds")));
    assert_string_equal(field(ok, "door"), "http");
    assert_string_equal(field(ok, "model"), "m02");
    assert_string_equal(field(ok, "request"), "/models/m02/cells/0/geometry");
    assert_int_equal(number(ok, "bytes"), (json_int_t)length);
    assert_int_equal(number(ok, "requests"), 1);
    assert_string_equal(field(missing, "status"), "404");
    assert_string_equal(field(missing, "model"), "nope");
    assert_int_equal(strlen(field(ok, "time")), 20); /* 2026-12-03T12:00:00Z */
    json_decref(lines);

    /* per model counters */
    assert_int_equal(metric(f, "meshstream_model_requests_total{model=\"m01\"} "), 2);
    assert_int_equal(metric(f, "meshstream_model_requests_total{model=\"m02\"} "), 1);
    assert_int_equal(metric(f, "meshstream_model_bytes_sent_total{model=\"m02\"} "), length);
    /* a model nobody asked for has no series (open models only: the page stays
     * bounded whatever the collection's size), and its archive is not open */
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/metrics", NULL, &r), 0);
    assert_null(strstr((const char *)r.body, "model=\"m04\""));
    assert_non_null(strstr((const char *)r.body, "\nmeshstream_open_models 3\n"));
    ms_test_http_free(&r);

    /* rotation: the file moved away, SIGHUP, and the next line is in a new file */
    assert_int_equal(rename(log_path, rotated), 0);
    assert_int_equal(kill(f->pid, SIGHUP), 0);
    json_t *fresh = NULL;
    for (int tries = 0; tries < 200 && !fresh; ++tries) {
        usleep(25000);
        if (access(log_path, F_OK) == 0)
            fresh = log_lines(log_path, 0);
    }
    assert_non_null(fresh);
    json_decref(fresh);
    assert_int_equal(cell_answer(f, "m04", NULL, NULL, NULL, 0), 200);
    fresh = log_lines(log_path, 1);
    assert_int_equal(json_array_size(fresh), 1);
    assert_string_equal(field(json_array_get(fresh, 0), "model"), "m04");
    json_decref(fresh);
    /* the moved file: the 3 lines above and the 4 /metrics answers, nothing later */
    json_t *old = log_lines(rotated, 7);
    assert_int_equal(json_array_size(old), 7);
    assert_string_equal(field(json_array_get(old, 6), "request"), "/metrics");
    json_decref(old);
    assert_int_equal(ms_test_stop(f->pid, SIGTERM, 15.0), 0);
    f->pid = 0;
}

/* meshserve --config FILE alone: the file names the directory (as the
 * systemd unit starts it); without it anywhere, a usage error. */
static void test_config_names_the_archive_dir(void **state)
{
    fixture *f = *state;
    char config[700], bin[512], cmd[1600], out[1024];
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    snprintf(config, sizeof config, "%s/bare.conf", f->dir);
    FILE *c = fopen(config, "w");
    fprintf(c, "port = 0\nhttp_port = off\n");
    fclose(c);
    snprintf(cmd, sizeof cmd, "%s --config %s", bin, config);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "no archive_dir (and no ARCHIVE_DIR argument)"));
    snprintf(cmd, sizeof cmd, "%s", bin);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "expected one ARCHIVE_DIR"));

    snprintf(config, sizeof config, "%s/site.conf", f->dir);
    c = fopen(config, "w");
    fprintf(c, "archive_dir = %s\nport = 0\nhttp_port = 0\nport_file = %s\n", f->archives,
            f->port_file);
    fclose(c);
    char *argv[] = {bin, "--config", config, NULL};
    f->pid = ms_test_spawn(argv, f->log);
    assert_int_equal(ms_test_wait_ports(f->port_file, 15.0, &f->port, &f->http_port), 0);
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/catalog", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    assert_non_null(strstr((const char *)r.body, "\"m19\""));
    ms_test_http_free(&r);
    assert_int_equal(ms_test_stop(f->pid, SIGTERM, 15.0), 0);
    f->pid = 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_list_checks_every_archive, setup, teardown),
        cmocka_unit_test_setup_teardown(test_add_replace_remove_while_serving, setup, teardown),
        cmocka_unit_test_setup_teardown(test_access_log_and_model_metrics, setup, teardown),
        cmocka_unit_test_setup_teardown(test_config_names_the_archive_dir, setup, teardown),
    };
    return cmocka_run_group_tests_name("collection", tests, NULL, NULL);
}
