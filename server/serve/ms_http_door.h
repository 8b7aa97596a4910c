/* The HTTP side door of meshserve (libevent evhttp): the same catalogue, model
 * indexes and cell payloads as the binary protocol, for browsers, curl and
 * caching proxies. Routes (GET and HEAD only):
 *
 *   /healthz                              "ok"
 *   /catalog, /catalog.json               JSON list of the models
 *   /models/NAME                          the model's header and cell index (binary)
 *   /models/NAME/head                     the index head: version-3 header + root subtree
 *   /models/NAME/subtrees/ID              subtree ID of the index, its stored zlib bytes
 *   /models/NAME/cells/ID/geometry[?bits=B]   geometry prefix complete at B bits
 *   /models/NAME/cells/ID/apo[?levels=L]      APO chunk prefix of L levels
 *   /metrics                              Prometheus text format
 *
 * Payloads, the head and subtrees honour a single `Range: bytes=...` (206 /
 * 416; several ranges are 416), carry an ETag (the head's and subtrees' from the model's content id) and are
 * sent from the archive mapping without copying. Access (ms_access.h decides):
 * above a model's public precision a client must present the operator's token
 * in `Authorization: Bearer TOKEN` (the scheme in any case), else 403; a
 * `token` query parameter is
 * refused (400: URLs end up in logs). Answers whose body the token widened are
 * `Cache-Control: private`, the others `public`, all with `Vary: Authorization`.
 * Requests per client address are rate-limited (429). At most
 * http_max_connections connections: at the cap a newcomer takes the slot of
 * the one that has waited longest for a request header (docs/SECURITY.md,
 * section 4). Thread-safety: runs on the server loop.
 */
#ifndef MS_HTTP_DOOR_H
#define MS_HTTP_DOOR_H

#include <stdint.h>

#include "ms_error.h"

struct ms_server;
struct ms_catalog_entry;
struct json_t;
typedef struct ms_http_door ms_http_door;

/* The Content-Type of a browser page file by its name (ms_http_pages.c):
 * [A-Za-z0-9_-]+ then .html, .js, .css or .wasm; NULL for any other name. */
const char *ms_http_page_type(const char *name);

/* One model as GET /catalog lists it (a new JSON object, or NULL when out of
 * memory): name, vertices, triangles, cells, bits, public_max_bits, apo,
 * archive_bytes, baked_at. */
struct json_t *ms_http_catalog_entry(const struct ms_catalog_entry *entry);

ms_status ms_http_door_open(struct ms_server *server, ms_http_door **door, uint16_t *bound_port,
                            ms_error *err);
void ms_http_door_close(ms_http_door *door);

#endif
