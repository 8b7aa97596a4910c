/* The index blob's wire encoding (protocol/ms_proto_index.c, PROTOCOL.md
 * section 4.8): a ZLIB-encoded index inflates back to the exact blob, and
 * every hostile stream (truncated, a bad declared size, above the maximum,
 * inflating to more or fewer bytes than declared, trailing bytes, not zlib at
 * all, a CRC mismatch, a zip bomb) gets its documented status without a byte
 * written past the declared buffer (ASan watches the exact-size buffers). */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <zlib.h>
#include <cmocka.h>

#include "ms_proto.h"

/* Something shaped like a model index: 80-byte records, most of them the
 * same empty record, the others with small counters and offsets. */
#define RECORDS 1281u
#define RECORD 80u
#define BLOB_SIZE (RECORDS * RECORD)

static uint8_t *make_blob(void)
{
    uint8_t *b = calloc(1, BLOB_SIZE);
    uint32_t offset = 0;
    for (uint32_t i = 0; i < RECORDS; ++i) {
        uint8_t *r = b + i * RECORD;
        if (i % 5 < 3)
            continue; /* an empty cell */
        memcpy(r, &i, 4);
        offset += 100 + (i * 7919u) % 4000;
        memcpy(r + 8, &offset, 4);
        r[16] = (uint8_t)(i % 17);
        r[40] = (uint8_t)(i * 31);
    }
    return b;
}

typedef struct encoded {
    uint8_t *blob, *z;
    size_t z_size;
    uint32_t crc;
} encoded;

static encoded encode_blob(void)
{
    encoded e;
    e.blob = make_blob();
    e.crc = (uint32_t)crc32_z(0L, e.blob, BLOB_SIZE);
    ms_error err;
    assert_int_equal(ms_proto_index_deflate(e.blob, BLOB_SIZE, &e.z, &e.z_size, &err), MS_OK);
    assert_true(e.z_size > 0 && e.z_size < BLOB_SIZE / 4);
    return e;
}

static void encoded_free(encoded *e)
{
    free(e->blob);
    free(e->z);
}

/* Inflates into a buffer of exactly declared bytes; returns the status and
 * checks that a failure leaves one line of text. */
static ms_status inflate_into_exact(const uint8_t *z, size_t z_size, uint32_t declared,
                                    uint32_t crc, const uint8_t *expect, const char *text_has)
{
    uint8_t *out = malloc(declared ? declared : 1);
    ms_error err;
    ms_status s = ms_proto_index_inflate(z, z_size, declared, crc, out, &err);
    if (s == MS_OK && expect)
        assert_memory_equal(out, expect, declared);
    if (s != MS_OK) {
        assert_int_equal(err.code, s);
        assert_null(strchr(err.text, '\n'));
        if (text_has && !strstr(err.text, text_has))
            fail_msg("error text '%s' lacks '%s'", err.text, text_has);
    }
    free(out);
    return s;
}

static void test_round_trip(void **state)
{
    (void)state;
    encoded e = encode_blob();
    assert_int_equal(inflate_into_exact(e.z, e.z_size, BLOB_SIZE, e.crc, e.blob, NULL), MS_OK);
    /* The stream is plain zlib: zlib's own uncompress reads it too. */
    uint8_t *out = malloc(BLOB_SIZE);
    uLongf n = BLOB_SIZE;
    assert_int_equal(uncompress(out, &n, e.z, (uLong)e.z_size), Z_OK);
    assert_int_equal(n, BLOB_SIZE);
    assert_memory_equal(out, e.blob, BLOB_SIZE);
    free(out);
    encoded_free(&e);
}

static void test_deflate_refuses(void **state)
{
    (void)state;
    /* Incompressible bytes: the stream would not be shorter, send raw. */
    uint8_t noise[4096];
    uint64_t x = 88172645463325252ull;
    for (size_t i = 0; i < sizeof noise; ++i) {
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        noise[i] = (uint8_t)x;
    }
    uint8_t *z = (uint8_t *)1;
    size_t z_size = 1;
    ms_error err;
    assert_int_equal(ms_proto_index_deflate(noise, sizeof noise, &z, &z_size, &err), MS_ERR_RANGE);
    assert_null(z);
    assert_int_equal(z_size, 0);
    assert_int_equal(ms_proto_index_deflate(noise, 0, &z, &z_size, &err), MS_ERR_ARG);
    assert_int_equal(ms_proto_index_deflate(noise, (size_t)MS_PROTO_MAX_INDEX_SIZE + 1, &z,
                                            &z_size, &err),
                     MS_ERR_ARG);
}

