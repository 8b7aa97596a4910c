#include "ms_viewer_model.h"

#include <inttypes.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <jansson.h>

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
        d->has_crease_angle = e->has_crease_angle;
        d->crease_angle_deg = e->crease_angle_deg;
        d->has_thumbnail = e->has_thumbnail;
        d->metadata = e->metadata; /* moved: the catalogue's copy is dropped below */
        catalog.entries[i].metadata = NULL;
    }
    list->count = catalog.count;
    ms_catalog_free(&catalog);
    return MS_OK;
}

void ms_viewer_entry_from_server(const ms_client_catalogue_entry *e, ms_viewer_model_entry *d)
{
    memset(d, 0, sizeof *d);
    snprintf(d->name, sizeof d->name, "%s", e->name);
    /* meshserve's title: "V vertices, T triangles"; other servers may say less. */
    unsigned long long vertices, triangles;
    if (sscanf(e->title, "%llu vertices, %llu triangles", &vertices, &triangles) == 2)
        d->triangles = triangles;
    d->bytes = e->archive_bytes;
    d->apo = e->apo_steps > 0;
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
    for (size_t i = 0; i < catalogue.count; ++i)
        ms_viewer_entry_from_server(&catalogue.entries[i], &list->entries[i]);
    list->count = catalogue.count;
    ms_client_catalogue_free(&catalogue);
    return MS_OK;
}

ms_status ms_viewer_list_models(const ms_viewer_source *source, ms_viewer_model_list *list,
                                ms_error *err)
{
    memset(list, 0, sizeof *list);
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
    for (size_t i = 0; i < list->count; ++i) {
        ms_metadata_free(list->entries[i].metadata);
        free(list->entries[i].thumbnail_png);
    }
    free(list->entries);
    list->entries = NULL;
    list->count = list->total = 0;
    list->query[0] = 0;
}

/* The METADATA document's sidecar fields, checked by the sidecar's parser. */
ms_status ms_viewer_entry_set_metadata(ms_viewer_model_entry *entry, const uint8_t *bytes,
                                       size_t length, ms_error *err)
{
    json_error_t jerr;
    json_t *doc = json_loadb((const char *)bytes, length, 0, &jerr);
    json_t *fields = doc && json_is_object(doc) ? json_object() : NULL;
    if (!fields) {
        json_decref(doc);
        return ms_error_set(err, MS_ERR_FORMAT, "%s: the server's metadata is not a JSON object",
                            entry->name);
    }
    for (int k = 0; k < MS_METADATA_FIELDS; ++k) {
        json_t *v = json_object_get(doc, ms_metadata_field_names[k]);
        if (v)
            json_object_set(fields, ms_metadata_field_names[k], v);
    }
    entry->has_thumbnail = json_is_true(json_object_get(doc, "thumbnail"));
    json_decref(doc);
    char *text = json_dumps(fields, JSON_COMPACT);
    json_decref(fields);
    if (!text)
        return ms_error_set(err, MS_ERR_NOMEM, "out of memory for metadata");
    ms_metadata_free(entry->metadata);
    entry->metadata = NULL;
    ms_status st = ms_metadata_parse(text, strlen(text), entry->name, &entry->metadata, err);
    free(text);
    return st;
}

ms_status ms_viewer_model_fetch_documents(const ms_viewer_source *source,
                                          ms_viewer_model_entry *entry, ms_error *err)
{
    if (source->archive_dir || entry->documents_fetched)
        return MS_OK;
    entry->documents_fetched = true;
    ms_client_options co = {.host = source->host, .port = source->port, .token = source->token,
                            .agent = "meshview/0.1"};
    uint8_t *bytes;
    size_t length;
    ms_status st = ms_client_fetch_document_at(&co, source->timeout_s, entry->name,
                                               MS_DOCUMENT_METADATA, &bytes, &length, err);
    if (st != MS_OK)
        return st;
    st = ms_viewer_entry_set_metadata(entry, bytes, length, err);
    free(bytes);
    if (st != MS_OK || !entry->has_thumbnail)
        return st;
    st = ms_client_fetch_document_at(&co, source->timeout_s, entry->name, MS_DOCUMENT_THUMBNAIL,
                                     &entry->thumbnail_png, &entry->thumbnail_png_size, err);
    if (st != MS_OK)
        entry->has_thumbnail = false;
    return st;
}

