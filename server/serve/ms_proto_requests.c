/* The answers of a binary-protocol connection to each message a client may
 * send (PROTOCOL.md sections 4 to 8): handshake, catalogue, models, batches of
 * cell requests with their limits and access rules, cancels, pings. See
 * ms_proto_conn.h. */
#include <event2/buffer.h>
#include <event2/bufferevent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ms_access.h"
#include "ms_catalog_page.h"
#include "ms_frame_out.h"
#include "ms_progress.h"
#include "ms_proto_conn.h"
#include "ms_model_document.h"
#include "ms_proto_range.h"
#include "ms_registry.h"
#include "ms_server_internal.h"
#include "ms_subtree.h"

#define INDEX_CHUNK_BYTES (1u << 20)
#define CATALOGUE_FRAME_BYTES 65536u
#define DOCUMENT_CHUNK_BYTES 65536u

static struct evbuffer *output(const ms_serve_conn *c) { return bufferevent_get_output(c->bev); }
static ms_server *server_of(const ms_serve_conn *c) { return c->door->server; }
static ms_server_metrics *metrics_of(const ms_serve_conn *c) { return &c->door->server->metrics; }

/* Compares without an early exit, so timing does not leak the token. */
static bool token_matches(const char *given, size_t length, const char *expected)
{
    size_t n = strlen(expected);
    unsigned diff = (unsigned)(length != n);
    for (size_t i = 0; i < n; ++i)
        diff |= (unsigned char)(i < length ? given[i] : 0) ^ (unsigned char)expected[i];
    return diff == 0;
}

/* Token bucket of section 7: rate max_request_rate, burst max_batch. Returns 0
 * when n requests may go now (and takes them), else the milliseconds to wait. */
static uint64_t rate_take(ms_serve_conn *c, uint32_t n)
{
    double rate = c->door->limits.max_request_rate;
    if (rate <= 0)
        return 0;
    double burst = c->door->limits.max_batch, now = ms_now_seconds();
    c->rate_tokens += (now - c->rate_updated) * rate;
    if (c->rate_tokens > burst)
        c->rate_tokens = burst;
    c->rate_updated = now;
    if (c->rate_tokens >= n) {
        c->rate_tokens -= n;
        return 0;
    }
    uint64_t wait = (uint64_t)ceil((n - c->rate_tokens) / rate * 1000.0);
    return wait ? wait : 1;
}

static bool rate_allows(ms_serve_conn *c, uint32_t request_id, uint32_t n)
{
    uint64_t wait = rate_take(c, n);
    if (!wait)
        return true;
    ms_serve_conn_send_error(c, MS_PROTO_E_RATE_LIMITED, request_id, n, wait, "request rate limit");
    return false;
}

/* The duplicate-id rule of section 5 (fatal). */
static bool ids_free(ms_serve_conn *c, uint32_t first, uint32_t count)
{
    for (uint32_t i = 0; i < count; ++i)
        if (ms_request_queue_find(&c->queue, first + i)) {
            char text[64];
            snprintf(text, sizeof text, "request id %u is already outstanding", first + i);
            ms_serve_conn_fail(c, MS_PROTO_E_DUPLICATE_REQUEST_ID, first + i, text);
            return false;
        }
    return true;
}

/* Steps of a model and those this connection may read (section 8). */
static void model_steps(const ms_serve_conn *c, const ms_model *m, uint8_t *geometry, uint8_t *apo,
                        uint8_t *permitted_geometry, uint8_t *permitted_apo)
{
    ms_access grant = ms_access_grant(m, c->token_accepted);
    *geometry = grant.geometry_steps;
    *apo = grant.apo_steps;
    *permitted_geometry = grant.permitted_geometry_steps;
    *permitted_apo = grant.permitted_apo_steps;
}

/* Whether this connection can open m: its cell count fits the protocol, and
 * the index it would receive does (the head with CAP_INDEX_SUBTREES, so that a
 * model whose whole index is above the 64 MiB limit is still served in
 * subtrees; the whole index otherwise). */
