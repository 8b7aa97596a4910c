/* catalog.json: names, add/replace/remove, malformed files, concurrent bakers. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>
#include <cmocka.h>
#include <jansson.h>

#include "ms_catalog.h"
#include "ms_archive.h"
#include "ms_test.h"
#include "ms_test_archive.h"

static ms_catalog_entry sample(const char *name, uint64_t triangles)
{
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", name);
    e.source = (char *)"/data/dragon.ply.gz";
    snprintf(e.baked_at, sizeof e.baked_at, "2026-11-22T02:30:00Z");
    e.vertices = 437645, e.triangles = triangles, e.archive_bytes = 1 << 20, e.cells = 65;
    e.bits = 16, e.n = 4, e.root_bits = 7, e.min_triangles = 8000;
    e.apo = true, e.apo_lead = 3, e.apo_max_depth = 13, e.apo_tolerance = 0.05;
    e.public_max_bits = 10;
    return e;
}

static void test_model_names(void **state)
{
    (void)state;
    assert_true(ms_model_name_valid("dragon"));
    assert_true(ms_model_name_valid("Igea_2-x"));
    char longest[65];
    memset(longest, 'a', 64);
    longest[64] = '\0';
    assert_true(ms_model_name_valid(longest));
    const char *bad[] = {"", "../etc", "a/b", "a.b", "x y", "dragon\n", "é", "..", "/abs"};
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i)
        assert_false(ms_model_name_valid(bad[i]));
    char too_long[66];
    memset(too_long, 'a', 65);
    too_long[65] = '\0';
    assert_false(ms_model_name_valid(too_long));
}

static void test_add_replace_remove(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    ms_catalog c;
    ms_error err;
    assert_int_equal(ms_catalog_load(dir, &c, &err), MS_OK);
    assert_int_equal(c.count, 0);
    ms_catalog_entry e = sample("dragon", 871414);
    assert_int_equal(ms_catalog_update(dir, &e, &err), MS_OK);
    e = sample("bunny", 69451);
    assert_int_equal(ms_catalog_update(dir, &e, &err), MS_OK);
    e = sample("dragon", 871000);
    assert_int_equal(ms_catalog_update(dir, &e, &err), MS_OK);
    assert_int_equal(ms_catalog_load(dir, &c, &err), MS_OK);
    assert_int_equal(c.count, 2);
    assert_string_equal(c.entries[0].name, "bunny");
    const ms_catalog_entry *d = ms_catalog_find(&c, "dragon");
    assert_non_null(d);
    assert_int_equal(d->triangles, 871000);
    assert_int_equal(d->vertices, 437645);
    assert_string_equal(d->source, "/data/dragon.ply.gz");
    assert_string_equal(d->baked_at, "2026-11-22T02:30:00Z");
    assert_true(d->apo && d->apo_tolerance == 0.05 && d->public_max_bits == 10);
    assert_null(ms_catalog_find(&c, "../dragon"));
    ms_catalog_free(&c);
    assert_int_equal(ms_catalog_remove(dir, "dragon", &err), MS_OK);
    assert_int_equal(ms_catalog_load(dir, &c, &err), MS_OK);
    assert_int_equal(c.count, 1);
    assert_null(ms_catalog_find(&c, "dragon"));
    ms_catalog_free(&c);
    e = sample("../evil", 1);
    assert_int_equal(ms_catalog_update(dir, &e, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "invalid model name"));
    ms_test_rmdir(dir);
}

static void expect_load_error(const char *text, ms_status code, const char *message)
{
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/catalog.json", dir);
    FILE *f = fopen(path, "w");
    assert_non_null(f);
    fputs(text, f);
    fclose(f);
    ms_catalog c;
    ms_error err;
    assert_int_equal(ms_catalog_load(dir, &c, &err), code);
    if (!strstr(err.text, message))
        fail_msg("'%s' does not mention '%s'", err.text, message);
    assert_int_equal(c.count, 0);
    assert_null(c.entries);
    ms_test_rmdir(dir);
}

static void test_malformed_catalogues(void **state)
{
    (void)state;
    expect_load_error("{\"version\": 1, \"models\": [", MS_ERR_FORMAT, "line 1");
    expect_load_error("[]", MS_ERR_FORMAT, "not a meshstream catalogue");
    expect_load_error("{\"version\": 9, \"models\": []}", MS_ERR_UNSUPPORTED, "version 9");
    expect_load_error("{\"version\": 1, \"models\": [{\"name\": \"x\"}]}", MS_ERR_FORMAT,
                      "model 0: missing or mistyped field");
    const char *entry =
        "{\"name\": \"%s\", \"source\": \"s\", \"baked_at\": \"t\", \"vertices\": %s, "
        "\"triangles\": 1, \"archive_bytes\": 1, \"cells\": 1, \"bits\": 16, \"n\": 4, "
        "\"root_bits\": 7, \"min_triangles\": 1, \"apo\": false, \"apo_lead\": 3, "
        "\"apo_max_depth\": 13, \"apo_tolerance\": 0.1, \"public_max_bits\": 16}";
    char one[1024], two[1024], text[4096];
    snprintf(one, sizeof one, entry, "a/b", "1");
    snprintf(text, sizeof text, "{\"version\": 1, \"models\": [%s]}", one);
    expect_load_error(text, MS_ERR_FORMAT, "invalid name");
    snprintf(one, sizeof one, entry, "a", "-5");
    snprintf(text, sizeof text, "{\"version\": 1, \"models\": [%s]}", one);
    expect_load_error(text, MS_ERR_FORMAT, "out of range");
    snprintf(one, sizeof one, entry, "a", "1");
    snprintf(two, sizeof two, entry, "a", "2");
    snprintf(text, sizeof text, "{\"version\": 1, \"models\": [%s, %s]}", one, two);
    expect_load_error(text, MS_ERR_FORMAT, "listed twice");
    /* the listing figures: 16 lower-case hex digits and an apo_levels */
    const char *listings[] = {"\"content_id\": \"0123456789ABCDEF\", \"apo_levels\": 3",
                              "\"content_id\": \"0123456789abcde\", \"apo_levels\": 3",
                              "\"content_id\": 7, \"apo_levels\": 3",
                              "\"content_id\": \"0123456789abcdef\"",
                              "\"content_id\": \"0123456789abcdef\", \"apo_levels\": 65"};
    for (size_t i = 0; i < sizeof listings / sizeof *listings; ++i) {
        snprintf(one, sizeof one, entry, "a", "1");
        snprintf(one + strlen(one) - 1, sizeof one - strlen(one) + 1, ", %s}", listings[i]);
        snprintf(text, sizeof text, "{\"version\": 1, \"models\": [%s]}", one);
        expect_load_error(text, MS_ERR_FORMAT, "content_id is not 16 lower-case hex digits");
    }
}

