/* meshview's catalogue screen against slow and silent servers: its fetches
 * (the selected model's documents, pages, searches) run on the catalogue's
 * worker (ms_viewer_fetcher.h), so that the drawing thread never waits. A
 * "frame" here is what the drawing thread does for the catalogue besides GL:
 * the keys, taking what came (ms_viewer_catalogue_poll) and the panel's
 * state (ms_viewer_catalogue_panel); each is timed.
 *   - a server that takes the connection and never answers: frames go on at
 *     their pace, the panel says "loading" until the time-out, then "no
 *     picture" with one failure line; a search typed keeps the list held;
 *     freeing the screen while a fetch is in flight returns at once (the
 *     search whose page never came dropped);
 *   - meshserve behind a relay adding DELAY_S each way: one selection fetched
 *     on the drawing thread (as before the worker) holds it for over 4 x
 *     DELAY_S; selecting through the
 *     ten models quickly keeps every frame under FRAME_LIMIT_MS, the last
 *     model's picture comes (the ones passed by are not fetched), over
 *     one connection; a typed search's first page comes in the background;
 *   - a fetcher asked for what a server refuses (an unknown model) reports
 *     the refusal and serves the next request on the same connection;
 *   - a server that drops the connection while idle: the next request
 *     reconnects once and comes whole; a document that never comes ends
 *     with the time-out's exact line;
 *   - a model's annotations (ms_viewer_annotate.h) come the same way: asked
 *     for at the model's first frame, which returns at once also on a silent
 *     server, and taken by a later frame; none stored is the empty set. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <setjmp.h>
#include <signal.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>
#include <GLFW/glfw3.h>

#include "ms_nsp_check.h"
#include "ms_progress.h"
#include "ms_test.h"
#include "ms_test_delay.h"
#include "ms_test_net.h"
#include "ms_test_quiet.h"
#include "ms_viewer_annotate.h"
#include "ms_viewer_catalogue.h"
#include "ms_viewer_fetcher.h"

#define MODELS 10
#define DELAY_S 0.2
#define FRAME_LIMIT_MS 50.0
#define SILENT_TIMEOUT_S 2.0

typedef struct fixture {
    char dir[512], archives[600];
    pid_t server;
    uint16_t port;
} fixture;

static fixture fx;

static void nap_ms(long ms)
{
    struct timespec t = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&t, NULL);
}

/* One frame of the catalogue screen without GL: a key (0: none), what came,
 * the panel. Its time in milliseconds into *ms (the slowest kept). */
static ms_catalogue_panel frame(ms_viewer_catalogue *cat, int key, double *slowest_ms)
{
    double t0 = ms_now_seconds();
    if (key)
        (void)ms_viewer_catalogue_key(cat, key, 400, 1);
    (void)ms_viewer_catalogue_poll(cat);
    ms_catalogue_panel p = ms_viewer_catalogue_panel(cat);
    double ms = (ms_now_seconds() - t0) * 1e3;
    if (ms > *slowest_ms)
        *slowest_ms = ms;
    return p;
}

/* Frames (16 ms apart) until the panel is no longer loading, for at most
 * seconds; the panel's last state. */
static ms_catalogue_panel frames_until_whole(ms_viewer_catalogue *cat, double seconds,
                                             double *slowest_ms)
{
    double t0 = ms_now_seconds();
    ms_catalogue_panel p;
    while ((p = frame(cat, 0, slowest_ms)) == MS_PANEL_LOADING && ms_now_seconds() - t0 < seconds)
        nap_ms(16);
    return p;
}

/* Frames until the worker has nothing left to do, for at most seconds. */
static void frames_until_idle(ms_viewer_catalogue *cat, double seconds, double *slowest_ms)
{
    double t0 = ms_now_seconds();
    for (;;) {
        bool busy = cat->fetcher && ms_viewer_fetcher_busy(cat->fetcher);
        (void)frame(cat, 0, slowest_ms); /* takes what a finished request left */
        if (!busy || ms_now_seconds() - t0 > seconds)
            return;
        nap_ms(16);
    }
}

