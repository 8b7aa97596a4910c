/* The HTTP door's model pictures (GET /models/NAME/thumbnail,
 * ms_http_internal.h): DIR/NAME.thumb.png as meshbake rendered it
 * (docs/ARCHIVE.md, "Thumbnails"), from the file, without opening the
 * model's archive: a catalogue page of 100 pictures opens nothing. Not
 * through ms_http_file_body: the ETag, the 304 and the size limit come from
 * the same descriptor's fstat as the bytes sent. */
#include <event2/buffer.h>
#include <event2/http.h>
#include <fcntl.h>
#include <inttypes.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>

#include "ms_http_internal.h"
#include "ms_http_parse.h"
#include "ms_server_internal.h"

/* A larger file is not a thumbnail meshbake wrote. */
#define THUMBNAIL_MAX_BYTES (256 << 10)

void ms_http_serve_thumbnail(ms_http_door *door, struct evhttp_request *req, const char *name)
{
    ms_server *server = ms_http_door_server(door);
    const ms_catalog_entry *e = ms_registry_entry_named(server->registry, name);
    if (!e) {
        ms_http_send_text(door, req, 404, "Not Found", "error: no such model");
        return;
    }
    /* the registry clamps public_max_bits to bits */
    if (!e->has_thumbnail || e->thumbnail_bits > e->public_max_bits) {
        ms_http_send_text(door, req, 404, "Not Found", "error: no thumbnail for this model");
        return;
    }
    char path[4200];
    snprintf(path, sizeof path, "%s/%s.thumb.png", server->config.archive_dir, e->name);
    int fd = open(path, O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode) || st.st_size <= 0 ||
        st.st_size > THUMBNAIL_MAX_BYTES) {
        if (fd >= 0)
            close(fd);
        ms_http_send_text(door, req, 404, "Not Found", "error: no thumbnail for this model");
        return;
    }
    char etag[96];
    snprintf(etag, sizeof etag, "\"%" PRIx64 "-%" PRIx64 "-%" PRIx64 "-thumb\"",
             (uint64_t)st.st_ino, (uint64_t)st.st_mtim.tv_sec * 1000000000u + (uint64_t)st.st_mtim.tv_nsec,
             (uint64_t)st.st_size);
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    evhttp_add_header(out, "Content-Type", "image/png");
    evhttp_add_header(out, "ETag", etag);
    /* the same picture for every reader: within the public preview */
    evhttp_add_header(out, "Cache-Control", "public, max-age=3600");
    struct evkeyvalq *in = evhttp_request_get_input_headers(req);
    if (ms_http_none_match(evhttp_find_header(in, "If-None-Match"), etag)) {
        close(fd);
        ms_http_reply(door, req, 304, "Not Modified", NULL, 0);
        return;
    }
    struct evbuffer *body = evbuffer_new();
    if (!body || evbuffer_add_file(body, fd, 0, st.st_size) != 0) {
        if (body)
            evbuffer_free(body);
        else
            close(fd);
        ms_http_send_text(door, req, 500, "Internal Server Error", "error: cannot send the file");
        return;
    }
    if (!ms_http_is_head(req))
        server->metrics.http_bytes_sent += (uint64_t)st.st_size;
    ms_http_reply(door, req, 200, "OK", body, (uint64_t)st.st_size); /* freeing body closes fd */
    evbuffer_free(body);
}
