/* A server that lists one model and then never answers (ms_test_quiet.h). */
#include "ms_test_quiet.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "ms_proto.h"

struct ms_test_quiet {
    int fd;
    pthread_t thread;
    atomic_bool stop;
    atomic_uint connections;
    bool hang_up;
    char name[65];
};

static void send_frame(int fd, const ms_proto_message *m)
{
    uint8_t out[4096];
    size_t n = 0;
    if (ms_proto_encode(m, out, sizeof out, &n, NULL) == MS_OK)
        (void)!send(fd, out, n, MSG_NOSIGNAL); /* the client may have hung up */
}

/* Answers m; true when it was a listing. */
static bool answer(ms_test_quiet *q, int conn, const ms_proto_message *m)
{
    if (m->type == MS_PROTO_HELLO) {
        ms_proto_message r = {.type = MS_PROTO_HELLO_REPLY};
        r.body.hello_reply = (ms_proto_hello_reply){
            .version = 3, .capabilities = MS_PROTO_CAP_APO, .max_frame = MS_PROTO_MIN_FRAME,
            .max_batch = 64, .max_outstanding = 1024, .max_queued_bytes = 1u << 26,
            .max_open_models = 4};
        send_frame(conn, &r);
    } else if (m->type == MS_PROTO_LIST_CATALOGUE || m->type == MS_PROTO_LIST_PAGE) {
        static const char title[] = "8 vertices, 12 triangles";
        ms_proto_catalogue_entry e = {.name = q->name, .name_length = (uint8_t)strlen(q->name),
                                      .geometry_steps = 20, .permitted_geometry_steps = 20,
                                      .title = title, .title_length = sizeof title - 1,
                                      .cell_count = 1, .content_id = 1, .archive_bytes = 1000};
        bool page = m->type == MS_PROTO_LIST_PAGE;
        ms_proto_message r = {.type = page ? MS_PROTO_CATALOGUE_PAGE : MS_PROTO_CATALOGUE,
                              .request_id = m->request_id, .flags = MS_PROTO_FLAG_LAST};
        bool first = !page || m->body.list_page.offset == 0;
        r.body.catalogue = (ms_proto_catalogue){first ? &e : NULL, first ? 1 : 0, 1};
        send_frame(conn, &r);
        return true;
    } /* anything else: silence */
    return false;
}

static double now_s(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + t.tv_nsec * 1e-9;
}

static void converse(ms_test_quiet *q, int conn)
{
    ms_proto_decoder *dec = NULL;
    ms_proto_decoder_config dc = {MS_PROTO_ROLE_SERVER, MS_PROTO_MIN_FRAME, 64};
    if (ms_proto_decoder_new(&dc, &dec, NULL) != MS_OK)
        return;
    uint8_t buf[16384];
    double hang_up_at = 0; /* 0: not yet */
    while (!atomic_load(&q->stop) && !(hang_up_at && now_s() > hang_up_at)) {
        struct pollfd p = {conn, POLLIN, 0};
        if (poll(&p, 1, 50) <= 0)
            continue;
        ssize_t got = read(conn, buf, sizeof buf);
        if (got <= 0)
            break;
        for (size_t at = 0; at < (size_t)got;) {
            size_t used;
            ms_proto_message m;
            bool have;
            ms_proto_fault fault;
            if (ms_proto_decoder_feed(dec, buf + at, (size_t)got - at, &used, &m, &have, &fault,
                                      NULL) != MS_OK)
                goto done;
            at += used;
            if (have && answer(q, conn, &m) && q->hang_up && !hang_up_at)
                hang_up_at = now_s() + 0.1;
        }
    }
done:
    ms_proto_decoder_free(dec);
}

static void *serve(void *arg)
{
    ms_test_quiet *q = arg;
    while (!atomic_load(&q->stop)) {
        struct pollfd p = {q->fd, POLLIN, 0};
        if (poll(&p, 1, 50) <= 0)
            continue;
        int conn = accept(q->fd, NULL, NULL);
        if (conn < 0)
            continue;
        atomic_fetch_add(&q->connections, 1);
        converse(q, conn);
        close(conn);
    }
    return NULL;
}

int ms_test_quiet_start(const char *name, bool hang_up, ms_test_quiet **server, uint16_t *port)
{
    *server = NULL;
    ms_test_quiet *q = calloc(1, sizeof *q);
    if (!q)
        return -1;
    q->hang_up = hang_up;
    snprintf(q->name, sizeof q->name, "%s", name);
    q->fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    if (q->fd < 0 || bind(q->fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(q->fd, 16) != 0 ||
        getsockname(q->fd, (struct sockaddr *)&a, &len) != 0 ||
        pthread_create(&q->thread, NULL, serve, q) != 0) {
        if (q->fd >= 0)
            close(q->fd);
        free(q);
        return -1;
    }
    *port = ntohs(a.sin_port);
    *server = q;
    return 0;
}

void ms_test_quiet_stop(ms_test_quiet *q)
{
    if (!q)
        return;
    atomic_store(&q->stop, true);
    pthread_join(q->thread, NULL);
    close(q->fd);
    free(q);
}

unsigned ms_test_quiet_connections(ms_test_quiet *q)
{
    return atomic_load(&q->connections);
}
