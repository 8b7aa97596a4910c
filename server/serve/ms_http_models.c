/* The side door's answers under /models/NAME (ms_http_internal.h): the index
 * blob, the index head and its subtrees (protocol version 3's index in
 * subtrees, PROTOCOL.md section 11), a cell's geometry or APO stream, and the
 * Draco file. Every byte range is decided by ms_access_resolve (or, for the
 * whole Draco model, ms_access_is_full): docs/SECURITY.md, section 2. Bodies
 * are sent from the archive's memory without copying. */
#include <errno.h>
#include <event2/buffer.h>
#include <event2/http.h>
#include <event2/keyvalq_struct.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ms_access.h"
#include "ms_http_internal.h"
#include "ms_http_parse.h"
#include "ms_server_internal.h"
#include "ms_subtree.h"

/* A payload reference handed to libevent: keeps the model mapped until sent. */
typedef struct transfer {
    ms_model *model;
    ms_server *server;
} transfer;

static void release_transfer(const void *data, size_t length, void *extra)
{
    (void)data, (void)length;
    transfer *t = extra;
    t->server->metrics.transfers_in_flight--;
    ms_model_unref(t->model);
    free(t);
}

/* Appends bytes [data, data + count) of the model's mapping to body by
 * reference, the model kept mapped until they are sent; false when out of
 * memory (nothing appended). */
static bool add_payload(ms_http_door *door, ms_model *model, struct evbuffer *body, const uint8_t *data,
                        size_t count)
{
    transfer *t = malloc(sizeof *t);
    if (!t)
        return false;
    t->model = model, t->server = ms_http_door_server(door);
    ms_model_ref(model);
    ms_http_door_server(door)->metrics.transfers_in_flight++;
    if (evbuffer_add_reference(body, data, count, release_transfer, t) != 0) {
        release_transfer(NULL, 0, t);
        return false;
    }
    return true;
}

/* Sends bytes [0, length) of data (inside model's mapping, or owned by the
 * model) honouring Range. private_answer: the body depends on the reader's
 * token, so only the reader's own cache may keep it; every answer varies with
 * Authorization. coding: NULL where the body has one form; else the form
 * chosen by Accept-Encoding ("identity", or the Content-Encoding sent), and
 * the answer varies with it too (ranges are of the encoded bytes). */
static void send_bytes(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                       const uint8_t *data, uint64_t length, const char *etag, bool private_answer,
                       const char *coding)
{
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    struct evkeyvalq *in = evhttp_request_get_input_headers(req);
    model->requests++;
    evhttp_add_header(out, "Content-Type", "application/octet-stream");
    evhttp_add_header(out, "Accept-Ranges", "bytes");
    evhttp_add_header(out, "ETag", etag);
    evhttp_add_header(out, "Cache-Control",
                      private_answer ? "private, max-age=3600" : "public, max-age=3600");
    evhttp_add_header(out, "Vary", "Authorization");
    if (coding) /* a line of its own: a Vary line names one field (as CORS adds Origin) */
        evhttp_add_header(out, "Vary", "Accept-Encoding");
    if (coding && strcmp(coding, "identity") != 0)
        evhttp_add_header(out, "Content-Encoding", coding);
    if (ms_http_none_match(evhttp_find_header(in, "If-None-Match"), etag)) {
        ms_http_reply(door, req, 304, "Not Modified", NULL, 0);
        return;
    }
    uint64_t first = 0, last = length ? length - 1 : 0;
    int code = 200;
    switch (ms_http_parse_range(evhttp_find_header(in, "Range"), length, &first, &last)) {
    case MS_HTTP_RANGE_NONE: break;
    case MS_HTTP_RANGE_UNSATISFIABLE: {
        char cr[64];
        snprintf(cr, sizeof cr, "bytes */%" PRIu64, length);
        evhttp_add_header(out, "Content-Range", cr);
        ms_http_send_text(door, req, 416, "Range Not Satisfiable", "error: range not satisfiable");
        return;
    }
    case MS_HTTP_RANGE_OK: {
        char cr[96];
        snprintf(cr, sizeof cr, "bytes %" PRIu64 "-%" PRIu64 "/%" PRIu64, first, last, length);
        evhttp_add_header(out, "Content-Range", cr);
        code = 206;
        break;
    }
    }
    uint64_t count = length ? last - first + 1 : 0;
    if (ms_http_is_head(req)) {
        ms_http_reply(door, req, code, code == 206 ? "Partial Content" : "OK", NULL, count);
        return;
    }
    struct evbuffer *body = evbuffer_new();
    if (!body) {
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: out of memory");
        return;
    }
    if (count && !add_payload(door, model, body, data + first, (size_t)count)) {
        evbuffer_free(body);
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: out of memory");
        return;
    }
    ms_http_door_server(door)->metrics.http_bytes_sent += count;
    model->bytes_sent += count;
    ms_http_reply(door, req, code, code == 206 ? "Partial Content" : "OK", body, count);
    evbuffer_free(body);
}

