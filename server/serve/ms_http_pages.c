/* The browser pages on the side door (ms_http_internal.h; docs/BROWSER.md):
 * files of the configured web_dir, sent as they are or deflated. They hold no model
 * bytes: the page fetches those through /models/..., where every byte range
 * goes through ms_access like any other reader's. */
#include <event2/buffer.h>
#include <event2/http.h>
#include <event2/keyvalq_struct.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "ms_catalog.h"
#include "ms_http_door.h"
#include "ms_http_internal.h"
#include "ms_http_parse.h"
#include "ms_page_cache.h"
#include "ms_server_internal.h"

/* The Content-Type of a page file by its name's ending, or NULL for a name
 * that is not one: [A-Za-z0-9_-]+ then .html, .js, .css or .wasm (no path,
 * no dot file, nothing else of the folder). */
const char *ms_http_page_type(const char *name)
{
    static const struct {
        const char *ending, *type;
    } types[] = {
        {".html", "text/html; charset=utf-8"},
        {".js", "text/javascript; charset=utf-8"},
        {".css", "text/css; charset=utf-8"},
        {".wasm", "application/wasm"},
    };
    size_t stem = strspn(name, "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789_-");
    if (stem == 0 || stem > 64)
        return NULL;
    for (size_t i = 0; i < sizeof types / sizeof *types; ++i)
        if (!strcmp(name + stem, types[i].ending))
            return types[i].type;
    return NULL;
}

static void send_page(ms_http_door *door, struct evhttp_request *req, const char *name)
{
    const char *dir = ms_http_door_server(door)->config.web_dir;
    const char *type = ms_http_page_type(name);
    if (!dir) {
        ms_http_send_text(door, req, 404, "Not Found",
                          "error: the browser pages are not served here (meshserve --web-dir DIR)");
        return;
    }
    if (!type) {
        ms_http_send_text(door, req, 404, "Not Found", "error: no such page file");
        return;
    }
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    uint64_t length;
    struct evkeyvalq *out = evhttp_request_get_output_headers(req);
    struct evbuffer *body = NULL;
    if (ms_http_accepts_coding(evhttp_find_header(evhttp_request_get_input_headers(req),
                                                  "Accept-Encoding"),
                               "deflate"))
        body = ms_page_cache_deflated(ms_http_door_page_cache(door), path, &length);
    if (body)
        evhttp_add_header(out, "Content-Encoding", "deflate");
    else if (!(body = ms_http_file_body(door, req, path, "error: no such page file", &length)))
        return;
    evhttp_add_header(out, "Vary", "Accept-Encoding");
    evhttp_add_header(out, "Content-Type", type);
    evhttp_add_header(out, "Cache-Control", "no-cache");
    evhttp_add_header(out, "X-Content-Type-Options", "nosniff");
    bool html = !strcmp(type, "text/html; charset=utf-8");
    if (html)
        evhttp_add_header(out, "Content-Security-Policy",
                          "default-src 'self'; script-src 'self' 'wasm-unsafe-eval'; "
                          "style-src 'self'; img-src 'self' data:; base-uri 'none'");
    /* Cross-origin isolation (docs/BROWSER.md, "Threads"): a page opened at
     * the top loads only its own origin's files, so it may have
     * SharedArrayBuffer and the worker the threaded module. In a frame of
     * another page the opener policy is ignored and the viewer runs on one
     * thread; the embedder policy does not stop it being framed. */
    if (html)
        evhttp_add_header(out, "Cross-Origin-Opener-Policy", "same-origin");
    if (html || !strcmp(type, "text/javascript; charset=utf-8"))
        evhttp_add_header(out, "Cross-Origin-Embedder-Policy", "require-corp");
    ms_http_reply(door, req, 200, "OK", body, length); /* a HEAD: freeing body closes the file */
    evbuffer_free(body);
}

bool ms_http_route_page(ms_http_door *door, struct evhttp_request *req, char **seg, int n)
{
    if (n == 0) {
        send_page(door, req, "index.html");
        return true;
    }
    if (n == 2 && !strcmp(seg[0], "view")) {
        /* The page's paths are relative (../web/...): /view/NAME/ would put
         * them under /view/; send the browser to /view/NAME (it keeps the
         * #hash). NAME is the checked segment, so the Location is plain. */
        const struct evhttp_uri *uri = evhttp_request_get_evhttp_uri(req);
        const char *path = uri ? evhttp_uri_get_path(uri) : NULL;
        size_t length = path ? strlen(path) : 0;
        if (length && path[length - 1] == '/' && ms_model_name_valid(seg[1])) {
            char location[128];
            snprintf(location, sizeof location, "/view/%s", seg[1]);
            evhttp_add_header(evhttp_request_get_output_headers(req), "Location", location);
            ms_http_send_text(door, req, 301, "Moved Permanently", location);
            return true;
        }
        send_page(door, req, "view.html");
        return true;
    }
    if (n == 2 && !strcmp(seg[0], "web")) {
        send_page(door, req, seg[1]);
        return true;
    }
    return false;
}