static void test_bad_declared_size(void **state)
{
    (void)state;
    encoded e = encode_blob();
    ms_error err;
    uint8_t one;
    assert_int_equal(ms_proto_index_inflate(e.z, e.z_size, 0, e.crc, &one, &err), MS_ERR_RANGE);
    assert_non_null(strstr(err.text, "declared index size 0"));
    /* Above the maximum: refused before any allocation or inflating. */
    assert_int_equal(ms_proto_index_inflate(e.z, e.z_size, MS_PROTO_MAX_INDEX_SIZE + 1u, e.crc,
                                            &one, &err),
                     MS_ERR_RANGE);
    assert_non_null(strstr(err.text, "outside [1, 67108864]"));
    /* A stream not shorter than what it declares is not a compressed index. */
    assert_int_equal(inflate_into_exact(e.z, e.z_size, (uint32_t)e.z_size, e.crc, NULL,
                                        "not shorter than the declared"),
                     MS_ERR_RANGE);
    assert_int_equal(inflate_into_exact(e.z, 0, BLOB_SIZE, e.crc, NULL, "not shorter"),
                     MS_ERR_RANGE);
    encoded_free(&e);
}

static void test_truncated(void **state)
{
    (void)state;
    encoded e = encode_blob();
    /* Cut anywhere: the last byte (Adler-32 trailer), mid-stream, the header. */
    const size_t cuts[] = {e.z_size - 1, e.z_size - 4, e.z_size / 2, 2, 1};
    for (size_t i = 0; i < sizeof cuts / sizeof *cuts; ++i)
        assert_int_equal(inflate_into_exact(e.z, cuts[i], BLOB_SIZE, e.crc, NULL, "truncated"),
                         MS_ERR_FORMAT);
    encoded_free(&e);
}

static void test_size_mismatch(void **state)
{
    (void)state;
    encoded e = encode_blob();
    /* Declared one byte short: the stream has more to give. */
    assert_int_equal(inflate_into_exact(e.z, e.z_size, BLOB_SIZE - 1, e.crc, NULL,
                                        "inflates to more than the declared 102479 bytes"),
                     MS_ERR_FORMAT);
    assert_int_equal(inflate_into_exact(e.z, e.z_size, BLOB_SIZE / 2, e.crc, NULL,
                                        "more than the declared"),
                     MS_ERR_FORMAT);
    /* Declared one byte long: the stream ends first. */
    assert_int_equal(inflate_into_exact(e.z, e.z_size, BLOB_SIZE + 1, e.crc, NULL,
                                        "inflates to 102480 bytes, not the declared 102481"),
                     MS_ERR_FORMAT);
    encoded_free(&e);
}

static void test_trailing_and_garbage(void **state)
{
    (void)state;
    encoded e = encode_blob();
    uint8_t *longer = malloc(e.z_size + 3);
    memcpy(longer, e.z, e.z_size);
    memcpy(longer + e.z_size, "xyz", 3);
    assert_int_equal(inflate_into_exact(longer, e.z_size + 3, BLOB_SIZE, e.crc, NULL,
                                        "3 bytes follow the end"),
                     MS_ERR_FORMAT);
    free(longer);
    /* Not a zlib header; then a good header on a corrupted body. */
    uint8_t junk[64];
    memset(junk, 0xA5, sizeof junk);
    assert_int_equal(inflate_into_exact(junk, sizeof junk, BLOB_SIZE, e.crc, NULL,
                                        "not a valid zlib stream"),
                     MS_ERR_FORMAT);
    uint8_t *bad = malloc(e.z_size);
    memcpy(bad, e.z, e.z_size);
    for (size_t i = 2; i < e.z_size; i += 7)
        bad[i] ^= 0x5A;
    assert_int_equal(inflate_into_exact(bad, e.z_size, BLOB_SIZE, e.crc, NULL, NULL),
                     MS_ERR_FORMAT);
    free(bad);
    encoded_free(&e);
}

static void test_crc_mismatch(void **state)
{
    (void)state;
    encoded e = encode_blob();
    assert_int_equal(inflate_into_exact(e.z, e.z_size, BLOB_SIZE, e.crc ^ 1u, NULL,
                                        "fails its CRC-32"),
                     MS_ERR_CORRUPT);
    encoded_free(&e);
}

/* 16 MiB of zeros in about 16 KB: declared as 1 MiB, the inflater stops at
 * the declared room and says so. */
static void test_zip_bomb(void **state)
{
    (void)state;
    const size_t big = 16u << 20;
    uint8_t *zeros = calloc(1, big);
    uLongf z_size = compressBound(big);
    uint8_t *z = malloc(z_size);
    assert_int_equal(compress2(z, &z_size, zeros, big, 9), Z_OK);
    assert_true(z_size < (1u << 20));
    assert_int_equal(inflate_into_exact(z, z_size, 1u << 20, 0, NULL,
                                        "inflates to more than the declared 1048576 bytes"),
                     MS_ERR_FORMAT);
    free(z);
    free(zeros);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_round_trip),
        cmocka_unit_test(test_deflate_refuses),
        cmocka_unit_test(test_bad_declared_size),
        cmocka_unit_test(test_truncated),
        cmocka_unit_test(test_size_mismatch),
        cmocka_unit_test(test_trailing_and_garbage),
        cmocka_unit_test(test_crc_mismatch),
        cmocka_unit_test(test_zip_bomb),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
