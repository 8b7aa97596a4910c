/* meshloadgen: N virtual clients, each following a camera-like sequence of
 * cell requests (client/load/ms_loadgen_plan.h), against meshserve's binary
 * protocol or against any HTTP server holding the same bytes (meshserve's side
 * door, or nginx serving meshexport's tree) with Range requests. Bounded in
 * time and in requests; reports payload throughput, request latency
 * percentiles, errors and, optionally, the server's peak RSS. */
#include <errno.h>
#include <event2/buffer.h>
#include <event2/event.h>
#include <event2/http.h>
#include <getopt.h>
#include <math.h>
#include <netinet/in.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "ms_archive.h"
#include "ms_cli.h"
#include "ms_client.h"
#include "ms_json_out.h"
#include "ms_loadgen_plan.h"
#include "ms_parse_number.h"
#include "ms_payload_assembly.h"
#include "ms_progress.h"
#include "ms_proto.h"
#include "ms_version.h"

#define MAX_WINDOW 64
#define GRACE_SECONDS 3.0

typedef struct options {
    const char *host, *model, *token, *index_path, *label;
    uint16_t port;
    bool http, json;
    unsigned clients, window;
    double duration, fps;  /* fps: camera steps per second per client, 0 = unpaced */
    double rate;           /* requests per second per client, 0 = unpaced */
    uint64_t max_requests; /* per client */
    uint32_t seed;
    long server_pid;
} options;

typedef struct vclient vclient;
typedef struct loadgen loadgen;

typedef struct slot {
    bool used, cancel_sent;
    uint32_t id;
    ms_loadgen_item item;
    uint32_t start, end, received;
    double sent_at;
    vclient *owner;        /* http: the request callback's way back */
    int http_error;        /* http: the evhttp_request_error of a failed request, -1 none */
} slot;

struct vclient {
    loadgen *lg;
    unsigned number;
    ms_loadgen_plan *plan;
    bool planning, done;
    ms_archive *own_index;      /* binary: from MODEL_OPENED */
    ms_client *client;          /* binary */
    ms_payload_assembly *assembly; /* binary: checks every PAYLOAD frame */
    uint32_t handle;
    /* http: libevent's client sends one request at a time per connection and
     * does not pipeline, so slot i has its own keep-alive connection, made on
     * first use: up to --window connections per client. */
    struct evhttp_connection *http_connections[MAX_WINDOW];
    slot slots[MAX_WINDOW];
    unsigned in_flight;
    uint64_t issued;
};

struct loadgen {
    options o;
    struct event_base *base;
    struct event *ticker;
    vclient *clients;
    ms_archive *shared_index;   /* http */
    double started, stop_issuing, finished, first_request;
    bool stopping, streaming;
    unsigned ready;             /* clients holding their model index */
    double *latencies, *apo_latencies;
    size_t latency_count, latency_capacity, apo_latency_count, apo_latency_capacity;
    uint64_t bytes, requests, errors, cancelled, rate_limited, connection_failures;
    char first_error[256];
};

/* --- Statistics --------------------------------------------------------------- */

static void note_error(loadgen *lg, const char *what)
{
    lg->errors++;
    if (!lg->first_error[0])
        snprintf(lg->first_error, sizeof lg->first_error, "%.200s", what);
}

/* Appends to a growable array of latencies (seconds). */
static void append_latency(double **values, size_t *count, size_t *capacity, double seconds)
{
    if (*count == *capacity) {
        size_t grown_capacity = *capacity ? *capacity * 2 : 65536;
        double *grown = realloc(*values, grown_capacity * sizeof *grown);
        if (!grown)
            return;
        *values = grown;
        *capacity = grown_capacity;
    }
    (*values)[(*count)++] = seconds;
}

/* Every answered request, and the APO ones apart (their priority puts them
 * behind the same client's geometry). */
