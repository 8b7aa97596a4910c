/* Every program's --json report parses as JSON, with hostile strings included:
 * file names, paths, model names, labels and error messages holding quotes,
 * backslashes, control characters and non-ASCII bytes come back exactly (valid
 * UTF-8) or with each stray byte as U+FFFD (anything else). The programs run
 * from build/asan/bin on small generated meshes; servers they would talk to are
 * left unreachable, as the reports are written all the same. meshserve's report
 * echoes no strings and needs a signal to end; it is not run here. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include <jansson.h>

#include "ms_test.h"

/* A valid UTF-8 name with every character JSON must escape, and one a shell
 * must: double and single quotes, backslash, tab, carriage return, 0x01, é. */
#define HOSTILE_NAME "we\"i'rd\\ \t\r\x01\xC3\xA9"
/* Not UTF-8: a lone 0xFF and a lead byte 0xC3 with no continuation byte. */
#define BROKEN_NAME "bad\xFF\xC3."
#define BROKEN_NAME_AS_JSON "bad\xEF\xBF\xBD\xEF\xBF\xBD."

/* s as one single-quoted shell word, appended to the command in buf. */
static void append_quoted(char *buf, size_t size, const char *s)
{
    size_t n = strlen(buf);
    assert_true(n + 2 < size);
    buf[n++] = '\'';
    for (; *s; ++s) {
        if (*s == '\'') {
            assert_true(n + 5 < size);
            memcpy(buf + n, "'\\''", 4);
            n += 4;
        } else {
            assert_true(n + 2 < size);
            buf[n++] = *s;
        }
    }
    buf[n++] = '\'';
    buf[n] = '\0';
}

static void append(char *buf, size_t size, const char *s)
{
    assert_true(strlen(buf) + strlen(s) < size);
    strcat(buf, s);
}

/* Runs command (stderr discarded), expects exit status want_status and one JSON
 * object on stdout; returns it (the caller releases it). */
static json_t *run_json(const char *command, int want_status)
{
    char full[8192];
    snprintf(full, sizeof full, "%s 2>/dev/null", command); /* the JSON is stdout alone */
    json_t *root = ms_test_run_json(full, want_status);
    assert_true(json_is_object(root));
    return root;
}

static void assert_text(const json_t *object, const char *key, const char *want)
{
    const json_t *value = json_object_get(object, key);
    assert_non_null(value);
    assert_true(json_is_string(value));
    assert_string_equal(json_string_value(value), want);
}

static long long integer(const json_t *object, const char *key)
{
    const json_t *value = json_object_get(object, key);
    assert_non_null(value);
    assert_true(json_is_integer(value));
    return (long long)json_integer_value(value);
}

/* meshgen writes a file, meshbake --info reads it, meshcodec round-trips it; each
 * echoes the path, which comes back byte for byte (or with U+FFFD for bytes
 * that are not UTF-8). */
