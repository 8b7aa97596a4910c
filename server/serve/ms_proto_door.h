/* The binary-protocol door of meshserve (protocol/PROTOCOL.md, versions 1 to 3): a
 * TCP listener on the server's loop, the connections it accepts (each with its
 * decoder, open models, request queue and limits: ms_proto_conn.h), the fair
 * output scheduler shared by all of them (ms_fair_scheduler.h), and a periodic
 * sweep for idle time-outs and lingering closes.
 *
 * Thread-safety: the server loop's thread only.
 */
#ifndef MS_PROTO_DOOR_H
#define MS_PROTO_DOOR_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

struct ms_server;
struct ms_registry;
typedef struct ms_serve_door ms_serve_door;

/* Listens on the server's bind address and port (0: ephemeral); *bound_port
 * receives the port actually bound. */
ms_status ms_serve_door_open(struct ms_server *server, ms_serve_door **door, uint16_t *bound_port,
                             ms_error *err);

/* Stops accepting and reading; every connection finishes the requests it has
 * queued, then gets ERROR SHUTTING_DOWN and is closed. */
void ms_serve_door_drain(ms_serve_door *door);

/* After a rescan installed registry: tells every connection holding a model
 * that was replaced or removed (ms_serve_conn_models_changed). */
void ms_serve_door_models_changed(ms_serve_door *door, const struct ms_registry *registry);

/* Connections still open (lingering closes included). */
size_t ms_serve_door_connection_count(const ms_serve_door *door);

/* Closes every connection at once (SHUTTING_DOWN best effort) and frees the
 * door. Accepts NULL. */
void ms_serve_door_close(ms_serve_door *door);

#endif
