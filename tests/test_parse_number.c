/* The fast decimal parsers against strtod / strtoll, bit for bit. */
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_parse_number.h"
#include "ms_test.h"


static void expect_same_as_strtod(const char *text)
{
    double fast = 0, reference = strtod(text, NULL);
    const char *end = ms_parse_double(text, &fast);
    if (!end)
        fail_msg("ms_parse_double rejected '%s'", text);
    if (*end != '\0')
        fail_msg("ms_parse_double stopped early in '%s'", text);
    if (memcmp(&fast, &reference, sizeof fast) != 0)
        fail_msg("'%s': got %.17g, strtod gives %.17g", text, fast, reference);
}

static void test_doubles_match_strtod(void **state)
{
    (void)state;
    static const char *const fixed[] = {
        "0", "-0", "+0", "1", "-1", "0.5", ".5", "5.", "-.25", "1e10", "1E-10", "1e+22",
        "1e23", "9007199254740992", "9007199254740993", "123456789012345678",
        "1234567890123456789", "12345678901234567890", "0.1", "0.2", "0.3",
        "2.2250738585072014e-308", "4.9e-324", "1.7976931348623157e308", "-0.0378297",
        "0.35444599999999998", "0.000000000000000000000000001", "3.14159265358979323846",
        "1e-22", "1e-23", "7.0e-10", "100000000000000000000000", "0.0000001", "-93.87400100000001",
    };
    for (size_t i = 0; i < sizeof fixed / sizeof fixed[0]; ++i)
        expect_same_as_strtod(fixed[i]);
    uint64_t rng = 0x9e3779b97f4a7c15u;
    char text[64];
    for (int i = 0; i < 300000; ++i) {
        uint64_t bits = ms_test_random(&rng);
        double value;
        int kind = i % 6;
        if (kind == 0) {
            memcpy(&value, &bits, sizeof value); /* any double, any exponent */
            if (value != value || value - value != 0)
                continue;
            snprintf(text, sizeof text, "%.17g", value);
        } else if (kind == 1) {
            value = (double)(int64_t)(bits >> 11) / 9007199254740992.0 * 2.0 - 1.0;
            snprintf(text, sizeof text, "%.*g", 1 + (int)(bits % 17), value * 0.25);
        } else if (kind == 2) {
            value = ((double)(bits >> 11) / 9007199254740992.0 - 0.5) * 1000.0;
            snprintf(text, sizeof text, "%.6f", value); /* typical scan coordinates */
        } else if (kind == 3) {
            value = ((double)(bits >> 11) / 9007199254740992.0 - 0.5) * 0.5;
            snprintf(text, sizeof text, "%g", value);
        } else if (kind == 4) {
            value = (double)(bits >> 11) / 9007199254740992.0;
            snprintf(text, sizeof text, "%.*e", (int)(bits % 20), value * 1e5);
        } else {
            /* Random digit strings with a random point and exponent. */
            int n = 1 + (int)(bits % 22), pos = 0;
            uint64_t more = ms_test_random(&rng);
            if (more & 1)
                text[pos++] = '-';
            int point = (int)((more >> 1) % (uint64_t)(n + 1));
            for (int d = 0; d < n; ++d) {
                if (d == point)
                    text[pos++] = '.';
                text[pos++] = (char)('0' + (ms_test_random(&rng) % 10));
            }
            if (point == n)
                text[pos++] = '0';
            if ((more >> 8) & 1)
                pos += snprintf(text + pos, sizeof text - (size_t)pos, "e%d",
                                (int)((more >> 16) % 61) - 30);
            text[pos] = '\0';
        }
        expect_same_as_strtod(text);
    }
}

static void test_double_token_rules(void **state)
{
    (void)state;
    double v = 0;
    const char *line = "1.5 -2e3\t7";
    const char *p = ms_parse_double(line, &v);
    assert_non_null(p);
    assert_true(v == 1.5);
    assert_int_equal(*p, ' ');
    p = ms_parse_double(p + 1, &v);
    assert_true(v == -2000.0);
    p = ms_parse_double(p + 1, &v);
    assert_true(v == 7.0);
    assert_int_equal(*p, '\0');
    static const char *const bad[] = {"", "abc", "1.5x", "1e", "1e+", "--1", "-", ".", "1,5",
                                      "0x", "1..2"};
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; ++i)
        if (ms_parse_double(bad[i], &v))
            fail_msg("accepted '%s'", bad[i]);
    /* strtod's spellings of non-finite values parse; callers reject them. */
    assert_non_null(ms_parse_double("nan", &v));
    assert_true(v != v);
    assert_non_null(ms_parse_double("-inf", &v));
    assert_true(v < 0 && v - v != 0);
}

