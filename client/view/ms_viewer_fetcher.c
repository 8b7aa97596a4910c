/* The catalogue screen's worker (ms_viewer_fetcher.h): a thread that takes
 * the newest request, runs it on its own event loop over one reused client
 * connection, and queues the result for the drawing thread. */
#include "ms_viewer_fetcher.h"

#include <event2/event.h>
#include <fcntl.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_client.h"

typedef struct node {
    ms_viewer_fetched r;
    struct node *next;
} node;

struct ms_viewer_fetcher {
    /* the source, copied */
    char host[64], *token;
    uint16_t port;
    double timeout_s;
    pthread_t thread;
    int wake[2];                 /* written once by _free: the worker's loop stops */
    pthread_mutex_t lock;
    pthread_cond_t cond;
    /* under lock */
    bool stop;
    bool doc_wanted, doc_busy;
    bool doc_notes, doc_busy_notes; /* the annotations, not metadata + thumbnail */
    char doc_name[MS_MODEL_NAME_MAX + 1], doc_busy_name[MS_MODEL_NAME_MAX + 1];
    bool page_wanted, page_busy;
    char page_query[65], page_busy_query[65];
    size_t page_offset, page_busy_offset;
    node *head, *tail;
    unsigned connections;
    /* the worker's own */
    struct event_base *base;
    struct event *wake_event, *timer;
    ms_client *client;
    uint16_t version;            /* the server's, once ready */
    bool ready, over, timed_out, interrupted;
    uint32_t request;            /* the request waited for */
    bool done, refused;
    char why[MS_ERROR_TEXT_MAX];
    uint8_t *bytes;              /* a document */
    size_t length;
    ms_client_catalogue cat;     /* a page */
    size_t cap;
};

/* --- the connection's handlers ------------------------------------------- */

static void on_ready(ms_client *c, const ms_proto_hello_reply *reply, void *arg)
{
    (void)c;
    ms_viewer_fetcher *f = arg;
    f->ready = true;
    f->version = reply->version;
}

static void on_document(ms_client *c, uint32_t id, uint8_t kind, const uint8_t *bytes,
                        size_t length, void *arg)
{
    (void)c, (void)kind;
    ms_viewer_fetcher *f = arg;
    if (id != f->request || f->done)
        return;
    f->done = true;
    f->bytes = malloc(length ? length : 1);
    if (!f->bytes) {
        f->refused = true;
        snprintf(f->why, sizeof f->why, "out of memory for a document");
        return;
    }
    memcpy(f->bytes, bytes, length);
    f->length = length;
}

static void on_catalogue(ms_client *c, uint32_t id, const ms_proto_catalogue *cat, bool last,
                         void *arg)
{
    (void)c;
    ms_viewer_fetcher *f = arg;
    if (id != f->request || f->done)
        return;
    ms_client_catalogue *out = &f->cat;
    if (out->count + cat->entry_count > f->cap) {
        size_t cap = f->cap ? f->cap : 64;
        while (cap < out->count + cat->entry_count)
            cap *= 2;
        ms_client_catalogue_entry *grown = realloc(out->entries, cap * sizeof *grown);
        if (!grown) {
            f->done = f->refused = true;
            snprintf(f->why, sizeof f->why, "out of memory for the catalogue");
            return;
        }
        out->entries = grown;
        f->cap = cap;
    }
    for (uint16_t i = 0; i < cat->entry_count; ++i) {
        const ms_proto_catalogue_entry *e = &cat->entries[i];
        ms_client_catalogue_entry *d = &out->entries[out->count++];
        memset(d, 0, sizeof *d);
        memcpy(d->name, e->name, e->name_length); /* bounded by the decoder */
        memcpy(d->title, e->title, e->title_length);
        d->apo_steps = e->apo_steps;
        d->archive_bytes = e->archive_bytes;
    }
    out->total = cat->total;
    f->done = last;
}

static void on_error(ms_client *c, uint32_t first, uint32_t count, const ms_proto_error_body *e,
                     void *arg)
{
    (void)c;
    ms_viewer_fetcher *f = arg;
    if (f->done || (count && (f->request < first || f->request - first >= count)))
        return;
    f->done = f->refused = true;
    snprintf(f->why, sizeof f->why, "%s %.*s", ms_proto_error_name(e->code),
             (int)(e->text_length > 150 ? 150 : e->text_length), e->text);
}

