/* meshserve's cross-origin answers (CORS, docs/BROWSER.md "Embed"), end to
 * end on loopback: the exact headers for an allowed origin, none for another
 * or with none configured, preflights (OPTIONS) answered and refused, "*",
 * and bad cors_origins values refused at start with one line. */
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <cmocka.h>

#include "ms_test.h"
#include "ms_test_archive.h"
#include "ms_test_net.h"

typedef struct fixture {
    char dir[512];
    pid_t pid;
    uint16_t port, http_port;
} fixture;

#define MUSEUM "https://museum.example"

/* meshserve on two generated models (dragon with an 8-bit preview), with
 * cors_origins set to origins (NULL: the key left out). */
static fixture *start(const char *origins)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    char archives[600], config[600], ports[600], log[600], option[700];
    snprintf(archives, sizeof archives, "%s/archive", f->dir);
    assert_int_equal(mkdir(archives, 0755), 0);
    ms_test_add_model(archives, "bunny", 1, 12);
    ms_test_add_model(archives, "dragon", 2, 8);
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    FILE *c = fopen(config, "w");
    fputs("token = s3cret-token\nhttp_rate = 100000\n", c);
    if (origins)
        fprintf(c, "cors_origins = %s\n", origins);
    fclose(c);
    snprintf(ports, sizeof ports, "%s/ports", f->dir);
    snprintf(log, sizeof log, "%s/meshserve.log", f->dir);
    snprintf(option, sizeof option, "--config=%s", config);
    const char *extra[] = {option, NULL};
    f->pid = ms_test_meshserve_start(archives, extra, 0, ports, log, &f->port, &f->http_port);
    assert_true(f->pid > 0);
    return f;
}

static void stop(fixture *f)
{
    ms_test_stop(f->pid, SIGKILL, 5.0);
    ms_test_rmdir(f->dir);
    free(f);
}

static void request(const fixture *f, const char *method, const char *path, const char *headers,
                    int status, ms_test_http_response *r)
{
    char text[2048];
    snprintf(text, sizeof text, "%s %s HTTP/1.1\r\nHost: 127.0.0.1\r\n%sConnection: close\r\n\r\n",
             method, path, headers ? headers : "");
    assert_int_equal(ms_test_http_raw(f->http_port, text, strlen(text), r), 0);
    if (r->status != status)
        fail_msg("%s %s: status %d, expected %d: %s", method, path, r->status, status,
                 (char *)r->body);
}

/* The value of header name, or "" when the answer has none. */
static const char *header(const ms_test_http_response *r, const char *name)
{
    static char value[512];
    return ms_test_http_header(r, name, value, sizeof value) ? value : "";
}

/* How many header lines the answer has whose name starts "Access-Control-". */
static int cors_lines(const ms_test_http_response *r)
{
    int n = 0;
    for (const char *p = strstr(r->headers, "\r\nAccess-Control-"); p;
         p = strstr(p + 2, "\r\nAccess-Control-"))
        ++n;
    return n;
}

static void test_no_origin_configured(void **state)
{
    (void)state;
    fixture *f = start(NULL);
    ms_test_http_response r;
    request(f, "GET", "/catalog", "Origin: " MUSEUM "\r\n", 200, &r);
    assert_int_equal(cors_lines(&r), 0);
    ms_test_http_free(&r);
    request(f, "OPTIONS", "/models/bunny",
            "Origin: " MUSEUM "\r\nAccess-Control-Request-Method: GET\r\n", 403, &r);
    assert_string_equal((char *)r.body,
                        "error: origin not allowed to read this server (meshserve cors_origins)\n");
    assert_int_equal(cors_lines(&r), 0);
    ms_test_http_free(&r);
    /* Not a preflight: the methods. */
    request(f, "OPTIONS", "/catalog", NULL, 204, &r);
    assert_string_equal(header(&r, "Allow"), "GET, HEAD, OPTIONS");
    ms_test_http_free(&r);
    uint64_t forbidden = 1;
    assert_int_equal(ms_test_metric(f->http_port, "meshstream_forbidden_total{door=\"http\"}", &forbidden), 0);
    assert_int_equal(forbidden, 0); /* a refused origin is not a read past a preview */
    stop(f);
}