/* A TCP listener on loopback that never accepts: the system completes the
 * handshake, nothing ever answers. */
static int silent_listener(uint16_t *port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, 16) != 0 ||
        getsockname(fd, (struct sockaddr *)&a, &len) != 0) {
        if (fd >= 0)
            close(fd);
        return -1;
    }
    *port = ntohs(a.sin_port);
    return fd;
}

static void test_a_silent_server_never_holds_the_frames(void **state)
{
    (void)state;
    uint16_t port = 0;
    int fd = silent_listener(&port);
    assert_true(fd >= 0);
    ms_viewer_model_entry entries[3] = {{.name = "alpha"}, {.name = "beta"}, {.name = "gamma"}};
    ms_viewer_model_list list = {.entries = entries, .count = 3, .total = 3};
    ms_viewer_source source = {.host = "127.0.0.1", .port = port, .timeout_s = SILENT_TIMEOUT_S};
    ms_viewer_catalogue cat = {.list = &list, .source = &source};
    /* 40 frames, 5 ms apart: all drawn in well under the time-out, all "loading" */
    double slowest_ms = 0, t0 = ms_now_seconds();
    for (int i = 0; i < 40; ++i) {
        assert_int_equal(frame(&cat, 0, &slowest_ms), MS_PANEL_LOADING);
        nap_ms(5);
    }
    double forty_s = ms_now_seconds() - t0;
    printf("silent server: 40 frames in %.0f ms, the slowest %.2f ms\n", forty_s * 1e3,
           slowest_ms);
    assert_true(forty_s < SILENT_TIMEOUT_S / 4);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    /* then, at the time-out, "no picture" and the failure's line */
    assert_int_equal(frames_until_whole(&cat, SILENT_TIMEOUT_S + 2, &slowest_ms),
                     MS_PANEL_NO_PICTURE);
    double whole_s = ms_now_seconds() - t0;
    printf("silent server: \"no picture\" after %.2f s: %s\n", whole_s, cat.failure);
    assert_true(whole_s >= SILENT_TIMEOUT_S - 0.1 && whole_s < SILENT_TIMEOUT_S + 1.5);
    assert_non_null(strstr(cat.failure, "alpha"));
    assert_non_null(strstr(cat.failure, "no answer in time"));
    assert_true(entries[0].documents_fetched);
    assert_null(entries[0].thumbnail_png);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    /* the next model: "loading" again; the screen closed while its fetch is
     * in flight returns at once */
    assert_int_equal(frame(&cat, GLFW_KEY_DOWN, &slowest_ms), MS_PANEL_LOADING);
    /* a search typed: asked for, the list held meanwhile */
    assert_int_equal(frame(&cat, GLFW_KEY_X, &slowest_ms), MS_PANEL_LOADING);
    assert_string_equal(cat.search, "x");
    assert_true(cat.page_pending);
    assert_int_equal(list.count, 3);
    nap_ms(150);
    assert_int_equal(frame(&cat, 0, &slowest_ms), MS_PANEL_LOADING); /* beta asked for */
    nap_ms(50);
    assert_true(ms_viewer_fetcher_busy(cat.fetcher));
    t0 = ms_now_seconds();
    ms_viewer_catalogue_free(&cat);
    double free_ms = (ms_now_seconds() - t0) * 1e3;
    printf("silent server: the screen closed in %.2f ms with a fetch in flight\n", free_ms);
    assert_true(free_ms < 200);
    assert_null(cat.fetcher);
    assert_false(entries[1].documents_fetched);
    assert_false(cat.page_pending);
    assert_string_equal(cat.search, ""); /* the search whose page never came: dropped */
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    close(fd);
}

