/* A long-distance link on loopback, for tests: a TCP relay on 127.0.0.1 that
 * holds every chunk it reads for a set delay before passing it on, in each
 * direction, to and from a server on 127.0.0.1. The round trip through it
 * costs twice the delay (plus the server's time), as over a real distance;
 * bandwidth is not limited. Each accepted connection gets its own upstream
 * connection; when either side closes, the pair closes once what it sent
 * before has been passed on. Meant for a few connections carrying little
 * data (openings, indexes): writes block. */
#ifndef MS_TEST_DELAY_H
#define MS_TEST_DELAY_H

#include <stdint.h>

typedef struct ms_test_delay ms_test_delay;

/* Starts the relay to 127.0.0.1:server_port with delay_s seconds each way;
 * *port is where it listens. 0 on success, -1 on a socket or thread failure. */
int ms_test_delay_start(uint16_t server_port, double delay_s, ms_test_delay **relay,
                        uint16_t *port);
/* The same relay, bending what the server sends: wherever the 4 bytes of
 * `magic` appear within one chunk read from the server, the byte after them
 * is increased by one (a batch answer's count, docs/BROWSER.md "The cells
 * route": a page must refuse it). */
int ms_test_delay_start_mangling(uint16_t server_port, double delay_s, const char magic[4],
                                 ms_test_delay **relay, uint16_t *port);
/* Closes every connection and the relay, and frees it (NULL: nothing). */
void ms_test_delay_stop(ms_test_delay *relay);
/* The connections accepted so far. Thread-safe. */
unsigned ms_test_delay_connections(ms_test_delay *relay);

#endif