static bool model_servable(const ms_serve_conn *c, const ms_model *m)
{
    if (ms_archive_get_header(m->archive)->cell_count > MS_PROTO_MAX_CELLS)
        return false;
    if ((c->capabilities & MS_PROTO_CAP_INDEX_SUBTREES) && m->index_head)
        return true;
    size_t size;
    ms_archive_index_bytes(m->archive, &size);
    return size >= 1 && size <= MS_PROTO_MAX_INDEX_SIZE;
}

static ms_open_model *find_handle(ms_serve_conn *c, uint32_t handle)
{
    for (unsigned i = 0; handle && i < MS_PROTO_CONN_MAX_OPEN_MODELS; ++i)
        if (c->models[i].handle == handle)
            return &c->models[i];
    return NULL;
}

/* Takes a queued request out (the frames already in the output buffer stay
 * whole) and, when announce, ends it with ERROR CANCELLED. */
static void drop_request(ms_serve_conn *c, ms_cell_request *r, bool announce)
{
    ms_server_metrics *m = metrics_of(c);
    m->queued_requests--;
    m->queued_bytes -= r->end - r->next;
    ms_request_queue_remove(&c->queue, r);
    if (announce)
        ms_serve_conn_send_error(c, MS_PROTO_E_CANCELLED, r->id, 1, 0, "cancelled");
    free(r);
}

static void cancel_request(ms_serve_conn *c, ms_cell_request *r) { drop_request(c, r, true); }

/* --- Messages --------------------------------------------------------------- */

static void handle_hello(ms_serve_conn *c, const ms_proto_hello *h)
{
    uint16_t version;
    if (ms_proto_choose_version(h->min_version, h->max_version, MS_PROTO_MIN_VERSION,
                                MS_PROTO_VERSION, &version) != MS_OK) {
        ms_serve_conn_fail(c, MS_PROTO_E_UNSUPPORTED_VERSION,
                           MS_PROTO_MIN_VERSION | (uint64_t)MS_PROTO_VERSION << 16,
                           "no common protocol version");
        return;
    }
    const char *token = server_of(c)->config.token;
    c->client_max_frame = h->max_frame;
    /* Only the capabilities the chosen version defines: a version-1 peer never
     * gets CAP_INDEX_ZLIB, a version-2 peer never CAP_INDEX_SUBTREES. */
    uint32_t offered =
        (MS_PROTO_CAP_APO | MS_PROTO_CAP_INDEX_ZLIB | MS_PROTO_CAP_INDEX_SUBTREES |
         MS_PROTO_CAP_COLOUR) &
        ms_proto_version_capabilities(version);
    c->version = version;
    c->capabilities = h->capabilities & offered;
    c->token_accepted = token && h->token_length && token_matches(h->token, h->token_length, token);
    ms_proto_message reply = {.type = MS_PROTO_HELLO_REPLY};
    reply.body.hello_reply = c->door->limits;
    reply.body.hello_reply.version = version;
    reply.body.hello_reply.capabilities = c->capabilities;
    reply.body.hello_reply.server_flags = c->token_accepted ? MS_PROTO_SERVER_TOKEN_ACCEPTED : 0;
    ms_serve_conn_send_message(c, &reply);
    if (c->state != MS_CONN_CLOSING)
        c->state = MS_CONN_READY;
}

/* What the binary listing says of one model: from its open archive, else
 * from the figures its catalogue entry recorded at bake, so that listing opens
 * no archive; an entry without them (an older bake) opens it. False when the
 * model cannot be listed to this connection. */