/* A bake records what a server lists without opening the archive, and the
 * catalogue keeps it exactly. */
static void test_listing_figures_round_trip(void **state)
{
    (void)state;
    char dir[512], path[700];
    ms_test_tmpdir(dir, sizeof dir);
    ms_test_add_model(dir, "bust", 5, 12);
    snprintf(path, sizeof path, "%s/bust.msa", dir);
    ms_archive *a;
    ms_error err;
    assert_int_equal(ms_archive_open(path, &a, &err), MS_OK);
    ms_catalog c;
    assert_int_equal(ms_catalog_load(dir, &c, &err), MS_OK);
    const ms_catalog_entry *e = ms_catalog_find(&c, "bust");
    assert_true(e->has_listing);
    assert_true(e->content_id == ms_archive_content_id(a));
    assert_int_equal(e->apo_levels, ms_archive_max_apo_levels(a));
    assert_true(e->apo_levels > 0);
    ms_archive_close(a);
    ms_catalog_entry changed = *e;
    changed.content_id = 0xfedcba9876543210ull;
    changed.apo_levels = 64;
    assert_int_equal(ms_catalog_update(dir, &changed, &err), MS_OK);
    ms_catalog_free(&c);
    assert_int_equal(ms_catalog_load(dir, &c, &err), MS_OK);
    e = ms_catalog_find(&c, "bust");
    assert_true(e->content_id == 0xfedcba9876543210ull && e->apo_levels == 64);
    ms_catalog_free(&c);
    snprintf(path, sizeof path, "%s/nothing.msa", dir);
    changed.has_listing = false;
    assert_int_equal(ms_catalog_entry_fill_listing(&changed, path, &err), MS_ERR_IO);
    assert_false(changed.has_listing);
    ms_test_rmdir(dir);
}

/* A reload parses again only the entries whose text changed: an unchanged
 * entry is copied from the previous catalogue (shown by a value changed in
 * memory surviving), a changed one is read from the file; a file in another
 * layout is parsed whole and gives the same entries. */