static void record_latency(loadgen *lg, double seconds, uint8_t stream)
{
    append_latency(&lg->latencies, &lg->latency_count, &lg->latency_capacity, seconds);
    if (stream == MS_PROTO_STREAM_APO)
        append_latency(&lg->apo_latencies, &lg->apo_latency_count, &lg->apo_latency_capacity,
                       seconds);
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Of sorted values. */
static double percentile(const double *values, size_t count, double q)
{
    if (!count)
        return 0;
    size_t k = (size_t)ceil(q * (double)count);
    return values[k ? k - 1 : 0];
}

static long status_kb(long pid, const char *key)
{
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%ld/status", pid);
    FILE *f = fopen(path, "r");
    long v = -1;
    while (f && fgets(line, sizeof line, f))
        if (!strncmp(line, key, strlen(key)))
            v = strtol(line + strlen(key), NULL, 10);
    if (f)
        fclose(f);
    return v;
}

/* --- Slots -------------------------------------------------------------------- */

static slot *find_slot(vclient *v, uint32_t id)
{
    for (unsigned i = 0; i < MAX_WINDOW; ++i)
        if (v->slots[i].used && v->slots[i].id == id)
            return &v->slots[i];
    return NULL;
}

static slot *free_slot(vclient *v)
{
    for (unsigned i = 0; i < v->lg->o.window; ++i)
        if (!v->slots[i].used)
            return &v->slots[i];
    return NULL;
}

static void release(vclient *v, slot *s)
{
    s->used = false;
    v->in_flight--;
}

static bool may_issue(const vclient *v)
{
    const loadgen *lg = v->lg;
    if (!(lg->streaming && !lg->stopping && !v->done && v->planning &&
          v->in_flight < lg->o.window && (!lg->o.max_requests || v->issued < lg->o.max_requests)))
        return false;
    /* Paced: a token bucket per client, burst 1, the clients' phases spread
     * over one period (users do not click in step). */
    double phase = (double)v->number / lg->o.clients;
    return lg->o.rate <= 0 ||
           (double)v->issued < (ms_now_seconds() - lg->first_request) * lg->o.rate - phase;
}

static void finish_client(vclient *v)
{
    if (v->done)
        return;
    v->done = true;
}

/* Camera moves a client may make now: unpaced, a few per call (each is a
 * whole view selection); paced, as many as the steps its clock allows. */
static unsigned moves_allowed(const vclient *v)
{
    const loadgen *lg = v->lg;
    if (lg->o.fps <= 0)
        return 4;
    double allowed = (ms_now_seconds() - lg->first_request) * lg->o.fps;
    double taken = (double)ms_loadgen_plan_steps(v->plan);
    if (allowed <= taken)
        return 0;
    double moves = allowed - taken;
    return moves > 4 ? 4 : (unsigned)moves;
}

/* --- Binary transport ----------------------------------------------------------- */

static void binary_fill(vclient *v)
{
    loadgen *lg = v->lg;
    if (!v->client || v->done)
        return;
    /* Cancel what left the view. */
    ms_proto_id_range ranges[MAX_WINDOW];
    uint16_t range_count = 0;
    for (unsigned i = 0; i < MAX_WINDOW; ++i) {
        slot *s = &v->slots[i];
        if (s->used && !s->cancel_sent && !ms_loadgen_plan_wanted(v->plan, s->item.cell)) {
            s->cancel_sent = true;
            ranges[range_count++] = (ms_proto_id_range){s->id, 1};
        }
    }
    ms_error err;
    if (range_count && ms_client_cancel(v->client, ranges, range_count, &err) != MS_OK)
        note_error(lg, err.text);
    ms_proto_cell_request batch[MAX_WINDOW];
    slot *targets[MAX_WINDOW];
    uint16_t count = 0;
    while (may_issue(v) && v->in_flight + count < lg->o.window) {
        ms_loadgen_item item;
        if (!ms_loadgen_plan_next(v->plan, &item, moves_allowed(v)))
            break;
        slot *s = NULL;
        for (unsigned i = 0; i < lg->o.window && !s; ++i)
            if (!v->slots[i].used) {
                bool taken = false;
                for (uint16_t k = 0; k < count; ++k)
                    taken |= targets[k] == &v->slots[i];
                if (!taken)
                    s = &v->slots[i];
            }
        if (!s)
            break;
        memset(s, 0, sizeof *s);
        s->item = item;
        targets[count] = s;
        batch[count++] = (ms_proto_cell_request){item.cell, item.stream, MS_PROTO_UNIT_STEPS,
                                                 item.priority, item.first, item.last};
        v->issued++;
    }
    if (!count)
        return;
    uint32_t first;
    if (ms_client_request_cells(v->client, v->handle, batch, count, &first, &err) != MS_OK) {
        note_error(lg, err.text);
        finish_client(v);
        return;
    }
    double now = ms_now_seconds();
    for (uint16_t k = 0; k < count; ++k) {
        targets[k]->used = true;
        targets[k]->id = first + k;
        targets[k]->sent_at = now;
        v->in_flight++;
        if (ms_payload_assembly_expect(v->assembly, first + k, batch[k].cell_id, batch[k].stream,
                                       &err) != MS_OK)
            note_error(lg, err.text);
    }
    lg->requests += count;
}

static void on_model_opened(ms_client *client, uint32_t request_id, const ms_proto_model_opened *o,
                            const uint8_t *index, void *arg)
{
    (void)client, (void)request_id;
    vclient *v = arg;
    ms_error err;
    if (ms_archive_open_index(index, o->index_size, v->lg->o.model, &v->own_index, &err) != MS_OK ||
        ms_loadgen_plan_new(v->own_index, v->lg->o.seed + v->number, o->permitted_geometry_steps,
                            o->apo_steps > 0, &v->plan, &err) != MS_OK) {
        note_error(v->lg, err.text);
        finish_client(v);
        return;
    }
    v->handle = o->model_handle;
    v->planning = true;
    v->lg->ready++;
}

static void on_payload(ms_client *client, uint32_t id, const ms_proto_payload *p, bool last,
                       void *arg)
{
    (void)client;
    vclient *v = arg;
    slot *s = find_slot(v, id);
    if (!s) {
        note_error(v->lg, "payload for an unknown request");
        return;
    }
    bool done;
    ms_assembled_range range;
    ms_error err;
    if (ms_payload_assembly_add(v->assembly, id, p, last, &done, &range, &err) != MS_OK) {
        note_error(v->lg, err.text);
        finish_client(v);
        return;
    }
    s->received += p->data_length;
    v->lg->bytes += p->data_length;
    if (!done)
        return;
    record_latency(v->lg, ms_now_seconds() - s->sent_at, s->item.stream);
    release(v, s);
    binary_fill(v);
}

static void on_request_error(ms_client *client, uint32_t first, uint32_t count,
                             const ms_proto_error_body *e, void *arg)
{
    (void)client;
    vclient *v = arg;
    for (uint32_t k = 0; k < count; ++k) {
        slot *s = find_slot(v, first + k);
        if (!s)
            continue;
        if (e->code == MS_PROTO_E_CANCELLED) {
            v->lg->cancelled++;
        } else if (e->code == MS_PROTO_E_RATE_LIMITED) {
            v->lg->rate_limited++;
        } else {
            char what[128];
            snprintf(what, sizeof what, "request error %s", ms_proto_error_name(e->code));
            note_error(v->lg, what);
        }
        ms_loadgen_plan_forget(v->plan, &s->item);
        ms_payload_assembly_forget(v->assembly, s->id);
        release(v, s);
    }
    if (!count) {
        char what[128];
        snprintf(what, sizeof what, "connection error %s", ms_proto_error_name(e->code));
        note_error(v->lg, what);
    }
    binary_fill(v);
}

static void on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    vclient *v = arg;
    if (!v->done && !v->lg->stopping) {
        v->lg->connection_failures++;
        note_error(v->lg, why);
    }
    v->in_flight = 0;
    finish_client(v);
}

