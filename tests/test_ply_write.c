/* PLY writer: exact bytes for a small ascii and binary mesh, count checks, and no
 * file left behind on failure. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_mesh_io.h"
#include "ms_test.h"

static size_t read_all(const char *path, char *buf, size_t size)
{
    FILE *f = fopen(path, "rb");
    assert_non_null(f);
    size_t n = fread(buf, 1, size, f);
    fclose(f);
    return n;
}

static const char header_ascii[] =
    "ply\nformat ascii 1.0\ncomment written by meshstream\nelement vertex 3\n"
    "property float x\nproperty float y\nproperty float z\nelement face 1\n"
    "property list uchar int vertex_indices\nend_header\n";

static void test_ascii_exact(void **state)
{
    (void)state;
    char dir[512], path[600], buf[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/t.ply", dir);
    double pos[9] = {0, 0, 0, 1.5, 0, 0, 0, -2.25, 1e-3};
    uint32_t tri[3] = {0, 1, 2};
    ms_mesh m = {.positions = pos, .triangles = tri, .vertex_count = 3, .triangle_count = 1};
    assert_int_equal(ms_ply_write(path, &m, false, false, NULL), MS_OK);
    size_t n = read_all(path, buf, sizeof buf - 1);
    buf[n] = '\0';
    char expect[1024];
    snprintf(expect, sizeof expect, "%s0 0 0\n1.5 0 0\n0 -2.25 0.00100000005\n3 0 1 2\n",
             header_ascii);
    assert_string_equal(buf, expect);
    ms_test_rmdir(dir);
}

static void test_binary_layout(void **state)
{
    (void)state;
    char dir[512], path[600], buf[4096];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/t.ply", dir);
    double pos[6] = {1, 2, 3, 4, 5, 6};
    uint32_t tri[3] = {1, 0, 1};
    ms_mesh m = {.positions = pos, .triangles = tri, .vertex_count = 2, .triangle_count = 1};
    assert_int_equal(ms_ply_write(path, &m, true, true, NULL), MS_OK);
    size_t n = read_all(path, buf, sizeof buf);
    const char *end = strstr(buf, "end_header\n");
    assert_non_null(end);
    assert_non_null(strstr(buf, "format binary_little_endian 1.0\n"));
    assert_non_null(strstr(buf, "property double x\n"));
    size_t body = (size_t)(end - buf) + strlen("end_header\n");
    assert_int_equal(n - body, 2 * 24 + 13);
    double x;
    memcpy(&x, buf + body + 24, 8);
    assert_true(x == 4.0);
    const uint8_t face[13] = {3, 1, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0};
    assert_memory_equal(buf + body + 48, face, 13);
    ms_test_rmdir(dir);
}

static void test_count_mismatch_leaves_nothing(void **state)
{
    (void)state;
    char dir[512], path[600], partial[700];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(path, sizeof path, "%s/t.ply", dir);
    snprintf(partial, sizeof partial, "%s.partial", path);
    ms_ply_writer *w;
    ms_error err;
    double p[3] = {0, 0, 0};
    uint32_t tri[3] = {0, 0, 5};
    assert_int_equal(ms_ply_writer_open(path, 2, 1, true, false, &w, &err), MS_OK);
    assert_int_equal(ms_ply_writer_vertex(w, p, &err), MS_OK);
    assert_int_equal(ms_ply_writer_finish(w, &err), MS_ERR_ARG);
    assert_non_null(strstr(err.text, "fewer elements"));
    assert_int_equal(access(path, F_OK), -1);
    assert_int_equal(access(partial, F_OK), -1);

    assert_int_equal(ms_ply_writer_open(path, 1, 1, true, false, &w, &err), MS_OK);
    assert_int_equal(ms_ply_writer_vertex(w, p, &err), MS_OK);
    assert_int_equal(ms_ply_writer_triangle(w, tri, &err), MS_ERR_RANGE);
    assert_int_equal(access(partial, F_OK), -1);

    assert_int_equal(ms_ply_writer_open(path, 1, 0, true, false, &w, &err), MS_OK);
    assert_int_equal(ms_ply_writer_vertex(w, p, &err), MS_OK);
    assert_int_equal(ms_ply_writer_vertex(w, p, &err), MS_ERR_ARG);
    assert_int_equal(access(path, F_OK), -1);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_ascii_exact),
        cmocka_unit_test(test_binary_layout),
        cmocka_unit_test(test_count_mismatch_leaves_nothing),
    };
    return cmocka_run_group_tests_name("ply_write", tests, NULL, NULL);
}
