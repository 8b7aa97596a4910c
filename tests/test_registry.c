/* Model registry: scan, reuse on rescan, replacement, removal while held,
 * broken archives skipped, names never used as paths, archives opened on first
 * request and closed by use order and idleness. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_progress.h"
#include "ms_registry.h"
#include "ms_test.h"
#include "ms_test_archive.h"

typedef struct warnings {
    int count;
    char last[1024];
} warnings;

static void collect(void *arg, const char *message)
{
    warnings *w = arg;
    w->count++;
    snprintf(w->last, sizeof w->last, "%s", message);
}

static void test_scan_rescan_replace_remove(void **state)
{
    (void)state;
    char dir[512], path[700];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_add_model(dir, "bunny", 1, 12);
    ms_test_add_model(dir, "dragon", 2, 9);
    warnings w = {0};
    ms_registry *r1, *r2, *r3;
    ms_error err;
    assert_int_equal(ms_registry_scan(dir, NULL, 16, &r1, collect, &w, &err), MS_OK);
    assert_int_equal(ms_registry_count(r1), 2);
    assert_int_equal(w.count, 0);
    ms_model *dragon = ms_registry_find(r1, "dragon");
    assert_non_null(dragon);
    assert_int_equal(dragon->entry.public_max_bits, 9);
    assert_null(ms_registry_find(r1, "../dragon"));
    assert_null(ms_registry_find(r1, "dragon.msa"));
    assert_null(ms_registry_find(r1, "zebra"));

    /* Unchanged files are reused, not reopened. */
    assert_int_equal(ms_registry_scan(dir, r1, 16, &r2, collect, &w, &err), MS_OK);
    assert_ptr_equal(ms_registry_find(r2, "dragon"), dragon);
    assert_int_equal(dragon->refs, 2);

    /* Hold the dragon (a transfer in progress), then replace bunny and remove it. */
    ms_model_ref(dragon);
    ms_test_add_model(dir, "bunny", 99, 12);
    assert_int_equal(ms_catalog_remove(dir, "dragon", &err), MS_OK);
    snprintf(path, sizeof path, "%s/dragon.msa", dir);
    assert_int_equal(unlink(path), 0);
    assert_int_equal(ms_registry_scan(dir, r2, 16, &r3, collect, &w, &err), MS_OK);
    assert_int_equal(ms_registry_count(r3), 1);
    assert_null(ms_registry_find(r3, "dragon"));
    ms_model *bunny_new = ms_registry_find(r3, "bunny");
    assert_true(bunny_new != ms_registry_find(r2, "bunny"));
    size_t len;
    const uint8_t *g = ms_archive_geometry(bunny_new->archive, 3, &len);
    uint8_t expect[1024];
    ms_test_archive_fill(expect, (uint32_t)len, 3 + 99);
    assert_memory_equal(g, expect, len);
    ms_registry_free(r1);
    ms_registry_free(r2);
    /* Still readable after every registry let go of it. */
    assert_int_equal(dragon->refs, 1);
    assert_int_equal(ms_archive_verify_payload(dragon->archive, 7, &err), MS_OK);
    ms_model_unref(dragon);
    ms_registry_free(r3);
    ms_test_rmdir(dir);
}

static void test_broken_models_are_skipped(void **state)
{
    (void)state;
    char dir[512], path[700];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_add_model(dir, "good", 1, 12);
    ms_test_add_model(dir, "broken", 2, 12);
    ms_test_add_model(dir, "missing", 3, 12);
    snprintf(path, sizeof path, "%s/broken.msa", dir);
    FILE *f = fopen(path, "r+b");
    assert_non_null(f);
    fseek(f, 200, SEEK_SET);
    fputc('X', f);
    fclose(f);
    snprintf(path, sizeof path, "%s/missing.msa", dir);
    assert_int_equal(unlink(path), 0);
    warnings w = {0};
    ms_registry *r;
    assert_int_equal(ms_registry_scan(dir, NULL, 16, &r, collect, &w, NULL), MS_OK);
    /* The scan reads no archive: the broken one is found at its first request,
     * warned about once, and then absent. */
    assert_int_equal(ms_registry_count(r), 2);
    assert_int_equal(w.count, 1);
    assert_non_null(strstr(w.last, "model 'missing' skipped: archive file missing"));
    assert_non_null(ms_registry_find(r, "good"));
    assert_null(ms_registry_find(r, "broken"));
    assert_int_equal(w.count, 2);
    assert_non_null(strstr(w.last, "model 'broken' cannot be served: "));
    assert_null(ms_registry_find(r, "broken"));
    assert_int_equal(w.count, 2);
    assert_int_equal(ms_registry_open_count(r), 1);
    ms_registry_free(r);

    ms_error err;
    assert_int_equal(ms_registry_scan("/nonexistent", NULL, 16, &r, NULL, NULL, &err), MS_ERR_IO);
    assert_null(r);
    snprintf(path, sizeof path, "%s/catalog.json", dir);
    f = fopen(path, "w");
    fputs("{", f);
    fclose(f);
    assert_int_equal(ms_registry_scan(dir, NULL, 16, &r, NULL, NULL, &err), MS_ERR_FORMAT);
    assert_null(r);
    ms_test_rmdir(dir);
}

