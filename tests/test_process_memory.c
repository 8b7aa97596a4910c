/* The process's resident memory (common/util/ms_process_memory.h): a status
 * text parses to its kB figures times 1024, missing Rss* lines read as 0, a
 * text without VmRSS or VmHWM is refused with one line; this process's own
 * figures are read, and touching 32 MiB more raises its resident memory by
 * at least that much. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <cmocka.h>

#include "ms_process_memory.h"

static void test_parse(void **state)
{
    (void)state;
    const char *text = "Name:\tmeshview\nVmPeak:\t 1200000 kB\nVmHWM:\t  812836 kB\nVmRSS:\t  794112 kB\n"
                       "RssAnon:\t  501000 kB\nRssFile:\t  290000 kB\nRssShmem:\t    3112 kB\nThreads:\t9\n";
    ms_process_memory m;
    ms_error err;
    assert_int_equal(ms_process_memory_parse(text, &m, &err), MS_OK);
    assert_int_equal(m.rss, 794112ull * 1024);
    assert_int_equal(m.rss_peak, 812836ull * 1024);
    assert_int_equal(m.rss_anon, 501000ull * 1024);
    assert_int_equal(m.rss_file, 290000ull * 1024);
    assert_int_equal(m.rss_shmem, 3112ull * 1024);
    /* an older kernel without the Rss* lines */
    assert_int_equal(ms_process_memory_parse("VmHWM:\t10 kB\nVmRSS:\t8 kB\n", &m, &err), MS_OK);
    assert_int_equal(m.rss, 8192);
    assert_int_equal(m.rss_peak, 10240);
    assert_int_equal(m.rss_anon + m.rss_file + m.rss_shmem, 0);
    /* "VmRSS" must start a line: a name holding it is not the figure */
    assert_int_equal(ms_process_memory_parse("Name:\tVmRSS:\t5 kB\nVmHWM:\t10 kB\n", &m, &err), MS_ERR_FORMAT);
    assert_string_equal(err.text, "process status: no VmRSS or VmHWM line");
    assert_int_equal(ms_process_memory_parse("VmRSS:\tmany kB\nVmHWM:\t10 kB\n", &m, &err), MS_ERR_FORMAT);
    assert_int_equal(ms_process_memory_parse("", &m, &err), MS_ERR_FORMAT);
}

static void test_this_process(void **state)
{
    (void)state;
    ms_process_memory before, after;
    ms_error err;
    assert_int_equal(ms_process_memory_read(&before, &err), MS_OK);
    assert_true(before.rss > 0);
    assert_true(before.rss_peak >= before.rss);
    enum { TOUCHED = 32 << 20 };
    unsigned char *block = malloc(TOUCHED);
    assert_non_null(block);
    memset(block, 0x5A, TOUCHED); /* resident once written */
    assert_int_equal(ms_process_memory_read(&after, &err), MS_OK);
    assert_true(after.rss >= before.rss + TOUCHED - (1 << 20)); /* a page or two may have been freed */
    assert_true(after.rss_peak >= after.rss);
    assert_true(after.rss_anon >= TOUCHED);
    assert_int_equal(block[TOUCHED - 1], 0x5A);
    free(block);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_parse),
        cmocka_unit_test(test_this_process),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
