/* User-named input files that are not regular files (issue 32, item 7): a
 * FIFO (which would block open(2) until a writer comes) or a directory given
 * as a model, an archive, a camera path, a scene, a server config or a
 * catalogue is refused at once with one line naming it, through the one
 * helper every program opens its inputs with (ms_input_file.h); meshload and
 * meshview given a FIFO exit 1 with that line instead of hanging (each run
 * bounded by `timeout`). Runs from the repository root. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_archive.h"
#include "ms_byte_source.h"
#include "ms_camera_path.h"
#include "ms_catalog.h"
#include "ms_input_file.h"
#include "ms_scene.h"
#include "ms_server_config.h"
#include "ms_test.h"

typedef struct fixture {
    char dir[512], fifo[600], folder[600], regular[600];
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f || !ms_test_tmpdir(f->dir, sizeof f->dir))
        return -1;
    snprintf(f->fifo, sizeof f->fifo, "%s/input.fifo", f->dir);
    snprintf(f->folder, sizeof f->folder, "%s/folder", f->dir);
    snprintf(f->regular, sizeof f->regular, "%s/plain.txt", f->dir);
    if (mkfifo(f->fifo, 0600) != 0 || mkdir(f->folder, 0700) != 0)
        return -1;
    ms_test_write_file(f->regular, "x\n", 2);
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

static void expect_refused(ms_status st, const ms_error *err, const char *prefix, const char *path,
                           const char *kind)
{
    char want[1400];
    snprintf(want, sizeof want, "%s%s: not a regular file (%s)", prefix, path, kind);
    assert_int_equal(st, MS_ERR_IO);
    assert_string_equal(err->text, want);
}

/* The helper: a FIFO and a directory refused, a regular file opened, a
 * missing one named. */
static void test_helper(void **state)
{
    fixture *f = *state;
    ms_error err;
    int fd = 5;
    expect_refused(ms_input_open(f->fifo, &fd, &err), &err, "", f->fifo, "a FIFO");
    assert_int_equal(fd, -1);
    FILE *file = (FILE *)&fd;
    expect_refused(ms_input_fopen(f->folder, &file, &err), &err, "", f->folder, "a directory");
    assert_null(file);
    expect_refused(ms_input_open("/dev/null", &fd, &err), &err, "", "/dev/null", "a device");
    assert_int_equal(ms_input_fopen(f->regular, &file, &err), MS_OK);
    char line[8] = "";
    assert_non_null(fgets(line, sizeof line, file));
    assert_string_equal(line, "x\n");
    fclose(file);
    char missing[700];
    snprintf(missing, sizeof missing, "%s/missing", f->dir);
    assert_int_equal(ms_input_open(missing, &fd, &err), MS_ERR_IO);
    char want[800];
    snprintf(want, sizeof want, "%s: cannot open: No such file or directory", missing);
    assert_string_equal(err.text, want);
}

/* Every loader of a user-named file goes through it. */
static void test_loaders(void **state)
{
    fixture *f = *state;
    ms_error err;
    ms_camera_path path;
    expect_refused(ms_camera_path_load(f->fifo, &path, &err), &err, "", f->fifo, "a FIFO");
    ms_archive *archive;
    expect_refused(ms_archive_open(f->fifo, &archive, &err), &err, "", f->fifo, "a FIFO");
    expect_refused(ms_archive_open(f->folder, &archive, &err), &err, "", f->folder, "a directory");
    expect_refused(ms_archive_open_index_file(f->fifo, "m", &archive, &err), &err, "", f->fifo,
                   "a FIFO");
    ms_byte_source src; /* a model (ms_mesh_read reads through it) */
    expect_refused(ms_byte_source_open(&src, f->fifo, 1 << 16, &err), &err, "", f->fifo, "a FIFO");
    ms_scene scene;
    expect_refused(ms_scene_load(f->fifo, &scene, &err), &err, "scene ", f->fifo, "a FIFO");
    ms_server_config config;
    ms_server_config_defaults(&config);
    expect_refused(ms_server_config_load(&config, f->fifo, &err), &err, "", f->fifo, "a FIFO");
    ms_server_config_free(&config);
    /* a catalogue that is a FIFO; none at all is an empty collection */
    char cat_dir[700], cat[800];
    snprintf(cat_dir, sizeof cat_dir, "%s/collection", f->dir);
    snprintf(cat, sizeof cat, "%s/catalog.json", cat_dir);
    assert_int_equal(mkdir(cat_dir, 0700), 0);
    ms_catalog catalog;
    assert_int_equal(ms_catalog_load(cat_dir, &catalog, &err), MS_OK);
    ms_catalog_free(&catalog);
    assert_int_equal(mkfifo(cat, 0600), 0);
    expect_refused(ms_catalog_load(cat_dir, &catalog, &err), &err, "", cat, "a FIFO");
}

/* The programs: one line, exit 1, at once (timeout 20 s: 124 if one hung). */
static void test_programs(void **state)
{
    fixture *f = *state;
    char bin[512], cmd[2400], out[4096], want[1400];
    ms_test_bin_path(bin, sizeof bin, "meshload");
    snprintf(cmd, sizeof cmd, "timeout 20 %s --archive %s --path %s 2>&1", bin, f->regular, f->fifo);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(want, sizeof want, "meshload: %s: not a regular file (a FIFO)\n", f->fifo);
    assert_string_equal(out, want);
    ms_test_bin_path(bin, sizeof bin, "meshview");
    snprintf(cmd, sizeof cmd, "timeout 20 %s %s --scene %s 2>&1", bin, f->dir, f->fifo);
    assert_int_equal(ms_test_run(cmd, out, sizeof out), 1);
    snprintf(want, sizeof want, "meshview: scene %s: not a regular file (a FIFO)\n", f->fifo);
    assert_string_equal(out, want);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_helper, setup, teardown),
        cmocka_unit_test_setup_teardown(test_loaders, setup, teardown),
        cmocka_unit_test_setup_teardown(test_programs, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
