/* Sidecar metadata (ms_metadata.h): valid sidecars, hostile ones refused with
 * one exact line each, and the metadata kept in catalog.json through a
 * rebake, a per-entry reload and the thumbnail update. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_catalog.h"
#include "ms_metadata.h"
#include "ms_test.h"

static ms_status parse(const char *text, ms_metadata **m, ms_error *err)
{
    ms_error_clear(err);
    return ms_metadata_parse(text, strlen(text), "side.json", m, err);
}

static void test_a_sidecar_is_read_whole(void **state)
{
    (void)state;
    ms_metadata *m;
    ms_error err;
    assert_int_equal(parse("{\"title\": \"Demo <script>alert(1)</script>\", \"creator\": "
                           "\"M\\u00fcller & S\\u00f8n\", \"date\": \"1998-03\", \"licence\": "
                           "\"CC BY 4.0\", \"description\": \"Two\\nlines\"}", &m, &err),
                     MS_OK);
    assert_non_null(m);
    assert_string_equal(m->title, "Demo <script>alert(1)</script>");
    assert_string_equal(m->creator, "M\xc3\xbcller & S\xc3\xb8n");
    assert_string_equal(m->date, "1998-03");
    assert_string_equal(m->licence, "CC BY 4.0");
    assert_string_equal(m->description, "Two\nlines");
    bool failed = false;
    ms_metadata *copy = ms_metadata_dup(m, &failed);
    assert_false(failed);
    assert_true(ms_metadata_equal(m, copy));
    assert_ptr_not_equal(copy->title, m->title);
    ms_metadata_free(copy);
    ms_metadata_free(m);
    /* empty strings and an empty object: no metadata */
    assert_int_equal(parse("{\"title\": \"\", \"creator\": \"A\"}", &m, &err), MS_OK);
    assert_null(m->title);
    assert_string_equal(m->creator, "A");
    assert_null(m->description);
    ms_metadata_free(m);
    assert_int_equal(parse("{}", &m, &err), MS_OK);
    assert_null(m);
    assert_int_equal(parse("{\"description\": \"\"}", &m, &err), MS_OK);
    assert_null(m);
    assert_true(ms_metadata_equal(NULL, NULL));
}