static const ms_client_handlers binary_handlers = {
    .model_opened = on_model_opened,
    .payload = on_payload,
    .request_error = on_request_error,
    .closed = on_closed,
};

static int binary_start(vclient *v)
{
    const options *o = &v->lg->o;
    ms_client_options co = {.host = o->host, .port = o->port, .token = o->token,
                            .agent = "meshloadgen/0.1"};
    ms_error err;
    uint32_t id;
    if (ms_payload_assembly_new(false, 0, &v->assembly, &err) != MS_OK ||
        ms_client_connect(v->lg->base, &co, &binary_handlers, v, &v->client, &err) != MS_OK ||
        ms_client_open_model(v->client, o->model, &id, &err) != MS_OK) {
        fprintf(stderr, "meshloadgen: %s\n", err.text);
        return -1;
    }
    return 0;
}

/* --- HTTP transport --------------------------------------------------------------- */

static void http_fail(vclient *v, const char *why)
{
    if (!v->lg->stopping || v->in_flight) {
        v->lg->connection_failures++;
        note_error(v->lg, why);
    }
    v->in_flight = 0;
    finish_client(v);
}

/* Why evhttp gave up on a request, in the words of a failed exchange. */
static const char *http_failure_text(int error)
{
    switch (error) {
    case EVREQ_HTTP_EOF: return "HTTP server closed the connection";
    case EVREQ_HTTP_INVALID_HEADER: return "bad HTTP response header";
    case EVREQ_HTTP_DATA_TOO_LONG: return "HTTP response too long";
    case EVREQ_HTTP_TIMEOUT: return "HTTP request timed out";
    default: return "HTTP socket error";
    }
}