static void test_a_distant_server_selecting_quickly(void **state)
{
    (void)state;
    ms_test_delay *relay;
    uint16_t relay_port;
    assert_int_equal(ms_test_delay_start(fx.port, DELAY_S, &relay, &relay_port), 0);
    ms_viewer_source source = {.host = "127.0.0.1", .port = relay_port, .timeout_s = 5};
    ms_viewer_model_list list;
    ms_error err;
    assert_int_equal(ms_viewer_list_page(&source, NULL, &list, &err), MS_OK);
    assert_int_equal(list.count, MODELS);
    /* what one selection cost the drawing thread when it fetched the
     * documents itself (a connection per document) */
    ms_viewer_model_entry alone = {.name = "m5"};
    double t_alone = ms_now_seconds();
    assert_int_equal(ms_viewer_model_fetch_documents(&source, &alone, &err), MS_OK);
    t_alone = ms_now_seconds() - t_alone;
    printf("distant server: one selection fetched on the drawing thread held it %.2f s\n",
           t_alone);
    assert_true(t_alone > 4 * DELAY_S);
    ms_metadata_free(alone.metadata);
    free(alone.thumbnail_png);
    unsigned listing = ms_test_delay_connections(relay);
    ms_viewer_catalogue cat = {.list = &list, .source = &source};
    /* Down nine times, a frame (16 ms) each: no frame waits for the network,
     * and no model passed by is asked for (each selected for under
     * MS_CATALOGUE_SETTLE_S) */
    double slowest_ms = 0, t0 = ms_now_seconds();
    assert_int_equal(frame(&cat, 0, &slowest_ms), MS_PANEL_LOADING);
    for (int i = 0; i < MODELS - 1; ++i) {
        nap_ms(16);
        assert_int_equal(frame(&cat, GLFW_KEY_DOWN, &slowest_ms), MS_PANEL_LOADING);
    }
    assert_int_equal(cat.selected, MODELS - 1);
    /* the last one's picture comes */
    assert_int_equal(frames_until_whole(&cat, 10, &slowest_ms), MS_PANEL_PICTURE);
    double picture_s = ms_now_seconds() - t0;
    size_t fetched = 0;
    for (size_t i = 0; i < list.count; ++i)
        fetched += list.entries[i].documents_fetched;
    printf("distant server (%.0f ms each way): the last model's picture after %.2f s, "
           "%zu of %d models fetched, the slowest frame %.2f ms\n",
           DELAY_S * 1e3, picture_s, fetched, MODELS, slowest_ms);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    assert_true(list.entries[MODELS - 1].has_thumbnail);
    assert_non_null(list.entries[MODELS - 1].thumbnail_png);
    assert_non_null(cat.thumbnail);
    assert_int_equal(cat.thumbnail_width, 160);
    assert_int_equal(fetched, 1); /* those passed by: never asked for */
    assert_string_equal(cat.failure, "");
    /* a search typed: the list as it was until its first page comes */
    assert_int_equal(frame(&cat, GLFW_KEY_M, &slowest_ms), MS_PANEL_PICTURE);
    assert_int_equal(frame(&cat, GLFW_KEY_7, &slowest_ms), MS_PANEL_PICTURE);
    assert_string_equal(cat.search, "m7");
    assert_int_equal(list.count, MODELS);
    frames_until_idle(&cat, 10, &slowest_ms);
    assert_string_equal(list.query, "m7");
    assert_int_equal(list.count, 1);
    assert_string_equal(list.entries[0].name, "m7");
    assert_int_equal(cat.selected, 0);
    /* one connection for every fetch of the screen */
    assert_int_equal(ms_viewer_fetcher_connections(cat.fetcher), 1);
    assert_int_equal(ms_test_delay_connections(relay) - listing, 1);
    printf("distant server: a search's page in the background, the slowest frame %.2f ms\n",
           slowest_ms);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    ms_viewer_catalogue_free(&cat);
    ms_viewer_model_list_free(&list);
    ms_test_delay_stop(relay);
}

