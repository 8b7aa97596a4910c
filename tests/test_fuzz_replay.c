/* Replays the regression corpora of ten libFuzzer targets through their
 * contract checks: tests/corpus/archive_index/ (the archive index reader,
 * tests/fuzz/fuzz_archive_index.c), tests/corpus/subtree/ (the index head and
 * subtree reader of a client's partial index, tests/fuzz/fuzz_subtree.c), tests/corpus/apo_chunk/ (the APO chunk
 * readers and traversal, tests/fuzz/fuzz_apo_chunk.c), tests/corpus/camera_path/ (the
 * camera-path parser, tests/fuzz/fuzz_camera_path.c),
 * tests/corpus/config_catalog/ (meshserve's config file and catalog.json,
 * tests/fuzz/fuzz_config_catalog.c), tests/corpus/mesh_reader/ (the mesh
 * readers, vertex colour included, tests/fuzz/fuzz_mesh_reader.c),
 * tests/corpus/colour/ (the colour decoder, tests/fuzz/fuzz_colour.c),
 * tests/corpus/metadata/ (meshbake's sidecar metadata, tests/fuzz/fuzz_metadata.c),
 * tests/corpus/annotations/ (a model's annotations, tests/fuzz/fuzz_annotations.c) and
 * tests/corpus/web_inflate/ (the browser build's inflater against zlib,
 * tests/fuzz/fuzz_web_inflate.c). Seeds named
 * seed-*-ok and seed-*.cam must be accepted, the other seed-* refused;
 * fuzzer finds only need to run clean. */
#include <dirent.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <cmocka.h>

#include "ms_test.h"

#define MS_FUZZ_NO_ENTRY_POINT
#include "fuzz/fuzz_annotations.c"
#include "fuzz/fuzz_apo_chunk.c"
#include "fuzz/fuzz_archive_index.c"
#include "fuzz/fuzz_camera_path.c"
#include "fuzz/fuzz_colour.c"
#include "fuzz/fuzz_config_catalog.c"
#include "fuzz/fuzz_mesh_reader.c"
#include "fuzz/fuzz_metadata.c"
#include "fuzz/fuzz_subtree.c"
#include "fuzz/fuzz_web_inflate.c"

typedef bool (*fuzz_one_fn)(const uint8_t *data, size_t size);

static bool ends_with(const char *s, const char *suffix)
{
    size_t a = strlen(s), b = strlen(suffix);
    return a >= b && !strcmp(s + a - b, suffix);
}

static unsigned replay(const char *dir_path, fuzz_one_fn one)
{
    DIR *dir = opendir(dir_path);
    if (!dir)
        fail_msg("cannot open %s (run the tests from the repository root)", dir_path);
    static uint8_t data[1 << 20];
    unsigned files = 0;
    struct dirent *entry;
    while ((entry = readdir(dir)) != NULL) {
        const char *name = entry->d_name;
        if (name[0] == '.')
            continue;
        char path[1024];
        snprintf(path, sizeof path, "%s/%s", dir_path, name);
        FILE *f = fopen(path, "rb");
        assert_non_null(f);
        size_t n = fread(data, 1, sizeof data, f);
        fclose(f);
        bool accepted = one(data, n); /* aborts on a broken contract */
        if (!strncmp(name, "seed-", 5)) {
            bool expect = ends_with(name, "-ok") || ends_with(name, ".cam");
            if (accepted != expect)
                fail_msg("%s: %s", path, accepted ? "accepted" : "refused");
        }
        ++files;
    }
    closedir(dir);
    return files;
}

static void test_archive_index_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/archive_index", ms_fuzz_archive_index_one) >= 6);
}

static void test_subtree_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/subtree", ms_fuzz_subtree_one) >= 6);
}

static void test_apo_chunk_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/apo_chunk", ms_fuzz_apo_chunk_one) >= 15);
}

static void test_camera_path_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/camera_path", ms_fuzz_camera_path_one) >= 10);
}

static void test_config_catalog_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/config_catalog", ms_fuzz_config_catalog_one) >= 6);
    if (ms_fuzz_files_dir[0])
        ms_test_rmdir(ms_fuzz_files_dir);
}

static void test_mesh_reader_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/mesh_reader", ms_fuzz_mesh_reader_one) >= 29);
    if (ms_fuzz_mesh_dir[0])
        ms_test_rmdir(ms_fuzz_mesh_dir);
}

static void test_colour_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/colour", ms_fuzz_colour_one) >= 14);
}

static void test_metadata_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/metadata", ms_fuzz_metadata_one) >= 30);
}

static void test_annotations_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/annotations", ms_fuzz_annotations_one) >= 26);
}

static void test_web_inflate_corpus(void **state)
{
    (void)state;
    assert_true(replay("tests/corpus/web_inflate", ms_fuzz_web_inflate_one) >= 10);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_archive_index_corpus),
        cmocka_unit_test(test_subtree_corpus),
        cmocka_unit_test(test_apo_chunk_corpus),
        cmocka_unit_test(test_camera_path_corpus),
        cmocka_unit_test(test_config_catalog_corpus),
        cmocka_unit_test(test_mesh_reader_corpus),
        cmocka_unit_test(test_colour_corpus),
        cmocka_unit_test(test_metadata_corpus),
        cmocka_unit_test(test_annotations_corpus),
        cmocka_unit_test(test_web_inflate_corpus),
    };
    return cmocka_run_group_tests_name("fuzz_replay", tests, NULL, NULL);
}