static void test_reload_parses_only_what_changed(void **state)
{
    (void)state;
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    ms_error err;
    const char *names[3] = {"alpha", "beta", "gamma"};
    for (int i = 0; i < 3; ++i) {
        ms_catalog_entry e = sample(names[i], 100 + (uint64_t)i);
        e.source = (char *)"a \"quoted\" {brace} [x] \\ path";
        assert_int_equal(ms_catalog_update(dir, &e, &err), MS_OK);
    }
    ms_catalog first, second;
    assert_int_equal(ms_catalog_load(dir, &first, &err), MS_OK);
    assert_int_equal(first.count, 3);
    for (size_t i = 0; i < 3; ++i)
        assert_true(first.entries[i].text_hash != 0);
    assert_string_equal(first.entries[1].source, "a \"quoted\" {brace} [x] \\ path");
    first.entries[0].vertices = 777; /* alpha: in memory only */
    first.entries[2].vertices = 888; /* gamma: in memory, and changed on disk */
    ms_catalog_entry g = sample("gamma", 555);
    assert_int_equal(ms_catalog_update(dir, &g, &err), MS_OK);
    assert_int_equal(ms_catalog_reload(dir, &first, &second, &err), MS_OK);
    assert_int_equal(second.count, 3);
    assert_int_equal(ms_catalog_find(&second, "alpha")->vertices, 777);
    assert_int_equal(ms_catalog_find(&second, "beta")->triangles, 101);
    assert_int_equal(ms_catalog_find(&second, "gamma")->triangles, 555);
    assert_int_equal(ms_catalog_find(&second, "gamma")->vertices, 437645);
    assert_string_equal(ms_catalog_find(&second, "beta")->source,
                        "a \"quoted\" {brace} [x] \\ path");
    ms_catalog_free(&second);
    ms_catalog_free(&first);

    /* "version" before "models": not the writer's layout, parsed whole */
    assert_int_equal(ms_catalog_load(dir, &first, &err), MS_OK);
    snprintf(path, sizeof path, "%s/catalog.json", dir);
    json_error_t jerr;
    json_t *root = json_load_file(path, 0, &jerr);
    json_t *swapped = json_pack("{s:i, s:O}", "version", 1, "models", json_object_get(root, "models"));
    assert_int_equal(json_dump_file(swapped, path, JSON_INDENT(1) | JSON_PRESERVE_ORDER), 0);
    json_decref(swapped);
    json_decref(root);
    assert_int_equal(ms_catalog_reload(dir, &first, &second, &err), MS_OK);
    assert_int_equal(second.count, 3);
    for (size_t i = 0; i < 3; ++i) {
        assert_string_equal(second.entries[i].name, first.entries[i].name);
        assert_int_equal(second.entries[i].triangles, first.entries[i].triangles);
        assert_int_equal(second.entries[i].text_hash, 0);
    }
    ms_catalog_free(&second);
    ms_catalog_free(&first);
    ms_test_rmdir(dir);
}

/* Several processes updating at once: every entry survives. */
static void test_concurrent_updates_lose_nothing(void **state)
{
    (void)state;
    char dir[512];
    ms_test_tmpdir(dir, sizeof dir);
    enum { WRITERS = 4, EACH = 10 };
    pid_t pids[WRITERS];
    for (int w = 0; w < WRITERS; ++w) {
        pids[w] = fork();
        assert_true(pids[w] >= 0);
        if (pids[w] == 0) {
            for (int k = 0; k < EACH; ++k) {
                char name[32];
                snprintf(name, sizeof name, "m%d_%d", w, k);
                ms_catalog_entry e = sample(name, (uint64_t)k);
                if (ms_catalog_update(dir, &e, NULL) != MS_OK)
                    _exit(1);
            }
            _exit(0);
        }
    }
    for (int w = 0; w < WRITERS; ++w) {
        int status;
        assert_int_equal(waitpid(pids[w], &status, 0), pids[w]);
        assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    }
    ms_catalog c;
    assert_int_equal(ms_catalog_load(dir, &c, NULL), MS_OK);
    assert_int_equal(c.count, WRITERS * EACH);
    ms_catalog_free(&c);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_model_names),
        cmocka_unit_test(test_add_replace_remove),
        cmocka_unit_test(test_malformed_catalogues),
        cmocka_unit_test(test_listing_figures_round_trip),
        cmocka_unit_test(test_reload_parses_only_what_changed),
        cmocka_unit_test(test_concurrent_updates_lose_nothing),
    };
    return cmocka_run_group_tests_name("catalog", tests, NULL, NULL);
}
