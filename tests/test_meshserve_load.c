/* meshserve under load, on loopback: meshloadgen's 50 camera-driven clients
 * get every answer while another client reads at 10 KB/s with megabytes
 * queued (their throughput against theirs alone: scripts/bench-limits); and
 * the load generator itself works against the binary protocol and the HTTP
 * side door. Bounded: a few seconds a run. */
#include <arpa/inet.h>
#include <jansson.h>
#include <netinet/in.h>
#include <stdarg.h>
#include <stddef.h>
#include <setjmp.h>
#include <stdint.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <cmocka.h>

#include "ms_proto.h"
#include "ms_synthetic_archive.h"
#include "ms_test.h"
#include "ms_test_net.h"

#define TOKEN "load-token"
#define SLOW_READER_BYTES_PER_S 10240

typedef struct fixture {
    char dir[512], archives[600], log[600];
    pid_t pid;
    uint16_t port, http_port;
} fixture;

static int start_server(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    ms_test_tmpdir(f->dir, sizeof f->dir);
    snprintf(f->archives, sizeof f->archives, "%s/archive", f->dir);
    assert_int_equal(mkdir(f->archives, 0755), 0);
    ms_synthetic_spec spec = {2, 12, 12288, 8192, 4, 5, 12};
    ms_error err;
    if (ms_synthetic_archive_write(f->archives, "museum", &spec, &err) != MS_OK)
        fail_msg("%s", err.text);
    char config[700], port_file[700], bin[512];
    snprintf(config, sizeof config, "%s/meshserve.conf", f->dir);
    FILE *c = fopen(config, "w");
    fputs("token = " TOKEN "\nrequest_rate = 1000000\nhttp_rate = 1000000\n", c);
    fclose(c);
    snprintf(port_file, sizeof port_file, "%s/ports", f->dir);
    snprintf(f->log, sizeof f->log, "%s/meshserve.log", f->dir);
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    char *argv[] = {bin, f->archives, "--config", config, "--port", "0", "--http-port", "0",
                    "--port-file", port_file, NULL};
    f->pid = ms_test_spawn(argv, f->log);
    if (ms_test_wait_ports(port_file, 10.0, &f->port, &f->http_port) != 0) {
        ms_test_stop(f->pid, SIGKILL, 5.0);
        fail_msg("meshserve did not start (see %s)", f->log);
    }
    *state = f;
    return 0;
}

static int stop_server(void **state)
{
    fixture *f = *state;
    if (f->pid > 0)
        assert_int_equal(ms_test_stop(f->pid, SIGTERM, 15.0), 0); /* clean exit, no leak */
    ms_test_rmdir(f->dir);
    free(f);
    return 0;
}

/* Runs meshloadgen with extra arguments; returns its parsed JSON report. */
static json_t *loadgen(const fixture *f, const char *args)
{
    char bin[512], command[2048], out[8192];
    ms_test_bin_path(bin, sizeof bin, "meshloadgen");
    snprintf(command, sizeof command, "%s --json --port %u --model museum --token " TOKEN " %s",
             bin, f->port, args);
    int status = ms_test_run(command, out, sizeof out);
    json_t *report = json_loads(strchr(out, '{') ? strchr(out, '{') : out, 0, NULL);
    if (status != 0 || !report)
        fail_msg("meshloadgen failed (%d): %s", status, out);
    return report;
}

static double number(const json_t *report, const char *key)
{
    return json_number_value(json_object_get(report, key));
}

/* --- The slow reader (a child process: no cmocka in it) ----------------------- */

static int put_frame(int fd, const ms_proto_message *m)
{
    uint8_t buf[4096];
    size_t n;
    return ms_proto_encode(m, buf, sizeof buf, &n, NULL) == MS_OK &&
                   send(fd, buf, n, MSG_NOSIGNAL) == (ssize_t)n
               ? 0
               : -1;
}

/* Asks for every geometry stream of the model (megabytes), then reads 1 KiB
 * every 100 ms for `seconds`. Exits 0 if the connection stayed up. */