/* The index blob; deflated (zlib, RFC 1950: HTTP's "deflate") when the
 * reader accepts it: the form the binary door sends with CAP_INDEX_ZLIB,
 * made once at the model's opening. The dragon's 143,580 bytes travel as
 * about 27 kB, a browser's first round trips' largest part. */
static void serve_index(ms_http_door *door, struct evhttp_request *req, ms_model *model)
{
    size_t size;
    const uint8_t *index = ms_archive_index_bytes(model->archive, &size);
    bool deflated = model->index_zlib &&
                    ms_http_accepts_coding(evhttp_find_header(evhttp_request_get_input_headers(req),
                                                              "Accept-Encoding"),
                                           "deflate");
    char etag[128];
    snprintf(etag, sizeof etag, "\"%" PRIx64 "-%" PRIx64 "-index%s\"", model->file_inode,
             (uint64_t)model->file_mtime_ns, deflated ? "-deflate" : "");
    if (deflated)
        send_bytes(door, req, model, model->index_zlib, model->index_zlib_size, etag, false,
                   "deflate");
    else
        send_bytes(door, req, model, index, size, etag, false, "identity");
}

/* The bytes from 0 of a cell's stream at *step (clamped to the protocol's
 * top) that `grant` may read, as ms_access_resolve decides for the binary
 * door, and whether the archive's copy is intact. Returns the HTTP status,
 * with *why the line of a refusal (403, 500). */
static int resolve_steps(ms_http_door *door, ms_model *model, const ms_access *grant, uint32_t cell,
                         uint8_t stream, uint32_t *step, ms_proto_byte_range *range, const char **why)
{
    ms_proto_cell_request entry = {cell, stream, MS_PROTO_UNIT_STEPS, 0, 0, 0};
    entry.b = *step > MS_PROTO_MAX_STEP ? MS_PROTO_MAX_STEP : *step;
    *step = entry.b;
    ms_proto_fault fault = {.code = MS_PROTO_E_INTERNAL};
    if (ms_access_resolve(model, grant, &entry, range, &fault, NULL) != MS_OK) {
        *why = fault.code == MS_PROTO_E_FORBIDDEN ? "error: precision beyond the public preview needs a token"
                                                  : "error: the cell's index is inconsistent";
        return fault.code == MS_PROTO_E_FORBIDDEN ? 403 : 500;
    }
    if (range->end > 0 && !ms_server_payload_intact(ms_http_door_server(door), model, cell, stream)) {
        *why = "error: the archive's copy of this payload is damaged";
        return 500;
    }
    return 200;
}

/* What a reader with `grant` may read of a cell's geometry or colour stream
 * (stream) at `bits` (NULL: all the grant allows): *range its bytes from 0,
 * *step the precision granted (clamped to the cell's). Returns the HTTP
 * status, with *why the line of a refusal: 404 (no such cell), 403 (beyond
 * the public preview), 500 (an inconsistent index, a damaged payload). The one
 * permission check of a cell's bits for the side door's routes, as
 * ms_access_resolve is the binary door's. */
