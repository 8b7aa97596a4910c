/* Model annotations (ms_annotations.h, docs/ANNOTATIONS.md): a file read
 * whole, written and read back to the same set bit for bit, edits, and
 * hostile files refused with one exact line each. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_annotations.h"
#include "ms_test.h"

static const char *const good =
    "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": [\n"
    " {\"id\": \"nose\", \"point\": [0.125, -3, 1e-7], \"title\": \"Nose <b>&amp;</b>\",\n"
    "  \"text\": \"Two\\nlines, M\\u00fcller\", \"view\": \"mv1:t=0,0,0:d=2:o=0.5,0.25:f=45:u=z\"},\n"
    " {\"id\": \"ear-2\", \"point\": [1, 2, 3], \"radius\": 0.5, \"title\": \"Ear\"}]}";

static ms_status parse(const char *text, ms_annotations **set, ms_error *err)
{
    ms_error_clear(err);
    return ms_annotations_parse(text, strlen(text), "a.json", set, err);
}

static void test_a_file_is_read_whole(void **state)
{
    (void)state;
    ms_annotations *set;
    ms_error err;
    assert_int_equal(parse(good, &set, &err), MS_OK);
    assert_int_equal(ms_annotations_count(set), 2);
    const ms_annotation *a = ms_annotations_get(set, 0), *b = ms_annotations_get(set, 1);
    assert_string_equal(a->id, "nose");
    assert_true(a->point[0] == 0.125 && a->point[1] == -3 && a->point[2] == 1e-7);
    assert_true(a->radius == 0);
    assert_string_equal(a->title, "Nose <b>&amp;</b>");
    assert_string_equal(a->text, "Two\nlines, M\xc3\xbcller");
    assert_string_equal(a->view, "mv1:t=0,0,0:d=2:o=0.5,0.25:f=45:u=z");
    assert_string_equal(b->id, "ear-2");
    assert_true(b->radius == 0.5);
    assert_string_equal(b->text, "");
    assert_null(b->view);
    assert_null(ms_annotations_get(set, 2));
    assert_int_equal(ms_annotations_find(set, "ear-2"), 1);
    assert_int_equal(ms_annotations_find(set, "eye"), -1);
    ms_annotations_free(set);
    /* no annotation at all */
    assert_int_equal(parse("{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": []}", &set,
                           &err),
                     MS_OK);
    assert_int_equal(ms_annotations_count(set), 0);
    ms_annotations_free(set);
}

