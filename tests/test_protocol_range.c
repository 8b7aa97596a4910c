/* Cell request to byte range (protocol/ms_proto_range.h, PROTOCOL.md 4.10):
 * step clamping, byte bounds, preview access, unknown cells, bad step tables. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <cmocka.h>

#include "ms_proto_range.h"

/* A cell whose stream holds steps 7, 8, 9, complete at bytes 100, 250, 400. */
static const uint32_t ends[] = {100, 250, 400};
static const ms_proto_stream_steps window = {7, 3, ends};

static ms_proto_cell_request steps_req(uint32_t a, uint32_t b)
{
    return (ms_proto_cell_request){.cell_id = 1, .unit = MS_PROTO_UNIT_STEPS, .a = a, .b = b};
}

static ms_proto_cell_request bytes_req(uint32_t offset, uint32_t length)
{
    return (ms_proto_cell_request){.cell_id = 1, .unit = MS_PROTO_UNIT_BYTES, .a = offset,
                                   .b = length};
}

static void expect_range(ms_proto_cell_request r, const ms_proto_stream_steps *s, uint8_t model,
                         uint8_t permitted, uint32_t begin, uint32_t end)
{
    ms_proto_stream_access access = {model, permitted};
    ms_proto_byte_range out = {99, 99};
    ms_error err;
    ms_status st = ms_proto_resolve_range(&r, s, &access, &out, NULL, &err);
    if (st != MS_OK)
        fail_msg("unexpected failure: %s", err.text);
    assert_int_equal(out.begin, begin);
    assert_int_equal(out.end, end);
}

static void expect_fault(ms_proto_cell_request r, const ms_proto_stream_steps *s, uint8_t model,
                         uint8_t permitted, ms_status status, uint16_t code, uint64_t detail)
{
    ms_proto_stream_access access = {model, permitted};
    ms_proto_byte_range out;
    ms_proto_fault fault;
    assert_int_equal(ms_proto_resolve_range(&r, s, &access, &out, &fault, NULL), status);
    assert_int_equal(fault.code, code);
    assert_int_equal(fault.detail, detail);
    assert_false(fault.fatal);
}

static void test_steps_clamped_with_full_access(void **state)
{
    (void)state;
    expect_range(steps_req(0, 63), &window, 16, 16, 0, 400);
    expect_range(steps_req(7, 7), &window, 16, 16, 0, 100);
    expect_range(steps_req(0, 8), &window, 16, 16, 0, 250);
    expect_range(steps_req(8, 9), &window, 16, 16, 100, 400);
    expect_range(steps_req(9, 9), &window, 16, 16, 250, 400);
    expect_range(steps_req(9, 63), &window, 16, 16, 250, 400);
    expect_range(steps_req(0, 6), &window, 16, 16, 0, 0);       /* before the window */
    expect_range(steps_req(10, 63), &window, 16, 16, 400, 400); /* past the window */
    const ms_proto_stream_steps empty = {0, 0, NULL};
    expect_range(steps_req(0, 63), &empty, 16, 16, 0, 0);
    /* A stream with a step that adds no byte. */
    static const uint32_t flat[] = {10, 10, 30};
    const ms_proto_stream_steps flat_steps = {0, 3, flat};
    expect_range(steps_req(1, 1), &flat_steps, 3, 3, 10, 10);
    expect_range(steps_req(1, 2), &flat_steps, 3, 3, 10, 30);
}

static void test_bytes(void **state)
{
    (void)state;
    expect_range(bytes_req(0, 400), &window, 16, 16, 0, 400);
    expect_range(bytes_req(399, 1), &window, 16, 16, 399, 400);
    expect_fault(bytes_req(400, 1), &window, 16, 16, MS_ERR_RANGE,
                 MS_PROTO_E_RANGE_NOT_SATISFIABLE, 400);
    expect_fault(bytes_req(0, 401), &window, 16, 16, MS_ERR_RANGE,
                 MS_PROTO_E_RANGE_NOT_SATISFIABLE, 400);
    const ms_proto_stream_steps empty = {0, 0, NULL};
    expect_fault(bytes_req(0, 1), &empty, 16, 16, MS_ERR_RANGE, MS_PROTO_E_RANGE_NOT_SATISFIABLE,
                 0);
}

