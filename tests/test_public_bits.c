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
#include "ms_bake.h"
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

/* --- Issue 32, item 2: the preview caps APO levels as it caps bits -------- */

/* The levels of cell's chunk an anonymous reader gets under a preview of
 * `preview` bits, by the rule of docs/SECURITY.md written out again (n = 4:
 * two bits a level): nothing of a hidden cell, else the depths
 * d <= preview - 2 * level. */
static uint32_t rule_apo_levels(const ms_archive *a, uint32_t cell, unsigned preview)
{
    const ms_archive_cell *c = ms_archive_get_cell(a, cell);
    assert_int_equal(ms_archive_get_header(a)->n, 4);
    if (c->bits_min > preview)
        return 0;
    int levels = (int)preview - 2 * (int)c->level + 1;
    if (levels < 0)
        levels = 0;
    return (uint32_t)levels < c->apo_levels ? (uint32_t)levels : c->apo_levels;
}

static uint32_t apo_prefix_bytes(const ms_archive *a, uint32_t cell, uint32_t levels)
{
    return levels ? ms_archive_apo_prefix(a, cell, levels - 1, NULL) : 0;
}

typedef struct preview_server {
    char dir[512], archives[700], log[700];
    pid_t pid;
    uint16_t port, http_port;
    ms_archive *archive;
} preview_server;

static uint64_t metric(const preview_server *s, const char *series)
{
    uint64_t value = 0;
    assert_int_equal(ms_test_metric(s->http_port, series, &value), 0);
    return value;
}

/* Every cell's APO over HTTP, anonymously, each exactly the rule's prefix of
 * the archive's bytes (403 for a hidden cell and for a chunk of which nothing
 * is readable); returns the bytes and counts the 403s. */
static uint64_t http_apo_total(const preview_server *s, unsigned preview, uint64_t *forbidden)
{
    uint64_t total = 0;
    const ms_archive *a = s->archive;
    for (uint32_t cell = 0; cell < ms_archive_get_header(a)->cell_count; ++cell) {
        char path[128];
        snprintf(path, sizeof path, "/models/bun/cells/%u/apo", cell);
        ms_test_http_response r;
        assert_int_equal(ms_test_http_get(s->http_port, path, NULL, &r), 0);
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        uint32_t levels = rule_apo_levels(a, cell, preview);
        if (c->bits_min > preview || (c->apo_levels > 0 && levels == 0)) {
            assert_int_equal(r.status, 403);
            ++*forbidden;
        } else {
            uint32_t want = apo_prefix_bytes(a, cell, levels);
            if (r.status != 200 || r.body_length != want)
                fail_msg("%s: status %d, %zu bytes, expected 200 and %u", path, r.status,
                         r.body_length, want);
            size_t size;
            const uint8_t *stored = ms_archive_apo(a, cell, &size);
            if (want)
                assert_memory_equal(r.body, stored, want);
            total += want;
        }
        ms_test_http_free(&r);
    }
    return total;
}

/* meshexport's anonymous tree: every cell's apo file is the rule's prefix, no
 * file where nothing is readable; returns the bytes. */
static uint64_t exported_apo_total(const preview_server *s, unsigned preview, bool full)
{
    char bin[4096], cmd[8192], out[4096], path[900];
    ms_test_bin_path(bin, sizeof bin, "meshexport");
    snprintf(cmd, sizeof cmd, "%s '%s' bun -o '%s/www'%s", bin, s->archives, s->dir,
             full ? " --full" : "");
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    uint64_t total = 0;
    for (uint32_t cell = 0; cell < ms_archive_get_header(s->archive)->cell_count; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(s->archive, cell);
        uint32_t want = full ? c->apo_length
                             : apo_prefix_bytes(s->archive, cell, rule_apo_levels(s->archive, cell, preview));
        snprintf(path, sizeof path, "%s/www/models/bun/cells/%u/apo", s->dir, cell);
        if (!want) {
            assert_int_equal(access(path, F_OK), -1);
            continue;
        }
        size_t size;
        free(ms_test_read_file(path, &size));
        assert_int_equal(size, want);
        total += want;
    }
    return total;
}

/* One binary connection (anonymous, or with the token): the grant's
 * permitted_apo_steps from MODEL_OPENED, and the answers to `count` entries. */
static uint8_t binary_apo(const preview_server *s, const char *token,
                          const ms_proto_cell_request *entries, uint16_t count, ms_test_answers *a)
{
    ms_test_conn c;
    assert_int_equal(ms_test_conn_open(&c, s->port), 0);
    ms_test_conn_hello(&c, token, NULL);
    ms_proto_model_opened o;
    uint8_t *index = NULL;
    uint32_t handle = ms_test_conn_open_model(&c, "bun", 1, &o, &index, NULL);
    assert_true(handle >= 1);
    free(index);
    ms_test_conn_send_batch(&c, handle, 10, entries, count);
    ms_test_answers_init(a, 10, count);
    ms_test_answers_collect(&c, a);
    ms_test_conn_close(&c);
    return o.permitted_apo_steps;
}