static void on_closed(ms_client *c, const char *why, void *arg)
{
    (void)c;
    ms_viewer_fetcher *f = arg;
    f->over = true;
    if (!f->done)
        snprintf(f->why, sizeof f->why, "%s", why);
}

static void on_timeout(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ((ms_viewer_fetcher *)arg)->timed_out = true;
}

static void on_wake(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    ms_viewer_fetcher *f = arg;
    f->interrupted = true; /* the pipe is not drained: every later turn ends at once */
    event_base_loopbreak(f->base);
}

/* --- requests ------------------------------------------------------------ */

static void drop_connection(ms_viewer_fetcher *f)
{
    ms_client_free(f->client);
    f->client = NULL;
    f->ready = f->over = false;
    f->version = 0;
}

/* Runs the loop until *flag, the connection's end, the time-out or _free. */
static bool run_until(ms_viewer_fetcher *f, const bool *flag)
{
    while (!*flag && !f->over && !f->timed_out && !f->interrupted)
        if (event_base_loop(f->base, EVLOOP_ONCE) < 0)
            break;
    return *flag;
}

/* A connection that finished its handshake; *fresh when made here. */
static ms_status connect_ready(ms_viewer_fetcher *f, bool *fresh, ms_error *err)
{
    *fresh = false;
    if (f->client && !f->over)
        return MS_OK;
    drop_connection(f);
    static const ms_client_handlers handlers = {.ready = on_ready, .document = on_document,
                                                .catalogue = on_catalogue,
                                                .request_error = on_error, .closed = on_closed};
    ms_client_options co = {.host = f->host, .port = f->port, .token = f->token,
                            .agent = "meshview/0.1"};
    ms_status st = ms_client_connect(f->base, &co, &handlers, f, &f->client, err);
    if (st != MS_OK)
        return st;
    *fresh = true;
    pthread_mutex_lock(&f->lock);
    f->connections++;
    pthread_mutex_unlock(&f->lock);
    if (run_until(f, &f->ready))
        return MS_OK;
    return ms_error_set(err, MS_ERR_IO, "%s:%u: %s", f->host, f->port,
                        f->interrupted ? "interrupted"
                        : f->timed_out ? "no answer in time"
                                       : f->why);
}

typedef struct job {
    bool page;
    const char *model;
    int kind;                         /* a document's */
    const ms_client_page_request *at; /* a page's */
} job;

/* One request on the connection, reconnecting once when a reused
 * connection turns out closed. The answer in f->bytes or f->cat. */
static ms_status run_job(ms_viewer_fetcher *f, const job *j, ms_error *err)
{
    for (int attempt = 0;; ++attempt) {
        bool fresh;
        ms_status st = connect_ready(f, &fresh, err);
        if (st == MS_OK) {
            f->done = f->refused = false;
            f->why[0] = 0;
            st = j->page ? ms_client_list_catalogue(f->client, j->at, &f->request, err)
                         : ms_client_request_document(f->client, j->model, j->kind, &f->request,
                                                      err);
            if (st == MS_OK && run_until(f, &f->done) && !f->refused)
                return MS_OK;
            if (st == MS_OK)
                st = ms_error_set(err, MS_ERR_IO, "%s:%u: %s", f->host, f->port,
                                  f->interrupted ? "interrupted"
                                  : f->timed_out ? "no answer in time"
                                                 : f->why);
        }
        if (f->done && !f->over)
            return st; /* the server's refusal: the connection stays */
        bool retry = !fresh && f->over && !f->timed_out && !f->interrupted && attempt == 0;
        drop_connection(f);
        if (!retry)
            return st;
    }
}

/* The time-out for one request (the handshake included) starts now. */
static void arm(ms_viewer_fetcher *f)
{
    double s = f->timeout_s > 0 ? f->timeout_s : 5.0;
    struct timeval tv = {(time_t)s, (suseconds_t)((s - (double)(time_t)s) * 1e6)};
    f->timed_out = false;
    evtimer_add(f->timer, &tv);
}

