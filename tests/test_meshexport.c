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

#include "ms_archive.h"
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

static void test_export_tree_matches_archive(void **state)
{
    (void)state;
    char dir[512], archives[600], out[600], bin[512], cmd[4096], text[4096], path[900];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(archives, sizeof archives, "%s/a", dir);
    snprintf(out, sizeof out, "%s/www", dir);
    assert_int_equal(mkdir(archives, 0755), 0);
    ms_test_add_model(archives, "bust", 4, 12);
    ms_test_bin_path(bin, sizeof bin, "meshexport");
    snprintf(cmd, sizeof cmd, "%s %s bust -o %s --json", bin, archives, out);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 0);
    /* 129 geometry files, 86 APO chunks (cells not divisible by 3), one index. */
    assert_non_null(strstr(text, "\"files\": 216"));
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
    assert_non_null(strstr(text, "nothere.msa: cannot open"));
    snprintf(cmd, sizeof cmd, "%s %s", bin, archives);
    assert_int_equal(ms_test_run(cmd, text, sizeof text), 2);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_export_tree_matches_archive),
    };
    return cmocka_run_group_tests_name("meshexport", tests, NULL, NULL);
}
