#include "ms_viewer_model.h"

#include <event2/event.h>
#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_client.h"

static int by_name(const void *a, const void *b)
{
    return strcmp(((const ms_viewer_model_entry *)a)->name,
                  ((const ms_viewer_model_entry *)b)->name);
}

static ms_status list_local(const char *dir, ms_viewer_model_list *list, ms_error *err)
{
    ms_catalog catalog;
    ms_status st = ms_catalog_load(dir, &catalog, err);
    if (st != MS_OK)
        return st;
    if (catalog.count) {
        list->entries = calloc(catalog.count, sizeof *list->entries);
        if (!list->entries) {
            ms_catalog_free(&catalog);
            return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the catalogue", dir);
        }
    }
    for (size_t i = 0; i < catalog.count; ++i) {
        const ms_catalog_entry *e = &catalog.entries[i];
        ms_viewer_model_entry *d = &list->entries[i];
        snprintf(d->name, sizeof d->name, "%s", e->name);
        d->triangles = e->triangles;
        d->bytes = e->archive_bytes;
        d->apo = e->apo;
    }
    list->count = catalog.count;
    ms_catalog_free(&catalog);
    return MS_OK;
}

static ms_status list_server(const ms_viewer_source *source, ms_viewer_model_list *list,
                             ms_error *err)
{
    ms_client_options co = {.host = source->host, .port = source->port, .token = source->token,
                            .agent = "meshview/0.1"};
    ms_client_catalogue catalogue;
    ms_status st = ms_client_fetch_catalogue(&co, source->timeout_s, &catalogue, err);
    if (st != MS_OK)
        return st;
    if (catalogue.count) {
        list->entries = calloc(catalogue.count, sizeof *list->entries);
        if (!list->entries) {
            ms_client_catalogue_free(&catalogue);
            return ms_error_set(err, MS_ERR_NOMEM, "out of memory for the catalogue");
        }
    }
    for (size_t i = 0; i < catalogue.count; ++i) {
        const ms_client_catalogue_entry *e = &catalogue.entries[i];
        ms_viewer_model_entry *d = &list->entries[i];
        snprintf(d->name, sizeof d->name, "%s", e->name);
        /* meshserve's title: "V vertices, T triangles"; other servers may say less. */
        unsigned long long vertices, triangles;
        if (sscanf(e->title, "%llu vertices, %llu triangles", &vertices, &triangles) == 2)
            d->triangles = triangles;
        d->bytes = e->archive_bytes;
        d->apo = e->apo_steps > 0;
    }
    list->count = catalogue.count;
    ms_client_catalogue_free(&catalogue);
    return MS_OK;
}

ms_status ms_viewer_list_models(const ms_viewer_source *source, ms_viewer_model_list *list,
                                ms_error *err)
{
    list->entries = NULL;
    list->count = 0;
    ms_status st = source->archive_dir ? list_local(source->archive_dir, list, err)
                                       : list_server(source, list, err);
    if (st == MS_OK && list->count)
        qsort(list->entries, list->count, sizeof *list->entries, by_name);
    return st;
}

void ms_viewer_model_list_free(ms_viewer_model_list *list)
{
    if (!list)
        return;
    free(list->entries);
    list->entries = NULL;
    list->count = 0;
}

/* Copies an opened archive's header and records into the model. */
static ms_status take_index(const ms_archive *archive, ms_viewer_model *model, ms_error *err)
{
    model->header = *ms_archive_get_header(archive);
    model->cells = calloc(model->header.cell_count, sizeof *model->cells);
    if (!model->cells)
        return ms_error_set(err, MS_ERR_NOMEM, "%s: out of memory for the index", model->name);
    for (uint32_t i = 0; i < model->header.cell_count; ++i)
        model->cells[i] = *ms_archive_get_cell(archive, i);
    return MS_OK;
}

/* --- the index from a server: one connection, one OPEN_MODEL -------------- */

typedef struct index_fetch {
    struct event_base *base;
    uint32_t request;
    ms_archive *archive;
    const char *name;
    bool done, unknown;
    ms_status status;
    char why[MS_ERROR_TEXT_MAX];
} index_fetch;

static void index_fail(index_fetch *f, const char *why)
{
    if (f->done)
        return;
    f->done = true;
    f->status = MS_ERR_IO;
    snprintf(f->why, sizeof f->why, "%s", why);
    event_base_loopbreak(f->base);
}

static void index_on_opened(ms_client *client, uint32_t request_id,
                            const ms_proto_model_opened *opened, const uint8_t *index, void *arg)
{
    (void)client;
    index_fetch *f = arg;
    if (request_id != f->request || f->done)
        return;
    ms_error e;
    f->done = true;
    if (ms_archive_open_index(index, opened->index_size, f->name, &f->archive, &e) != MS_OK) {
        f->status = MS_ERR_FORMAT;
        snprintf(f->why, sizeof f->why, "%s", e.text);
    }
    event_base_loopbreak(f->base);
}