/* Takes the fetcher's next result, waiting up to 10 s. */
static void next_result(ms_viewer_fetcher *f, ms_viewer_fetched *r)
{
    double t0 = ms_now_seconds();
    while (!ms_viewer_fetcher_take(f, r)) {
        assert_true(ms_now_seconds() - t0 < 10);
        nap_ms(5);
    }
}

static void test_a_refusal_keeps_the_connection(void **state)
{
    (void)state;
    ms_viewer_source source = {.host = "127.0.0.1", .port = fx.port, .timeout_s = 5};
    ms_viewer_fetcher *f;
    ms_error err;
    assert_int_equal(ms_viewer_fetcher_new(&source, &f, &err), MS_OK);
    ms_viewer_fetched r;
    assert_false(ms_viewer_fetcher_take(f, &r));
    ms_viewer_fetcher_want_documents(f, "nosuch");
    next_result(f, &r);
    assert_int_equal(r.kind, MS_FETCHED_DOCUMENTS);
    assert_int_equal(r.status, MS_ERR_IO);
    assert_string_equal(r.entry.name, "nosuch");
    assert_non_null(strstr(r.why, "nosuch"));
    assert_non_null(strstr(r.why, "UNKNOWN_MODEL"));
    ms_viewer_fetched_free(&r);
    ms_viewer_fetcher_want_documents(f, "m3");
    next_result(f, &r);
    assert_int_equal(r.status, MS_OK);
    assert_true(r.entry.documents_fetched);
    assert_true(r.entry.has_thumbnail);
    assert_non_null(r.entry.thumbnail_png);
    ms_viewer_fetched_free(&r);
    /* a page from offset 8: the last two; offset 10: none, nothing more */
    ms_viewer_fetcher_want_page(f, "", 8);
    next_result(f, &r);
    assert_int_equal(r.kind, MS_FETCHED_PAGE);
    assert_int_equal(r.status, MS_OK);
    assert_int_equal(r.offset, 8);
    assert_int_equal(r.page.count, 2);
    assert_int_equal(r.page.total, MODELS);
    assert_string_equal(r.page.entries[0].name, "m8");
    ms_viewer_fetched_free(&r);
    ms_viewer_fetcher_want_page(f, "", MODELS);
    next_result(f, &r);
    assert_int_equal(r.page.count, 0);
    assert_int_equal(r.page.total, MODELS);
    ms_viewer_fetched_free(&r);
    assert_int_equal(ms_viewer_fetcher_connections(f), 1);
    assert_false(ms_viewer_fetcher_busy(f));
    ms_viewer_fetcher_free(f);
    /* a local source is no server's */
    ms_viewer_source local = {.archive_dir = fx.archives};
    assert_int_equal(ms_viewer_fetcher_new(&local, &f, &err), MS_ERR_ARG);
    assert_null(f);
}

/* A server that drops the connection while it is idle: the next request
 * finds it closed and reconnects once, and comes whole. */
