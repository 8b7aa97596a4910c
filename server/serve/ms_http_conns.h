/* The HTTP side door's connections (ms_http_door.c hands each one over as
 * evhttp accepts it): the cap (http_max_connections: at the cap a newcomer
 * takes the slot of the connection waiting longest for a request header,
 * trickling ones first), the accepts per loop turn, the header and send
 * deadlines and the trickle priority (docs/SECURITY.md, section 4). Private to
 * server/serve/; every function runs on the server loop.
 *
 * Work per connection does not grow with the number of connections: the live
 * count is kept, the connections waiting for a header are kept in two lists
 * (trickling, and the others) in the order of their wait, and evhttp's free
 * of a connection is reported by its close callback; only the sweep (every
 * 250 ms) walks them all. A connection shed before any request of its own was
 * handled (nothing of ours is on its way to it) is freed at once, without
 * waiting for evhttp to read the end of stream.
 *
 * Parked: such a connection whose header arrives in pieces (trickling) is
 * not closed but held, unread and
 * unwatched (no event, a small receive buffer), for http_park seconds, then
 * reset; when the lot is full its oldest is reset first. A slowloris client
 * sees no end to its connection and does not reconnect, so the accepts,
 * reads and closes of its reconnections (the server's work under the attack)
 * stop; the lot costs a descriptor and a few kilobytes of kernel buffer a
 * connection. http_park 0: closed at once.
 */
#ifndef MS_HTTP_CONNS_H
#define MS_HTTP_CONNS_H

#include "ms_error.h"

struct evconnlistener;
struct ms_server_config;
struct evhttp;
struct evhttp_request;
struct ms_server;

typedef struct ms_http_conns ms_http_conns;

/* Tracks the connections evhttp accepts through listener (it becomes evhttp's
 * bufferevent callback) and starts the sweep. */
ms_status ms_http_conns_new(struct ms_server *server, struct evhttp *http,
                            struct evconnlistener *listener, ms_http_conns **out, ms_error *err);

/* A request received on req's connection: its header deadline starts over,
 * it returns to the normal priority, and Nagle's algorithm is turned off on
 * its socket (pipelined answers must not wait for a delayed ACK). */
void ms_http_conns_request(ms_http_conns *conns, struct evhttp_request *req);

/* After evhttp_free (which frees the connections): lets go of the rest, the
 * parked connections reset. */
void ms_http_conns_free(ms_http_conns *conns);

/* The most connections the door holds parked: http_park_max (0 when
 * http_park is 0); meshserve's descriptor limit makes room for them, and the
 * lot is smaller when the limit could not be raised. */
size_t ms_http_park_capacity(const struct ms_server_config *config);

#endif