static bool listed_model(ms_serve_conn *c, ms_registry *r, size_t i, ms_proto_catalogue_entry *e)
{
    const ms_catalog_entry *entry = ms_registry_entry(r, i);
    const ms_model *m = ms_registry_peek(r, entry->name);
    if (!m && !entry->has_listing && !(m = ms_registry_find(r, entry->name)))
        return false;
    memset(e, 0, sizeof *e);
    e->name = entry->name;
    e->name_length = (uint8_t)strlen(entry->name);
    if (m) {
        if (!model_servable(c, m))
            return false;
        model_steps(c, m, &e->geometry_steps, &e->apo_steps, &e->permitted_geometry_steps,
                    &e->permitted_apo_steps);
        e->cell_count = ms_archive_get_header(m->archive)->cell_count;
        e->content_id = m->content_id;
        e->archive_bytes = m->file_size;
        return true;
    }
    if (entry->cells > MS_PROTO_MAX_CELLS)
        return false;
    ms_access grant = ms_access_grant_listed(entry, c->token_accepted);
    e->geometry_steps = grant.geometry_steps;
    e->apo_steps = grant.apo_steps;
    e->permitted_geometry_steps = grant.permitted_geometry_steps;
    e->permitted_apo_steps = grant.permitted_apo_steps;
    e->cell_count = entry->cells;
    e->content_id = entry->content_id;
    e->archive_bytes = entry->archive_bytes;
    return true;
}

/* Sends the models at registry positions indices[0..count) (indices NULL:
 * every model) as frames of type (CATALOGUE, or CATALOGUE_PAGE carrying
 * total), split by the client's max_frame, the last with LAST. */
static void send_listing(ms_serve_conn *c, uint32_t id, uint8_t type, const size_t *indices,
                         size_t count_in, uint32_t total)
{
    ms_registry *r = server_of(c)->registry;
    ms_proto_catalogue_entry entries[CATALOGUE_FRAME_BYTES / MS_PROTO_CATALOGUE_ENTRY_FIXED];
    char titles[CATALOGUE_FRAME_BYTES / MS_PROTO_CATALOGUE_ENTRY_FIXED][64];
    uint32_t limit =
        c->client_max_frame < CATALOGUE_FRAME_BYTES ? c->client_max_frame : CATALOGUE_FRAME_BYTES;
    size_t fixed = type == MS_PROTO_CATALOGUE ? MS_PROTO_CATALOGUE_FIXED
                                              : MS_PROTO_CATALOGUE_PAGE_FIXED;
    size_t count = 0, body = fixed, listed = 0;
    for (size_t k = 0; k <= count_in; ++k) {
        ms_proto_catalogue_entry next;
        bool last = k == count_in;
        size_t i = last ? 0 : indices ? indices[k] : k;
        if (!last && !listed_model(c, r, i, &next))
            continue;
        const ms_catalog_entry *entry = last ? NULL : ms_registry_entry(r, i);
        size_t entry_size = 0;
        if (!last) {
            snprintf(titles[count], sizeof titles[count], "%llu vertices, %llu triangles",
                     (unsigned long long)entry->vertices, (unsigned long long)entry->triangles);
            entry_size = MS_PROTO_CATALOGUE_ENTRY_FIXED + next.name_length + strlen(titles[count]);
        }
        bool flush = last || body + entry_size > limit ||
                     count + 1 == sizeof entries / sizeof *entries || listed == 65535;
        if (flush && (count || last)) {
            ms_proto_message msg = {.type = type, .request_id = id};
            msg.flags = last || listed == 65535 ? MS_PROTO_FLAG_LAST : 0;
            msg.body.catalogue.entries = entries;
            msg.body.catalogue.entry_count = (uint16_t)count;
            msg.body.catalogue.total = total;
            ms_serve_conn_send_message(c, &msg);
            if (last || listed == 65535)
                return;
            /* The pending title was written at titles[count]: move it. */
            memcpy(titles[0], titles[count], sizeof titles[0]);
            count = 0;
            body = fixed;
        }
        entries[count] = next;
        entries[count].title = titles[count];
        entries[count].title_length = (uint16_t)strlen(titles[count]);
        body += entry_size;
        ++count;
        ++listed;
    }
}

static void handle_list_catalogue(ms_serve_conn *c, uint32_t id)
{
    metrics_of(c)->binary_requests++;
    c->requests++;
    if (!ids_free(c, id, 1) || !rate_allows(c, id, 1))
        return;
    send_listing(c, id, MS_PROTO_CATALOGUE, NULL, ms_registry_count(server_of(c)->registry), 0);
}

