/* The delaying relay (ms_test_delay.h): one thread polls the listening socket
 * and every connection; what it reads waits in a per-direction queue, stamped
 * with the time it may leave, and is written when that time has come. */
#include "ms_test_delay.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#define MAX_PAIRS 32
#define CHUNK_MAX 65536

typedef struct chunk {
    struct chunk *next;
    double due;   /* when it may be passed on (monotonic seconds) */
    size_t size;  /* 0: the side that sent it closed */
    uint8_t data[];
} chunk;

/* fd[0] the client's, fd[1] the server's; queue[i] holds what side i sent,
 * for side 1 - i. */
typedef struct pair {
    int fd[2];
    bool read_done[2];
    chunk *head[2], *tail[2];
} pair;

struct ms_test_delay {
    int listen_fd;
    uint16_t server_port;
    double delay_s;
    bool mangling;
    uint8_t magic[4];   /* with mangling: the byte after these, from the server, goes up by one */
    pair pairs[MAX_PAIRS];
    size_t pair_count;
    atomic_bool stop;
    atomic_uint connections;
    pthread_t thread;
};

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static int connect_loopback(uint16_t port)
{
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd < 0)
        return -1;
    struct sockaddr_in addr = {.sin_family = AF_INET, .sin_port = htons(port),
                               .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (connect(fd, (struct sockaddr *)&addr, sizeof addr) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

static void pair_close(ms_test_delay *d, size_t k)
{
    pair *p = &d->pairs[k];
    for (int i = 0; i < 2; ++i) {
        close(p->fd[i]);
        while (p->head[i]) {
            chunk *c = p->head[i];
            p->head[i] = c->next;
            free(c);
        }
    }
    d->pairs[k] = d->pairs[--d->pair_count];
}

static void accept_one(ms_test_delay *d)
{
    int client = accept(d->listen_fd, NULL, NULL);
    if (client < 0)
        return;
    int server = d->pair_count < MAX_PAIRS ? connect_loopback(d->server_port) : -1;
    if (server < 0) {
        close(client);
        return;
    }
    d->pairs[d->pair_count++] = (pair){.fd = {client, server}};
    atomic_fetch_add(&d->connections, 1);
}

/* Reads what side i sent into its queue; false when the pair must close now. */
static bool read_side(ms_test_delay *d, pair *p, int i)
{
    chunk *c = malloc(sizeof *c + CHUNK_MAX);
    if (!c)
        return false;
    ssize_t n = recv(p->fd[i], c->data, CHUNK_MAX, 0);
    c->next = NULL;
    c->due = now_s() + d->delay_s;
    c->size = n > 0 ? (size_t)n : 0;
    for (size_t k = 0; d->mangling && i == 1 && k + 4 < c->size; ++k)
        if (memcmp(c->data + k, d->magic, 4) == 0)
            c->data[k + 4]++;
    if (n <= 0)
        p->read_done[i] = true;
    if (p->tail[i])
        p->tail[i]->next = c;
    else
        p->head[i] = c;
    p->tail[i] = c;
    return true;
}

/* Passes on what is due; false when the pair must close. */
static bool deliver(pair *p, double now)
{
    for (int i = 0; i < 2; ++i)
        while (p->head[i] && p->head[i]->due <= now) {
            chunk *c = p->head[i];
            if (c->size == 0 || send(p->fd[1 - i], c->data, c->size, MSG_NOSIGNAL) != (ssize_t)c->size)
                return false;
            p->head[i] = c->next;
            if (!p->head[i])
                p->tail[i] = NULL;
            free(c);
        }
    return true;
}

static void *relay_main(void *arg)
{
    ms_test_delay *d = arg;
    while (!atomic_load(&d->stop)) {
        double now = now_s(), wait = 0.02; /* the stop flag is looked at this often */
        struct pollfd fds[1 + 2 * MAX_PAIRS];
        size_t owner[1 + 2 * MAX_PAIRS];
        nfds_t n = 0;
        fds[n++] = (struct pollfd){.fd = d->listen_fd, .events = POLLIN};
        for (size_t k = 0; k < d->pair_count; ++k)
            for (int i = 0; i < 2; ++i) {
                pair *p = &d->pairs[k];
                if (p->head[i] && p->head[i]->due - now < wait)
                    wait = p->head[i]->due - now;
                if (!p->read_done[i]) {
                    owner[n] = 2 * k + (size_t)i;
                    fds[n++] = (struct pollfd){.fd = p->fd[i], .events = POLLIN};
                }
            }
        int ms = wait > 0 ? (int)(wait * 1000.0) + 1 : 0;
        if (poll(fds, n, ms) < 0)
            continue;
        if (fds[0].revents & POLLIN)
            accept_one(d);
        /* reads before closes, so that the indices in owner stay valid */
        bool failed[MAX_PAIRS] = {false};
        for (nfds_t j = 1; j < n; ++j)
            if (fds[j].revents & (POLLIN | POLLHUP | POLLERR))
                failed[owner[j] / 2] |= !read_side(d, &d->pairs[owner[j] / 2], (int)(owner[j] % 2));
        now = now_s();
        for (size_t k = d->pair_count; k-- > 0;)
            if (failed[k] || !deliver(&d->pairs[k], now))
                pair_close(d, k);
    }
    return NULL;
}

int ms_test_delay_start(uint16_t server_port, double delay_s, ms_test_delay **out, uint16_t *port)
{
    return ms_test_delay_start_mangling(server_port, delay_s, NULL, out, port);
}

int ms_test_delay_start_mangling(uint16_t server_port, double delay_s, const char magic[4], ms_test_delay **out,
                                 uint16_t *port)
{
    *out = NULL;
    ms_test_delay *d = calloc(1, sizeof *d);
    if (!d)
        return -1;
    d->server_port = server_port;
    d->delay_s = delay_s;
    d->mangling = magic != NULL;
    if (magic)
        memcpy(d->magic, magic, 4);
    struct sockaddr_in addr = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof addr;
    d->listen_fd = socket(AF_INET, SOCK_STREAM, 0);
    if (d->listen_fd < 0 || bind(d->listen_fd, (struct sockaddr *)&addr, sizeof addr) != 0 ||
        listen(d->listen_fd, 16) != 0 || getsockname(d->listen_fd, (struct sockaddr *)&addr, &len) != 0 ||
        pthread_create(&d->thread, NULL, relay_main, d) != 0) {
        if (d->listen_fd >= 0)
            close(d->listen_fd);
        free(d);
        return -1;
    }
    *port = ntohs(addr.sin_port);
    *out = d;
    return 0;
}

void ms_test_delay_stop(ms_test_delay *d)
{
    if (!d)
        return;
    atomic_store(&d->stop, true);
    pthread_join(d->thread, NULL);
    while (d->pair_count)
        pair_close(d, d->pair_count - 1);
    close(d->listen_fd);
    free(d);
}

unsigned ms_test_delay_connections(ms_test_delay *d) { return atomic_load(&d->connections); }