static void fetch_documents(ms_viewer_fetcher *f, ms_viewer_fetched *r)
{
    ms_error err;
    ms_viewer_model_entry *e = &r->entry;
    e->documents_fetched = true;
    job j = {.model = e->name, .kind = MS_DOCUMENT_METADATA};
    arm(f);
    r->status = run_job(f, &j, &err);
    if (r->status == MS_OK) {
        r->status = ms_viewer_entry_set_metadata(e, f->bytes, f->length, &err);
        free(f->bytes);
        f->bytes = NULL;
    }
    if (r->status == MS_OK && e->has_thumbnail) {
        j.kind = MS_DOCUMENT_THUMBNAIL;
        arm(f);
        r->status = run_job(f, &j, &err);
        e->thumbnail_png = f->bytes, e->thumbnail_png_size = f->length;
        f->bytes = NULL;
        e->has_thumbnail = r->status == MS_OK;
    }
    if (r->status != MS_OK)
        snprintf(r->why, sizeof r->why, "%s: %.400s", e->name, err.text);
}

static void fetch_annotations(ms_viewer_fetcher *f, ms_viewer_fetched *r)
{
    ms_error err;
    job j = {.model = r->entry.name, .kind = MS_DOCUMENT_ANNOTATIONS};
    arm(f);
    r->status = run_job(f, &j, &err);
    if (r->status == MS_OK) {
        r->document = f->bytes, r->document_size = f->length;
        f->bytes = NULL;
    } else if (f->refused && !strncmp(f->why, "NO_DOCUMENT", 11)) {
        r->status = MS_OK; /* none stored: the empty set */
    } else {
        snprintf(r->why, sizeof r->why, "%s: %.400s", r->entry.name, err.text);
    }
}

static void fetch_page(ms_viewer_fetcher *f, ms_viewer_fetched *r)
{
    ms_error err;
    ms_client_page_request at = {.offset = (uint32_t)r->offset, .limit = MS_VIEWER_PAGE,
                                 .sort = MS_PROTO_SORT_NAME, .query = r->query};
    job j = {.page = true, .at = &at};
    bool fresh;
    arm(f);
    r->status = connect_ready(f, &fresh, &err);
    if (r->status == MS_OK && f->version < 3) { /* no pages: the whole list, filtered */
        ms_viewer_source s = {.host = f->host, .port = f->port, .token = f->token,
                              .timeout_s = f->timeout_s};
        r->status = r->offset ? ms_error_set(&err, MS_ERR_UNSUPPORTED, "no catalogue pages")
                              : ms_viewer_list_page(&s, r->query, &r->page, &err);
    } else if (r->status == MS_OK) {
        ms_client_catalogue_free(&f->cat);
        f->cap = 0;
        r->status = run_job(f, &j, &err);
    }
    if (r->status == MS_OK && f->version >= 3) {
        ms_viewer_model_list *p = &r->page;
        p->entries = f->cat.count ? calloc(f->cat.count, sizeof *p->entries) : NULL;
        if (f->cat.count && !p->entries)
            r->status = ms_error_set(&err, MS_ERR_NOMEM, "out of memory for the catalogue");
        for (size_t i = 0; p->entries && i < f->cat.count; ++i)
            ms_viewer_entry_from_server(&f->cat.entries[i], &p->entries[i]);
        p->count = p->entries ? f->cat.count : 0;
        p->total = f->cat.total > r->offset + p->count ? f->cat.total : r->offset + p->count;
        if (!p->count)
            p->total = r->offset; /* nothing more comes */
        snprintf(p->query, sizeof p->query, "%s", r->query);
    }
    ms_client_catalogue_free(&f->cat);
    f->cap = 0;
    if (r->status != MS_OK)
        snprintf(r->why, sizeof r->why, "catalogue: %.400s", err.text);
}