static void test_preview_access(void **state)
{
    (void)state;
    /* Steps 0..8 permitted out of 16. */
    expect_range(steps_req(0, 8), &window, 16, 9, 0, 250);
    expect_fault(steps_req(0, 9), &window, 16, 9, MS_ERR_RANGE, MS_PROTO_E_FORBIDDEN, 9);
    expect_fault(steps_req(0, 63), &window, 16, 9, MS_ERR_RANGE, MS_PROTO_E_FORBIDDEN, 9);
    expect_range(bytes_req(0, 250), &window, 16, 9, 0, 250);
    expect_range(bytes_req(100, 150), &window, 16, 9, 100, 250);
    expect_fault(bytes_req(0, 251), &window, 16, 9, MS_ERR_RANGE, MS_PROTO_E_FORBIDDEN, 9);
    /* Out of the stream is reported before access. */
    expect_fault(bytes_req(0, 401), &window, 16, 9, MS_ERR_RANGE,
                 MS_PROTO_E_RANGE_NOT_SATISFIABLE, 400);
    /* A preview ending below the cell's window: no byte of it is readable. */
    expect_range(steps_req(0, 4), &window, 16, 5, 0, 0);
    expect_fault(bytes_req(0, 1), &window, 16, 5, MS_ERR_RANGE, MS_PROTO_E_FORBIDDEN, 5);
    /* A preview reaching past the cell's window: the whole stream. */
    expect_range(bytes_req(0, 400), &window, 16, 12, 0, 400);
    expect_range(steps_req(0, 11), &window, 16, 12, 0, 400);
    /* An APO-less model: nothing to read, nothing forbidden. */
    const ms_proto_stream_steps empty = {0, 0, NULL};
    expect_range(steps_req(0, 63), &empty, 0, 0, 0, 0);
}

static void test_unknown_cell(void **state)
{
    (void)state;
    ms_proto_fault fault;
    assert_int_equal(ms_proto_check_cell_id(4, 5, &fault, NULL), MS_OK);
    assert_int_equal(ms_proto_check_cell_id(5, 5, &fault, NULL), MS_ERR_RANGE);
    assert_int_equal(fault.code, MS_PROTO_E_UNKNOWN_CELL);
    assert_int_equal(fault.detail, 5);
    assert_false(fault.fatal);
    assert_int_equal(ms_proto_check_cell_id(UINT32_MAX, MS_PROTO_MAX_CELLS, &fault, NULL),
                     MS_ERR_RANGE);
    assert_int_equal(fault.detail, UINT32_MAX);
}

static void test_bad_tables_and_arguments(void **state)
{
    (void)state;
    static const uint32_t decreasing[] = {10, 5, 30};
    const ms_proto_stream_steps bad = {0, 3, decreasing};
    expect_fault(steps_req(0, 1), &bad, 3, 3, MS_ERR_CORRUPT, MS_PROTO_E_INTERNAL, 0);
    const ms_proto_stream_steps too_wide = {62, 3, ends};
    expect_fault(steps_req(0, 1), &too_wide, 64, 64, MS_ERR_CORRUPT, MS_PROTO_E_INTERNAL, 0);
    ms_proto_stream_access access = {16, 16};
    ms_proto_byte_range out;
    ms_proto_cell_request r = steps_req(5, 4);
    assert_int_equal(ms_proto_resolve_range(&r, &window, &access, &out, NULL, NULL), MS_ERR_ARG);
    r = bytes_req(1, 0);
    assert_int_equal(ms_proto_resolve_range(&r, &window, &access, &out, NULL, NULL), MS_ERR_ARG);
    access = (ms_proto_stream_access){4, 5};
    r = steps_req(0, 1);
    assert_int_equal(ms_proto_resolve_range(&r, &window, &access, &out, NULL, NULL), MS_ERR_ARG);
    assert_int_equal(ms_proto_resolve_range(NULL, &window, &access, &out, NULL, NULL), MS_ERR_ARG);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_steps_clamped_with_full_access),
        cmocka_unit_test(test_bytes),
        cmocka_unit_test(test_preview_access),
        cmocka_unit_test(test_unknown_cell),
        cmocka_unit_test(test_bad_tables_and_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
