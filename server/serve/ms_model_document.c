/* A model's documents for both doors: see ms_model_document.h. */
#include "ms_model_document.h"

#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ms_access.h"
#include "ms_http_door.h"

static ms_status refuse(ms_document_refusal *refusal, ms_document_refusal why, ms_status st,
                        ms_error *err, const char *text)
{
    *refusal = why;
    return ms_error_set(err, st, "%s", text);
}

/* DIR/NAME.SUFFIX, a regular file of 1 .. max bytes (an empty thumbnail is
 * none; empty annotations are an empty document), read whole. */
static ms_status read_file(const char *dir, const char *name, const char *suffix, size_t max,
                           bool empty_ok, const char *absent, ms_model_document *out,
                           ms_document_refusal *refusal, ms_error *err)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/%s%s", dir, name, suffix);
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || (st.st_size == 0 && !empty_ok)) {
        if (fd >= 0)
            close(fd);
        return refuse(refusal, MS_DOCUMENT_ABSENT, MS_ERR_RANGE, err, absent);
    }
    if ((uint64_t)st.st_size > max) {
        close(fd);
        *refusal = MS_DOCUMENT_TOO_LARGE;
        return ms_error_set(err, MS_ERR_FORMAT, "the model's %s file is above %zu bytes",
                            suffix + 1, max);
    }
    size_t size = (size_t)st.st_size, have = 0;
    uint8_t *bytes = size ? malloc(size) : NULL;
    if (size && !bytes) {
        close(fd);
        return refuse(refusal, MS_DOCUMENT_FAILED, MS_ERR_NOMEM, err, "out of memory");
    }
    while (have < size) {
        ssize_t n = read(fd, bytes + have, size - have);
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            break;
        have += (size_t)n;
    }
    close(fd);
    if (have != size) { /* shrank or failed under us */
        free(bytes);
        return refuse(refusal, MS_DOCUMENT_FAILED, MS_ERR_IO, err, "the file does not read");
    }
    out->bytes = bytes;
    out->length = size;
    out->inode = (uint64_t)st.st_ino;
    out->mtime_ns = (uint64_t)st.st_mtim.tv_sec * 1000000000u + (uint64_t)st.st_mtim.tv_nsec;
    out->size = size;
    return MS_OK;
}

/* The entry as GET /catalog lists it, as compact JSON text. */
static ms_status read_metadata(const ms_catalog_entry *e, ms_model_document *out,
                               ms_document_refusal *refusal, ms_error *err)
{
    json_t *obj = ms_http_catalog_entry(e);
    char *text = obj ? json_dumps(obj, JSON_COMPACT | JSON_SORT_KEYS) : NULL;
    json_decref(obj);
    if (!text)
        return refuse(refusal, MS_DOCUMENT_FAILED, MS_ERR_NOMEM, err, "out of memory");
    size_t n = strlen(text);
    if (n > MS_PROTO_MAX_DOCUMENT) { /* the sidecar's limits keep it far below */
        free(text);
        return refuse(refusal, MS_DOCUMENT_TOO_LARGE, MS_ERR_FORMAT, err,
                      "the model's metadata is above the document limit");
    }
    out->bytes = (uint8_t *)text;
    out->length = n;
    return MS_OK;
}

ms_status ms_model_document_read_entry(const ms_catalog_entry *e, const char *dir, int kind,
                                       ms_model_document *out, ms_document_refusal *refusal,
                                       ms_error *err)
{
    memset(out, 0, sizeof *out);
    *refusal = MS_DOCUMENT_REFUSED_NONE;
    if (kind < MS_DOCUMENT_FIRST || kind > MS_DOCUMENT_LAST)
        return refuse(refusal, MS_DOCUMENT_ABSENT, MS_ERR_RANGE, err, "no such document kind");
    if (!ms_access_document(e, kind))
        return refuse(refusal, MS_DOCUMENT_ABSENT, MS_ERR_RANGE, err,
                      kind == MS_DOCUMENT_THUMBNAIL ? "no thumbnail for this model"
                                                    : "no such document for this model");
    switch (kind) {
    case MS_DOCUMENT_THUMBNAIL:
        out->content_type = "image/png";
        return read_file(dir, e->name, ".thumb.png", MS_MODEL_THUMBNAIL_MAX, false,
                         "no thumbnail for this model", out, refusal, err);
    case MS_DOCUMENT_METADATA:
        out->content_type = "application/json";
        return read_metadata(e, out, refusal, err);
    default:
        out->content_type = "application/json";
        return read_file(dir, e->name, ".annotations.json", MS_MODEL_ANNOTATIONS_MAX, true,
                         "no annotations for this model", out, refusal, err);
    }
}

ms_status ms_model_document_read(const ms_registry *r, const char *dir, const char *name,
                                 int kind, ms_model_document *out,
                                 ms_document_refusal *refusal, ms_error *err)
{
    const ms_catalog_entry *e = ms_registry_entry_named(r, name);
    if (!e) {
        memset(out, 0, sizeof *out);
        return refuse(refusal, MS_DOCUMENT_NO_MODEL, MS_ERR_RANGE, err, "no such model");
    }
    return ms_model_document_read_entry(e, dir, kind, out, refusal, err);
}

void ms_model_document_free(ms_model_document *doc)
{
    if (!doc)
        return;
    free(doc->bytes);
    doc->bytes = NULL;
    doc->length = 0;
}