static void test_integers(void **state)
{
    (void)state;
    int64_t v = 0;
    const char *p = ms_parse_int64("12345/6", &v);
    assert_non_null(p);
    assert_int_equal(v, 12345);
    assert_int_equal(*p, '/');
    assert_non_null(ms_parse_int64("-1", &v));
    assert_int_equal(v, -1);
    assert_non_null(ms_parse_int64("+42", &v));
    assert_int_equal(v, 42);
    assert_non_null(ms_parse_int64("9223372036854775807", &v));
    assert_true(v == INT64_MAX);
    assert_non_null(ms_parse_int64("-9223372036854775808", &v));
    assert_true(v == INT64_MIN);
    assert_non_null(ms_parse_int64("00000000000000000000000000042", &v));
    assert_int_equal(v, 42);
    assert_null(ms_parse_int64("9223372036854775808", &v));
    assert_null(ms_parse_int64("-9223372036854775809", &v));
    assert_null(ms_parse_int64("99999999999999999999", &v));
    assert_null(ms_parse_int64("", &v));
    assert_null(ms_parse_int64("-", &v));
    assert_null(ms_parse_int64("x1", &v));
    uint64_t rng = 12345;
    char text[32];
    for (int i = 0; i < 100000; ++i) {
        int64_t want = (int64_t)ms_test_random(&rng) >> (ms_test_random(&rng) % 63);
        snprintf(text, sizeof text, "%lld", (long long)want);
        assert_non_null(ms_parse_int64(text, &v));
        assert_true(v == want);
    }
}

/* Option values: whole-text numbers within the range, one wording for the rest. */
static void test_option_values(void **state)
{
    (void)state;
    int64_t i = -7;
    double d = -7;
    ms_error e;
    assert_int_equal(ms_option_int("--clients", "12", 1, 256, &i, &e), MS_OK);
    assert_int_equal(i, 12);
    assert_int_equal(ms_option_int("port", "0", 0, 65535, &i, &e), MS_OK);
    assert_int_equal(i, 0);
    assert_int_equal(ms_option_int("--seed", "4294967295", 0, UINT32_MAX, &i, &e), MS_OK);
    assert_true(i == UINT32_MAX);
    static const char *const bad_ints[] = {"", "x", "4.0", "12 ", " 12", "0", "257", "-1",
                                           "99999999999999999999", "1e2"};
    for (size_t k = 0; k < sizeof bad_ints / sizeof *bad_ints; ++k) {
        i = -7;
        assert_int_equal(ms_option_int("--clients", bad_ints[k], 1, 256, &i, &e), MS_ERR_RANGE);
        assert_int_equal(i, -7); /* untouched */
        char want[128];
        snprintf(want, sizeof want, "--clients wants an integer in [1, 256], got '%s'", bad_ints[k]);
        assert_string_equal(e.text, want);
    }
    assert_int_equal(ms_option_double("--tolerance", "0.5", 0.01, 1000, &d, &e), MS_OK);
    assert_true(d == 0.5);
    assert_int_equal(ms_option_double("--tolerance", "1e3", 0.01, 1000, &d, &e), MS_OK);
    assert_true(d == 1000);
    static const char *const bad_doubles[] = {"", "x", "nan", "inf", "-inf", "1001", "0.001",
                                              "0.5x", "0.5 "};
    for (size_t k = 0; k < sizeof bad_doubles / sizeof *bad_doubles; ++k) {
        d = -7;
        assert_int_equal(ms_option_double("--tolerance", bad_doubles[k], 0.01, 1000, &d, &e),
                         MS_ERR_RANGE);
        assert_true(d == -7);
        char want[128];
        snprintf(want, sizeof want, "--tolerance wants a number in [0.01, 1000], got '%s'",
                 bad_doubles[k]);
        assert_string_equal(e.text, want);
    }
    assert_int_equal(ms_option_double("--memory", "-1", 0.01, 1e7, &d, &e), MS_ERR_RANGE);
    assert_string_equal(e.text, "--memory wants a number in [0.01, 10000000], got '-1'");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_doubles_match_strtod),
        cmocka_unit_test(test_double_token_rules),
        cmocka_unit_test(test_integers),
        cmocka_unit_test(test_option_values),
    };
    return cmocka_run_group_tests_name("parse_number", tests, NULL, NULL);
}