static void test_a_dropped_connection_reconnects_once(void **state)
{
    (void)state;
    ms_test_quiet *quiet;
    uint16_t port;
    assert_int_equal(ms_test_quiet_start("solo", true, &quiet, &port), 0);
    ms_viewer_source source = {.host = "127.0.0.1", .port = port, .timeout_s = 5};
    ms_viewer_fetcher *f;
    ms_error err;
    assert_int_equal(ms_viewer_fetcher_new(&source, &f, &err), MS_OK);
    ms_viewer_fetched r;
    for (int k = 0; k < 2; ++k) {
        ms_viewer_fetcher_want_page(f, k ? "so" : "", 0);
        next_result(f, &r);
        assert_int_equal(r.kind, MS_FETCHED_PAGE);
        assert_int_equal(r.status, MS_OK);
        assert_int_equal(r.page.count, 1);
        assert_string_equal(r.page.entries[0].name, "solo");
        ms_viewer_fetched_free(&r);
        nap_ms(300); /* the server hangs up meanwhile */
    }
    assert_int_equal(ms_viewer_fetcher_connections(f), 2);
    assert_int_equal(ms_test_quiet_connections(quiet), 2);
    /* its documents never come: the time-out's line (a 1 s one here) */
    ms_viewer_fetcher_free(f);
    source.timeout_s = 1;
    assert_int_equal(ms_viewer_fetcher_new(&source, &f, &err), MS_OK);
    ms_viewer_fetcher_want_documents(f, "solo");
    next_result(f, &r);
    assert_int_equal(r.status, MS_ERR_IO);
    assert_true(r.entry.documents_fetched);
    assert_null(r.entry.thumbnail_png);
    char want[128];
    snprintf(want, sizeof want, "solo: 127.0.0.1:%u: no answer in time", port);
    assert_string_equal(r.why, want);
    ms_viewer_fetched_free(&r);
    ms_viewer_fetcher_free(f);
    ms_test_quiet_stop(quiet);
}

/* Frames of a model's annotations (ms_viewer_annotate_load, as every frame
 * calls it) until they came, for at most seconds; the slowest kept. */
static void annotation_frames(ms_viewer_annotate *a, const ms_viewer_source *source, const char *model,
                              double seconds, double *slowest_ms)
{
    double t0 = ms_now_seconds();
    for (;;) {
        double f0 = ms_now_seconds();
        ms_viewer_annotate_load(a, source, model, NULL);
        double ms = (ms_now_seconds() - f0) * 1e3;
        if (ms > *slowest_ms)
            *slowest_ms = ms;
        if (!ms_viewer_annotate_pending(a) || ms_now_seconds() - t0 >= seconds)
            return;
        nap_ms(16);
    }
}

/* meshview's annotations from a server: the fetcher brings the document (none
 * stored: no bytes, no failure); the viewer's load asks and returns at once,
 * on a silent server too, and a later frame takes them. */