/* Version 3: one page of the catalogue, as the HTTP door's GET /catalog
 * selects it (ms_catalog_page.h). Its total counts the models the filter
 * matches, listable or not. */
static void handle_list_page(ms_serve_conn *c, uint32_t id, const ms_proto_list_page *l)
{
    metrics_of(c)->binary_requests++;
    c->requests++;
    if (!ids_free(c, id, 1) || !rate_allows(c, id, 1))
        return;
    ms_catalog_page_query q = {.offset = l->offset, .limit = l->limit,
                               .sort = (ms_catalog_sort)l->sort, .descending = l->descending};
    memcpy(q.text, l->query, l->query_length);
    q.text[l->query_length] = '\0';
    size_t *indices, count, total;
    if (ms_catalog_page_select(server_of(c)->registry, &q, &indices, &count, &total, NULL) !=
        MS_OK) {
        ms_serve_conn_send_error(c, MS_PROTO_E_INTERNAL, id, 1, 0, "out of memory");
        return;
    }
    send_listing(c, id, MS_PROTO_CATALOGUE_PAGE, indices, count, (uint32_t)total);
    free(indices);
}

/* Version 3: one document of a model (PROTOCOL.md 4.5b), read as the HTTP
 * door reads it (ms_model_document.h), in DOCUMENT frames of at most 64 KiB
 * (and the client's max_frame), the last with LAST. */
static void handle_get_document(ms_serve_conn *c, const ms_proto_message *msg)
{
    const ms_proto_get_document *g = &msg->body.get_document;
    uint32_t id = msg->request_id;
    metrics_of(c)->binary_requests++;
    c->requests++;
    ms_proto_fault fault;
    ms_error err;
    if (ms_proto_check_negotiated(msg, c->version, c->capabilities, &fault, &err) != MS_OK) {
        ms_serve_conn_send_error(c, fault.code, id, 1, fault.detail, err.text);
        return;
    }
    if (!ids_free(c, id, 1) || !rate_allows(c, id, 1))
        return;
    char name[MS_PROTO_MAX_MODEL_NAME + 1];
    memcpy(name, g->name, g->name_length);
    name[g->name_length] = '\0';
    ms_model_document doc;
    ms_document_refusal why;
    ms_server *server = server_of(c);
    if (ms_model_document_read(server->registry, server->config.archive_dir, name, g->kind, &doc,
                               &why, &err) != MS_OK) {
        uint16_t code = why == MS_DOCUMENT_NO_MODEL ? MS_PROTO_E_UNKNOWN_MODEL
                        : why == MS_DOCUMENT_ABSENT ? MS_PROTO_E_NO_DOCUMENT
                                                    : MS_PROTO_E_INTERNAL;
        ms_serve_conn_send_error(c, code, id, 1, g->kind, err.text);
        return;
    }
    uint32_t chunk = c->client_max_frame - MS_PROTO_DOCUMENT_FIXED;
    if (chunk > DOCUMENT_CHUNK_BYTES)
        chunk = DOCUMENT_CHUNK_BYTES;
    uint32_t total = (uint32_t)doc.length, offset = 0;
    do {
        uint32_t n = total - offset < chunk ? total - offset : chunk;
        ms_proto_message out = {.type = MS_PROTO_DOCUMENT, .request_id = id};
        out.flags = offset + n == total ? MS_PROTO_FLAG_LAST : 0;
        out.body.document = (ms_proto_document){.kind = g->kind, .total_length = total,
                                                .offset = offset, .data = doc.bytes + offset,
                                                .data_length = n};
        ms_serve_conn_send_message(c, &out);
        offset += n;
    } while (offset < total && c->state != MS_CONN_CLOSING);
    ms_model_document_free(&doc);
}