static void slow_reader(uint16_t port, double seconds)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    int small = 4096;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, (struct sockaddr *)&addr, sizeof addr) != 0)
        _exit(2);
    ms_proto_message m = {.type = MS_PROTO_HELLO};
    m.body.hello = (ms_proto_hello){1, 1, MS_PROTO_CAP_APO, 1u << 20, TOKEN, 10, "slow", 4};
    ms_proto_message open = {.type = MS_PROTO_OPEN_MODEL, .request_id = 1};
    open.body.open_model = (ms_proto_open_model){"museum", 6};
    static ms_proto_cell_request all[200];
    for (uint32_t i = 0; i < 200; ++i)
        all[i] = (ms_proto_cell_request){i, 0, MS_PROTO_UNIT_STEPS, 0, 0, 63};
    ms_proto_message batch = {.type = MS_PROTO_REQUEST_CELLS, .request_id = 10};
    batch.body.request_cells = (ms_proto_request_cells){1, all, 200};
    if (put_frame(fd, &m) || put_frame(fd, &open) || put_frame(fd, &batch))
        _exit(3);
    struct timespec step = {0, 100000000};
    char buf[SLOW_READER_BYTES_PER_S / 10];
    for (double t = 0; t < seconds; t += 0.1) {
        if (recv(fd, buf, sizeof buf, MSG_DONTWAIT) == 0)
            _exit(4); /* the server gave up on us */
        nanosleep(&step, NULL);
    }
    close(fd);
    _exit(0);
}

/* --- Tests ------------------------------------------------------------------------ */

/* 50 clients of 40 requests each: the run ends when every answer is in (or
 * after 60 s, a bound and not a measurement). */
static const char *FAIR_RUN = "--clients 50 --window 4 --requests 40 --duration 60 --seed 7";

/* Beside a client that reads at 10 KB/s with megabytes queued for it (its
 * output buffer full: the fair scheduler takes it out of the ring), the 50
 * others get every answer, without an error, and the slow one is not
 * dropped. How their throughput compares with theirs alone is a figure, not
 * a verdict: scripts/bench-limits reports it. */
static void test_slow_reader_does_not_slow_the_others(void **state)
{
    fixture *f = *state;
    pid_t slow = fork();
    if (slow == 0)
        slow_reader(f->port, 6.0);
    usleep(300000); /* its output buffer is full by now */
    json_t *with_slow = loadgen(f, FAIR_RUN);
    int status;
    assert_int_equal(waitpid(slow, &status, 0), slow);
    assert_true(WIFEXITED(status) && WEXITSTATUS(status) == 0);
    print_message("50 clients beside a 10 KB/s reader: %.1f MB/s\n",
                  number(with_slow, "throughput_MBps"));
    assert_int_equal((int)number(with_slow, "requests"), 50 * 40);
    assert_int_equal((int)number(with_slow, "answered"), 50 * 40);
    assert_true(number(with_slow, "errors") == 0);
    assert_true(number(with_slow, "connection_failures") == 0);
    json_decref(with_slow);
}

static void test_loadgen_binary_and_http(void **state)
{
    fixture *f = *state;
    json_t *binary = loadgen(f, "--clients 4 --window 8 --duration 1");
    assert_true(number(binary, "answered") > 100);
    assert_true(number(binary, "payload_bytes") > 100000);
    assert_true(number(binary, "errors") == 0);
    json_decref(binary);
    /* The same sequence over the HTTP side door, with the index from /models/NAME. */
    char index_path[700], args[1200];
    snprintf(index_path, sizeof index_path, "%s/museum.index", f->dir);
    ms_test_http_response r;
    assert_int_equal(ms_test_http_get(f->http_port, "/models/museum", NULL, &r), 0);
    assert_int_equal(r.status, 200);
    FILE *out = fopen(index_path, "wb");
    fwrite(r.body, 1, r.body_length, out);
    fclose(out);
    ms_test_http_free(&r);
    char bin[512], command[2048], text[8192];
    ms_test_bin_path(bin, sizeof bin, "meshloadgen");
    snprintf(args, sizeof args, "--http --index %s --clients 4 --window 1 --duration 1", index_path);
    snprintf(command, sizeof command, "%s --json --port %u --model museum --token " TOKEN " %s",
             bin, f->http_port, args);
    assert_int_equal(ms_test_run(command, text, sizeof text), 0);
    json_t *http = json_loads(strchr(text, '{'), 0, NULL);
    assert_non_null(http);
    assert_true(number(http, "answered") > 10);
    assert_true(number(http, "errors") == 0);
    json_decref(http);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(test_loadgen_binary_and_http, start_server, stop_server),
        cmocka_unit_test_setup_teardown(test_slow_reader_does_not_slow_the_others, start_server,
                                        stop_server),
    };
    return cmocka_run_group_tests_name("meshserve under load", tests, NULL, NULL);
}
