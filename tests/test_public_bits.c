/* The preview precision from the baker (issue 19, "Also"): meshbake
 * --public-bits B writes it into the catalogue, meshbake --set-public-bits B
 * changes it for a baked model, and every door follows: meshserve's binary
 * protocol and HTTP side door (after SIGHUP), and meshexport. */
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <setjmp.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_test.h"
#include "ms_test_net.h"
#include "ms_test_proto.h"

#define TOKEN "preview-token"

static unsigned catalog_public_bits(const char *dir)
{
    ms_catalog catalog;
    assert_int_equal(ms_catalog_load(dir, &catalog, NULL), MS_OK);
    const ms_catalog_entry *e = ms_catalog_find(&catalog, "bun");
    assert_non_null(e);
    unsigned bits = e->public_max_bits;
    ms_catalog_free(&catalog);
    return bits;
}

static int http_status(uint16_t port, const char *path, const char *headers)
{
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(port, path, headers, &r), 0);
    int status = r.status;
    ms_test_http_free(&r);
    return status;
}

static uint8_t permitted_steps(uint16_t port)
{
    ms_test_conn c;
    assert_int_equal(ms_test_conn_open(&c, port), 0);
    ms_test_conn_hello(&c, NULL, NULL);
    ms_proto_model_opened o;
    uint8_t *index = NULL;
    assert_true(ms_test_conn_open_model(&c, "bun", 1, &o, &index, NULL) >= 1);
    free(index);
    ms_test_conn_close(&c);
    return o.permitted_geometry_steps;
}

static size_t exported_geometry(const char *dir, uint32_t cell, bool full)
{
    char bin[4096], cmd[8192], out[4096], path[900];
    ms_test_bin_path(bin, sizeof bin, "meshexport");
    snprintf(cmd, sizeof cmd, "%s '%s/archive' bun -o '%s/www'%s", bin, dir, dir,
             full ? " --full" : "");
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    snprintf(path, sizeof path, "%s/www/models/bun/cells/%u/geometry", dir, cell);
    size_t size;
    free(ms_test_read_file(path, &size));
    return size;
}

static void test_public_bits_through_every_door(void **state)
{
    (void)state;
    char dir[512], archives[700], bin[4096], model[4096], cmd[16384], out[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(archives, sizeof archives, "%s/archive", dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    /* Out of range, or without a bake to apply to: usage errors. */
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name bun --bits 12 --public-bits 13", bin, model,
             archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 2);
    assert_string_equal(out, "meshbake: --public-bits must be at most --bits (12): 13 (see "
                             "meshbake --help)\n");
    snprintf(cmd, sizeof cmd, "%s '%s' -o '%s' --name bun --bits 12 --no-apo --min-tris 500 "
             "--public-bits 8", bin, model, archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_int_equal(catalog_public_bits(archives), 8);

    /* A cell whose window straddles the preview. */
    char path[900];
    snprintf(path, sizeof path, "%s/bun.msa", archives);
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    uint32_t cell = UINT32_MAX;
    for (uint32_t i = 0; cell == UINT32_MAX && i < ms_archive_get_header(a)->cell_count; ++i) {
        const ms_archive_cell *c = ms_archive_get_cell(a, i);
        if (c->bits_min <= 8 && c->bits_max > 8 && ms_archive_geometry_prefix(a, i, 8) < c->geometry_length)
            cell = i;
    }
    assert_true(cell != UINT32_MAX);
    const uint32_t full = ms_archive_get_cell(a, cell)->geometry_length;
    const uint32_t preview = ms_archive_geometry_prefix(a, cell, 8);
    ms_archive_close(a);

    char config[700], ports[700], log[700], serve[4096];
    snprintf(config, sizeof config, "%s/meshserve.conf", dir);
    const char settings[] = "token = " TOKEN "\nhttp_rate = 100000\n";
    ms_test_write_file(config, settings, sizeof settings - 1);
    snprintf(ports, sizeof ports, "%s/ports", dir);
    snprintf(log, sizeof log, "%s/meshserve.log", dir);
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    char *argv[] = {serve, archives, "--config", config, "--port", "0", "--http-port", "0",
                    "--port-file", ports, NULL};
    pid_t pid = ms_test_spawn(argv, log);
    uint16_t port, http_port;
    if (ms_test_wait_ports(ports, 10.0, &port, &http_port) != 0) {
        ms_test_stop(pid, SIGKILL, 5.0);
        fail_msg("meshserve did not start (see %s)", log);
    }
    char url[200];
    snprintf(url, sizeof url, "/models/bun/cells/%u/geometry?bits=12", cell);
    assert_int_equal(permitted_steps(port), 9);
    assert_int_equal(http_status(http_port, url, NULL), 403);
    assert_int_equal(http_status(http_port, url, "Authorization: Bearer " TOKEN "\r\n"), 200);
    assert_int_equal(exported_geometry(dir, cell, false), preview);
    assert_int_equal(exported_geometry(dir, cell, true), full);

    /* Changing it for the baked model: the catalogue, then SIGHUP. */
    snprintf(cmd, sizeof cmd, "%s --set-public-bits 13 -o '%s' --name bun", bin, archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    assert_string_equal(out, "meshbake: model 'bun' has 12 bits; --set-public-bits 13 is more\n");
    snprintf(cmd, sizeof cmd, "%s --set-public-bits 12 -o '%s' --name nosuch", bin, archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(cmd, sizeof cmd, "%s --set-public-bits 12 -o '%s' --name bun", bin, archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_string_equal(out, "meshbake: model 'bun': public_max_bits 8 -> 12 (SIGHUP a running "
                             "meshserve to apply it)\n");
    assert_int_equal(catalog_public_bits(archives), 12);
    assert_int_equal(kill(pid, SIGHUP), 0);
    int status = 0;
    for (int attempt = 0; attempt < 100 && status != 200; ++attempt) {
        status = http_status(http_port, url, NULL);
        if (status != 200)
            usleep(20000);
    }
    assert_int_equal(status, 200);
    assert_int_equal(permitted_steps(port), 13);
    assert_int_equal(exported_geometry(dir, cell, false), full);
    assert_int_equal(ms_test_stop(pid, SIGTERM, 15.0), 0);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_public_bits_through_every_door),
    };
    return cmocka_run_group_tests_name("public_bits", tests, NULL, NULL);
}