/* Adds name to the connection's list of models for the access log, once. */
static void note_model_name(ms_serve_conn *c, const char *name)
{
    size_t have = strlen(c->model_names), length = strlen(name);
    for (const char *p = c->model_names; (p = strstr(p, name)); p += length)
        if ((p == c->model_names || p[-1] == ',') && (p[length] == ',' || !p[length]))
            return;
    if (have + (have ? 1 : 0) + length + 1 > sizeof c->model_names)
        return; /* cut: the line stays short */
    snprintf(c->model_names + have, sizeof c->model_names - have, "%s%s", have ? "," : "", name);
}

static void handle_open_model(ms_serve_conn *c, uint32_t id, const ms_proto_open_model *o)
{
    metrics_of(c)->binary_requests++;
    c->requests++;
    if (!ids_free(c, id, 1) || !rate_allows(c, id, 1))
        return;
    char name[MS_PROTO_MAX_MODEL_NAME + 1];
    memcpy(name, o->name, o->name_length);
    name[o->name_length] = '\0';
    ms_model *m = ms_registry_find(server_of(c)->registry, name);
    if (!m || !model_servable(c, m)) {
        ms_serve_conn_send_error(c, MS_PROTO_E_UNKNOWN_MODEL, id, 1, 0, "no such model");
        return;
    }
    ms_open_model *slot = find_handle(c, 0);
    for (unsigned i = 0; !slot && i < MS_PROTO_CONN_MAX_OPEN_MODELS; ++i)
        if (!c->models[i].handle)
            slot = &c->models[i];
    if (!slot) {
        ms_serve_conn_send_error(c, MS_PROTO_E_TOO_MANY_MODELS, id, 1,
                                 MS_PROTO_CONN_MAX_OPEN_MODELS, "too many open models");
        return;
    }
    do
        ++c->next_handle;
    while (!c->next_handle || find_handle(c, c->next_handle));
    slot->handle = c->next_handle;
    slot->model = m;
    ms_model_ref(m);
    m->requests++;
    note_model_name(c, m->entry.name);
    ms_proto_message msg = {.type = MS_PROTO_MODEL_OPENED, .request_id = id};
    ms_proto_model_opened *mo = &msg.body.model_opened;
    size_t index_size;
    const uint8_t *index = ms_archive_index_bytes(m->archive, &index_size);
    /* What INDEX_DATA carries: the blob, or its zlib stream (a fifth of it), or
     * (version 3) the head only, whose size does not grow with the model. */
    const uint8_t *wire = index;
    size_t wire_size = index_size;
    mo->index_size = (uint32_t)index_size;
    mo->index_crc32 = m->index_crc32;
    mo->archive_version = MS_ARCHIVE_BLOB_VERSION; /* the blob's own version, not the file's */
    if ((c->capabilities & MS_PROTO_CAP_INDEX_SUBTREES) && m->index_head) {
        wire = m->index_head;
        wire_size = m->index_head_size;
        mo->index_size = (uint32_t)m->index_head_size;
        mo->index_crc32 = m->index_head_crc32;
        mo->archive_version = MS_ARCHIVE_VERSION; /* the head's header */
        mo->index_encoding = MS_PROTO_INDEX_SUBTREES;
    } else if ((c->capabilities & MS_PROTO_CAP_INDEX_ZLIB) && m->index_zlib) {
        wire = m->index_zlib;
        wire_size = m->index_zlib_size;
        mo->index_encoding = MS_PROTO_INDEX_ZLIB;
    }
    mo->model_handle = slot->handle;
    mo->cell_count = ms_archive_get_header(m->archive)->cell_count;
    mo->content_id = m->content_id;
    model_steps(c, m, &mo->geometry_steps, &mo->apo_steps, &mo->permitted_geometry_steps,
                &mo->permitted_apo_steps);
    slot->grant = ms_access_grant(m, c->token_accepted);
    ms_serve_conn_send_message(c, &msg);
    uint32_t chunk = c->client_max_frame - MS_PROTO_INDEX_DATA_FIXED;
    if (chunk > INDEX_CHUNK_BYTES)
        chunk = INDEX_CHUNK_BYTES;
    for (uint32_t offset = 0; offset < wire_size && c->state != MS_CONN_CLOSING;) {
        uint32_t n = (uint32_t)wire_size - offset < chunk ? (uint32_t)wire_size - offset : chunk;
        ms_error err;
        if (ms_frame_out_index_data(output(c), id, offset, offset + n == wire_size, wire + offset,
                                    n, m, &metrics_of(c)->transfers_in_flight, &err) != MS_OK)
            ms_serve_conn_broken(c);
        offset += n;
    }
}

