/* ms_mesh container and ms_error basics. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_mesh.h"

static void test_reserve_keeps_content_and_free_zeroes(void **state)
{
    (void)state;
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, 2, 1, &err), MS_OK);
    m.positions[0] = 1.5;
    m.triangles[2] = 7;
    assert_int_equal(ms_mesh_reserve(&m, 100000, 300000, &err), MS_OK);
    assert_true(m.vertex_capacity >= 100000);
    assert_true(m.triangle_capacity >= 300000);
    assert_true(m.positions[0] == 1.5);
    assert_int_equal(m.triangles[2], 7);
    ms_mesh_free(&m);
    assert_null(m.positions);
    assert_int_equal(m.vertex_capacity, 0);
    ms_mesh_free(NULL);
}

static void test_reserve_absurd_size_fails_cleanly(void **state)
{
    (void)state;
    ms_mesh m = {0};
    ms_error err;
    assert_int_equal(ms_mesh_reserve(&m, SIZE_MAX / 2, 0, &err), MS_ERR_NOMEM);
    assert_int_equal(err.code, MS_ERR_NOMEM);
    assert_non_null(strstr(err.text, "too large"));
    ms_mesh_free(&m);
}

static void test_error_text_is_one_line(void **state)
{
    (void)state;
    ms_error err;
    assert_int_equal(ms_error_set(&err, MS_ERR_FORMAT, "a\nb %d", 3), MS_ERR_FORMAT);
    assert_string_equal(err.text, "a b 3");
    ms_error_clear(&err);
    assert_int_equal(err.code, MS_OK);
    assert_string_equal(ms_status_name(MS_ERR_CORRUPT), "corrupted data");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reserve_keeps_content_and_free_zeroes),
        cmocka_unit_test(test_reserve_absurd_size_fails_cleanly),
        cmocka_unit_test(test_error_text_is_one_line),
    };
    return cmocka_run_group_tests_name("mesh", tests, NULL, NULL);
}
