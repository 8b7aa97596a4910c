/* The browser tests' shared pieces: see ms_test_browser.h. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <cmocka.h>

#include "ms_test_browser.h"
#include <sys/stat.h>

#include "ms_test.h"
#include "ms_test_net.h"

bool ms_test_have_program(const char *name)
{
    char command[256], out[256];
    snprintf(command, sizeof command, "command -v %s", name);
    return ms_test_run(command, out, sizeof out) == 0;
}

static bool site_built(void)
{
    struct stat st;
    return stat(MS_TEST_SITE "/meshstream.wasm", &st) == 0;
}

void ms_test_browser_why_skip(char *why, size_t size)
{
    why[0] = '\0';
    if (!ms_test_have_program("chromium-headless-shell"))
        snprintf(why, size, "chromium-headless-shell is not installed (scripts/install-deps)");
    else if (!site_built() && !ms_test_have_program("emcc"))
        snprintf(why, size, "emscripten is not installed (scripts/install-deps), so no " MS_TEST_SITE);
}

const char *ms_test_browser_web_dir(void) { return site_built() ? MS_TEST_SITE : "web"; }

json_t *ms_test_browser_run(const char *url, const char *arguments)
{
    char command[8192];
    snprintf(command, sizeof command, "tests/browser-page '%s' %s", url, arguments);
    json_t *report = ms_test_run_json(command, 0);
    printf("%s: %s, %s\n", url, json_string_value(json_object_get(report, "state")),
           json_string_value(json_object_get(report, "message")));
    return report;
}

json_int_t ms_test_browser_page_int(json_t *report, const char *key)
{
    return json_integer_value(json_object_get(json_object_get(report, "page"), key));
}

pid_t ms_test_browser_serve(const char *dir, const char *archives, uint16_t *port, uint16_t *http_port)
{
    char log[700], ports[700];
    snprintf(log, sizeof log, "%s/meshserve.log", dir);
    snprintf(ports, sizeof ports, "%s/ports", dir);
    const char *extra[] = {"--web-dir", ms_test_browser_web_dir(), NULL};
    return ms_test_meshserve_start(archives, extra, 0, ports, log, port, http_port);
}

json_t *ms_test_browser_reference(const char *dir, const char *archive, const char *const *cameras, int count,
                                  int width, int height, char *ref_dir, size_t ref_size)
{
    /* the cameras as keyframes "K PX PY PZ TX TY TZ UX UY UZ FOVY" */
    char path_file[700], text[2048], command[4096], meshrender[600];
    size_t used = (size_t)snprintf(text, sizeof text, "meshstream-camera-path 1\n");
    for (int k = 0; k < count && used < sizeof text; ++k) {
        char line[128];
        snprintf(line, sizeof line, "%d %s\n", k, cameras[k]);
        for (char *c = line; *c; ++c)
            *c = *c == ',' ? ' ' : *c;
        used += (size_t)snprintf(text + used, sizeof text - used, "%s", line);
    }
    snprintf(path_file, sizeof path_file, "%s/cameras.cam", dir);
    ms_test_write_file(path_file, text, used);
    snprintf(ref_dir, ref_size, "%s/ref", dir);
    ms_test_bin_path(meshrender, sizeof meshrender, "meshrender");
    snprintf(command, sizeof command, "%s %s -p %s -o %s --width %d --height %d --tolerance 1 --threads 2 --json",
             meshrender, archive, path_file, ref_dir, width, height);
    json_t *ref = ms_test_run_json(command, 0);
    assert_int_equal(json_array_size(json_object_get(ref, "frames")), count);
    return ref;
}