static void check_mesh_programs(const char *file_name, const char *file_name_as_json)
{
    char dir[512], path[1024], path_as_json[1024], bin[512], cmd[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/%s.ply", dir, file_name);
    snprintf(path_as_json, sizeof path_as_json, "%s/%s.ply", dir, file_name_as_json);

    ms_test_bin_path(bin, sizeof bin, "meshgen");
    snprintf(cmd, sizeof cmd, "%s --triangles 200 --json -o ", bin);
    append_quoted(cmd, sizeof cmd, path);
    json_t *root = run_json(cmd, 0);
    assert_text(root, "output", path_as_json);
    assert_int_equal(integer(root, "triangles"), 192);
    json_decref(root);

    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s --info --json ", bin);
    append_quoted(cmd, sizeof cmd, path);
    root = run_json(cmd, 0);
    assert_text(root, "file", path_as_json);
    assert_int_equal(integer(root, "triangles"), 192);
    assert_true(json_is_false(json_object_get(root, "gzip")));
    assert_int_equal(json_array_size(json_object_get(root, "bbox_min")), 3);
    json_decref(root);

    ms_test_bin_path(bin, sizeof bin, "meshcodec");
    snprintf(cmd, sizeof cmd, "%s roundtrip --bits 12 --json ", bin);
    append_quoted(cmd, sizeof cmd, path);
    root = run_json(cmd, 0);
    assert_text(root, "input", path_as_json);
    assert_int_equal(integer(root, "triangles"), 192);
    assert_true(json_is_true(json_object_get(root, "lossless")));
    assert_true(json_is_real(json_object_get(root, "bits_per_vertex")));
    json_decref(root);
    ms_test_rmdir(dir);
}

static void test_mesh_programs_hostile_path(void **state)
{
    (void)state;
    check_mesh_programs(HOSTILE_NAME, HOSTILE_NAME);
}

static void test_mesh_programs_path_not_utf8(void **state)
{
    (void)state;
    check_mesh_programs(BROKEN_NAME, BROKEN_NAME_AS_JSON);
}

/* meshbake's bake and --apo-classic reports echo the source (and archive) paths;
 * meshexport's the model name. */
static void test_meshbake_and_meshexport(void **state)
{
    (void)state;
    char dir[512], input[1024], archives[1024], archives_as_json[1024], www[1024];
    char bin[512], cmd[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(input, sizeof input, "%s/%s.ply", dir, HOSTILE_NAME);
    snprintf(archives, sizeof archives, "%s/%s", dir, BROKEN_NAME);
    snprintf(archives_as_json, sizeof archives_as_json, "%s/%s", dir, BROKEN_NAME_AS_JSON);
    snprintf(www, sizeof www, "%s/www", dir);

    ms_test_bin_path(bin, sizeof bin, "meshgen");
    snprintf(cmd, sizeof cmd, "%s --triangles 2000 -o ", bin);
    append_quoted(cmd, sizeof cmd, input);
    json_decref(run_json(strcat(cmd, " --json"), 0));

    ms_test_bin_path(bin, sizeof bin, "meshbake");
    snprintf(cmd, sizeof cmd, "%s --name m --min-tris 500 --json ", bin);
    append_quoted(cmd, sizeof cmd, input);
    append(cmd, sizeof cmd, " -o ");
    append_quoted(cmd, sizeof cmd, archives);
    json_t *root = run_json(cmd, 0);
    assert_text(root, "name", "m");
    assert_text(root, "source", input);
    const char *archive = json_string_value(json_object_get(root, "archive"));
    assert_non_null(archive);
    assert_memory_equal(archive, archives_as_json, strlen(archives_as_json));
    assert_true(integer(root, "cells") >= 1);
    assert_true(json_is_object(json_object_get(root, "apo")));
    json_decref(root);

    /* the whole-model APO report, compact, echoes its input */
    snprintf(cmd, sizeof cmd, "%s --apo-classic --simplify 500 --apo-max-depth 4 --json ", bin);
    append_quoted(cmd, sizeof cmd, input);
    root = run_json(cmd, 0);
    assert_text(root, "input", input);
    assert_int_equal(integer(root, "input_triangles"), 2028); /* 12 * 13^2 */
    assert_true(json_is_object(json_object_get(root, "phases")));
    assert_int_equal(json_array_size(json_object_get(root, "texture")), 2);
    json_decref(root);

    ms_test_bin_path(bin, sizeof bin, "meshexport");
    snprintf(cmd, sizeof cmd, "%s ", bin);
    append_quoted(cmd, sizeof cmd, archives);
    append(cmd, sizeof cmd, " m --json -o ");
    append_quoted(cmd, sizeof cmd, www);
    root = run_json(cmd, 0);
    assert_text(root, "model", "m");
    assert_true(integer(root, "files") >= 2);
    json_decref(root);
    ms_test_rmdir(dir);
}

/* meshload with a hostile model name and path file, against a server that is
 * not there: the client's error message quotes the model name. */
static void test_meshload_hostile_model_and_path(void **state)
{
    (void)state;
    char dir[512], path[1024], bin[512], cmd[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/%s.cam", dir, HOSTILE_NAME);
    size_t size = 0;
    unsigned char *cam = ms_test_read_file("scripts/paths/dragon-closeup.cam", &size);
    ms_test_write_file(path, cam, size);
    free(cam);

    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd, "%s --server 127.0.0.1:1 --duration 2 --json --model ", bin);
    append_quoted(cmd, sizeof cmd, HOSTILE_NAME);
    append(cmd, sizeof cmd, " --path ");
    append_quoted(cmd, sizeof cmd, path);
    json_t *root = run_json(cmd, 1); /* the one client failed */
    assert_text(root, "mode", "stream");
    assert_text(root, "model", HOSTILE_NAME);
    assert_text(root, "path", path);
    assert_int_equal(integer(root, "failures"), 1);
    json_t *clients = json_object_get(root, "per_client");
    assert_int_equal(json_array_size(clients), 1);
    const char *error = json_string_value(json_object_get(json_array_get(clients, 0), "error"));
    assert_non_null(error);
    /* (the error line keeps the quotes, backslash, tab and é; ms_error turns the
     * carriage return into a space) */
    assert_non_null(strstr(error, "'we\"i'rd\\ \t"));
    assert_non_null(strstr(error, "\xC3\xA9' is not a model name"));
    assert_true(json_is_array(json_object_get(json_array_get(clients, 0), "keyframes")));
    json_decref(root);
    ms_test_rmdir(dir);
}

/* meshloadgen echoes its label; with no server, its first error. */
static void test_meshloadgen_hostile_label(void **state)
{
    (void)state;
    char bin[512], cmd[4096];
    ms_test_bin_path(bin, sizeof bin, "meshloadgen");
    snprintf(cmd, sizeof cmd, "%s --port 1 --model m --clients 2 --duration 1 --json --label ", bin);
    append_quoted(cmd, sizeof cmd, HOSTILE_NAME BROKEN_NAME);
    json_t *root = run_json(cmd, 1); /* no server: every connection failed */
    assert_text(root, "label", HOSTILE_NAME BROKEN_NAME_AS_JSON);
    assert_text(root, "transport", "binary");
    assert_int_equal(integer(root, "connection_failures"), 2);
    assert_true(json_is_string(json_object_get(root, "first_error")));
    assert_true(json_is_object(json_object_get(root, "latency_ms")));
    json_decref(root);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_mesh_programs_hostile_path),
        cmocka_unit_test(test_mesh_programs_path_not_utf8),
        cmocka_unit_test(test_meshbake_and_meshexport),
        cmocka_unit_test(test_meshload_hostile_model_and_path),
        cmocka_unit_test(test_meshloadgen_hostile_label),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