static void test_hostile_sidecars_get_one_line(void **state)
{
    (void)state;
    char longest[MS_METADATA_TITLE_MAX + 40], too_long[MS_METADATA_TITLE_MAX + 40];
    snprintf(longest, sizeof longest, "{\"title\": \"%*s\"}", MS_METADATA_TITLE_MAX, "x");
    snprintf(too_long, sizeof too_long, "{\"title\": \"%*s\"}", MS_METADATA_TITLE_MAX + 1, "x");
    ms_metadata *m = NULL;
    ms_error err;
    assert_int_equal(parse(longest, &m, &err), MS_OK);
    assert_int_equal(strlen(m->title), MS_METADATA_TITLE_MAX);
    ms_metadata_free(m);
    const struct {
        const char *text;
        ms_status status;
        const char *error;
    } cases[] = {
        {"", MS_ERR_FORMAT, "side.json: line 1: '[' or '{' expected near end of file"},
        {"[\"title\"]", MS_ERR_FORMAT, "side.json: metadata is not a JSON object"},
        {"{\"title\": 1}", MS_ERR_FORMAT, "side.json: metadata title is not a string"},
        {"{\"author\": \"x\"}", MS_ERR_FORMAT,
         "side.json: unknown metadata field 'author' (title, creator, date, licence, description, unit)"},
        {"{\"title\": \"a\", \"title\": \"b\"}", MS_ERR_FORMAT,
         "side.json: line 1: duplicate object key near '\"title\"'"},
        {"{\"title\": \"a\\u0000b\"}", MS_ERR_FORMAT,
         "side.json: line 1: \\u0000 is not allowed without JSON_ALLOW_NUL near '\"a\\u0000b\"'"},
        {"{\"title\": \"\xff\"}", MS_ERR_FORMAT, "side.json: line 1: unable to decode byte 0xff near '\"'"},
        {"{\"title\": \"two\\nlines\"}", MS_ERR_FORMAT,
         "side.json: metadata title holds a control character or a line break"},
        {"{\"creator\": \"bell\\u0007\"}", MS_ERR_FORMAT,
         "side.json: metadata creator holds a control character or a line break"},
        {"{\"description\": \"tab\\there\"}", MS_ERR_FORMAT,
         "side.json: metadata description holds a control character (only line feeds are allowed)"},
        {"{\"licence\": \"c1 \\u0085\"}", MS_ERR_FORMAT,
         "side.json: metadata licence holds a control character or a line break"},
        {"{\"title\": \"abc\\u202edcba\"}", MS_ERR_FORMAT,
         "side.json: metadata title holds a bidirectional override or isolate character"},
        {"{\"date\": \"\\u2066x\"}", MS_ERR_FORMAT,
         "side.json: metadata date holds a bidirectional override or isolate character"},
        {too_long, MS_ERR_RANGE, "side.json: metadata title is 201 bytes, at most 200"},
        {"{\"date\": \"2026-12-06T11:30:00Z and a few more words\"}", MS_ERR_RANGE,
         "side.json: metadata date is 41 bytes, at most 40"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        m = (ms_metadata *)&err; /* set to NULL on failure */
        assert_int_equal(parse(cases[i].text, &m, &err), cases[i].status);
        assert_null(m);
        assert_string_equal(err.text, cases[i].error);
        assert_null(strchr(err.text, '\n'));
    }
    /* a file over the size limit, whatever it holds */
    size_t big = MS_METADATA_FILE_MAX + 1;
    char *text = malloc(big);
    memset(text, ' ', big);
    text[0] = '{', text[big - 1] = '}';
    assert_int_equal(ms_metadata_parse(text, big, "big.json", &m, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "big.json: 16385 bytes, a metadata file holds at most 16384");
    free(text);
    /* the checker alone: a surrogate, an overlong, a truncated sequence */
    const char *why = NULL;
    assert_false(ms_metadata_text_ok("\xed\xa0\x80", 3, true, &why));
    assert_string_equal(why, "is not valid UTF-8");
    assert_false(ms_metadata_text_ok("\xc0\xaf", 2, true, &why));
    assert_false(ms_metadata_text_ok("\xe2\x82", 2, true, &why));
    assert_false(ms_metadata_text_ok("\xf4\x90\x80\x80", 4, true, &why));
    assert_true(ms_metadata_text_ok("\xf0\x9f\x97\xbf \xe2\x82\xac", 8, false, &why));
}

static void test_a_sidecar_file(void **state)
{
    (void)state;
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/side.json", dir);
    const char *text = "{\"title\": \"Igea\"}\n";
    ms_test_write_file(path, text, strlen(text));
    ms_metadata *m;
    ms_error err;
    assert_int_equal(ms_metadata_load(path, &m, &err), MS_OK);
    assert_string_equal(m->title, "Igea");
    ms_metadata_free(m);
    assert_int_equal(ms_metadata_load(dir, &m, &err), MS_ERR_IO);
    char want[700];
    snprintf(want, sizeof want, "%s: not a regular file (a directory)", dir);
    assert_string_equal(err.text, want);
    ms_test_rmdir(dir);
}

static ms_catalog_entry sample(const char *name)
{
    ms_catalog_entry e;
    memset(&e, 0, sizeof e);
    snprintf(e.name, sizeof e.name, "%s", name);
    e.source = (char *)"in.ply";
    snprintf(e.baked_at, sizeof e.baked_at, "2026-12-06T11:00:00Z");
    e.vertices = 10, e.triangles = 16, e.archive_bytes = 1000, e.cells = 1;
    e.bits = 16, e.n = 4, e.root_bits = 7, e.min_triangles = 8000;
    e.public_max_bits = 16;
    return e;
}

static void test_the_catalogue_keeps_metadata(void **state)
{
    (void)state;
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    ms_error err;
    ms_metadata *meta;
    assert_int_equal(parse("{\"title\": \"A \\\"quoted\\\" {brace}\", \"description\": "
                           "\"<b>x</b>\\nsecond line\", \"unit\": \"cm\"}", &meta, &err), MS_OK);
    ms_catalog_entry a = sample("alpha"), b = sample("beta");
    a.metadata = meta;
    a.has_thumbnail = true, a.thumbnail_bits = 9;
    assert_int_equal(ms_catalog_update(dir, &a, &err), MS_OK);
    assert_int_equal(ms_catalog_update(dir, &b, &err), MS_OK);
    ms_catalog first, second;
    assert_int_equal(ms_catalog_load(dir, &first, &err), MS_OK);
    const ms_catalog_entry *got = ms_catalog_find(&first, "alpha");
    assert_true(ms_metadata_equal(got->metadata, meta));
    assert_true(got->has_thumbnail);
    assert_int_equal(got->thumbnail_bits, 9);
    assert_null(ms_catalog_find(&first, "beta")->metadata);
    assert_false(ms_catalog_find(&first, "beta")->has_thumbnail);
    assert_true(got->text_hash != 0); /* the writer's layout, entry by entry */
    /* baked again without metadata: kept; the thumbnail goes as the bake says */
    ms_catalog_entry again = sample("alpha");
    again.triangles = 99;
    assert_int_equal(ms_catalog_update(dir, &again, &err), MS_OK);
    assert_int_equal(ms_catalog_reload(dir, &first, &second, &err), MS_OK);
    got = ms_catalog_find(&second, "alpha");
    assert_int_equal(got->triangles, 99);
    assert_true(ms_metadata_equal(got->metadata, meta));
    assert_false(got->has_thumbnail);
    /* beta's entry was copied from first, not parsed: its own copy */
    assert_int_equal(ms_catalog_find(&second, "beta")->text_hash,
                     ms_catalog_find(&first, "beta")->text_hash);
    ms_catalog_free(&first);
    ms_catalog_free(&second);
    /* the thumbnail fields alone */
    assert_int_equal(ms_catalog_update_thumbnail(dir, "beta", true, 12, 1, &err), MS_OK);
    assert_int_equal(ms_catalog_update_thumbnail(dir, "gamma", true, 12, 1, &err), MS_ERR_RANGE);
    char want[700];
    snprintf(want, sizeof want, "no model 'gamma' in %s/catalog.json", dir);
    assert_string_equal(err.text, want);
    assert_int_equal(ms_catalog_load(dir, &first, &err), MS_OK);
    assert_int_equal(ms_catalog_find(&first, "beta")->thumbnail_bits, 12);
    assert_int_equal(ms_catalog_find(&first, "beta")->thumbnail_up, 1);
    assert_int_equal(ms_catalog_find(&first, "beta")->triangles, 16);
    assert_true(ms_metadata_equal(ms_catalog_find(&first, "alpha")->metadata, meta));
    ms_catalog_free(&first);
    ms_metadata_free(meta);
    /* hostile metadata in catalog.json itself: the same one-line errors */
    snprintf(path, sizeof path, "%s/catalog.json", dir);
    static const struct {
        const char *meta;
        const char *error;
    } bad[] = {
        {"\"metadata\": \"title\"", "metadata is not a JSON object"},
        {"\"metadata\": {\"title\": \"a\\u202eb\"}",
         "metadata title holds a bidirectional override or isolate character"},
        {"\"metadata\": {\"x\": \"y\"}",
         "unknown metadata field 'x' (title, creator, date, licence, description, unit)"},
        {"\"metadata\": {\"unit\": \"inch\"}",
         "metadata unit is not one of um, mm, cm, m, in, ft"},
        {"\"thumbnail_bits\": 21", "thumbnail_bits is not an integer in 0..20"},
        {"\"thumbnail_bits\": 8, \"thumbnail_up\": \"w\"",
         "thumbnail_up is not \"x\", \"y\" or \"z\""},
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        char text[1200];
        snprintf(text, sizeof text,
                 "{\"models\": [{\"name\": \"m\", \"source\": \"s\", \"baked_at\": \"t\", "
                 "\"vertices\": 1, \"triangles\": 1, \"archive_bytes\": 1, \"cells\": 1, "
                 "\"bits\": 16, \"n\": 4, \"root_bits\": 7, \"min_triangles\": 1, \"apo\": false, "
                 "\"apo_lead\": 0, \"apo_max_depth\": 0, \"apo_tolerance\": 0, "
                 "\"public_max_bits\": 16, %s}], \"version\": 1}", bad[i].meta);
        ms_test_write_file(path, text, strlen(text));
        assert_int_equal(ms_catalog_load(dir, &first, &err), MS_ERR_FORMAT);
        snprintf(want, sizeof want, "%s: model 0: %s", path, bad[i].error);
        assert_string_equal(err.text, want);
        assert_int_equal(first.count, 0);
    }
    ms_test_rmdir(dir);
}

/* Each unit of the list is kept as given; anything else is refused with one
 * line; an empty unit is none ("model units"). */
static void test_a_unit_is_one_of_the_list(void **state)
{
    (void)state;
    static const char *const units[] = {"um", "mm", "cm", "m", "in", "ft"};
    char text[200];
    ms_metadata *m;
    ms_error err;
    for (size_t i = 0; i < sizeof units / sizeof *units; ++i) {
        snprintf(text, sizeof text, "{\"title\": \"t\", \"unit\": \"%s\"}", units[i]);
        assert_int_equal(parse(text, &m, &err), MS_OK);
        assert_string_equal(m->unit, units[i]);
        assert_string_equal(ms_metadata_field(m, 5), units[i]);
        assert_string_equal(ms_metadata_unit_name(m), units[i]);
        assert_true(ms_metadata_unit_valid(units[i]));
        ms_metadata *copy = ms_metadata_dup(m, NULL);
        assert_true(ms_metadata_equal(m, copy));
        ms_metadata_free(copy);
        ms_metadata_free(m);
    }
    /* a unit alone is metadata; an empty one is none */
    assert_int_equal(parse("{\"unit\": \"mm\"}", &m, &err), MS_OK);
    assert_null(m->title);
    assert_string_equal(m->unit, "mm");
    ms_metadata_free(m);
    assert_int_equal(parse("{\"unit\": \"\"}", &m, &err), MS_OK);
    assert_null(m);
    assert_string_equal(ms_metadata_unit_name(NULL), "model units");
    assert_int_equal(parse("{\"title\": \"t\"}", &m, &err), MS_OK);
    assert_string_equal(ms_metadata_unit_name(m), "model units");
    ms_metadata_free(m);
    static const char *const bad[] = {
        "{\"unit\": \"MM\"}",         "{\"unit\": \"mm \"}",      "{\"unit\": \"millimetre\"}",
        "{\"unit\": \"model units\"}", "{\"unit\": \"m\\u202e\"}", "{\"unit\": \"\\u00b5m\"}",
        "{\"unit\": \"km\"}",         "{\"unit\": \"m\\n\"}",
    };
    for (size_t i = 0; i < sizeof bad / sizeof *bad; ++i) {
        m = (ms_metadata *)&err;
        assert_int_equal(parse(bad[i], &m, &err), MS_ERR_FORMAT);
        assert_null(m);
        assert_string_equal(err.text, "side.json: metadata unit is not one of um, mm, cm, m, in, ft");
    }
    assert_int_equal(parse("{\"unit\": 1}", &m, &err), MS_ERR_FORMAT);
    assert_string_equal(err.text, "side.json: metadata unit is not a string");
    assert_false(ms_metadata_unit_valid(NULL));
    assert_false(ms_metadata_unit_valid(""));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_sidecar_is_read_whole),
        cmocka_unit_test(test_hostile_sidecars_get_one_line),
        cmocka_unit_test(test_a_sidecar_file),
        cmocka_unit_test(test_the_catalogue_keeps_metadata),
        cmocka_unit_test(test_a_unit_is_one_of_the_list),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
