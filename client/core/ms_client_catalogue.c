/* A server's catalogue in one call (ms_client_fetch_catalogue and
 * ms_client_fetch_catalogue_page, ms_client.h): its own event loop, one
 * connection, one LIST_CATALOGUE or LIST_PAGE, every frame of the answer. */
#include <event2/event.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_client.h"

/* --- ms_client_fetch_catalogue: one connection, one LIST_CATALOGUE ---------- */

typedef struct catalogue_fetch {
    struct event_base *base;
    uint32_t request;
    const ms_client_page_request *page; /* NULL: the whole catalogue */
    ms_status page_status;              /* of sending LIST_PAGE once ready */
    ms_client_catalogue *out;
    size_t cap;
    bool done, failed;
    char why[MS_ERROR_TEXT_MAX];
} catalogue_fetch;

static void fetch_fail(catalogue_fetch *f, const char *why)
{
    if (f->done)
        return;
    f->done = f->failed = true;
    snprintf(f->why, sizeof f->why, "%s", why);
    event_base_loopbreak(f->base);
}

static void fetch_on_catalogue(ms_client *client, uint32_t request_id,
                               const ms_proto_catalogue *cat, bool last, void *arg)
{
    (void)client;
    catalogue_fetch *f = arg;
    if (request_id != f->request || f->done)
        return;
    ms_client_catalogue *out = f->out;
    if (out->count + cat->entry_count > f->cap) {
        size_t cap = f->cap ? f->cap : 16;
        while (cap < out->count + cat->entry_count)
            cap *= 2;
        ms_client_catalogue_entry *grown = realloc(out->entries, cap * sizeof *grown);
        if (!grown) {
            fetch_fail(f, "out of memory for the catalogue");
            return;
        }
        out->entries = grown;
        f->cap = cap;
    }
    for (uint16_t i = 0; i < cat->entry_count; ++i) {
        const ms_proto_catalogue_entry *e = &cat->entries[i];
        ms_client_catalogue_entry *d = &out->entries[out->count++];
        memset(d, 0, sizeof *d);
        /* lengths are bounded by the decoder (PROTOCOL.md 4.5) */
        memcpy(d->name, e->name, e->name_length);
        memcpy(d->title, e->title, e->title_length);
        d->geometry_steps = e->geometry_steps, d->apo_steps = e->apo_steps;
        d->permitted_geometry_steps = e->permitted_geometry_steps;
        d->permitted_apo_steps = e->permitted_apo_steps;
        d->cell_count = e->cell_count;
        d->content_id = e->content_id;
        d->archive_bytes = e->archive_bytes;
    }
    out->total = f->page ? cat->total : out->count;
    if (last) {
        f->done = true;
        event_base_loopbreak(f->base);
    }
}

/* A page waits for the handshake: LIST_PAGE needs version 3. */
static void fetch_on_ready(ms_client *client, const ms_proto_hello_reply *reply, void *arg)
{
    catalogue_fetch *f = arg;
    if (!f->page)
        return;
    if (reply->version < 3) {
        f->page_status = MS_ERR_UNSUPPORTED;
        char why[120];
        snprintf(why, sizeof why, "the server speaks protocol version %u, which has no "
                 "catalogue pages (version 3)", reply->version);
        fetch_fail(f, why);
        return;
    }
    ms_error e;
    if ((f->page_status = ms_client_list_catalogue(client, f->page, &f->request, &e)) != MS_OK)
        fetch_fail(f, e.text);
}

static void fetch_on_error(ms_client *client, uint32_t first_id, uint32_t count,
                           const ms_proto_error_body *e, void *arg)
{
    (void)client;
    catalogue_fetch *f = arg;
    if (count != 0 && (f->request < first_id || f->request - first_id >= count))
        return;
    char why[MS_ERROR_TEXT_MAX];
    snprintf(why, sizeof why, "%s %.*s", ms_proto_error_name(e->code),
             (int)(e->text_length > 150 ? 150 : e->text_length), e->text);
    fetch_fail(f, why);
}