static void test_archives_open_on_first_request_and_close_by_use(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    const char *names[4] = {"a", "b", "c", "d"};
    for (int i = 0; i < 4; ++i)
        ms_test_add_model(dir, names[i], (uint32_t)i + 1, 12);
    ms_registry *r;
    ms_error err;
    assert_int_equal(ms_registry_scan(dir, NULL, 2, &r, NULL, NULL, &err), MS_OK);
    assert_int_equal(ms_registry_count(r), 4);
    assert_int_equal(ms_registry_open_count(r), 0);
    assert_string_equal(ms_registry_entry(r, 2)->name, "c");
    assert_null(ms_registry_peek(r, "a"));

    ms_model *a = ms_registry_find(r, "a");
    assert_non_null(a);
    assert_ptr_equal(ms_registry_peek(r, "a"), a);
    assert_ptr_equal(ms_registry_open_model_at(r, 0), a);
    assert_null(ms_registry_open_model_at(r, 1));
    a->requests = 5;
    assert_non_null(ms_registry_find(r, "b"));
    assert_int_equal(ms_registry_open_count(r), 2);
    /* A third: the least recently used one (a) closes, its counters kept. */
    assert_non_null(ms_registry_find(r, "c"));
    assert_int_equal(ms_registry_open_count(r), 2);
    assert_null(ms_registry_peek(r, "a"));
    assert_non_null(ms_registry_peek(r, "b"));
    /* Using b makes c the oldest. */
    assert_non_null(ms_registry_find(r, "b"));
    a = ms_registry_find(r, "a");
    assert_int_equal(a->requests, 5);
    assert_null(ms_registry_peek(r, "c"));
    /* A model a client holds is never closed, even over the limit. */
    ms_model_ref(a);
    assert_non_null(ms_registry_find(r, "c"));
    assert_non_null(ms_registry_find(r, "d"));
    assert_int_equal(ms_registry_open_count(r), 2);
    assert_ptr_equal(ms_registry_peek(r, "a"), a);
    assert_non_null(ms_registry_peek(r, "d"));
    assert_null(ms_registry_peek(r, "b"));
    assert_null(ms_registry_peek(r, "c"));

    /* Idleness: every model unused for the period closes, unless held. */
    ms_registry_close_idle(r, ms_now_seconds() + 1000.0, 300.0);
    assert_int_equal(ms_registry_open_count(r), 1);
    assert_ptr_equal(ms_registry_peek(r, "a"), a);
    ms_model_unref(a);
    assert_non_null(ms_registry_find(r, "b"));
    ms_registry_close_idle(r, ms_now_seconds(), 300.0);
    assert_int_equal(ms_registry_open_count(r), 2);
    ms_registry_close_idle(r, ms_now_seconds() + 301.0, 300.0);
    assert_int_equal(ms_registry_open_count(r), 0);
    ms_registry_free(r);
    ms_test_rmdir(dir);
}

/* A rescan keeps the open models' order of use (not their name order), so
 * the least recently used closes first after it too. */
static void test_rescan_keeps_the_order_of_use(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_add_model(dir, "a", 1, 12);
    ms_test_add_model(dir, "b", 2, 12);
    ms_test_add_model(dir, "c", 3, 12);
    ms_registry *r1, *r2;
    assert_int_equal(ms_registry_scan(dir, NULL, 8, &r1, NULL, NULL, NULL), MS_OK);
    assert_non_null(ms_registry_find(r1, "b"));
    usleep(2000);
    assert_non_null(ms_registry_find(r1, "a")); /* a used after b */
    assert_int_equal(ms_registry_scan(dir, r1, 2, &r2, NULL, NULL, NULL), MS_OK);
    assert_int_equal(ms_registry_open_count(r2), 2);
    ms_registry_free(r1);
    assert_non_null(ms_registry_find(r2, "c"));
    assert_int_equal(ms_registry_open_count(r2), 2);
    assert_non_null(ms_registry_peek(r2, "a"));
    assert_null(ms_registry_peek(r2, "b"));
    ms_registry_free(r2);
    ms_test_rmdir(dir);
}

static void test_rescan_keeps_the_served_version_of_a_broken_replacement(void **state)
{
    (void)state;
    char dir[512], path[700], aside[720];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_add_model(dir, "bust", 1, 12);
    ms_test_add_model(dir, "idle", 2, 12);
    warnings w = {0};
    ms_registry *r1, *r2;
    assert_int_equal(ms_registry_scan(dir, NULL, 8, &r1, collect, &w, NULL), MS_OK);
    ms_model *bust = ms_registry_find(r1, "bust");
    assert_non_null(bust);
    bust->bytes_sent = 1234;
    /* A broken file renamed over both: the open one is checked at the rescan,
     * the idle one at its next request. */
    const char *names[2] = {"bust", "idle"};
    for (int i = 0; i < 2; ++i) {
        snprintf(path, sizeof path, "%s/%s.msa", dir, names[i]);
        snprintf(aside, sizeof aside, "%s/%s.new", dir, names[i]);
        FILE *f = fopen(aside, "wb");
        assert_non_null(f);
        fputs("not an archive", f);
        fclose(f);
        assert_int_equal(rename(aside, path), 0);
    }
    assert_int_equal(ms_registry_scan(dir, r1, 8, &r2, collect, &w, NULL), MS_OK);
    assert_int_equal(w.count, 1);
    assert_non_null(strstr(w.last, "model 'bust': keeping the version being served"));
    assert_ptr_equal(ms_registry_find(r2, "bust"), bust);
    assert_int_equal(bust->bytes_sent, 1234);
    assert_null(ms_registry_find(r2, "idle"));
    assert_int_equal(w.count, 2);
    assert_non_null(strstr(w.last, "model 'idle' cannot be served: "));
    ms_registry_free(r1);
    ms_registry_free(r2);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_scan_rescan_replace_remove),
        cmocka_unit_test(test_broken_models_are_skipped),
        cmocka_unit_test(test_archives_open_on_first_request_and_close_by_use),
        cmocka_unit_test(test_rescan_keeps_the_order_of_use),
        cmocka_unit_test(test_rescan_keeps_the_served_version_of_a_broken_replacement),
    };
    return cmocka_run_group_tests_name("registry", tests, NULL, NULL);
}
