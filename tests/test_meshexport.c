/* meshexport writes the HTTP side door's tree as files with the archive's bytes. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include <jansson.h>

#include "ms_annotations.h"
#include "ms_archive.h"
#include "ms_catalog.h"
#include "ms_subtree.h"
#include "ms_test.h"
#include "ms_test_archive.h"

static uint8_t *slurp(const char *path, size_t *size)
{
    FILE *f = fopen(path, "rb");
    if (!f)
        fail_msg("missing %s", path);
    uint8_t *data = malloc(1 << 20);
    *size = fread(data, 1, 1 << 20, f);
    fclose(f);
    return data;
}

/* A fresh dir holding the archive folder dir/a with one test model
 * (ms_test_add_model: salt, public_max_bits), out = dir/www (not made), and
 * meshexport's path in bin. */
static void export_setup(char dir[512], char archives[600], char out[600], char bin[512], const char *model,
                         uint32_t salt, uint8_t public_max_bits)
{
    ms_test_tmpdir(dir, 512);
    snprintf(archives, 600, "%s/a", dir);
    snprintf(out, 600, "%s/www", dir);
    assert_int_equal(mkdir(archives, 0755), 0);
    ms_test_add_model(archives, model, salt, public_max_bits);
    ms_test_bin_path(bin, 512, "meshexport");
}

static void test_export_tree_matches_archive(void **state)
{
    (void)state;
    char dir[512], archives[600], out[600], bin[512], cmd[4096], text[4096], path[900];
    export_setup(dir, archives, out, bin, "bust", 4, 12);
    snprintf(cmd, sizeof cmd, "%s %s bust -o %s --json", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    /* 129 geometry files, 86 APO chunks (cells not divisible by 3), one index,
     * one head, three subtrees (0, 1, 65), the annotations (the empty set). */
    assert_non_null(strstr(text, "\"files\": 221"));
    snprintf(path, sizeof path, "%s/bust.msa", archives);
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    size_t size, expect_size;
    snprintf(path, sizeof path, "%s/models/bust.index", out);
    uint8_t *data = slurp(path, &size);
    const uint8_t *expect = ms_archive_index_bytes(a, &expect_size);
    assert_int_equal(size, expect_size);
    assert_memory_equal(data, expect, size);
    free(data);
    /* The index head and the stored subtrees, the server's bytes. */
    snprintf(path, sizeof path, "%s/models/bust.head", out);
    data = slurp(path, &size);
    expect = ms_archive_index_head(a, &expect_size);
    assert_int_equal(size, expect_size);
    assert_memory_equal(data, expect, size);
    free(data);
    static const uint32_t subtrees[3] = {0, 1, 65};
    for (int i = 0; i < 3; ++i) {
        snprintf(path, sizeof path, "%s/models/bust/subtrees/%u", out, subtrees[i]);
        data = slurp(path, &size);
        expect = ms_archive_subtree(a, subtrees[i], &expect_size);
        assert_int_equal(size, expect_size);
        assert_memory_equal(data, expect, size);
        free(data);
    }
    snprintf(path, sizeof path, "%s/models/bust/subtrees/2", out);
    assert_int_equal(access(path, F_OK), -1);
    for (uint32_t cell = 0; cell < MS_TEST_ARCHIVE_CELLS; ++cell) {
        snprintf(path, sizeof path, "%s/models/bust/cells/%u/geometry", out, cell);
        data = slurp(path, &size);
        expect = ms_archive_geometry(a, cell, &expect_size);
        assert_int_equal(size, expect_size);
        assert_memory_equal(data, expect, size);
        free(data);
        snprintf(path, sizeof path, "%s/models/bust/cells/%u/apo", out, cell);
        expect = ms_archive_apo(a, cell, &expect_size);
        assert_int_equal(access(path, F_OK) == 0, expect_size > 0);
    }
    ms_archive_close(a);
    /* Bad input: invalid name, missing archive, usage. */
    snprintf(cmd, sizeof cmd, "%s %s ../bust -o %s", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 2);
    assert_string_equal(text, "meshexport: invalid model name '../bust'\n");
    snprintf(cmd, sizeof cmd, "%s %s nothere -o %s", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 1);
    char expect_text[1000];
    snprintf(expect_text, sizeof expect_text,
             "meshexport: model 'nothere' is not in %s/catalog.json\n", archives);
    assert_string_equal(text, expect_text);
    snprintf(cmd, sizeof cmd, "%s %s", bin, archives);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 2);
    ms_test_rmdir(dir);
}