static int stream_range(ms_http_door *door, ms_model *model, const ms_access *grant, uint32_t cell,
                        uint8_t stream, const uint32_t *bits, ms_proto_byte_range *range, uint32_t *step,
                        const char **why)
{
    const ms_archive_cell *c = ms_archive_get_cell(model->archive, cell);
    if (!c) {
        *why = "error: no such cell";
        return 404;
    }
    if (ms_access_cell_hidden(model, grant, cell)) {
        *why = "error: this cell is beyond the public preview; a token is required";
        return 403;
    }
    uint32_t b = c->bits_max;
    if (bits)
        b = *bits;
    else if (grant->permitted_geometry_steps - 1u < b)
        b = grant->permitted_geometry_steps - 1u; /* by default, all the grant allows */
    *step = b < c->bits_max ? b : c->bits_max;
    return resolve_steps(door, model, grant, cell, stream, step, range, why);
}

/* A cell's geometry or colour stream (?bits=B: the prefix complete at B bits;
 * bits above the cell's own top mean all of it) or APO (?levels=L: the first L levels; by
 * default as many as the grant reads of it). The
 * URL is turned into a request entry and ms_access_resolve decides, as for the
 * binary door: the preview check runs on the clamped precision. */
static void serve_cell(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                       const char *cell_text, const char *kind, const struct evkeyvalq *query)
{
    uint32_t cell;
    const ms_archive_cell *c = NULL;
    if (ms_http_parse_u32(cell_text, UINT32_MAX, &cell))
        c = ms_archive_get_cell(model->archive, cell);
    if (!c) {
        ms_http_send_text(door, req, 404, "Not Found", "error: no such cell");
        return;
    }
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    if (ms_access_cell_hidden(model, &grant, cell)) {
        ms_http_send_text(door, req, 403, "Forbidden", "error: this cell is beyond the public preview; a token is required");
        return;
    }
    bool colour = !strcmp(kind, "colour");
    bool geometry = colour || !strcmp(kind, "geometry"); /* colour steps are bits too */
    uint8_t stream = colour     ? MS_PROTO_STREAM_COLOUR
                     : geometry ? MS_PROTO_STREAM_GEOMETRY
                                : MS_PROTO_STREAM_APO;
    ms_proto_byte_range range = {0, 0};
    uint32_t step = 0;
    bool empty = false;
    if (geometry) {
        uint32_t bits;
        const char *bits_text = evhttp_find_header(query, "bits");
        if (bits_text && !ms_http_parse_u32(bits_text, 64, &bits)) {
            ms_http_send_text(door, req, 400, "Bad Request", "error: bits must be an integer in 0..64");
            return;
        }
        const char *why = NULL;
        int status = stream_range(door, model, &grant, cell, stream, bits_text ? &bits : NULL, &range, &step, &why);
        if (status != 200) {
            ms_http_send_text(door, req, status, status == 403 ? "Forbidden" : "Internal Server Error", why);
            return;
        }
    } else {
        /* by default, all the grant allows (a preview reads fewer levels) */
        uint32_t permitted = ms_access_cell_apo_steps(model, &grant, cell);
        uint32_t levels = c->apo_levels < permitted ? c->apo_levels : permitted;
        if (c->apo_levels > 0 && permitted == 0) {
            ms_http_send_text(door, req, 403, "Forbidden",
                              "error: this cell's detail normals are beyond the public preview; a token is required");
            return;
        }
        const char *levels_text = evhttp_find_header(query, "levels");
        if (levels_text && (!ms_http_parse_u32(levels_text, 64, &levels) || levels == 0)) {
            ms_http_send_text(door, req, 400, "Bad Request", "error: levels must be an integer in 1..64");
            return;
        }
        empty = levels == 0; /* a cell without APO */
        step = levels ? levels - 1 : 0;
        const char *why = NULL;
        int status = empty ? 200 : resolve_steps(door, model, &grant, cell, stream, &step, &range, &why);
        if (status != 200) {
            ms_http_send_text(door, req, status, status == 403 ? "Forbidden" : "Internal Server Error", why);
            return;
        }
    }
    size_t total;
    const uint8_t *data = colour     ? ms_archive_colour(model->archive, cell, &total)
                          : geometry ? ms_archive_geometry(model->archive, cell, &total)
                                     : ms_archive_apo(model->archive, cell, &total);
    char etag[160];
    snprintf(etag, sizeof etag, "\"%" PRIx64 "-%" PRIx64 "-%u-%c%u\"", model->file_inode,
             (uint64_t)model->file_mtime_ns, cell, colour ? 'c' : geometry ? 'g' : 'a',
             geometry ? step : (empty ? 0 : step + 1));
    /* Resolved ranges of a STEPS request from step 0 start at byte 0. */
    send_bytes(door, req, model, data, range.end, etag, token_used, NULL);
}

