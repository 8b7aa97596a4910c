/* Removing repeated triangles (server/geometry/ms_tri_unify.h): the earliest copy stays,
 * the order is kept, an opposite-orientation repeat is reported, and indices at
 * or above 2^21 (the packed radix key's limit) give the same result. */
#include <setjmp.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>
#include <cmocka.h>

#include "ms_tri_unify.h"

static void check_unify(uint32_t offset)
{
    /* (0,1,2) twice (the second rotated: same orientation), (3,4,5) then its
     * mirror (2 of them), (1,2,3) once. */
    uint32_t t[] = {0, 1, 2, 3, 4, 5, 1, 2, 0, 1, 2, 3, 5, 4, 3, 4, 3, 5};
    for (size_t i = 0; i < sizeof t / sizeof *t; ++i)
        t[i] += offset;
    size_t n = 6, removed = 10;
    bool conflict = false;
    ms_error err;
    assert_int_equal(ms_tri_unify(t, &n, &conflict, &removed, &err), MS_OK);
    assert_int_equal(n, 3);
    assert_int_equal(removed, 13);
    assert_true(conflict);
    const uint32_t want[] = {0, 1, 2, 3, 4, 5, 1, 2, 3};
    for (size_t i = 0; i < 9; ++i)
        assert_int_equal(t[i], want[i] + offset);
    /* Without conflict reporting, only same-orientation repeats: no conflict. */
    uint32_t u[] = {7, 8, 9, 8, 9, 7, 9, 7, 8};
    for (size_t i = 0; i < 9; ++i)
        u[i] += offset;
    n = 3;
    conflict = false;
    assert_int_equal(ms_tri_unify(u, &n, &conflict, NULL, &err), MS_OK);
    assert_int_equal(n, 1);
    assert_false(conflict);
    assert_int_equal(u[0], 7 + offset);
    assert_int_equal(u[1], 8 + offset);
    assert_int_equal(u[2], 9 + offset);
    n = 0;
    assert_int_equal(ms_tri_unify(u, &n, NULL, NULL, &err), MS_OK);
    assert_int_equal(n, 0);
}

static void test_small_indices(void **state)
{
    (void)state;
    check_unify(0);
}

static void test_indices_past_the_packed_key(void **state)
{
    (void)state;
    check_unify((1u << 21) - 2); /* some indices below the limit, some above */
    check_unify(4000000000u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_small_indices),
        cmocka_unit_test(test_indices_past_the_packed_key),
    };
    return cmocka_run_group_tests_name("tri_unify", tests, NULL, NULL);
}