/* Issue 19, item 1: a preview-limited model exports only what an anonymous
 * reader may have (the same grant as both doors of meshserve): geometry up to
 * the preview, nothing of cells wholly beyond it; --full exports everything. */
static void test_export_respects_preview(void **state)
{
    (void)state;
    char dir[512], archives[600], out[600], bin[512], cmd[4096], text[4096], path[900];
    export_setup(dir, archives, out, bin, "vault", 2, 8); /* preview: 8 of 12 bits */
    snprintf(cmd, sizeof cmd, "%s %s vault -o %s", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    snprintf(path, sizeof path, "%s/vault.msa", archives);
    ms_archive *a;
    assert_int_equal(ms_archive_open(path, &a, NULL), MS_OK);
    unsigned hidden = 0, cut = 0;
    for (uint32_t cell = 0; cell < MS_TEST_ARCHIVE_CELLS; ++cell) {
        const ms_archive_cell *c = ms_archive_get_cell(a, cell);
        size_t size, expect_size;
        snprintf(path, sizeof path, "%s/models/vault/cells/%u/geometry", out, cell);
        char apo_path[1000];
        snprintf(apo_path, sizeof apo_path, "%s/models/vault/cells/%u/apo", out, cell);
        if (c->bits_min > 8) { /* nothing of it is public */
            assert_int_equal(access(path, F_OK), -1);
            assert_int_equal(access(apo_path, F_OK), -1);
            ++hidden;
            continue;
        }
        uint8_t *data = slurp(path, &size);
        const uint8_t *expect = ms_archive_geometry(a, cell, &expect_size);
        uint32_t allowed = ms_archive_geometry_prefix(a, cell, 8);
        assert_int_equal(size, allowed);
        assert_memory_equal(data, expect, size);
        cut += allowed < expect_size;
        free(data);
        ms_archive_apo(a, cell, &expect_size);
        assert_int_equal(access(apo_path, F_OK) == 0, expect_size > 0);
    }
    assert_true(hidden > 0 && cut > 0);
    /* --full: what a token holder reads, every byte. */
    snprintf(cmd, sizeof cmd, "%s %s vault -o %s --full", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    for (uint32_t cell = 0; cell < MS_TEST_ARCHIVE_CELLS; ++cell) {
        size_t size, expect_size;
        snprintf(path, sizeof path, "%s/models/vault/cells/%u/geometry", out, cell);
        uint8_t *data = slurp(path, &size);
        ms_archive_geometry(a, cell, &expect_size);
        assert_int_equal(size, expect_size);
        free(data);
    }
    /* Back to the preview: the files of hidden cells go. */
    snprintf(cmd, sizeof cmd, "%s %s vault -o %s", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    snprintf(path, sizeof path, "%s/models/vault/cells/70/geometry", out);
    assert_int_equal(access(path, F_OK), -1);
    snprintf(path, sizeof path, "%s/models/vault/cells/6/geometry", out);
    size_t size;
    free(slurp(path, &size));
    assert_int_equal(size, ms_archive_geometry_prefix(a, 6, 8));
    ms_archive_close(a);
    ms_test_rmdir(dir);
}

/* The model's documents in the export, read as both doors read them
 * (ms_model_document_read_entry, under ms_access_document): the thumbnail
 * and annotations as stored, the picture named by the site's catalogue; a
 * picture drawn finer than the public preview, and one the model lost, is
 * removed by the next export; a model without annotations exports the empty
 * set (a static server answers the page with a document, not a 404). */
static void test_export_documents(void **state)
{
    (void)state;
    char dir[512], archives[600], out[600], bin[512], cmd[8192], text[4096], path[900];
    export_setup(dir, archives, out, bin, "bust", 4, 12);
    /* a minimal folder of pages: meshexport --web-dir needs these two */
    char web[700];
    snprintf(web, sizeof web, "%s/web", dir);
    assert_int_equal(mkdir(web, 0755), 0);
    snprintf(path, sizeof path, "%s/index.html", web);
    ms_test_write_file(path, "<!doctype html>\n", 16);
    snprintf(path, sizeof path, "%s/view.html", web);
    ms_test_write_file(path, "<!doctype html>\n", 16);
    static const uint8_t picture[] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 1, 2, 3};
    snprintf(path, sizeof path, "%s/bust.thumb.png", archives);
    ms_test_write_file(path, picture, sizeof picture);
    ms_error err;
    assert_int_equal(ms_catalog_update_thumbnail(archives, "bust", true, 8, 2, &err), MS_OK);
    const char *notes = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": "
                        "[{\"id\": \"a1\", \"point\": [0, 0, 0], \"title\": \"<b>mark</b>\"}]}\n";
    snprintf(path, sizeof path, "%s/bust.annotations.json", archives);
    ms_test_write_file(path, notes, strlen(notes));
    snprintf(cmd, sizeof cmd, "%s %s bust -o %s --web-dir %s --json", bin, archives, out, web);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    /* the 220 of the model, its two documents, index.html, view/bust.html, the
     * two pages again under web/ and catalog.json */
    assert_non_null(strstr(text, "\"files\": 227"));
    size_t size;
    snprintf(path, sizeof path, "%s/models/bust/thumbnail.png", out);
    uint8_t *data = slurp(path, &size);
    assert_int_equal(size, sizeof picture);
    assert_memory_equal(data, picture, size);
    free(data);
    snprintf(path, sizeof path, "%s/models/bust/annotations.json", out);
    data = slurp(path, &size);
    assert_int_equal(size, strlen(notes));
    assert_memory_equal(data, notes, size);
    free(data);
    snprintf(path, sizeof path, "%s/catalog.json", out);
    json_t *site = json_load_file(path, 0, NULL);
    json_t *entry = json_array_get(json_object_get(site, "models"), 0);
    assert_string_equal(json_string_value(json_object_get(entry, "thumbnail")), "models/bust/thumbnail.png");
    json_decref(site);
    /* The preview made coarser than the picture (a hand edit), the
     * annotations removed: the next export takes the picture back and says
     * so, and writes the empty set. */
    ms_catalog catalogue;
    assert_int_equal(ms_catalog_load(archives, &catalogue, &err), MS_OK);
    ms_catalog_entry coarser = *ms_catalog_find(&catalogue, "bust");
    coarser.public_max_bits = 7;
    assert_int_equal(ms_catalog_update(archives, &coarser, &err), MS_OK);
    ms_catalog_free(&catalogue);
    snprintf(path, sizeof path, "%s/bust.annotations.json", archives);
    assert_int_equal(unlink(path), 0);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    snprintf(path, sizeof path, "%s/models/bust/thumbnail.png", out);
    assert_int_equal(access(path, F_OK), -1);
    snprintf(path, sizeof path, "%s/catalog.json", out);
    site = json_load_file(path, 0, NULL);
    entry = json_array_get(json_object_get(site, "models"), 0);
    assert_true(json_is_false(json_object_get(entry, "thumbnail")));
    json_decref(site);
    snprintf(path, sizeof path, "%s/models/bust/annotations.json", out);
    data = slurp(path, &size);
    const char *empty = "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": []}\n";
    assert_int_equal(size, strlen(empty));
    assert_memory_equal(data, empty, size);
    free(data);
    ms_annotations *set = NULL;
    assert_int_equal(ms_annotations_parse(empty, strlen(empty), "the empty set", &set, &err), MS_OK);
    assert_int_equal(ms_annotations_count(set), 0);
    ms_annotations_free(set);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_export_tree_matches_archive),
        cmocka_unit_test(test_export_respects_preview),
        cmocka_unit_test(test_export_documents),
    };
    return cmocka_run_group_tests_name("meshexport", tests, NULL, NULL);
}