static void *worker_main(void *arg)
{
    ms_viewer_fetcher *f = arg;
    for (;;) {
        pthread_mutex_lock(&f->lock);
        while (!f->stop && !f->doc_wanted && !f->page_wanted)
            pthread_cond_wait(&f->cond, &f->lock);
        if (f->stop) {
            pthread_mutex_unlock(&f->lock);
            break;
        }
        node *n = calloc(1, sizeof *n);
        if (!n) { /* nothing to hand the result in: try again later */
            pthread_mutex_unlock(&f->lock);
            usleep(10000);
            continue;
        }
        ms_viewer_fetched *r = &n->r;
        if (f->page_wanted) { /* the list first: what the screen shows */
            f->page_wanted = false, f->page_busy = true;
            r->kind = MS_FETCHED_PAGE;
            memcpy(r->query, f->page_query, sizeof r->query);
            r->offset = f->page_offset;
            memcpy(f->page_busy_query, f->page_query, sizeof f->page_busy_query);
            f->page_busy_offset = f->page_offset;
        } else {
            f->doc_wanted = false, f->doc_busy = true;
            r->kind = f->doc_notes ? MS_FETCHED_ANNOTATIONS : MS_FETCHED_DOCUMENTS;
            memcpy(r->entry.name, f->doc_name, sizeof r->entry.name);
            memcpy(f->doc_busy_name, f->doc_name, sizeof f->doc_busy_name);
            f->doc_busy_notes = f->doc_notes;
        }
        pthread_mutex_unlock(&f->lock);
        if (r->kind == MS_FETCHED_PAGE)
            fetch_page(f, r);
        else if (r->kind == MS_FETCHED_ANNOTATIONS)
            fetch_annotations(f, r);
        else
            fetch_documents(f, r);
        evtimer_del(f->timer);
        pthread_mutex_lock(&f->lock);
        if (r->kind == MS_FETCHED_PAGE)
            f->page_busy = false;
        else
            f->doc_busy = false;
        if (f->tail)
            f->tail->next = n;
        else
            f->head = n;
        f->tail = n;
        pthread_mutex_unlock(&f->lock);
    }
    drop_connection(f);
    return NULL;
}

/* --- the drawing thread's side ------------------------------------------ */

ms_status ms_viewer_fetcher_new(const ms_viewer_source *source, ms_viewer_fetcher **out,
                                ms_error *err)
{
    *out = NULL;
    if (!source || source->archive_dir || !source->host ||
        strlen(source->host) >= sizeof ((ms_viewer_fetcher *)0)->host)
        return ms_error_set(err, MS_ERR_ARG, "fetcher: a server's numeric address is needed");
    ms_viewer_fetcher *f = calloc(1, sizeof *f);
    if (!f)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the catalogue's fetcher");
    snprintf(f->host, sizeof f->host, "%s", source->host);
    f->port = source->port;
    f->timeout_s = source->timeout_s;
    f->wake[0] = f->wake[1] = -1;
    if (source->token && !(f->token = strdup(source->token))) {
        free(f);
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the catalogue's fetcher");
    }
    bool locks = false;
    ms_status st = MS_OK;
    if (pipe(f->wake) != 0 || fcntl(f->wake[0], F_SETFD, FD_CLOEXEC) != 0 ||
        fcntl(f->wake[1], F_SETFD, FD_CLOEXEC) != 0)
        st = ms_error_set(err, MS_ERR_IO, "fetcher: no pipe");
    else if (!(f->base = event_base_new()) ||
             !(f->wake_event = event_new(f->base, f->wake[0], EV_READ | EV_PERSIST, on_wake, f)) ||
             !(f->timer = evtimer_new(f->base, on_timeout, f)) ||
             event_add(f->wake_event, NULL) != 0)
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for the catalogue's fetcher");
    else if (pthread_mutex_init(&f->lock, NULL) != 0)
        st = ms_error_set(err, MS_ERR_NOMEM, "fetcher: no lock");
    else if (pthread_cond_init(&f->cond, NULL) != 0) {
        pthread_mutex_destroy(&f->lock);
        st = ms_error_set(err, MS_ERR_NOMEM, "fetcher: no lock");
    } else {
        locks = true;
        if (pthread_create(&f->thread, NULL, worker_main, f) != 0)
            st = ms_error_set(err, MS_ERR_IO, "fetcher: no thread");
    }
    if (st == MS_OK) {
        *out = f;
        return MS_OK;
    }
    if (locks) {
        pthread_cond_destroy(&f->cond);
        pthread_mutex_destroy(&f->lock);
    }
    if (f->timer)
        event_free(f->timer);
    if (f->wake_event)
        event_free(f->wake_event);
    if (f->base)
        event_base_free(f->base);
    for (int k = 0; k < 2; ++k)
        if (f->wake[k] >= 0)
            close(f->wake[k]);
    free(f->token);
    free(f);
    return st;
}