/* Which queued requests a CANCEL range or a CLOSE_MODEL names. */
typedef struct request_match {
    uint32_t handle;       /* 0: match by ids */
    uint32_t first, count; /* ids first .. first + count - 1 */
} request_match;

static bool matches(const ms_cell_request *r, const request_match *m)
{
    return m->handle ? r->handle == m->handle : r->id >= m->first && r->id - m->first < m->count;
}

/* Drops every queued request that matches, each ended with ERROR CANCELLED
 * when announce. The matches are collected before any removal, because a
 * removal reorders the heap. */
static void drop_matching(ms_serve_conn *c, const request_match *m, bool announce)
{
    ms_cell_request **doomed = c->queue.count ? malloc(c->queue.count * sizeof *doomed) : NULL;
    if (!doomed) { /* empty queue, or out of memory: rescan after each removal */
        for (size_t i = 0; i < c->queue.count;) {
            if (matches(c->queue.heap[i], m)) {
                drop_request(c, c->queue.heap[i], announce);
                i = 0;
            } else {
                ++i;
            }
        }
        return;
    }
    size_t n = 0;
    for (size_t i = 0; i < c->queue.count; ++i)
        if (matches(c->queue.heap[i], m))
            doomed[n++] = c->queue.heap[i];
    for (size_t i = 0; i < n; ++i)
        drop_request(c, doomed[i], announce);
    free(doomed);
}

static void cancel_matching(ms_serve_conn *c, const request_match *m) { drop_matching(c, m, true); }

void ms_serve_conn_models_changed(ms_serve_conn *c, const ms_registry *registry)
{
    if (c->state != MS_CONN_READY)
        return;
    for (unsigned i = 0; i < MS_PROTO_CONN_MAX_OPEN_MODELS && c->state == MS_CONN_READY; ++i) {
        ms_open_model *slot = &c->models[i];
        if (!slot->handle)
            continue;
        const ms_model *current = ms_registry_peek(registry, slot->model->entry.name);
        if (current && current->content_id == slot->model->content_id)
            continue; /* unchanged, even if its file was rewritten */
        char text[128];
        snprintf(text, sizeof text, "model '%s' %s on the server; reopen it",
                 slot->model->entry.name, current ? "changed" : "was removed");
        uint32_t handle = slot->handle;
        request_match m = {handle, 0, 0};
        drop_matching(c, &m, false);
        ms_model_unref(slot->model);
        memset(slot, 0, sizeof *slot);
        ms_serve_conn_send_error(c, MS_PROTO_E_MODEL_CHANGED, 0, 0, handle, text);
    }
    if (c->door->draining && !c->queue.count)
        ms_serve_conn_fail(c, MS_PROTO_E_SHUTTING_DOWN, 0, "server shutting down");
}

static void handle_close_model(ms_serve_conn *c, uint32_t handle)
{
    ms_open_model *slot = find_handle(c, handle);
    if (!slot) {
        ms_serve_conn_send_error(c, MS_PROTO_E_UNKNOWN_MODEL, 0, 0, handle,
                                 "no open model with this handle");
        return;
    }
    request_match m = {handle, 0, 0};
    cancel_matching(c, &m);
    ms_model_unref(slot->model);
    memset(slot, 0, sizeof *slot);
}

