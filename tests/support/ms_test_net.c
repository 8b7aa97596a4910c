#include "ms_test_net.h"

#include "ms_test.h"

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

static double now_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

int ms_test_http_raw(uint16_t port, const char *request, size_t request_length,
                     ms_test_http_response *r)
{
    memset(r, 0, sizeof *r);
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0)
        return -1;
    struct timeval tv = {5, 0};
    setsockopt(fd, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    setsockopt(fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    struct sockaddr_in addr = {0};
    addr.sin_family = AF_INET;
    addr.sin_port = htons(port);
    addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    if (connect(fd, (struct sockaddr *)&addr, sizeof addr) != 0 ||
        send(fd, request, request_length, MSG_NOSIGNAL) != (ssize_t)request_length) {
        close(fd);
        return -1;
    }
    size_t cap = 1 << 16, len = 0;
    uint8_t *buf = malloc(cap + 1);
    for (;;) {
        if (len == cap) {
            cap *= 2;
            buf = realloc(buf, cap + 1);
        }
        ssize_t n = recv(fd, buf + len, cap - len, 0);
        if (n < 0) {
            free(buf);
            close(fd);
            return -1;
        }
        if (n == 0)
            break;
        len += (size_t)n;
    }
    close(fd);
    buf[len] = '\0';
    char *end = strstr((char *)buf, "\r\n\r\n");
    if (!end || sscanf((char *)buf, "HTTP/1.%*d %d", &r->status) != 1) {
        free(buf);
        return -1;
    }
    size_t head = (size_t)(end - (char *)buf) + 4;
    snprintf(r->headers, sizeof r->headers, "%.*s", (int)head, (char *)buf);
    r->body_length = len - head;
    r->body = malloc(r->body_length + 1);
    memcpy(r->body, buf + head, r->body_length);
    r->body[r->body_length] = '\0';
    free(buf);
    return 0;
}

int ms_test_http_get(uint16_t port, const char *path, const char *extra_headers,
                     ms_test_http_response *response)
{
    char request[4096];
    int n = snprintf(request, sizeof request,
                     "GET %s HTTP/1.1\r\nHost: 127.0.0.1\r\n%sConnection: close\r\n\r\n", path,
                     extra_headers ? extra_headers : "");
    return ms_test_http_raw(port, request, (size_t)n, response);
}

int ms_test_metric(uint16_t http_port, const char *series, uint64_t *value)
{
    ms_test_http_response r;
    if (ms_test_http_get(http_port, "/metrics", NULL, &r) != 0)
        return -1;
    size_t n = strlen(series);
    const char *at = NULL;
    for (const char *p = r.status == 200 && r.body ? (const char *)r.body : NULL; p && !at;
         p = strchr(p, '\n'), p = p ? p + 1 : NULL)
        if (strncmp(p, series, n) == 0 && p[n] == ' ')
            at = p + n + 1;
    if (at)
        *value = strtoull(at, NULL, 10);
    ms_test_http_free(&r);
    return at ? 0 : -1;
}

void ms_test_http_free(ms_test_http_response *r)
{
    free(r->body);
    r->body = NULL;
}

const char *ms_test_http_header(const ms_test_http_response *r, const char *name, char *out,
                                size_t size)
{
    size_t name_len = strlen(name);
    for (const char *line = strstr(r->headers, "\r\n"); line && line[2];
         line = strstr(line + 2, "\r\n")) {
        const char *start = line + 2;
        if (!strncasecmp(start, name, name_len) && start[name_len] == ':') {
            const char *v = start + name_len + 1;
            while (*v == ' ')
                ++v;
            size_t vlen = strcspn(v, "\r");
            snprintf(out, size, "%.*s", (int)vlen, v);
            return out;
        }
    }
    return NULL;
}

pid_t ms_test_spawn(char *const argv[], const char *log_path)
{
    pid_t pid = fork();
    if (pid == 0) {
        int fd = open(log_path, O_WRONLY | O_CREAT | O_TRUNC, 0644);
        if (fd >= 0) {
            dup2(fd, 1);
            dup2(fd, 2);
            close(fd);
        }
        execv(argv[0], argv);
        _exit(127);
    }
    return pid;
}

int ms_test_wait_ports(const char *port_file, double seconds, uint16_t *port, uint16_t *http_port)
{
    double deadline = now_seconds() + seconds;
    while (now_seconds() < deadline) {
        FILE *f = fopen(port_file, "r");
        if (f) {
            unsigned a, b;
            int ok = fscanf(f, "%u %u", &a, &b) == 2;
            fclose(f);
            if (ok) {
                *port = (uint16_t)a;
                *http_port = (uint16_t)b;
                return 0;
            }
        }
        usleep(20000);
    }
    return -1;
}

pid_t ms_test_meshserve_start(const char *archives, const char *const *extra,
                              uint16_t listen_port, const char *port_file, const char *log_path, uint16_t *port,
                              uint16_t *http_port)
{
    char bin[512], port_arg[16];
    ms_test_bin_path(bin, sizeof bin, "meshserve");
    snprintf(port_arg, sizeof port_arg, "%u", (unsigned)listen_port);
    char *argv[24];
    int n = 0;
    argv[n++] = bin;
    argv[n++] = (char *)archives;
    for (int k = 0; extra && extra[k] && k < 8; ++k)
        argv[n++] = (char *)extra[k];
    const char *tail[] = {"--bind", "127.0.0.1",   "--port",      port_arg,
                          "--http-port", "0", "--port-file", port_file};
    for (size_t k = 0; k < sizeof tail / sizeof *tail; ++k)
        argv[n++] = (char *)tail[k];
    argv[n] = NULL;
    unlink(port_file);
    pid_t pid = ms_test_spawn(argv, log_path);
    if (ms_test_wait_ports(port_file, 15.0, port, http_port) != 0) {
        fprintf(stderr, "meshserve did not start (see %s)\n", log_path);
        ms_test_stop(pid, SIGKILL, 5.0);
        return 0;
    }
    return pid;
}

int ms_test_stop(pid_t pid, int sig, double seconds)
{
    kill(pid, sig);
    double deadline = now_seconds() + seconds;
    int status;
    while (now_seconds() < deadline) {
        pid_t r = waitpid(pid, &status, WNOHANG);
        if (r == pid)
            return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        usleep(20000);
    }
    kill(pid, SIGKILL);
    waitpid(pid, &status, 0);
    return -1;
}

int ms_test_http_varies_on(const ms_test_http_response *r, const char *field)
{
    char line[128];
    snprintf(line, sizeof line, "\r\nVary: %s\r\n", field);
    return strstr(r->headers, line) != NULL;
}