static void http_fill(vclient *v);

static void http_error(enum evhttp_request_error error, void *arg)
{
    slot *s = arg;
    s->http_error = (int)error;
}

/* The answer to slot's request, or its failure (req NULL, or no status). */
static void http_done(struct evhttp_request *req, void *arg)
{
    slot *s = arg;
    vclient *v = s->owner;
    if (v->done || !s->used)
        return;
    int status = req ? evhttp_request_get_response_code(req) : 0;
    if (status <= 0) {
        http_fail(v, http_failure_text(s->http_error));
        return;
    }
    /* Copied out, as a client keeping the bytes would (the binary client's
     * decoder copies each frame too): both transports do the same work. */
    struct evbuffer *in = evhttp_request_get_input_buffer(req);
    uint8_t sink[65536];
    while (evbuffer_remove(in, sink, sizeof sink) > 0) {
    }
    if (status == 206 || status == 200) {
        v->lg->bytes += s->end - s->start;
        record_latency(v->lg, ms_now_seconds() - s->sent_at, s->item.stream);
    } else {
        char what[64];
        snprintf(what, sizeof what, "HTTP status %d", status);
        note_error(v->lg, what);
    }
    release(v, s);
    http_fill(v);
}

/* Sends slot's Range GET on the slot's own connection; false when libevent
 * cannot (out of memory: the request is not in flight). */
static bool http_send(vclient *v, slot *s)
{
    const options *o = &v->lg->o;
    struct evhttp_connection **conn = &v->http_connections[s - v->slots];
    if (!*conn && !(*conn = evhttp_connection_base_new(v->lg->base, NULL, o->host, o->port)))
        return false;
    /* the body is bounded by the range asked for: a server announcing more
     * fails the request (EVREQ_HTTP_DATA_TOO_LONG) before it is read */
    evhttp_connection_set_max_body_size(*conn, (ev_ssize_t)(s->end - s->start));
    struct evhttp_request *req = evhttp_request_new(http_done, s);
    if (!req)
        return false;
    evhttp_request_set_error_cb(req, http_error);
    struct evkeyvalq *headers = evhttp_request_get_output_headers(req);
    char path[256], range[64], auth[600];
    snprintf(path, sizeof path, "/models/%s/cells/%u/%s", o->model, s->item.cell,
             s->item.stream == MS_PROTO_STREAM_GEOMETRY ? "geometry" : "apo");
    snprintf(range, sizeof range, "bytes=%u-%u", s->start, s->end - 1);
    evhttp_add_header(headers, "Host", o->host);
    evhttp_add_header(headers, "Range", range);
    if (o->token) {
        snprintf(auth, sizeof auth, "Bearer %.500s", o->token);
        evhttp_add_header(headers, "Authorization", auth);
    }
    /* On failure libevent has freed the request. */
    return evhttp_make_request(*conn, req, EVHTTP_REQ_GET, path) == 0;
}