/* Several cells' geometry in one answer: GET /models/NAME/cells?geometry=
 * ID.BITS.FROM[,ID.BITS.FROM...] (at most MS_HTTP_BATCH_CELLS entries): for
 * each, what GET /models/NAME/cells/ID/geometry?bits=BITS would send from byte
 * FROM on (a reader holding a prefix asks for the rest), every cell through
 * stream_range's check. A page far from the server reads a level of its cut
 * in one round trip instead of one per six cells (a browser's connections).
 * Body (docs/BROWSER.md, "The cells route"), little-endian: "MSB1", u32
 * count, then per entry in the query's order u32 cell, u16 status (200; 403,
 * 404, 500 with no bytes: the single route's refusal; 416: FROM past the
 * prefix), u16 the bits granted, u32 FROM, u32 length, and length bytes. */
#define MS_HTTP_BATCH_CELLS 64u

typedef struct batch_entry {
    uint32_t cell, bits, from;
} batch_entry;

/* A batch query's list: at most `cap` comma-separated entries of `arity`
 * dot-separated integers, field k at most max[k], into out (arity words an
 * entry); false for anything else (empty, an empty entry, a stray dot). */
static bool parse_u32_tuples(const char *text, unsigned arity, const uint32_t *max, uint32_t *out, size_t cap,
                             size_t *count)
{
    *count = 0;
    if (!text || !*text)
        return false;
    for (const char *at = text;;) {
        size_t length = strcspn(at, ",");
        char item[40], *field[3];
        if (*count == cap || length == 0 || length >= sizeof item || arity > 3)
            return false;
        memcpy(item, at, length);
        item[length] = '\0';
        field[0] = item;
        for (unsigned k = 1; k < arity; ++k) {
            char *dot = strchr(field[k - 1], '.');
            if (!dot)
                return false;
            *dot = '\0';
            field[k] = dot + 1;
        }
        for (unsigned k = 0; k < arity; ++k)
            if (!ms_http_parse_u32(field[k], max[k], &out[arity * *count + k]))
                return false;
        ++*count;
        if (at[length] == '\0')
            return true;
        at += length + 1;
    }
}

/* The query's entries, or false with *why. */
static bool parse_batch(const char *text, batch_entry *out, size_t *count, const char **why)
{
    *why = "error: geometry= wants ID.BITS.FROM entries, comma-separated, at most 64";
    uint32_t words[3 * MS_HTTP_BATCH_CELLS];
    const uint32_t max[3] = {UINT32_MAX, 64, UINT32_MAX};
    if (!parse_u32_tuples(text, 3, max, words, MS_HTTP_BATCH_CELLS, count))
        return false;
    for (size_t i = 0; i < *count; ++i)
        out[i] = (batch_entry){words[3 * i], words[3 * i + 1], words[3 * i + 2]};
    return true;
}

static void put_u32(uint8_t *p, uint32_t v)
{
    for (int k = 0; k < 4; ++k)
        p[k] = (uint8_t)(v >> (8 * k));
}