static void index_on_error(ms_client *client, uint32_t first_id, uint32_t count,
                           const ms_proto_error_body *e, void *arg)
{
    (void)client;
    index_fetch *f = arg;
    if (count != 0 && (f->request < first_id || f->request - first_id >= count))
        return;
    char why[MS_ERROR_TEXT_MAX];
    snprintf(why, sizeof why, "%s %.*s", ms_proto_error_name(e->code),
             (int)(e->text_length > 150 ? 150 : e->text_length), e->text);
    f->unknown = e->code == MS_PROTO_E_UNKNOWN_MODEL;
    index_fail(f, why);
}

static void index_on_closed(ms_client *client, const char *why, void *arg)
{
    (void)client;
    index_fail(arg, why);
}

static void index_on_timeout(evutil_socket_t fd, short what, void *arg)
{
    (void)fd, (void)what;
    index_fail(arg, "no answer in time");
}

static ms_status open_server(const ms_viewer_source *source, ms_viewer_model *model,
                             ms_error *err)
{
    ms_client_options co = {.host = source->host, .port = source->port, .token = source->token,
                            .agent = "meshview/0.1", .max_frame = 0};
    static const ms_client_handlers handlers = {.model_opened = index_on_opened,
                                                .request_error = index_on_error,
                                                .closed = index_on_closed};
    index_fetch f = {.name = model->name};
    struct event *timer = NULL;
    ms_client *client = NULL;
    ms_status st = MS_OK;
    double timeout = source->timeout_s > 0 ? source->timeout_s : 5.0;
    if (!(f.base = event_base_new()) || !(timer = evtimer_new(f.base, index_on_timeout, &f))) {
        st = ms_error_set(err, MS_ERR_NOMEM, "out of memory for a model request");
        goto done;
    }
    if ((st = ms_client_connect(f.base, &co, &handlers, &f, &client, err)) != MS_OK)
        goto done;
    if ((st = ms_client_open_model(client, model->name, &f.request, err)) != MS_OK)
        goto done;
    struct timeval limit = {(time_t)timeout,
                            (suseconds_t)((timeout - (double)(time_t)timeout) * 1e6)};
    evtimer_add(timer, &limit);
    event_base_dispatch(f.base);
    if (!f.done)
        index_fail(&f, "the event loop ended early");
    if (f.unknown)
        st = ms_error_set(err, MS_ERR_RANGE, "model '%s' does not exist on %s:%u", model->name,
                          source->host, source->port);
    else if (f.status != MS_OK)
        st = ms_error_set(err, f.status, "server %s:%u: %s", source->host, source->port, f.why);
    else
        st = take_index(f.archive, model, err);
done:
    ms_archive_close(f.archive);
    ms_client_free(client);
    if (timer)
        event_free(timer);
    if (f.base)
        event_base_free(f.base);
    return st;
}

static ms_status open_local(const ms_viewer_source *source, ms_viewer_model *model,
                            ms_error *err)
{
    ms_catalog catalog;
    ms_status st = ms_catalog_load(source->archive_dir, &catalog, err);
    if (st != MS_OK)
        return st;
    bool known = ms_catalog_find(&catalog, model->name) != NULL;
    ms_catalog_free(&catalog);
    if (!known)
        return ms_error_set(err, MS_ERR_RANGE, "model '%s' does not exist in %s", model->name,
                            source->archive_dir);
    int n = snprintf(model->archive_path, sizeof model->archive_path, "%s/%s.msa",
                     source->archive_dir, model->name);
    if (n < 0 || (size_t)n >= sizeof model->archive_path)
        return ms_error_set(err, MS_ERR_ARG, "%s: archive directory path too long",
                            source->archive_dir);
    ms_archive *archive;
    if ((st = ms_archive_open(model->archive_path, &archive, err)) != MS_OK)
        return st;
    st = take_index(archive, model, err);
    ms_archive_close(archive);
    return st;
}

ms_status ms_viewer_model_open(const ms_viewer_source *source, const char *name,
                               ms_viewer_model *model, ms_error *err)
{
    memset(model, 0, sizeof *model);
    if (!name || !ms_model_name_valid(name))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", name ? name : "");
    snprintf(model->name, sizeof model->name, "%s", name);
    ms_status st = source->archive_dir ? open_local(source, model, err)
                                       : open_server(source, model, err);
    if (st != MS_OK)
        ms_viewer_model_close(model);
    return st;
}

void ms_viewer_model_bounds(const ms_viewer_model *model, double lo[3], double hi[3])
{
    const ms_archive_header *h = &model->header;
    bool any = false;
    for (uint32_t i = 0; i < h->cell_count; ++i) {
        const ms_archive_cell *c = &model->cells[i];
        if (c->first_child != MS_ARCHIVE_NONE || c->triangle_count == 0)
            continue;
        double side = h->box_side / pow((double)h->n, (double)c->level);
        for (int k = 0; k < 3; ++k) {
            double a = h->box_origin[k] + c->position[k] * side, b = a + side;
            lo[k] = any && lo[k] < a ? lo[k] : a;
            hi[k] = any && hi[k] > b ? hi[k] : b;
        }
        any = true;
    }
    if (!any)
        for (int k = 0; k < 3; ++k) {
            lo[k] = h->box_origin[k];
            hi[k] = h->box_origin[k] + h->box_side;
        }
}

void ms_viewer_model_close(ms_viewer_model *model)
{
    if (!model)
        return;
    free(model->cells);
    model->cells = NULL;
}