static void http_fill(vclient *v)
{
    loadgen *lg = v->lg;
    if (v->done)
        return;
    while (may_issue(v)) {
        ms_loadgen_item item;
        if (!ms_loadgen_plan_next(v->plan, &item, moves_allowed(v)))
            break;
        uint32_t start, end;
        ms_loadgen_item_range(lg->shared_index, &item, &start, &end);
        if (start == end)
            continue; /* nothing to fetch: no request over HTTP */
        slot *s = free_slot(v);
        if (!s)
            break;
        memset(s, 0, sizeof *s);
        s->owner = v;
        s->http_error = -1;
        s->item = item;
        s->start = start, s->end = end;
        s->sent_at = ms_now_seconds();
        if (!http_send(v, s)) {
            http_fail(v, "cannot send an HTTP request");
            return;
        }
        s->used = true;
        v->in_flight++;
        v->issued++;
        lg->requests++;
    }
}

static int http_start(vclient *v)
{
    loadgen *lg = v->lg;
    struct in_addr probe;
    if (evutil_inet_pton(AF_INET, lg->o.host, &probe) != 1) {
        fprintf(stderr, "meshloadgen: '%s' is not a numeric IPv4 address\n", lg->o.host);
        return -1;
    }
    ms_error err;
    if (ms_loadgen_plan_new(lg->shared_index, lg->o.seed + v->number, 64, true, &v->plan, &err) !=
        MS_OK) {
        fprintf(stderr, "meshloadgen: %s\n", err.text);
        return -1;
    }
    v->planning = true;
    lg->ready++;
    http_fill(v);
    return 0;
}

/* --- Run ------------------------------------------------------------------------- */

static void tick(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    loadgen *lg = arg;
    double now = ms_now_seconds();
    /* Every client streams from the same moment, once all hold the model index
     * (or after a 10 s start-up limit). */
    if (!lg->streaming) {
        unsigned finished = 0;
        for (unsigned i = 0; i < lg->o.clients; ++i)
            finished += lg->clients[i].done && !lg->clients[i].planning;
        if (lg->ready + finished < lg->o.clients && now - lg->started < 10.0)
            return;
        lg->streaming = true;
        lg->first_request = now;
        lg->stop_issuing = now + lg->o.duration;
    }
    if (!lg->stopping && now >= lg->stop_issuing)
        lg->stopping = true;
    bool busy = false;
    for (unsigned i = 0; i < lg->o.clients; ++i) {
        vclient *v = &lg->clients[i];
        if (may_issue(v)) /* its view was complete, or its pace allows more */
            lg->o.http ? http_fill(v) : binary_fill(v);
        if (!v->done && v->in_flight)
            busy = true;
        else if (!v->done && !lg->stopping && !v->planning)
            busy = true; /* still connecting */
        else if (!v->done && !lg->stopping && lg->o.max_requests && v->issued < lg->o.max_requests)
            busy = true;
        else if (!v->done && !lg->stopping && !lg->o.max_requests)
            busy = true;
    }
    if (!busy || now >= lg->stop_issuing + GRACE_SECONDS) {
        lg->finished = now;
        event_base_loopexit(lg->base, NULL);
    }
}

