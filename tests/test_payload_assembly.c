/* Client-side reassembly of PAYLOAD frames: ranges complete in any
 * interleaving, and every way a server could break section 4.11 is refused. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_payload_assembly.h"

static ms_proto_payload frame(uint32_t cell, uint8_t stream, uint32_t offset, uint32_t end,
                              const uint8_t *data, uint32_t length)
{
    ms_proto_payload p = {cell, stream, offset, end, data, length};
    return p;
}

static void test_interleaved_ranges(void **state)
{
    (void)state;
    uint8_t bytes[1000];
    for (int i = 0; i < 1000; ++i)
        bytes[i] = (uint8_t)(i * 7);
    ms_payload_assembly *a;
    assert_int_equal(ms_payload_assembly_new(true, 1 << 20, &a, NULL), MS_OK);
    assert_int_equal(ms_payload_assembly_expect(a, 1, 10, 0, NULL), MS_OK);
    assert_int_equal(ms_payload_assembly_expect(a, 2, 11, 1, NULL), MS_OK);
    assert_int_equal(ms_payload_assembly_expect(a, 3, 12, 0, NULL), MS_OK);
    assert_int_equal(ms_payload_assembly_expect(a, 3, 12, 0, NULL), MS_ERR_ARG);
    bool done;
    ms_assembled_range r;
    ms_proto_payload f = frame(10, 0, 100, 400, bytes + 100, 100);
    assert_int_equal(ms_payload_assembly_add(a, 1, &f, false, &done, &r, NULL), MS_OK);
    assert_false(done);
    f = frame(11, 1, 0, 50, bytes, 50);
    assert_int_equal(ms_payload_assembly_add(a, 2, &f, true, &done, &r, NULL), MS_OK);
    assert_true(done);
    assert_int_equal(r.request_id, 2);
    assert_memory_equal(r.data, bytes, 50);
    f = frame(10, 0, 200, 400, bytes + 200, 200);
    assert_int_equal(ms_payload_assembly_add(a, 1, &f, true, &done, &r, NULL), MS_OK);
    assert_true(done);
    assert_int_equal(r.start, 100);
    assert_int_equal(r.end, 400);
    assert_memory_equal(r.data, bytes + 100, 300);
    /* An empty range: one frame, no data, LAST. */
    f = frame(12, 0, 7, 7, NULL, 0);
    assert_int_equal(ms_payload_assembly_add(a, 3, &f, true, &done, &r, NULL), MS_OK);
    assert_true(done);
    assert_int_equal(ms_payload_assembly_pending(a), 0);
    assert_int_equal(ms_payload_assembly_held_bytes(a), 0);
    ms_payload_assembly_free(a);
}

static void test_broken_servers_are_refused(void **state)
{
    (void)state;
    uint8_t bytes[100] = {0};
    ms_payload_assembly *a;
    assert_int_equal(ms_payload_assembly_new(true, 150, &a, NULL), MS_OK);
    for (uint32_t id = 1; id <= 8; ++id)
        assert_int_equal(ms_payload_assembly_expect(a, id, 5, 0, NULL), MS_OK);
    bool done;
    ms_assembled_range r;
    ms_proto_payload f = frame(5, 0, 0, 10, bytes, 10);
    assert_int_equal(ms_payload_assembly_add(a, 99, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(6, 0, 0, 10, bytes, 10); /* another cell */
    assert_int_equal(ms_payload_assembly_add(a, 1, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 1, 0, 10, bytes, 10); /* another stream */
    assert_int_equal(ms_payload_assembly_add(a, 2, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 0, 0, 20, bytes, 10);
    assert_int_equal(ms_payload_assembly_add(a, 3, &f, false, &done, &r, NULL), MS_OK);
    f = frame(5, 0, 11, 20, bytes, 9); /* a gap */
    assert_int_equal(ms_payload_assembly_add(a, 3, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 0, 10, 30, bytes, 10); /* the end moved */
    assert_int_equal(ms_payload_assembly_add(a, 3, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 0, 0, 20, bytes, 10); /* LAST short of the end */
    assert_int_equal(ms_payload_assembly_add(a, 4, &f, true, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 0, 0, 5, bytes, 10); /* past the end */
    assert_int_equal(ms_payload_assembly_add(a, 5, &f, false, &done, &r, NULL), MS_ERR_FORMAT);
    f = frame(5, 0, 0, 100, bytes, 10); /* held bytes over the limit (20 + 100 + 100 > 150) */
    assert_int_equal(ms_payload_assembly_add(a, 6, &f, false, &done, &r, NULL), MS_OK);
    assert_int_equal(ms_payload_assembly_add(a, 7, &f, false, &done, &r, NULL), MS_ERR_NOMEM);
    ms_payload_assembly_forget(a, 6);
    ms_payload_assembly_forget(a, 6);
    assert_int_equal(ms_payload_assembly_add(a, 7, &f, false, &done, &r, NULL), MS_OK);
    ms_payload_assembly_free(a); /* frees what is still pending */
}

static void test_many_pending_without_bytes(void **state)
{
    (void)state;
    ms_payload_assembly *a;
    assert_int_equal(ms_payload_assembly_new(false, 0, &a, NULL), MS_OK);
    for (uint32_t id = 1; id <= 5000; ++id)
        assert_int_equal(ms_payload_assembly_expect(a, id * 13, id, 0, NULL), MS_OK);
    uint8_t bytes[8] = {0};
    for (uint32_t id = 5000; id >= 1; --id) {
        bool done;
        ms_assembled_range r;
        ms_proto_payload f = frame(id, 0, 0, 8, bytes, 8);
        assert_int_equal(ms_payload_assembly_add(a, id * 13, &f, true, &done, &r, NULL), MS_OK);
        assert_true(done && r.data == NULL && r.cell == id);
    }
    assert_int_equal(ms_payload_assembly_pending(a), 0);
    ms_payload_assembly_free(a);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_interleaved_ranges),
        cmocka_unit_test(test_broken_servers_are_refused),
        cmocka_unit_test(test_many_pending_without_bytes),
    };
    return cmocka_run_group_tests_name("payload assembly", tests, NULL, NULL);
}
