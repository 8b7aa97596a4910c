/* The repository stands alone (issue 33): a clone of the committed tree into a
 * scratch folder with nothing beside it (no sibling folders, no MESHSTREAM_MODELS,
 * no build/) builds and passes `make check`, the unit tier. The clone is of
 * HEAD, so uncommitted changes are not part of it; outside a git checkout (a
 * release tarball) the test is skipped, saying so. The figures of the run (its
 * summary line and the time) are printed. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <cmocka.h>

#include "ms_test.h"

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* For each program `named` lists ("failed programs: NAME(rc=N) ..."), the
 * end of its own output in the log: the 3000 characters before its
 * "=== NAME: rc=" line (a failure under the clone's load shows its
 * assertion here, not in the log's end). */
static void print_failed_outputs(const char *log, const char *named)
{
    const char *p = strchr(named, ':');
    while (p && *p) {
        p += strspn(p, ": ");
        size_t n = strcspn(p, "( ");
        if (n == 0 || n > 200)
            break;
        char marker[256];
        snprintf(marker, sizeof marker, "=== %.*s: rc=", (int)n, p);
        const char *at = strstr(log, marker);
        if (at) { /* plain stdio: cmocka's messages are cut short */
            const char *from = at - log > 3000 ? at - 3000 : log;
            printf("--- the clone's output of %.*s:\n", (int)n, p);
            fwrite(from, 1, (size_t)(at - from), stdout);
            printf("\n");
            fflush(stdout);
        }
        p = strchr(p + n, ' ');
    }
}

static void test_clone_alone_passes_make_check(void **state)
{
    (void)state;
    char out[4096];
    if (ms_test_run("git rev-parse --is-inside-work-tree", out, sizeof out) != 0) {
        print_message("not a git checkout: no clone to test\n");
        skip();
    }
    char dir[512], command[8192], log[700];
    ms_test_tmpdir(dir, sizeof dir);
    snprintf(log, sizeof log, "%s/check.log", dir);
    /* the environment a new user has: none of the test harness's variables */
    snprintf(command, sizeof command,
             "git clone --quiet --no-hardlinks . '%s/meshstream' && "
             "cd '%s/meshstream' && "
             "env -u MESHSTREAM_MODELS -u MESHSTREAM_BIN -u MESHSTREAM_MODEL_CACHE "
             "-u MAKEFLAGS -u MFLAGS -u MAKELEVEL make -j2 check > '%s' 2>&1",
             dir, dir, log);
    double t0 = now_s();
    int status = ms_test_run(command, out, sizeof out);
    double seconds = now_s() - t0;
    size_t length = 0;
    unsigned char *data = ms_test_read_file(log, &length);
    char *text = malloc(length + 1); /* the file's bytes are not a string */
    assert_non_null(text);
    memcpy(text, data, length);
    text[length] = 0;
    free(data);
    char *summary = NULL;
    for (char *p = text; (p = strstr(p, "tests: ")) != NULL; ++p)
        summary = p; /* the last summary line: run-tests prints it last */
    unsigned passed = 0, failed = 1;
    if (summary && sscanf(summary, "tests: %u passed, %u failed", &passed, &failed) == 2)
        print_message("fresh clone, make check: %u passed, %u failed, %.0f s\n", passed, failed,
                      seconds);
    if (status != 0 || failed != 0 || passed < 100) {
        /* which programs failed (run-tests names them before its summary),
         * then each one's own output (what run-tests printed before its
         * "=== NAME: rc=" line), else the log's end */
        const char *which = strstr(text, "failed programs:");
        char named[512] = "";
        if (which)
            snprintf(named, sizeof named, "%.*s", (int)strcspn(which, "\n"), which);
        print_failed_outputs(text, named);
        size_t from = length > 3000 ? length - 3000 : 0;
        char tail[3100];
        snprintf(tail, sizeof tail, "%.*s", (int)(length - from), text + from);
        free(text);
        fail_msg("make check in a fresh clone: status %d, %s; %s\n%s", status, out, named, tail);
    }
    free(text);
    ms_test_rmdir(dir);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_clone_alone_passes_make_check),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