static void handle_cancel(ms_serve_conn *c, const ms_proto_cancel *k)
{
    if (k->flags & MS_PROTO_CANCEL_ALL) {
        while (c->queue.count)
            cancel_request(c, c->queue.heap[c->queue.count - 1]);
        return;
    }
    for (uint16_t i = 0; i < k->range_count; ++i) {
        uint32_t first = k->ranges[i].first_id, count = k->ranges[i].count;
        if (count > c->queue.count) { /* a wide range: scan the queue */
            request_match m = {0, first, count};
            cancel_matching(c, &m);
            continue;
        }
        for (uint32_t j = 0; j < count; ++j) { /* a narrow one: look each id up */
            ms_cell_request *r = ms_request_queue_find(&c->queue, first + j);
            if (r)
                cancel_request(c, r);
        }
    }
}

/* One entry of a batch resolved to a byte range, or to the error ending it. */
typedef struct resolved {
    uint16_t code; /* 0 = fine */
    uint64_t detail;
    uint32_t start, end;
} resolved;

/* What may be sent (ms_access_resolve), and only from an intact payload. */
static resolved resolve_entry(const ms_serve_conn *c, const ms_open_model *slot,
                              const ms_proto_cell_request *e)
{
    ms_proto_byte_range range;
    ms_proto_fault fault = {.code = MS_PROTO_E_INTERNAL};
    if (ms_access_resolve(slot->model, &slot->grant, e, &range, &fault, NULL) != MS_OK)
        return (resolved){fault.code, fault.detail, 0, 0};
    /* Subtrees were validated (CRC, structure) when the archive was opened. */
    if (range.begin < range.end && e->stream != MS_PROTO_STREAM_INDEX &&
        !ms_server_payload_intact(server_of(c), slot->model, e->cell_id, e->stream))
        return (resolved){MS_PROTO_E_INTERNAL, 0, 0, 0};
    return (resolved){0, 0, range.begin, range.end};
}

static const char *entry_error_text(uint16_t code)
{
    switch (code) {
    case MS_PROTO_E_UNKNOWN_CELL: return "no such cell (or, on the index stream, subtree)";
    case MS_PROTO_E_RANGE_NOT_SATISFIABLE: return "byte range outside the stream";
    case MS_PROTO_E_FORBIDDEN: return "beyond the public preview; a token is required";
    case MS_PROTO_E_INTERNAL: return "the archive's copy of this payload is damaged";
    default: return "request failed";
    }
}