static void usage(FILE *out)
{
    fprintf(out,
            "Usage: meshloadgen --port PORT --model NAME [options]\n"
            "Runs N virtual clients, each streaming a camera-like sequence of cell requests\n"
            "(an orbit that zooms in and out; cells selected by frustum and screen error,\n"
            "coarse steps first, APO chunks, cancels for cells that leave the view), and\n"
            "reports payload throughput and request latency.\n\n"
            "  --host ADDRESS       numeric server address (default 127.0.0.1)\n"
            "  --port PORT          server port (binary protocol, or HTTP with --http)\n"
            "  --model NAME         model to stream\n"
            "  --http               speak HTTP/1.1 with Range requests (meshserve's side door,\n"
            "                       or a static server holding meshexport's tree); needs --index\n"
            "  --index FILE         the model's index blob (meshexport's models/NAME.index)\n"
            "  --clients N          virtual clients (default 16), one connection each (with\n"
            "                       --http, one per request in flight)\n"
            "  --window N           requests in flight per client, 1..64 (default 4); with\n"
            "                       --http each on its own keep-alive connection\n"
            "  --duration S         stream for S seconds (default 5) from the moment every\n"
            "                       client holds the model index, then wait up to 3 s for\n"
            "                       answers\n"
            "  --requests N         at most N requests per client (default: no limit)\n"
            "  --fps F              move each camera at most F steps per second, like a\n"
            "                       browsing user (default 0: as fast as answers come, to\n"
            "                       saturate the server)\n"
            "  --rate R             at most R requests per second per client (default 0: no\n"
            "                       limit); paced runs measure latency under a given load\n"
            "  --token TOKEN        access token (full precision)\n"
            "  --seed S             camera phases (default 1)\n"
            "  --server-pid PID     report the server's peak RSS (VmHWM) from /proc\n"
            "  --label TEXT         copied into the JSON output\n"
            "  --json               print one JSON object\n"
            "  -h, --help           show this help\n"
            "      --version        show the version\n"
            "Exit status 0 when every request was answered without error, 1 otherwise.\n");
}

static int parse_options(int argc, char **argv, options *o)
{
    static const struct option opts[] = {
        {"host", required_argument, NULL, 'H'},     {"port", required_argument, NULL, 'p'},
        {"model", required_argument, NULL, 'm'},    {"http", no_argument, NULL, 'w'},
        {"index", required_argument, NULL, 'i'},    {"clients", required_argument, NULL, 'c'},
        {"window", required_argument, NULL, 'W'},   {"duration", required_argument, NULL, 'd'},
        {"requests", required_argument, NULL, 'r'}, {"token", required_argument, NULL, 't'},
        {"seed", required_argument, NULL, 's'},     {"server-pid", required_argument, NULL, 'P'},
        {"label", required_argument, NULL, 'l'},    {"json", no_argument, NULL, 'j'},
        {"fps", required_argument, NULL, 'f'},      {"rate", required_argument, NULL, 'R'},
        {"help", no_argument, NULL, 'h'},           {NULL, 0, NULL, 0},
    };
    *o = (options){.host = "127.0.0.1", .clients = 16, .window = 4, .duration = 5, .seed = 1,
                   .server_pid = -1, .label = ""};
    int c;
    double v = 0;
    int64_t i = 0;
    ms_error e;
    while ((c = ms_cli_next("meshloadgen", argc, argv, "h", opts)) != -1) {
        ms_status bad = MS_OK;
        switch (c) {
        case 'H': o->host = optarg; break;
        case 'p': bad = ms_option_int("--port", optarg, 1, 65535, &i, &e); o->port = (uint16_t)i; break;
        case 'm': o->model = optarg; break;
        case 'w': o->http = true; break;
        case 'i': o->index_path = optarg; break;
        case 'c':
            bad = ms_option_int("--clients", optarg, 1, 10000, &i, &e);
            o->clients = (unsigned)i;
            break;
        case 'W':
            bad = ms_option_int("--window", optarg, 1, MAX_WINDOW, &i, &e);
            o->window = (unsigned)i;
            break;
        case 'd': bad = ms_option_double("--duration", optarg, 0.1, 3600, &v, &e); o->duration = v; break;
        case 'r':
            bad = ms_option_int("--requests", optarg, 1, 1000000000000, &i, &e);
            o->max_requests = (uint64_t)i;
            break;
        case 't': o->token = optarg; break;
        case 's': bad = ms_option_int("--seed", optarg, 0, UINT32_MAX, &i, &e); o->seed = (uint32_t)i; break;
        case 'P':
            bad = ms_option_int("--server-pid", optarg, 1, 4194304, &i, &e);
            o->server_pid = (long)i;
            break;
        case 'l': o->label = optarg; break;
        case 'f': bad = ms_option_double("--fps", optarg, 0, 1000, &v, &e); o->fps = v; break;
        case 'R': bad = ms_option_double("--rate", optarg, 0, 1e6, &v, &e); o->rate = v; break;
        case 'j': o->json = true; break;
        case 'h': usage(stdout); exit(0);
        default: return -1; /* reported by ms_cli_next */
        }
        if (bad != MS_OK) {
            ms_cli_usage_error("meshloadgen", e.text, NULL);
            return -1;
        }
    }
    if (optind != argc || !o->port || !o->model || (o->http && !o->index_path)) {
        ms_cli_usage_error("meshloadgen", "needs --port and --model (and --index with --http)", NULL);
        return -1;
    }
    return 0;
}