void ms_viewer_fetcher_free(ms_viewer_fetcher *f)
{
    if (!f)
        return;
    pthread_mutex_lock(&f->lock);
    f->stop = true;
    pthread_cond_signal(&f->cond);
    pthread_mutex_unlock(&f->lock);
    ssize_t w = write(f->wake[1], "x", 1); /* a request in flight ends at once */
    (void)w;
    pthread_join(f->thread, NULL);
    for (node *n = f->head, *next; n; n = next) {
        next = n->next;
        ms_viewer_fetched_free(&n->r);
        free(n);
    }
    pthread_cond_destroy(&f->cond);
    pthread_mutex_destroy(&f->lock);
    event_free(f->timer);
    event_free(f->wake_event);
    event_base_free(f->base);
    close(f->wake[0]);
    close(f->wake[1]);
    free(f->token);
    free(f);
}

/* A model's documents (notes: its annotations), superseding a request still
 * waiting. */
static void want_model_documents(ms_viewer_fetcher *f, const char *name, bool notes)
{
    if (!name || strlen(name) > MS_MODEL_NAME_MAX)
        return;
    ms_fetched_kind kind = notes ? MS_FETCHED_ANNOTATIONS : MS_FETCHED_DOCUMENTS;
    pthread_mutex_lock(&f->lock);
    bool come = false; /* fetched, not taken yet */
    for (const node *n = f->head; n && !come; n = n->next)
        come = n->r.kind == kind && !strcmp(n->r.entry.name, name);
    if (come || (f->doc_busy && f->doc_busy_notes == notes && !strcmp(f->doc_busy_name, name)))
        f->doc_wanted = false; /* it is on its way */
    else if (!f->doc_wanted || f->doc_notes != notes || strcmp(f->doc_name, name)) {
        snprintf(f->doc_name, sizeof f->doc_name, "%s", name);
        f->doc_notes = notes;
        f->doc_wanted = true;
        pthread_cond_signal(&f->cond);
    }
    pthread_mutex_unlock(&f->lock);
}

void ms_viewer_fetcher_want_documents(ms_viewer_fetcher *f, const char *name)
{
    want_model_documents(f, name, false);
}

void ms_viewer_fetcher_want_annotations(ms_viewer_fetcher *f, const char *name)
{
    want_model_documents(f, name, true);
}

void ms_viewer_fetcher_want_page(ms_viewer_fetcher *f, const char *query, size_t offset)
{
    pthread_mutex_lock(&f->lock);
    if (!query || strlen(query) >= sizeof f->page_query ||
        (f->page_busy && !strcmp(f->page_busy_query, query) && f->page_busy_offset == offset)) {
        f->page_wanted = false;
    } else if (!f->page_wanted || strcmp(f->page_query, query) || f->page_offset != offset) {
        snprintf(f->page_query, sizeof f->page_query, "%s", query);
        f->page_offset = offset;
        f->page_wanted = true;
        pthread_cond_signal(&f->cond);
    }
    pthread_mutex_unlock(&f->lock);
}

bool ms_viewer_fetcher_take(ms_viewer_fetcher *f, ms_viewer_fetched *out)
{
    pthread_mutex_lock(&f->lock);
    node *n = f->head;
    if (n) {
        f->head = n->next;
        if (!f->head)
            f->tail = NULL;
    }
    pthread_mutex_unlock(&f->lock);
    if (!n)
        return false;
    *out = n->r;
    free(n);
    return true;
}

void ms_viewer_fetched_free(ms_viewer_fetched *r)
{
    if (!r)
        return;
    ms_metadata_free(r->entry.metadata);
    free(r->entry.thumbnail_png);
    free(r->document);
    r->entry.metadata = NULL, r->entry.thumbnail_png = NULL, r->document = NULL;
    ms_viewer_model_list_free(&r->page);
}

bool ms_viewer_fetcher_busy(ms_viewer_fetcher *f)
{
    pthread_mutex_lock(&f->lock);
    bool busy = f->doc_wanted || f->doc_busy || f->page_wanted || f->page_busy;
    pthread_mutex_unlock(&f->lock);
    return busy;
}

unsigned ms_viewer_fetcher_connections(ms_viewer_fetcher *f)
{
    pthread_mutex_lock(&f->lock);
    unsigned n = f->connections;
    pthread_mutex_unlock(&f->lock);
    return n;
}