static void handle_request_cells(ms_serve_conn *c, const ms_proto_message *msg)
{
    const uint32_t first_id = msg->request_id;
    const ms_proto_request_cells *b = &msg->body.request_cells;
    const ms_proto_hello_reply *limits = &c->door->limits;
    uint32_t n = b->count;
    metrics_of(c)->binary_requests += n;
    c->requests += n;
    ms_open_model *slot = find_handle(c, b->model_handle);
    if (slot)
        slot->model->requests += n;
    if (!slot) {
        ms_serve_conn_send_error(c, MS_PROTO_E_UNKNOWN_MODEL, first_id, n, b->model_handle,
                                 "no open model with this handle");
        return;
    }
    /* APO without CAP_APO, subtrees without CAP_INDEX_SUBTREES: the whole batch. */
    ms_proto_fault fault;
    ms_error err;
    if (ms_proto_check_negotiated(msg, c->version, c->capabilities, &fault, &err) != MS_OK) {
        ms_serve_conn_send_error(c, fault.code, first_id, n, fault.detail, err.text);
        return;
    }
    if (!ids_free(c, first_id, n))
        return;
    if (c->queue.count + n > limits->max_outstanding) {
        ms_serve_conn_send_error(c, MS_PROTO_E_TOO_MANY_OUTSTANDING, first_id, n,
                                 limits->max_outstanding, "too many outstanding requests");
        return;
    }
    resolved *ranges = malloc(n * sizeof *ranges);
    if (!ranges) {
        ms_serve_conn_send_error(c, MS_PROTO_E_INTERNAL, first_id, n, 0, "out of memory");
        return;
    }
    uint64_t bytes = 0;
    for (uint32_t i = 0; i < n; ++i) {
        ranges[i] = resolve_entry(c, slot, &b->entries[i]);
        if (!ranges[i].code)
            bytes += ranges[i].end - ranges[i].start;
    }
    if (c->queue.queued_bytes + bytes > limits->max_queued_bytes) {
        ms_serve_conn_send_error(c, MS_PROTO_E_QUEUE_FULL, first_id, n, limits->max_queued_bytes,
                                 "too many payload bytes queued");
    } else if (rate_allows(c, first_id, n)) {
        if (ms_request_queue_reserve(&c->queue, n, &err) != MS_OK) {
            ms_serve_conn_send_error(c, MS_PROTO_E_INTERNAL, first_id, n, 0, "out of memory");
        } else {
            bool queued = false;
            for (uint32_t i = 0; i < n && c->state != MS_CONN_CLOSING; ++i) {
                const ms_proto_cell_request *e = &b->entries[i];
                const resolved *r = &ranges[i];
                ms_cell_request *q = r->code || r->start == r->end ? NULL : malloc(sizeof *q);
                if (r->code) {
                    ms_serve_conn_send_error(c, r->code, first_id + i, 1, r->detail,
                                             entry_error_text(r->code));
                } else if (r->start == r->end) {
                    if (ms_frame_out_payload(output(c), first_id + i, e->cell_id, e->stream,
                                             r->start, r->end, true, NULL, 0, slot->model,
                                             &metrics_of(c)->transfers_in_flight, &err) != MS_OK)
                        ms_serve_conn_broken(c);
                } else if (!q) {
                    ms_serve_conn_send_error(c, MS_PROTO_E_INTERNAL, first_id + i, 1, 0,
                                             "out of memory");
                } else {
                    memset(q, 0, sizeof *q);
                    q->id = first_id + i;
                    q->priority = e->priority;
                    q->stream = e->stream;
                    q->handle = slot->handle;
                    q->model = slot->model;
                    q->cell = e->cell_id;
                    q->next = r->start;
                    q->end = r->end;
                    ms_request_queue_push(&c->queue, q);
                    metrics_of(c)->queued_requests++;
                    metrics_of(c)->queued_bytes += r->end - r->start;
                    queued = true;
                }
            }
            if (queued && c->state == MS_CONN_READY)
                ms_fair_scheduler_wake(&c->door->scheduler, &c->link);
        }
    }
    free(ranges);
}

void ms_serve_conn_handle_message(ms_serve_conn *c, const ms_proto_message *msg)
{
    switch ((ms_proto_type)msg->type) {
    case MS_PROTO_HELLO: handle_hello(c, &msg->body.hello); break;
    case MS_PROTO_LIST_CATALOGUE: handle_list_catalogue(c, msg->request_id); break;
    case MS_PROTO_LIST_PAGE: handle_list_page(c, msg->request_id, &msg->body.list_page); break;
    case MS_PROTO_GET_DOCUMENT: handle_get_document(c, msg); break;
    case MS_PROTO_OPEN_MODEL: handle_open_model(c, msg->request_id, &msg->body.open_model); break;
    case MS_PROTO_CLOSE_MODEL: handle_close_model(c, msg->body.close_model.model_handle); break;
    case MS_PROTO_REQUEST_CELLS:
        handle_request_cells(c, msg);
        break;
    case MS_PROTO_CANCEL: handle_cancel(c, &msg->body.cancel); break;
    case MS_PROTO_PING: {
        ms_proto_message pong = {.type = MS_PROTO_PONG};
        pong.body.ping = msg->body.ping;
        ms_serve_conn_send_message(c, &pong);
        break;
    }
    case MS_PROTO_PONG: break;
    case MS_PROTO_ERROR:
        if (msg->body.error.fatal) {
            ms_server_log_client(server_of(c), "binary: client reported %s: %.*s",
                                 ms_proto_error_name(msg->body.error.code),
                                 (int)msg->body.error.text_length, msg->body.error.text);
            ms_serve_conn_start_closing(c);
        }
        break;
    default: /* the decoder lets no other type through */ break;
    }
}