static ms_archive *load_index(const char *path, const char *name)
{
    ms_archive *a = NULL;
    ms_error err;
    if (ms_archive_open_index_file(path, name, &a, &err) != MS_OK)
        fprintf(stderr, "meshloadgen: %s\n", err.text);
    return a;
}

int main(int argc, char **argv)
{
    if (ms_version_asked(argc, argv))
        return ms_version_print("meshloadgen");
    loadgen lg;
    memset(&lg, 0, sizeof lg);
    if (parse_options(argc, argv, &lg.o) != 0)
        return MS_CLI_USAGE; /* said in one line */
    struct rlimit rl;
    /* A socket per connection (with --http, one per request in flight). */
    rlim_t files = (rlim_t)lg.o.clients * (lg.o.http ? lg.o.window + 1 : 2) + 64;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0 && rl.rlim_cur < files) {
        rl.rlim_cur = files;
        if (rl.rlim_cur > rl.rlim_max)
            rl.rlim_cur = rl.rlim_max;
        setrlimit(RLIMIT_NOFILE, &rl);
    }
    if (lg.o.http && !(lg.shared_index = load_index(lg.o.index_path, lg.o.model)))
        return 1;
    /* epoll's change list folds the add/delete of a socket's write interest
     * within one loop turn into one system call (at most), which matters with
     * many connections that each fill and drain every turn. */
    struct event_config *event_settings = event_config_new();
    if (event_settings)
        event_config_set_flag(event_settings, EVENT_BASE_FLAG_EPOLL_USE_CHANGELIST);
    lg.base = event_settings ? event_base_new_with_config(event_settings) : NULL;
    if (event_settings)
        event_config_free(event_settings);
    lg.clients = calloc(lg.o.clients, sizeof *lg.clients);
    if (!lg.base || !lg.clients) {
        fprintf(stderr, "meshloadgen: out of memory\n");
        return 1;
    }
    lg.started = ms_now_seconds();
    lg.stop_issuing = lg.started + 3600;
    int status = 0;
    for (unsigned i = 0; i < lg.o.clients && !status; ++i) {
        vclient *v = &lg.clients[i];
        v->lg = &lg;
        v->number = i;
        status = lg.o.http ? http_start(v) : binary_start(v);
    }
    struct timeval every = {0, lg.o.rate > 0 ? 5000 : 20000};
    lg.ticker = event_new(lg.base, -1, EV_PERSIST, tick, &lg);
    if (status || !lg.ticker || event_add(lg.ticker, &every) != 0) {
        fprintf(stderr, "meshloadgen: cannot start the clients\n");
        return 1;
    }
    event_base_dispatch(lg.base);
    /* Throughput over the streaming phase: from the moment every client held
     * the model index to the end. */
    double elapsed = lg.finished - (lg.first_request ? lg.first_request : lg.started);

    if (lg.latency_count)
        qsort(lg.latencies, lg.latency_count, sizeof *lg.latencies, compare_double);
    if (lg.apo_latency_count)
        qsort(lg.apo_latencies, lg.apo_latency_count, sizeof *lg.apo_latencies, compare_double);
    double p50 = percentile(lg.latencies, lg.latency_count, 0.5),
           p99 = percentile(lg.latencies, lg.latency_count, 0.99),
           max = percentile(lg.latencies, lg.latency_count, 1.0),
           apo_p99 = percentile(lg.apo_latencies, lg.apo_latency_count, 0.99);
    long hwm = lg.o.server_pid > 0 ? status_kb(lg.o.server_pid, "VmHWM:") : -1;
    long rss = lg.o.server_pid > 0 ? status_kb(lg.o.server_pid, "VmRSS:") : -1;
    long anon = lg.o.server_pid > 0 ? status_kb(lg.o.server_pid, "RssAnon:") : -1;
    uint64_t answered = lg.latency_count;
    double mbps = elapsed > 0 ? lg.bytes / elapsed / 1e6 : 0;
    if (lg.o.json)
        ms_json_print(
            stdout,
            json_pack("{s:o, s:s, s:i, s:i, s:f, s:f, s:o, s:I, s:I, s:I, s:I, s:I, s:I, s:I, s:o, "
                      "s:{s:o, s:o, s:o, s:o}, s:I, s:I, s:I, s:o}",
                      "label", ms_json_text(lg.o.label), "transport", lg.o.http ? "http" : "binary", "clients",
                      (int)lg.o.clients, "window", (int)lg.o.window, "fps", lg.o.fps, "rate", lg.o.rate,
                      "seconds", ms_json_fixed(elapsed, 3), "requests", (json_int_t)lg.requests, "answered", (json_int_t)answered,
                      "cancelled", (json_int_t)lg.cancelled, "rate_limited", (json_int_t)lg.rate_limited,
                      "errors", (json_int_t)lg.errors, "connection_failures", (json_int_t)lg.connection_failures,
                      "payload_bytes", (json_int_t)lg.bytes, "throughput_MBps", ms_json_fixed(mbps, 1), "latency_ms", "p50",
                      ms_json_fixed(p50 * 1e3, 3), "p99", ms_json_fixed(p99 * 1e3, 3), "max",
                      ms_json_fixed(max * 1e3, 3), "apo_p99", ms_json_fixed(apo_p99 * 1e3, 3),
                      "server_vmhwm_kb", (json_int_t)hwm, "server_vmrss_kb", (json_int_t)rss,
                      "server_rssanon_kb", (json_int_t)anon, "first_error", ms_json_text(lg.first_error)),
            MS_JSON_SPACED);
    else
        printf("meshloadgen: %u %s clients, %.2f s: %llu requests (%llu answered, %llu cancelled, "
               "%llu errors), %.1f MB/s payload, latency p50 %.2f ms p99 %.2f ms%s%s\n",
               lg.o.clients, lg.o.http ? "HTTP" : "binary", elapsed,
               (unsigned long long)lg.requests, (unsigned long long)answered,
               (unsigned long long)lg.cancelled, (unsigned long long)lg.errors, mbps,
               p50 * 1e3, p99 * 1e3, lg.first_error[0] ? "; first error: " : "", lg.first_error);
    for (unsigned i = 0; i < lg.o.clients; ++i) {
        vclient *v = &lg.clients[i];
        ms_client_free(v->client);
        ms_payload_assembly_free(v->assembly);
        for (unsigned k = 0; k < MAX_WINDOW; ++k)
            if (v->http_connections[k])
                evhttp_connection_free(v->http_connections[k]); /* and a request pending */
        ms_loadgen_plan_free(v->plan);
        ms_archive_close(v->own_index);
    }
    free(lg.clients);
    free(lg.latencies);
    free(lg.apo_latencies);
    event_free(lg.ticker);
    event_base_free(lg.base);
    ms_archive_close(lg.shared_index);
    return lg.errors || lg.connection_failures ? 1 : 0;
}
