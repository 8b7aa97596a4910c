/* A server for tests that lists and then falls silent: on 127.0.0.1 it speaks
 * the binary protocol's handshake (version 3), answers LIST_CATALOGUE and
 * LIST_PAGE with one model, and never answers anything else (GET_DOCUMENT,
 * OPEN_MODEL, ...): a peer that is there and does not answer, as a stalled
 * server is. One thread; connections one after another (each until the
 * client closes it or the server stops; with hang_up, the server closes each
 * itself 100 ms after its first listing, as a server dropping idle
 * connections does). */
#ifndef MS_TEST_QUIET_H
#define MS_TEST_QUIET_H

#include <stdbool.h>
#include <stdint.h>

typedef struct ms_test_quiet ms_test_quiet;

/* Starts it, listing the model `name` (a valid model name); *port is where
 * it listens. 0, or -1 on a socket or thread failure. */
int ms_test_quiet_start(const char *name, bool hang_up, ms_test_quiet **server, uint16_t *port);
/* Stops and frees it (NULL: nothing). */
void ms_test_quiet_stop(ms_test_quiet *server);
/* The connections accepted so far. Thread-safe. */
unsigned ms_test_quiet_connections(ms_test_quiet *server);

#endif