static void fetch_on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    fetch_fail(arg, why);
}

static void fetch_on_timeout(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    fetch_fail(arg, "no complete answer in time");
}

static ms_status fetch_catalogue(const ms_client_options *options, double timeout_s,
                                 const ms_client_page_request *page,
                                 ms_client_catalogue *catalogue, ms_error *err)
{
    catalogue->entries = NULL;
    catalogue->count = catalogue->total = 0;
    if (!options || !options->host || !(timeout_s >= 0) || timeout_s > 86400)
        return ms_error_set(err, MS_ERR_ARG, "catalogue: a server address and a time-out in "
                            "[0, 86400] s are needed");
    if (timeout_s == 0)
        timeout_s = 5.0;
    static const ms_client_handlers handlers = {.ready = fetch_on_ready,
                                                .catalogue = fetch_on_catalogue,
                                                .request_error = fetch_on_error,
                                                .closed = fetch_on_closed};
    catalogue_fetch f = {.out = catalogue, .page = page};
    struct event *timer = NULL;
    ms_client *client = NULL;
    ms_status st = MS_OK;
    if (!(f.base = event_base_new()) || !(timer = evtimer_new(f.base, fetch_on_timeout, &f))) {
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for a catalogue request");
        goto done;
    }
    if ((st = ms_client_connect(f.base, options, &handlers, &f, &client, err)) != MS_OK)
        goto done;
    if (!page && (st = ms_client_list_catalogue(client, NULL, &f.request, err)) != MS_OK)
        goto done;
    struct timeval limit = {(time_t)timeout_s, (suseconds_t)((timeout_s - (double)(time_t)timeout_s) * 1e6)};
    evtimer_add(timer, &limit);
    event_base_dispatch(f.base);
    if (!f.done)
        fetch_fail(&f, "the event loop ended early");
    if (f.failed)
        st = ms_error_set(err, f.page_status != MS_OK ? f.page_status : MS_ERR_IO,
                          "catalogue of %s:%u: %s", options->host, options->port, f.why);
done:
    ms_client_free(client);
    if (timer)
        event_free(timer);
    if (f.base)
        event_base_free(f.base);
    if (st != MS_OK)
        ms_client_catalogue_free(catalogue);
    return st;
}

ms_status ms_client_fetch_catalogue(const ms_client_options *options, double timeout_s,
                                    ms_client_catalogue *catalogue, ms_error *err)
{
    return fetch_catalogue(options, timeout_s, NULL, catalogue, err);
}

ms_status ms_client_fetch_catalogue_page(const ms_client_options *options, double timeout_s,
                                         const ms_client_page_request *page,
                                         ms_client_catalogue *catalogue, ms_error *err)
{
    size_t query = page && page->query ? strnlen(page->query, MS_PROTO_MAX_PAGE_QUERY + 1) : 0;
    if (!page || page->limit < 1 || page->limit > MS_PROTO_MAX_PAGE ||
        page->sort > MS_PROTO_SORT_LAST || query > MS_PROTO_MAX_PAGE_QUERY) {
        catalogue->entries = NULL;
        catalogue->count = catalogue->total = 0;
        return ms_error_set(err, MS_ERR_ARG, "catalogue page: a limit in 1..%u, a sort in "
                            "0..%u and a query of at most %u bytes are needed",
                            MS_PROTO_MAX_PAGE, MS_PROTO_SORT_LAST, MS_PROTO_MAX_PAGE_QUERY);
    }
    return fetch_catalogue(options, timeout_s, page, catalogue, err);
}

void ms_client_catalogue_free(ms_client_catalogue *catalogue)
{
    if (!catalogue)
        return;
    free(catalogue->entries);
    catalogue->entries = NULL;
    catalogue->count = catalogue->total = 0;
}