static void test_preview_caps_apo_through_every_door(void **state)
{
    (void)state;
    preview_server s = {.pid = -1};
    char bin[4096], model[4096], cmd[16384], out[4096];
    ms_test_tmpdir(s.dir, sizeof s.dir);
    snprintf(s.archives, sizeof s.archives, "%s/archive", s.dir);
    ms_test_bin_path(bin, sizeof bin, "meshbake");
    ms_test_model_path(model, sizeof model, "stanford_bunny_res3.ply.gz");
    /* A chunk in every cell (leaves included), at most 9 levels: a level-1
     * leaf's finest texels (depth 8, 10-bit cubes) are finer than a 9-bit
     * preview, the root's (8-bit cubes) are not. */
    ms_bake_options bo;
    ms_bake_options_default(&bo);
    bo.input = model;
    bo.archive_dir = s.archives;
    bo.name = "bun";
    bo.bits = 12;
    bo.min_triangles = 500;
    bo.apo.every_cell = true; /* no longer a meshbake option: through the library */
    bo.apo.max_depth = 8;
    bo.apo.budget = 0; /* every level of every chunk: the preview's cap is what is tested */
    bo.public_bits = 9;
    bo.threads = 2;
    ms_bake_report br;
    ms_error berr;
    ms_error_clear(&berr);
    if (ms_bake(&bo, &br, &berr) != MS_OK)
        fail_msg("bake: %s", berr.text);
    char path[900];
    snprintf(path, sizeof path, "%s/bun.msa", s.archives);
    assert_int_equal(ms_archive_open(path, &s.archive, NULL), MS_OK);
    const ms_archive *a = s.archive;
    const uint32_t cells = ms_archive_get_header(a)->cell_count;
    /* What the rule gives at 9 bits: the root's whole chunk, 8 of a level-1
     * cell's 9 levels. */
    uint64_t all = 0, rule9 = 0;
    uint32_t capped = UINT32_MAX;
    for (uint32_t cell = 0; cell < cells; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        uint32_t levels = rule_apo_levels(a, cell, 9);
        all += c->apo_length;
        rule9 += apo_prefix_bytes(a, cell, levels);
        if (capped == UINT32_MAX && c->level == 1 && c->apo_levels == 9)
            capped = cell;
    }
    assert_true(capped != UINT32_MAX);
    assert_int_equal(rule_apo_levels(a, capped, 9), 8);
    assert_int_equal(rule_apo_levels(a, 0, 9), ms_archive_get_cell(a, 0)->apo_levels);
    assert_true(rule9 < all);
    const uint32_t capped_full = ms_archive_get_cell(a, capped)->apo_length;
    const uint32_t capped_preview = apo_prefix_bytes(a, capped, 8);
    assert_true(capped_preview < capped_full);

    char config[700], ports[700], serve[4096];
    snprintf(config, sizeof config, "%s/meshserve.conf", s.dir);
    const char settings[] = "token = " TOKEN "\nhttp_rate = 100000\n";
    ms_test_write_file(config, settings, sizeof settings - 1);
    snprintf(ports, sizeof ports, "%s/ports", s.dir);
    snprintf(s.log, sizeof s.log, "%s/meshserve.log", s.dir);
    ms_test_bin_path(serve, sizeof serve, "meshserve");
    char *argv[] = {serve, s.archives, "--config", config, "--port", "0", "--http-port", "0",
                    "--port-file", ports, NULL};
    s.pid = ms_test_spawn(argv, s.log);
    if (ms_test_wait_ports(ports, 10.0, &s.port, &s.http_port) != 0) {
        ms_test_stop(s.pid, SIGKILL, 5.0);
        fail_msg("meshserve did not start (see %s)", s.log);
    }

    /* HTTP: every cell exactly the rule's prefix, the sum exact. */
    uint64_t forbidden = 0;
    assert_int_equal(http_apo_total(&s, 9, &forbidden), rule9);
    assert_int_equal(forbidden, 0);
    char url[200], value[128], expect[128];
    ms_test_http_response r;
    snprintf(url, sizeof url, "/models/bun/cells/%u/apo?levels=9", capped);
    assert_int_equal(http_status(s.http_port, url, NULL), 403);
    assert_int_equal(http_status(s.http_port, url, "Range: bytes=0-3\r\n"), 403);
    snprintf(url, sizeof url, "/models/bun/cells/%u/apo?levels=8", capped);
    assert_int_equal(ms_test_http_get(s.http_port, url, NULL, &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, capped_preview);
    ms_test_http_free(&r);
    /* a suffix Range ends where the preview does */
    snprintf(url, sizeof url, "/models/bun/cells/%u/apo", capped);
    assert_int_equal(ms_test_http_get(s.http_port, url, "Range: bytes=-4\r\n", &r), 0);
    assert_int_equal(r.status, 206);
    snprintf(expect, sizeof expect, "bytes %u-%u/%u", capped_preview - 4, capped_preview - 1,
             capped_preview);
    assert_string_equal(ms_test_http_header(&r, "Content-Range", value, sizeof value), expect);
    ms_test_http_free(&r);
    assert_int_equal(ms_test_http_get(s.http_port, url, "Authorization: Bearer " TOKEN "\r\n", &r), 0);
    assert_int_equal(r.status, 200);
    assert_int_equal(r.body_length, capped_full);
    ms_test_http_free(&r);
    assert_int_equal(metric(&s, "meshstream_forbidden_total{door=\"http\"}"), 2);

    /* The binary door: the same cut, FORBIDDEN one level or one byte past it. */
    ms_proto_cell_request e[5] = {
        {capped, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_STEPS, 0, 0, 7},
        {capped, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_STEPS, 0, 0, 8},
        {capped, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_BYTES, 0, 0, capped_preview},
        {capped, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_BYTES, 0, 0, capped_preview + 1},
        {0, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_STEPS, 0, 0, 8},
    };
    ms_test_answers ans;
    assert_int_equal(binary_apo(&s, NULL, e, 5, &ans), 9); /* min(apo_steps 9, 9 + 1) */
    assert_int_equal(ans.error[0], 0);
    assert_int_equal(ans.length[0], capped_preview);
    assert_int_equal(ans.error[1], MS_PROTO_E_FORBIDDEN);
    assert_int_equal(ans.error[2], 0);
    assert_int_equal(ans.length[2], capped_preview);
    assert_int_equal(ans.error[3], MS_PROTO_E_FORBIDDEN);
    assert_int_equal(ans.error[4], 0);
    assert_int_equal(ans.length[4], ms_archive_get_cell(a, 0)->apo_length);
    ms_test_answers_free(&ans);
    assert_int_equal(metric(&s, "meshstream_forbidden_total{door=\"binary\"}"), 2);
    assert_int_equal(binary_apo(&s, TOKEN, e + 1, 1, &ans), 9);
    assert_int_equal(ans.error[0], 0);
    assert_int_equal(ans.length[0], capped_full);
    ms_test_answers_free(&ans);

    /* meshexport: the same cut; --full writes everything, and the next
     * anonymous export cuts it back. */
    assert_int_equal(exported_apo_total(&s, 9, false), rule9);
    assert_int_equal(exported_apo_total(&s, 9, true), all);
    assert_int_equal(exported_apo_total(&s, 9, false), rule9);

    /* A preview of 3 bits: the root's four coarsest levels, every other cell
     * hidden; the grant says so. */
    snprintf(cmd, sizeof cmd, "%s --set-public-bits 3 -o '%s' --name bun", bin, s.archives);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 0);
    assert_int_equal(kill(s.pid, SIGHUP), 0);
    int status = 0;
    for (int attempt = 0; attempt < 100 && status != 403; ++attempt) {
        status = http_status(s.http_port, "/models/bun/cells/0/apo?levels=5", NULL);
        if (status != 403)
            usleep(20000);
    }
    assert_int_equal(status, 403);
    uint64_t rule3 = 0;
    for (uint32_t cell = 0; cell < cells; ++cell)
        rule3 += apo_prefix_bytes(a, cell, rule_apo_levels(a, cell, 3));
    assert_int_equal(rule3, ms_archive_apo_prefix(a, 0, 3, NULL));
    forbidden = 0;
    assert_int_equal(http_apo_total(&s, 3, &forbidden), rule3);
    assert_int_equal(forbidden, cells - 1);
    ms_proto_cell_request root = {0, MS_PROTO_STREAM_APO, MS_PROTO_UNIT_STEPS, 0, 0, 4};
    assert_int_equal(binary_apo(&s, NULL, &root, 1, &ans), 4);
    assert_int_equal(ans.error[0], MS_PROTO_E_FORBIDDEN);
    ms_test_answers_free(&ans);
    assert_int_equal(exported_apo_total(&s, 3, false), rule3);
    printf("# anonymous APO bytes: preview 9: %llu of %llu; preview 3: %llu\n",
           (unsigned long long)rule9, (unsigned long long)all, (unsigned long long)rule3);

    assert_int_equal(ms_test_stop(s.pid, SIGTERM, 15.0), 0);
    ms_archive_close(s.archive);
    ms_test_rmdir(s.dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_public_bits_through_every_door),
        cmocka_unit_test(test_preview_caps_apo_through_every_door),
    };
    return cmocka_run_group_tests_name("public_bits", tests, NULL, NULL);
}
