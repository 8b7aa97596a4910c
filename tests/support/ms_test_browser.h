/* What the browser tests (tests/test_browser*.c) share: whether the browser
 * cases can run, the web folder to serve, and tests/browser-page (headless
 * Chromium driven over the DevTools protocol) run on a URL.
 *
 * Include after <cmocka.h> (MS_TEST_NEED_BROWSER skips and fails through it).
 * Not thread-safe: one test thread. */
#ifndef MS_TEST_BROWSER_H
#define MS_TEST_BROWSER_H

#include <jansson.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <sys/stat.h>
#include <sys/types.h>

/* `make wasm`'s site: the module and the pages. */
#define MS_TEST_SITE "build/wasm/site"

/* Whether a program is on PATH. */
bool ms_test_have_program(const char *name);

/* Why the cases that need the browser cannot run, into why ("" when they
 * can): chromium-headless-shell is not installed, or no built site and no
 * emscripten to build it. With emscripten installed, a missing site is a
 * failure (MS_TEST_NEED_BROWSER), not a skip: `make test` builds it. */
void ms_test_browser_why_skip(char *why, size_t size);

/* The folder meshserve serves as --web-dir: the built site when it exists,
 * else web/ (its routes still answer; the cases that need the module skip or
 * fail). */
const char *ms_test_browser_web_dir(void);

/* Starts meshserve on archives with the web folder (its log and port file in
 * dir), filling its ports: the pid, or 0 when it did not start. */
pid_t ms_test_browser_serve(const char *dir, const char *archives, uint16_t *port, uint16_t *http_port);

/* meshrender's pictures of archive for the page's cameras (`cam=` values:
 * "PX,PY,PZ,TX,TY,TZ,UX,UY,UZ,FOVY"), count of them, at width x height and a
 * 1 px tolerance, into ref_dir (DIR/ref; frame_NNN.png each): its JSON report
 * (the caller frees it), with one frame per camera checked. */
json_t *ms_test_browser_reference(const char *dir, const char *archive, const char *const *cameras, int count,
                                  int width, int height, char *ref_dir, size_t ref_size);

/* Runs `tests/browser-page 'URL' ARGUMENTS` (the size, --out, --timeout,
 * ...) and returns the driver's JSON report (the test fails when it prints
 * none), after printing the page's state and message. Caller frees. */
json_t *ms_test_browser_run(const char *url, const char *arguments);

/* The report's page figure `key` (window.meshstream.KEY) as an integer. */
json_int_t ms_test_browser_page_int(json_t *report, const char *key);

/* Skips a case that needs the browser when why_skip says so; fails it when
 * emscripten is installed but the site was not built. */
#define MS_TEST_NEED_BROWSER(why_skip)                                                         \
    do {                                                                                       \
        if ((why_skip)[0]) {                                                                   \
            printf("skipped: %s\n", (why_skip));                                               \
            skip();                                                                            \
        }                                                                                      \
        struct stat site_;                                                                     \
        if (stat(MS_TEST_SITE "/meshstream.wasm", &site_) != 0)                                \
            fail_msg("emscripten is installed but " MS_TEST_SITE "/meshstream.wasm is "        \
                     "missing: run make wasm");                                                \
    } while (0)

#endif