ms_status ms_viewer_model_open_listed(const ms_viewer_source *source,
                                      const ms_viewer_model_list *list, const char *name,
                                      ms_viewer_model *model, ms_error *err)
{
    memset(model, 0, sizeof *model);
    if (!name || !ms_model_name_valid(name))
        return ms_error_set(err, MS_ERR_ARG, "'%s' is not a model name", name ? name : "");
    snprintf(model->name, sizeof model->name, "%s", name);
    ms_viewer_model_entry key;
    snprintf(key.name, sizeof key.name, "%s", name);
    const ms_viewer_model_entry *entry =
        list->count ? bsearch(&key, list->entries, list->count, sizeof *list->entries, by_name)
                    : NULL;
    ms_viewer_model_entry found; /* a model of a server's later pages */
    if (!entry && !source->archive_dir && list->total > list->count) {
        ms_status st = ms_viewer_list_lookup(source, name, &found, err);
        if (st != MS_OK && st != MS_ERR_RANGE)
            return st;
        entry = st == MS_OK ? &found : NULL;
    }
    if (!entry) {
        if (source->archive_dir)
            return ms_error_set(err, MS_ERR_RANGE, "model '%s' does not exist in %s", name,
                                source->archive_dir);
        return ms_error_set(err, MS_ERR_RANGE, "model '%s' does not exist on %s:%u", name,
                            source->host, source->port);
    }
    model->apo = entry->apo;
    model->has_crease_angle = entry->has_crease_angle;
    model->crease_angle_deg = entry->crease_angle_deg;
    model->unit_known = source->archive_dir || entry->documents_fetched;
    if (entry->metadata && entry->metadata->unit)
        snprintf(model->unit, sizeof model->unit, "%s", entry->metadata->unit);
    if (source->archive_dir) {
        int n = snprintf(model->archive_path, sizeof model->archive_path, "%s/%s.msa",
                         source->archive_dir, model->name);
        if (n < 0 || (size_t)n >= sizeof model->archive_path)
            return ms_error_set(err, MS_ERR_ARG, "%s: archive directory path too long",
                                source->archive_dir);
    }
    /* from a server the catalogue lists it: no index crosses the network here */
    return MS_OK;
}

ms_status ms_viewer_model_open(const ms_viewer_source *source, const char *name,
                               ms_viewer_model *model, ms_error *err)
{
    memset(model, 0, sizeof *model);
    ms_viewer_model_list list;
    ms_status st = ms_viewer_list_models(source, &list, err);
    if (st == MS_OK)
        st = ms_viewer_model_open_listed(source, &list, name, model, err);
    ms_viewer_model_list_free(&list);
    if (st != MS_OK)
        ms_viewer_model_close(model);
    return st;
}

static int compare_id(const void *a, const void *b)
{
    uint32_t x = *(const uint32_t *)a, y = *(const uint32_t *)b;
    return x < y ? -1 : x > y;
}

void ms_viewer_model_bounds(const ms_viewer_model *model, double lo[3], double hi[3])
{
    const ms_archive_header *h = &model->header;
    const ms_core_opening *index = &model->index;
    if (index->content_known) {
        memcpy(lo, index->content_lo, sizeof index->content_lo);
        memcpy(hi, index->content_hi, sizeof index->content_hi);
        return;
    }
    bool any = false;
    for (size_t i = 0; i < index->count; ++i) {
        const ms_archive_cell *c = &index->records[i];
        if (c->triangle_count == 0)
            continue;
        if (c->first_child != MS_ARCHIVE_NONE &&
            bsearch(&c->first_child, index->ids, index->count, sizeof *index->ids, compare_id))
            continue; /* its children are held: they bound it more tightly */
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
    ms_core_opening_free(&model->index);
}