static void test_listed_origins(void **state)
{
    (void)state;
    fixture *f = start(MUSEUM ", http://localhost:8080");
    ms_test_http_response r;
    const char *expose = "Content-Range, Content-Length, Accept-Ranges, ETag, Retry-After";
    /* The catalogue, an index, a cell (with its token), an error: each readable. */
    const char *paths[] = {"/catalog?limit=10", "/models/bunny", "/models/dragon/cells/6/geometry?bits=12",
                           "/models/no-such-model"};
    const int statuses[] = {200, 200, 200, 404};
    for (int i = 0; i < 4; ++i) {
        request(f, "GET", paths[i],
                "Origin: " MUSEUM "\r\nAuthorization: Bearer s3cret-token\r\n", statuses[i], &r);
        assert_string_equal(header(&r, "Access-Control-Allow-Origin"), MUSEUM);
        assert_string_equal(header(&r, "Access-Control-Expose-Headers"), expose);
        assert_int_equal(cors_lines(&r), 2);
        assert_true(ms_test_http_varies_on(&r, "Origin"));
        ms_test_http_free(&r);
    }
    /* Case-insensitively, and the second origin of the list. */
    request(f, "GET", "/models/bunny", "Origin: http://LOCALHOST:8080\r\n", 200, &r);
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), "http://LOCALHOST:8080");
    assert_true(ms_test_http_varies_on(&r, "Authorization") && ms_test_http_varies_on(&r, "Origin"));
    ms_test_http_free(&r);
    /* Another origin, a port that differs, none: no CORS header at all. */
    const char *others[] = {"Origin: https://evil.example\r\n", "Origin: http://localhost:8081\r\n",
                            "Origin: null\r\n", NULL};
    for (int i = 0; i < 4; ++i) {
        request(f, "GET", "/models/bunny", others[i], 200, &r);
        assert_int_equal(cors_lines(&r), 0);
        assert_false(ms_test_http_varies_on(&r, "Origin"));
        ms_test_http_free(&r);
    }
    /* The preflight of a cell request with the token and a range. */
    request(f, "OPTIONS", "/models/dragon/cells/6/geometry?bits=12",
            "Origin: " MUSEUM "\r\nAccess-Control-Request-Method: GET\r\n"
            "Access-Control-Request-Headers: authorization,range\r\n",
            204, &r);
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), MUSEUM);
    assert_string_equal(header(&r, "Access-Control-Allow-Methods"), "GET, HEAD");
    assert_string_equal(header(&r, "Access-Control-Allow-Headers"),
                        "Authorization, Range, If-None-Match");
    assert_string_equal(header(&r, "Access-Control-Max-Age"), "600");
    assert_int_equal(cors_lines(&r), 4);
    assert_true(ms_test_http_varies_on(&r, "Origin"));
    assert_int_equal(r.body_length, 0);
    ms_test_http_free(&r);
    request(f, "OPTIONS", "/catalog",
            "Origin: https://evil.example\r\nAccess-Control-Request-Method: GET\r\n", 403, &r);
    assert_int_equal(cors_lines(&r), 0);
    ms_test_http_free(&r);
    /* Other methods stay refused, the CORS headers with the refusal. */
    request(f, "POST", "/catalog", "Origin: " MUSEUM "\r\nContent-Length: 0\r\n", 405, &r);
    assert_string_equal(header(&r, "Allow"), "GET, HEAD, OPTIONS");
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), MUSEUM);
    ms_test_http_free(&r);
    /* CORS adds no access: past the preview without the token, still 403. */
    request(f, "GET", "/models/dragon/cells/6/geometry?bits=12", "Origin: " MUSEUM "\r\n", 403, &r);
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), MUSEUM);
    ms_test_http_free(&r);
    stop(f);
}

static void test_any_origin(void **state)
{
    (void)state;
    fixture *f = start("*");
    ms_test_http_response r;
    request(f, "GET", "/models/bunny", "Origin: https://anywhere.example\r\n", 200, &r);
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), "*");
    assert_false(ms_test_http_varies_on(&r, "Origin")); /* the same answer for every origin */
    ms_test_http_free(&r);
    request(f, "OPTIONS", "/models/bunny",
            "Origin: https://anywhere.example\r\nAccess-Control-Request-Method: GET\r\n", 204, &r);
    assert_string_equal(header(&r, "Access-Control-Allow-Origin"), "*");
    assert_string_equal(header(&r, "Access-Control-Allow-Headers"),
                        "Authorization, Range, If-None-Match");
    ms_test_http_free(&r);
    stop(f);
}

static void test_bad_values_refused(void **state)
{
    (void)state;
    char bin[512], command[1200], out[2048];
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    const char *bad[] = {"https://museum.example/path", "ftp://museum.example", "museum.example",
                         "https://a.example,*", "https://a.example:123456", " , "};
    const char *named[] = {"https://museum.example/path", "ftp://museum.example", "museum.example",
                           "*", "https://a.example:123456", NULL};
    for (int i = 0; i < 6; ++i) {
        snprintf(command, sizeof command, "%s /nonexistent --cors-origins '%s' 2>&1", bin, bad[i]);
        assert_int_equal(ms_test_run(command, out, sizeof out), 2);
        char want[300];
        if (named[i])
            snprintf(want, sizeof want,
                     "meshserve: --cors-origins: cors_origins: '%s' is not an origin "
                     "(scheme://host[:port], no path; or '*' alone)\n", named[i]);
        else
            snprintf(want, sizeof want, "meshserve: --cors-origins: cors_origins wants origins "
                                        "(https://host[:port], separated by commas) or '*'\n");
        assert_string_equal(out, want);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_no_origin_configured),
        cmocka_unit_test(test_listed_origins),
        cmocka_unit_test(test_any_origin),
        cmocka_unit_test(test_bad_values_refused),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