/* A batch answer's body so far: its 4-byte magic and u32 count; NULL when
 * out of memory. */
static struct evbuffer *batch_body_new(const char magic[4], size_t count)
{
    struct evbuffer *body = evbuffer_new();
    uint8_t head[8];
    memcpy(head, magic, 4);
    put_u32(head + 4, (uint32_t)count);
    if (body && evbuffer_add(body, head, sizeof head) != 0) {
        evbuffer_free(body);
        body = NULL;
    }
    return body;
}

/* A batch route's answer (cells, subtrees): body as built (ok: every entry
 * went in; else 500 and body freed), `sent` its payload bytes for the
 * figures; private_answer: the token widened it. */
static void reply_batch(ms_http_door *door, struct evhttp_request *req, ms_model *model, struct evbuffer *body,
                        bool ok, uint64_t sent, bool private_answer)
{
    if (!ok) {
        if (body)
            evbuffer_free(body);
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: out of memory");
        return;
    }
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    evhttp_add_header(out, "Content-Type", "application/octet-stream");
    evhttp_add_header(out, "Cache-Control", private_answer ? "private, max-age=3600" : "public, max-age=3600");
    evhttp_add_header(out, "Vary", "Authorization");
    model->requests++;
    size_t length = evbuffer_get_length(body);
    if (!ms_http_is_head(req)) {
        ms_http_door_server(door)->metrics.http_bytes_sent += sent;
        model->bytes_sent += sent;
    }
    ms_http_reply(door, req, 200, "OK", body, length);
    evbuffer_free(body);
}

static void serve_cell_batch(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                             const struct evkeyvalq *query)
{
    batch_entry entries[MS_HTTP_BATCH_CELLS];
    size_t count;
    const char *why;
    if (!parse_batch(evhttp_find_header(query, "geometry"), entries, &count, &why)) {
        ms_http_send_text(door, req, 400, "Bad Request", why);
        return;
    }
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    struct evbuffer *body = batch_body_new("MSB1", count);
    bool ok = body != NULL;
    uint64_t sent = 0;
    for (size_t i = 0; ok && i < count; ++i) {
        ms_proto_byte_range range = {0, 0};
        uint32_t step = 0;
        int status = stream_range(door, model, &grant, entries[i].cell, MS_PROTO_STREAM_GEOMETRY, &entries[i].bits,
                                  &range, &step, &why);
        if (status == 200 && entries[i].from > range.end)
            status = 416;
        uint32_t length = status == 200 ? (uint32_t)(range.end - entries[i].from) : 0;
        uint8_t fields[16];
        put_u32(fields, entries[i].cell);
        fields[4] = (uint8_t)status, fields[5] = (uint8_t)(status >> 8);
        fields[6] = (uint8_t)step, fields[7] = (uint8_t)(step >> 8);
        put_u32(fields + 8, entries[i].from);
        put_u32(fields + 12, length);
        ok = evbuffer_add(body, fields, sizeof fields) == 0;
        if (ok && length) {
            size_t total;
            const uint8_t *data = ms_archive_geometry(model->archive, entries[i].cell, &total);
            ok = add_payload(door, model, body, data + entries[i].from, length);
            sent += length;
        }
    }
    reply_batch(door, req, model, body, ok, sent, token_used);
}

/* The index head (what MODEL_OPENED's INDEX_DATA carries with encoding
 * SUBTREES). Its root subtree is resolved through ms_access like every other
 * subtree, so the head is readable exactly when the subtrees are. */
static void serve_head(ms_http_door *door, struct evhttp_request *req, ms_model *model)
{
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    const ms_proto_cell_request root = {0, MS_PROTO_STREAM_INDEX, MS_PROTO_UNIT_STEPS, 0, 0, 0};
    ms_proto_byte_range range;
    if (ms_access_resolve(model, &grant, &root, &range, NULL, NULL) != MS_OK || !model->index_head) {
        ms_http_send_text(door, req, 500, "Internal Server Error",
                          "error: the model's index head is not available");
        return;
    }
    char etag[64];
    snprintf(etag, sizeof etag, "\"%016" PRIx64 "-head\"", model->content_id);
    send_bytes(door, req, model, model->index_head, model->index_head_size, etag, false, NULL);
}

