/* Colour streams through every door (docs/SECURITY.md: colour follows the
 * geometric preview): meshserve's binary door (stream COLOUR with CAP_COLOUR,
 * refused without it), its HTTP side door (/models/M/cells/C/colour?bits=B),
 * meshexport's static files, each giving an anonymous reader exactly the
 * colour prefix of the preview's precision and the token holder all of it;
 * the client core over the network, whose frames carry the colours; and
 * meshbake's colour options and reports. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_bake.h"
#include "ms_camera.h"
#include "ms_client_core.h"
#include "ms_colour_check.h"
#include "ms_nsp_check.h"
#include "ms_test.h"
#include "ms_test_core.h"
#include "ms_test_net.h"
#include "ms_test_proto.h"

#define TOKEN "colour-token"
#define FIXTURE "trefoil_color.ply.gz"
#define PREVIEW 10

typedef struct served {
    char dir[512], archives[700], file[4096];
    pid_t pid;
    uint16_t port, http_port;
    ms_archive *a;
    uint32_t cell; /* a cell whose window holds the preview and goes beyond it */
} served;

static void serve(served *s)
{
    char model[4096];
    ms_test_tmpdir(s->dir, sizeof s->dir);
    snprintf(s->archives, sizeof s->archives, "%s/archive", s->dir);
    ms_bake_options o;
    ms_nsp_test_bake_options(ms_test_model_path(model, sizeof model, FIXTURE), s->archives, "tre", &o);
    o.min_triangles = 2000;
    o.public_bits = PREVIEW;
    ms_bake_report rep;
    ms_error err;
    if (ms_bake(&o, &rep, &err) != MS_OK)
        fail_msg("bake: %s", err.text);
    snprintf(s->file, sizeof s->file, "%s", rep.archive_path);
    assert_int_equal(ms_archive_open(s->file, &s->a, &err), MS_OK);
    s->cell = UINT32_MAX;
    for (uint32_t i = 0; s->cell == UINT32_MAX && i < ms_archive_get_header(s->a)->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(s->a, i);
        if (c->bits_min <= PREVIEW && c->bits_max > PREVIEW &&
            ms_archive_colour_prefix(s->a, i, PREVIEW) < ms_archive_colour_length(s->a, i))
            s->cell = i;
    }
    assert_true(s->cell != UINT32_MAX);
    char config[700], ports[700], log[700], bin[4096];
    snprintf(config, sizeof config, "%s/meshserve.conf", s->dir);
    const char settings[] = "token = " TOKEN "\nhttp_rate = 100000\n";
    ms_test_write_file(config, settings, sizeof settings - 1);
    snprintf(ports, sizeof ports, "%s/ports", s->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", s->dir);
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    char *argv[] = {bin, s->archives, "--config", config, "--port", "0", "--http-port", "0",
                    "--port-file", ports, NULL};
    s->pid = ms_test_spawn(argv, log);
    if (ms_test_wait_ports(ports, 15.0, &s->port, &s->http_port) != 0) {
        ms_test_stop(s->pid, SIGKILL, 5.0);
        fail_msg("meshserve did not start (see %s)", log);
    }
}

static void unserve(served *s)
{
    ms_test_stop(s->pid, SIGTERM, 10.0);
    ms_archive_close(s->a);
    ms_test_rmdir(s->dir);
}

/* The binary door: REQUEST_CELLS of colour at `bits` on cell, with or without
 * the token and CAP_COLOUR. Fills *ans. */
static void binary_colour(const served *s, const char *token, uint32_t caps, uint32_t cell,
                          unsigned bits, ms_test_answers *ans, uint16_t *batch_error)
{
    ms_test_conn c;
    assert_int_equal(ms_test_conn_open(&c, s->port), 0);
    ms_proto_hello_reply reply;
    ms_test_conn_hello_with(&c, token, 3, caps, &reply);
    assert_int_equal(reply.capabilities & MS_PROTO_CAP_COLOUR, caps & MS_PROTO_CAP_COLOUR);
    ms_proto_model_opened o;
    uint8_t *index = NULL;
    uint32_t handle = ms_test_conn_open_model(&c, "tre", 1, &o, &index, NULL);
    assert_true(handle >= 1);
    free(index);
    const ms_proto_cell_request e = {cell, MS_PROTO_STREAM_COLOUR, MS_PROTO_UNIT_STEPS, 0, 0, bits};
    ms_test_conn_send_batch(&c, handle, 10, &e, 1);
    if (batch_error) {
        uint32_t id;
        ms_proto_error_body body;
        *batch_error = ms_test_conn_expect_error(&c, &id, &body);
    } else {
        ms_test_answers_init(ans, 10, 1);
        ms_test_answers_collect(&c, ans);
    }
    ms_test_conn_close(&c);
}

static void test_binary_door(void **state)
{
    (void)state;
    served s;
    serve(&s);
    size_t len;
    const uint8_t *colour = ms_archive_colour(s.a, s.cell, &len);
    uint32_t preview = ms_archive_colour_prefix(s.a, s.cell, PREVIEW);
    const uint32_t caps = MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_SUBTREES | MS_PROTO_CAP_COLOUR;
    ms_test_answers ans;
    /* anonymous: the preview's prefix, and nothing finer */
    binary_colour(&s, NULL, caps, s.cell, PREVIEW, &ans, NULL);
    assert_int_equal(ans.error[0], 0);
    assert_int_equal(ans.length[0], preview);
    assert_memory_equal(ans.data[0], colour, preview);
    ms_test_answers_free(&ans);
    binary_colour(&s, NULL, caps, s.cell, PREVIEW + 1, &ans, NULL);
    assert_int_equal(ans.error[0], MS_PROTO_E_FORBIDDEN);
    ms_test_answers_free(&ans);
    /* the token: all of it */
    binary_colour(&s, TOKEN, caps, s.cell, 20, &ans, NULL);
    assert_int_equal(ans.error[0], 0);
    assert_int_equal(ans.length[0], len);
    assert_memory_equal(ans.data[0], colour, len);
    ms_test_answers_free(&ans);
    /* without CAP_COLOUR the stream is not negotiated: the batch is refused */
    uint16_t code = 0;
    binary_colour(&s, TOKEN, caps & ~MS_PROTO_CAP_COLOUR, s.cell, 20, NULL, &code);
    assert_int_not_equal(code, 0);
    unserve(&s);
}

static void test_http_door_and_export(void **state)
{
    (void)state;
    served s;
    serve(&s);
    size_t len;
    const uint8_t *colour = ms_archive_colour(s.a, s.cell, &len);
    uint32_t preview = ms_archive_colour_prefix(s.a, s.cell, PREVIEW);
    char url[200];
    ms_test_http_response r;
    snprintf(url, sizeof url, "/models/tre/cells/%u/colour?bits=%u", s.cell, PREVIEW);
    assert_int_equal(ms_test_http_get(s.http_port, url, NULL, &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, preview);
    assert_memory_equal(r.body, colour, preview);
    ms_test_http_free(&r);
    snprintf(url, sizeof url, "/models/tre/cells/%u/colour?bits=%u", s.cell, PREVIEW + 1);
    assert_int_equal(ms_test_http_get(s.http_port, url, NULL, &r), 0);
    assert_int_equal(r.status, 403);
    ms_test_http_free(&r);
    snprintf(url, sizeof url, "/models/tre/cells/%u/colour", s.cell);
    assert_int_equal(ms_test_http_get(s.http_port, url, "Authorization: Bearer " TOKEN "\r\n", &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, len);
    assert_memory_equal(r.body, colour, len);
    ms_test_http_free(&r);
    /* meshexport: the preview's prefix, or with --full all of it */
    char bin[4096], cmd[8192], out[4096], path[1200];
    ms_test_bin_path(bin, sizeof bin, "meshexport");
    for (int full = 0; full < 2; ++full) {
        snprintf(cmd, sizeof cmd, "%s '%s' tre -o '%s/www'%s", bin, s.archives, s.dir,
                 full ? " --full" : "");
        assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
        snprintf(path, sizeof path, "%s/www/models/tre/cells/%u/colour", s.dir, s.cell);
        size_t size;
        uint8_t *bytes = ms_test_read_file(path, &size);
        assert_int_equal(size, full ? len : preview);
        assert_memory_equal(bytes, colour, size);
        free(bytes);
    }
    unserve(&s);
}

/* The client core over the network, with the token: its frames carry the
 * rule's colours. */
static void test_client_core_network(void **state)
{
    (void)state;
    served s;
    serve(&s);
    char model[4096];
    const ms_archive_header *h = ms_archive_get_header(s.a);
    ms_colour_test_welded w;
    ms_colour_test_weld(ms_test_model_path(model, sizeof model, FIXTURE), h, &w);
    double centre[3], eye[3], up[3] = {0, 1, 0};
    for (int k = 0; k < 3; ++k)
        centre[k] = h->box_origin[k] + h->box_side / 2;
    memcpy(eye, centre, sizeof eye);
    eye[2] += 1.5 * h->box_side;
    ms_camera cam;
    ms_error err;
    assert_int_equal(ms_camera_look_at(eye, centre, up, 50, 640, 480, 1e-3 * h->box_side,
                                       10 * h->box_side, &cam, &err), MS_OK);
    ms_core_options o = {0};
    o.host = "127.0.0.1";
    o.port = s.port;
    o.model = "tre";
    o.token = TOKEN;
    o.tolerance_px = 0.05;
    o.hysteresis_bits = 0;
    o.export_frames = true;
    ms_core *core;
    assert_int_equal(ms_core_start(&o, &core, &err), MS_OK);
    ms_core_set_camera(core, &cam);
    ms_core_stats st;
    ms_core_frame *frame = NULL;
    if (!ms_test_core_wait_complete(core, 60, &st, &frame))
        fail_msg("view not complete: '%s'", st.error);
    assert_non_null(frame);
    ms_colour_test_check(&frame->mesh, &w, h->bits, 8);
    ms_core_frame_free(frame);
    ms_core_stop(core);
    ms_colour_test_welded_free(&w);
    unserve(&s);
}

/* meshbake's colour options and reports: --colour-bits (1..8), --no-colour,
 * the JSON report's colour object, --list's colour column and colour_bytes. */
static void test_meshbake_options(void **state)
{
    (void)state;
    char dir[512], bin[4096], model[4096], cmd[16384];
    static char out[1 << 16];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, FIXTURE);
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s/a' --colour-bits 9 2>&1", bin, model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_non_null(strstr(out, "--colour-bits"));
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s/a' --name c5 --no-apo --colour-bits 5 --json", bin,
             model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"colour\":{\"present\":true,\"alpha\":true,\"bits\":5,\"bytes\":"));
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s/a' --name none --no-apo --no-colour --json", bin,
             model, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "\"colour\":{\"present\":false,\"alpha\":false,\"bits\":0,\"bytes\":0}"));
    snprintf(cmd, sizeof cmd, "%s --list '%s/a'", bin, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, "colour  preview"));
    char path[700];
    snprintf(path, sizeof path, "%s/a/c5.msa", dir);
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    uint64_t sum = 0;
    for (uint32_t i = 0; i < ms_archive_get_header(a)->cell_count; ++i)
        sum += ms_archive_colour_length(a, i);
    assert_int_equal(ms_archive_get_header(a)->colour_bits, 5);
    ms_archive_close(a);
    char want[64];
    snprintf(want, sizeof want, "\"colour_bytes\": %llu", (unsigned long long)sum);
    snprintf(cmd, sizeof cmd, "%s --list '%s/a' --json", bin, dir);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_non_null(strstr(out, want));
    assert_non_null(strstr(out, "\"colour_bytes\": 0"));
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_binary_door),
        cmocka_unit_test(test_http_door_and_export),
        cmocka_unit_test(test_client_core_network),
        cmocka_unit_test(test_meshbake_options),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