static void test_annotations_never_hold_the_frames(void **state)
{
    (void)state;
    static const char notes[] =
        "{\"format\": \"meshstream-annotations\", \"version\": 1, \"annotations\": [\n"
        " {\"id\": \"tip\", \"point\": [0, 0, 0], \"title\": \"The tip\"},\n"
        " {\"id\": \"base\", \"point\": [0, -1, 0], \"title\": \"The base\"}]}\n";
    char sidecar[700];
    snprintf(sidecar, sizeof sidecar, "%s/m4.annotations.json", fx.archives);
    ms_test_write_file(sidecar, (const uint8_t *)notes, sizeof notes - 1);
    ms_viewer_source source = {.host = "127.0.0.1", .port = fx.port, .timeout_s = 5};
    ms_viewer_fetcher *f;
    ms_error err;
    assert_int_equal(ms_viewer_fetcher_new(&source, &f, &err), MS_OK);
    ms_viewer_fetched r;
    ms_viewer_fetcher_want_annotations(f, "m3");
    next_result(f, &r);
    assert_int_equal(r.kind, MS_FETCHED_ANNOTATIONS);
    assert_int_equal(r.status, MS_OK);
    assert_string_equal(r.entry.name, "m3");
    assert_null(r.document);
    ms_viewer_fetched_free(&r);
    ms_viewer_fetcher_want_annotations(f, "m4");
    next_result(f, &r);
    assert_int_equal(r.status, MS_OK);
    assert_int_equal(r.document_size, sizeof notes - 1);
    assert_memory_equal(r.document, notes, sizeof notes - 1);
    ms_viewer_fetched_free(&r);
    assert_int_equal(ms_viewer_fetcher_connections(f), 1);
    ms_viewer_fetcher_free(f);

    /* the viewer's side: asked, then taken by a later frame, the one selected */
    ms_viewer_annotate a;
    ms_viewer_annotate_init(&a, NULL, "base");
    double slowest_ms = 0;
    annotation_frames(&a, &source, "m4", 10, &slowest_ms);
    assert_false(ms_viewer_annotate_pending(&a));
    assert_int_equal(ms_annotations_count(a.set), 2);
    assert_string_equal(a.from, "server");
    assert_int_equal(a.selected, 1);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    annotation_frames(&a, &source, "m3", 10, &slowest_ms); /* none stored: the empty set */
    assert_false(ms_viewer_annotate_pending(&a));
    assert_non_null(a.set);
    assert_int_equal(ms_annotations_count(a.set), 0);
    assert_string_equal(a.from, "none");
    assert_string_equal(a.message, "--annotation: no annotation 'base' among 0");
    ms_viewer_annotate_free(&a);

    /* a silent server: 40 frames go on at their pace, still waiting; leaving
     * the model with the fetch in flight returns at once */
    uint16_t port = 0;
    int fd = silent_listener(&port);
    assert_true(fd >= 0);
    ms_viewer_source silent = {.host = "127.0.0.1", .port = port, .timeout_s = SILENT_TIMEOUT_S};
    ms_viewer_annotate_init(&a, NULL, NULL);
    slowest_ms = 0;
    double t0 = ms_now_seconds();
    for (int i = 0; i < 40; ++i) {
        annotation_frames(&a, &silent, "m4", 0, &slowest_ms);
        nap_ms(5);
    }
    double forty_s = ms_now_seconds() - t0;
    printf("annotations from a silent server: 40 frames in %.0f ms, the slowest %.2f ms\n",
           forty_s * 1e3, slowest_ms);
    assert_true(forty_s < SILENT_TIMEOUT_S / 4);
    assert_true(slowest_ms < FRAME_LIMIT_MS);
    assert_true(ms_viewer_annotate_pending(&a));
    assert_null(a.set);
    t0 = ms_now_seconds();
    ms_viewer_annotate_free(&a);
    assert_true((ms_now_seconds() - t0) * 1e3 < 200);
    assert_false(ms_viewer_annotate_pending(&a));
    close(fd);
    unlink(sidecar);
}

static int setup(void **state)
{
    (void)state;
    ms_test_tmpdir(fx.dir, sizeof fx.dir);
    snprintf(fx.archives, sizeof fx.archives, "%s/archive", fx.dir);
    if (mkdir(fx.archives, 0755) != 0)
        return -1;
    for (int i = 0; i < MODELS; ++i) { /* m0 .. m9, small demo sculptures with thumbnails */
        char name[16];
        snprintf(name, sizeof name, "m%d", i);
        if (ms_nsp_test_bake_demo(fx.dir, 2000, fx.archives, name, 1500, false) != 0)
            return -1;
    }
    char port_file[700], log[700];
    snprintf(port_file, sizeof port_file, "%s/meshserve.port", fx.dir);
    snprintf(log, sizeof log, "%s/meshserve.log", fx.dir);
    uint16_t http_port;
    fx.server = ms_test_meshserve_start(fx.archives, NULL, 0, port_file, log, &fx.port, &http_port);
    return fx.server ? 0 : -1;
}

static int teardown(void **state)
{
    (void)state;
    if (fx.server)
        ms_test_stop(fx.server, SIGTERM, 10.0);
    ms_test_rmdir(fx.dir);
    return 0;
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_a_silent_server_never_holds_the_frames),
        cmocka_unit_test(test_a_distant_server_selecting_quickly),
        cmocka_unit_test(test_a_refusal_keeps_the_connection),
        cmocka_unit_test(test_a_dropped_connection_reconnects_once),
        cmocka_unit_test(test_annotations_never_hold_the_frames),
    };
    return cmocka_run_group_tests(tests, setup, teardown);
}