/* Subtree id's stored bytes (*data, *length: [0, stored size), what a STEPS
 * request of the whole subtree resolves to) through ms_access_resolve, as
 * stream INDEX carries them: 200, or 404 for an id that is not a subtree id
 * of the model, 500 where it cannot be read (*why). */
static int subtree_bytes(ms_model *model, const ms_access *grant, uint32_t id, const uint8_t **data,
                         uint32_t *length, const char **why)
{
    const ms_proto_cell_request whole = {id, MS_PROTO_STREAM_INDEX, MS_PROTO_UNIT_STEPS, 0, 0, 0};
    ms_proto_byte_range range;
    ms_proto_fault fault = {.code = MS_PROTO_E_INTERNAL};
    if (ms_access_resolve(model, grant, &whole, &range, &fault, NULL) != MS_OK) {
        bool unknown = fault.code == MS_PROTO_E_UNKNOWN_CELL;
        *why = unknown ? "error: no such subtree" : "error: the subtree cannot be read";
        return unknown ? 404 : 500;
    }
    size_t size;
    *data = ms_archive_subtree(model->archive, id, &size);
    *length = (uint32_t)range.end;
    return 200;
}

/* One subtree of the index by id. The bytes do not depend on the reader's
 * token: always a public answer. */
static void serve_subtree(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                          const char *id_text)
{
    uint32_t id;
    if (!ms_http_parse_u32(id_text, UINT32_MAX, &id)) {
        ms_http_send_text(door, req, 404, "Not Found", "error: no such subtree");
        return;
    }
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    const uint8_t *stored = NULL;
    uint32_t length = 0;
    const char *why = NULL;
    int status = subtree_bytes(model, &grant, id, &stored, &length, &why);
    if (status != 200) {
        ms_http_send_text(door, req, status, status == 404 ? "Not Found" : "Internal Server Error", why);
        return;
    }
    char etag[80];
    snprintf(etag, sizeof etag, "\"%016" PRIx64 "-subtree-%" PRIu32 "\"", model->content_id, id);
    send_bytes(door, req, model, stored, length, etag, false, NULL);
}

/* Several subtrees of the index in one answer: GET /models/NAME/subtrees?ids=
 * ID[,ID...] (at most MS_HTTP_BATCH_SUBTREES), each what
 * /models/NAME/subtrees/ID sends, through the same subtree_bytes. A page
 * far from the server learns a level of the index in one round trip, where
 * one request a subtree queued behind a browser's six connections. Body
 * (docs/BROWSER.md, "The subtrees route"), little-endian: "MSS1", u32 count,
 * then per entry in the query's order u32 id, u16 status (200; 404, 500 with
 * no bytes), u16 zero, u32 length, and length bytes. Public, like a subtree. */
#define MS_HTTP_BATCH_SUBTREES 64u

static void serve_subtree_batch(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                                const struct evkeyvalq *query)
{
    uint32_t ids[MS_HTTP_BATCH_SUBTREES];
    const uint32_t max = UINT32_MAX;
    size_t count;
    if (!parse_u32_tuples(evhttp_find_header(query, "ids"), 1, &max, ids, MS_HTTP_BATCH_SUBTREES, &count)) {
        ms_http_send_text(door, req, 400, "Bad Request", "error: ids= wants subtree ids, comma-separated, at most 64");
        return;
    }
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    struct evbuffer *body = batch_body_new("MSS1", count);
    bool ok = body != NULL;
    uint64_t sent = 0;
    for (size_t i = 0; ok && i < count; ++i) {
        const uint8_t *stored = NULL;
        uint32_t length = 0;
        const char *why;
        int status = subtree_bytes(model, &grant, ids[i], &stored, &length, &why);
        uint8_t fields[12] = {0};
        put_u32(fields, ids[i]);
        fields[4] = (uint8_t)status, fields[5] = (uint8_t)(status >> 8);
        put_u32(fields + 8, status == 200 ? length : 0);
        ok = evbuffer_add(body, fields, sizeof fields) == 0 &&
             (status != 200 || add_payload(door, model, body, stored, length));
        sent += status == 200 ? length : 0;
    }
    reply_batch(door, req, model, body, ok, sent, false);
}