/* Written then read gives the same set, bit for bit; written again gives the same text. */
static void test_a_file_round_trips(void **state)
{
    (void)state;
    ms_annotations *set = ms_annotations_new(), *back;
    ms_error err;
    const double awkward[] = {0.1, -1.0 / 3.0, 6.02214076e23, 5e-324, -0.0, 1.7976931348623157e308};
    for (size_t i = 0; i < sizeof awkward / sizeof *awkward; ++i) {
        char id[MS_ANNOTATION_ID_MAX + 1], title[64];
        ms_annotations_next_id(set, id, sizeof id);
        snprintf(title, sizeof title, "Point %zu \xe2\x82\xac <script>", i);
        ms_annotation a = {.id = id, .point = {awkward[i], -awkward[i], 1}, .radius = i % 2 ? awkward[1] * -1 : 0,
                           .title = title, .text = i % 3 ? "a\nb \"quoted\" \\ back" : NULL,
                           .view = i % 2 ? "mv1:t=1,2,3:d=4:o=0,0:f=40:u=y" : NULL};
        assert_int_equal(ms_annotations_add(set, &a, &err), MS_OK);
    }
    assert_string_equal(ms_annotations_get(set, 5)->id, "a6");
    char *text, *again;
    size_t size, size_again;
    assert_int_equal(ms_annotations_write(set, &text, &size, &err), MS_OK);
    assert_int_equal(strlen(text), size);
    assert_int_equal(ms_annotations_parse(text, size, "w.json", &back, &err), MS_OK);
    assert_true(ms_annotations_equal(set, back));
    assert_int_equal(ms_annotations_write(back, &again, &size_again, &err), MS_OK);
    assert_string_equal(text, again);
    free(again);
    ms_annotations_free(back);
    /* through a file */
    char dir[512], path[600];
    ms_test_tmpdir(dir, sizeof dir);
    ms_annotations_sidecar_path(dir, "bust", path, sizeof path);
    char want[600];
    snprintf(want, sizeof want, "%s/bust.annotations.json", dir);
    assert_string_equal(path, want);
    assert_int_equal(ms_annotations_save(set, path, &err), MS_OK);
    assert_int_equal(ms_annotations_load(path, &back, &err), MS_OK);
    assert_true(ms_annotations_equal(set, back));
    /* edits: remove, a fresh id fills the gap, a taken id is refused */
    assert_true(ms_annotations_remove(back, 1));
    assert_false(ms_annotations_remove(back, 5));
    assert_false(ms_annotations_equal(set, back));
    char id[MS_ANNOTATION_ID_MAX + 1];
    ms_annotations_next_id(back, id, sizeof id);
    assert_string_equal(id, "a2");
    ms_annotation dup = {.id = "a3", .title = "x"};
    assert_int_equal(ms_annotations_add(back, &dup, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "annotation 6: id 'a3' is already used");
    ms_annotations_free(back);
    free(text);
    ms_annotations_free(set);
    ms_test_rmdir(dir);
}

static void test_hostile_files_get_one_line(void **state)
{
    (void)state;
#define HEAD "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": ["
    char long_title[MS_ANNOTATION_TITLE_MAX + 300], long_id[200], long_text[MS_ANNOTATION_TEXT_MAX + 300];
    snprintf(long_title, sizeof long_title, HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"%*s\"}]}",
             MS_ANNOTATION_TITLE_MAX + 1, "x");
    snprintf(long_id, sizeof long_id, HEAD "{\"id\": \"%065d\", \"point\": [0, 0, 0], \"title\": \"t\"}]}", 0);
    snprintf(long_text, sizeof long_text,
             HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"text\": \"%*s\"}]}",
             MS_ANNOTATION_TEXT_MAX + 1, "x");
    const struct {
        const char *text;
        ms_status status;
        const char *error;
    } cases[] = {
        {"", MS_ERR_FORMAT, "a.json: line 1: '[' or '{' expected near end of file"},
        {"[]", MS_ERR_FORMAT, "a.json: not a JSON object"},
        {"{\"format\": \"meshstream-annotations\", \"version\": 1}", MS_ERR_FORMAT,
         "a.json: annotations is not an array"},
        {"{\"format\": \"x\", \"version\": 1, \"annotations\": []}", MS_ERR_FORMAT,
         "a.json: format is not \"meshstream-annotations\""},
        {"{\"format\": \"meshstream-annotations\", \"version\": 2, \"annotations\": []}", MS_ERR_UNSUPPORTED,
         "a.json: version 2 is not supported (1)"},
        {"{\"format\": \"meshstream-annotations\", \"version\": 1.0, \"annotations\": []}", MS_ERR_FORMAT,
         "a.json: version is not an integer"},
        {HEAD "], \"extra\": 1}", MS_ERR_FORMAT,
         "a.json: unknown member 'extra' (format, version, annotations)"},
        {HEAD "7]}", MS_ERR_FORMAT, "a.json: annotation 1: not a JSON object"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"colour\": 1}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): unknown member 'colour' (id, point, radius, title, text, view)"},
        {HEAD "{\"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT, "a.json: annotation 1: no id"},
        {HEAD "{\"id\": \"a\", \"title\": \"t\"}]}", MS_ERR_FORMAT, "a.json: annotation 1 (a): no point"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0]}]}", MS_ERR_FORMAT, "a.json: annotation 1 (a): no title"},
        {HEAD "{\"id\": 5, \"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1: id is not a string"},
        {HEAD "{\"id\": \"a b\", \"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a b): id holds a character other than A-Z a-z 0-9 . _ -"},
        {HEAD "{\"id\": \"a\\n\", \"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a?): id holds a character other than A-Z a-z 0-9 . _ -"},
        {HEAD "{\"id\": \"\", \"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_RANGE,
         "a.json: annotation 1 (): id is 0 bytes, 1 to 64"},
        {long_id, MS_ERR_RANGE, "a.json: annotation 1: id is 65 bytes, 1 to 64"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): point is not an array of 3 numbers"},
        {HEAD "{\"id\": \"a\", \"point\": [0, \"1\", 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): point is not an array of 3 numbers"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 1e999, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: line 1: real number overflow near '1e999'"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"radius\": -1, \"title\": \"t\"}]}", MS_ERR_RANGE,
         "a.json: annotation 1 (a): radius is not a finite number >= 0"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"radius\": null, \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): radius is not a number"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"\"}]}", MS_ERR_RANGE,
         "a.json: annotation 1 (a): title is 0 bytes, 1 to 200"},
        {long_title, MS_ERR_RANGE, "a.json: annotation 1 (a): title is 201 bytes, 1 to 200"},
        {long_text, MS_ERR_RANGE, "a.json: annotation 1 (a): text is 8001 bytes, at most 8000"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"two\\nlines\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): title holds a control character or a line break"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"text\": \"tab\\t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): text holds a control character (only line feeds are allowed)"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"abc\\u202edcba\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): title holds a bidirectional override or isolate character"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"\xff\"}]}", MS_ERR_FORMAT,
         "a.json: line 1: unable to decode byte 0xff near '\"'"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"a\\u0000b\"}]}", MS_ERR_FORMAT,
         "a.json: line 1: \\u0000 is not allowed without JSON_ALLOW_NUL near '\"a\\u0000b\"'"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"view\": \"t=0\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): view does not start with mv1:"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\", \"view\": \"mv1: t\"}]}", MS_ERR_FORMAT,
         "a.json: annotation 1 (a): view holds a space or a character outside printable ASCII"},
        {HEAD "{\"id\": \"a\", \"point\": [0, 0, 0], \"title\": \"t\"}, {\"id\": \"a\", \"point\": [1, 0, 0], "
              "\"title\": \"u\"}]}",
         MS_ERR_FORMAT, "a.json: annotation 2 (a): id 'a' is used twice"},
        {HEAD "{\"id\": \"a\", \"id\": \"b\", \"point\": [0, 0, 0], \"title\": \"t\"}]}", MS_ERR_FORMAT,
         "a.json: line 1: duplicate object key near '\"id\"'"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; ++i) {
        ms_annotations *set = (ms_annotations *)&i; /* set to NULL on failure */
        ms_error err;
        ms_status st = parse(cases[i].text, &set, &err);
        if (st != cases[i].status || strcmp(err.text, cases[i].error) != 0)
            fail_msg("case %zu: %d '%s'", i, (int)st, err.text);
        assert_null(set);
        assert_null(strchr(err.text, '\n'));
    }
    /* too many annotations; a file over the size limit */
    size_t big = MS_ANNOTATIONS_FILE_MAX + 1;
    char *text = malloc(big + 1);
    int n = snprintf(text, big, HEAD);
    for (int k = 0; k <= MS_ANNOTATIONS_MAX; ++k)
        n += snprintf(text + n, big - n, "%s{\"id\": \"a%d\", \"point\": [0, 0, 0], \"title\": \"t\"}", k ? "," : "",
                      k);
    n += snprintf(text + n, big - n, "]}");
    ms_annotations *set;
    ms_error err;
    assert_int_equal(ms_annotations_parse(text, (size_t)n, "many.json", &set, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "many.json: 1001 annotations, at most 1000");
    memset(text, ' ', big);
    text[0] = '{', text[big - 1] = '}';
    assert_int_equal(ms_annotations_parse(text, big, "big.json", &set, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "big.json: 1048577 bytes, an annotations file holds at most 1048576");
    /* the same through a file: the read stops past the limit */
    char dir[512], path[600], want[700];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/big.json", dir);
    ms_test_write_file(path, text, big);
    assert_int_equal(ms_annotations_load(path, &set, &err), MS_ERR_RANGE);
    snprintf(want, sizeof want, "%s: more than 1048576 bytes, an annotations file holds at most that", path);
    assert_string_equal(err.text, want);
    assert_int_equal(ms_annotations_load(dir, &set, &err), MS_ERR_IO);
    snprintf(want, sizeof want, "%s: not a regular file (a directory)", dir);
    assert_string_equal(err.text, want);
    free(text);
    ms_test_rmdir(dir);
    /* a set that would write more than a file holds is refused by the writer */
    set = ms_annotations_new();
    char *text_max = malloc(MS_ANNOTATION_TEXT_MAX + 1);
    memset(text_max, 'x', MS_ANNOTATION_TEXT_MAX);
    text_max[MS_ANNOTATION_TEXT_MAX] = '\0';
    for (int k = 0; k < 140; ++k) {
        char id[16];
        snprintf(id, sizeof id, "a%d", k);
        ms_annotation a = {.id = id, .title = "t", .text = text_max};
        assert_int_equal(ms_annotations_add(set, &a, &err), MS_OK);
    }
    char *out;
    size_t size;
    assert_int_equal(ms_annotations_write(set, &out, &size, &err), MS_ERR_RANGE);
    assert_null(out);
    assert_non_null(strstr(err.text, "a file holds at most 1048576"));
    ms_annotation nan_point = {.id = "n", .point = {0, NAN, 0}, .title = "t"};
    assert_int_equal(ms_annotations_add(set, &nan_point, &err), MS_ERR_RANGE);
    assert_string_equal(err.text, "annotation 141: point coordinate 2 is not finite");
    free(text_max);
    ms_annotations_free(set);
#undef HEAD
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_file_is_read_whole),
        cmocka_unit_test(test_a_file_round_trips),
        cmocka_unit_test(test_hostile_files_get_one_line),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