/* The model compressed whole with Draco (ARCHIVE_DIR/NAME.drc, written by the
 * benchmark), for meshload's baseline: the same bytes a non-streaming viewer
 * would download. Public models only; 404 when there is no such file. */
static void serve_draco(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                        const char *name)
{
    bool token_used;
    ms_access grant = ms_http_reader_grant(door, req, model, &token_used);
    if (!ms_access_is_full(&grant)) {
        ms_http_send_text(door, req, 403, "Forbidden", "error: the whole model needs a token");
        return;
    }
    char path[4096];
    snprintf(path, sizeof path, "%s/%s.drc", ms_http_door_server(door)->config.archive_dir, name);
    uint64_t length;
    struct evbuffer *body =
        ms_http_file_body(door, req, path, "error: no Draco file for this model", &length);
    if (!body)
        return;
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    evhttp_add_header(out, "Content-Type", "application/octet-stream");
    evhttp_add_header(out, "Cache-Control", token_used ? "private, max-age=3600" : "public, max-age=3600");
    evhttp_add_header(out, "Vary", "Authorization");
    if (!ms_http_is_head(req))
        ms_http_door_server(door)->metrics.http_bytes_sent += length;
    ms_http_reply(door, req, 200, "OK", body, length); /* a HEAD: freeing body closes the file */
    evbuffer_free(body);
}

struct evbuffer *ms_http_file_body(ms_http_door *door, struct evhttp_request *req,
                                   const char *path, const char *missing, uint64_t *length)
{
    int fd = open(path, O_RDONLY | O_CLOEXEC);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        if (fd >= 0)
            close(fd);
        ms_http_send_text(door, req, 404, "Not Found", missing);
        return NULL;
    }
    struct evbuffer *body = evbuffer_new();
    if (!body || (st.st_size > 0 && evbuffer_add_file(body, fd, 0, st.st_size) != 0)) {
        if (body)
            evbuffer_free(body);
        else
            close(fd);
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: cannot send the file");
        return NULL;
    }
    if (st.st_size == 0)
        close(fd);
    *length = (uint64_t)st.st_size;
    return body;
}

bool ms_http_route_model(ms_http_door *door, struct evhttp_request *req, ms_model *model,
                         char **seg, int n, const struct evkeyvalq *query)
{
    if (n == 1) {
        serve_index(door, req, model);
        return true;
    }
    if (n == 2 && !strcmp(seg[1], "draco")) {
        serve_draco(door, req, model, seg[0]);
        return true;
    }
    if (n == 2 && !strcmp(seg[1], "head")) {
        serve_head(door, req, model);
        return true;
    }
    if (n == 2 && !strcmp(seg[1], "cells")) {
        serve_cell_batch(door, req, model, query);
        return true;
    }
    if (n == 2 && !strcmp(seg[1], "subtrees")) {
        serve_subtree_batch(door, req, model, query);
        return true;
    }
    if (n == 3 && !strcmp(seg[1], "subtrees")) {
        serve_subtree(door, req, model, seg[2]);
        return true;
    }
    if (n == 4 && !strcmp(seg[1], "cells") &&
        (!strcmp(seg[3], "geometry") || !strcmp(seg[3], "apo") || !strcmp(seg[3], "colour"))) {
        serve_cell(door, req, model, seg[2], seg[3], query);
        return true;
    }
    return false;
}
