/* Loopback helpers for tests of the servers: start a program in the
 * background, read the ports it wrote, and talk raw HTTP/1.1 to it. Every call
 * is bounded in time (a few seconds). */
#ifndef MS_TEST_NET_H
#define MS_TEST_NET_H

#include <stddef.h>
#include <stdint.h>
#include <sys/types.h>

typedef struct ms_test_http_response {
    int status;
    char headers[8192];  /* raw header block, NUL-terminated */
    uint8_t *body;       /* malloc'd, NUL-terminated past body_length */
    size_t body_length;
} ms_test_http_response;

/* Sends `request` verbatim to 127.0.0.1:port and reads the whole response (the
 * request should say `Connection: close`). Returns 0, or -1 on a socket error or
 * time-out. */
int ms_test_http_raw(uint16_t port, const char *request, size_t request_length,
                     ms_test_http_response *response);

/* GET path with optional extra header lines ("Name: value\r\n..."). */
int ms_test_http_get(uint16_t port, const char *path, const char *extra_headers,
                     ms_test_http_response *response);

void ms_test_http_free(ms_test_http_response *response);

/* The value of one series of a server's GET /metrics (Prometheus text, e.g.
 * "meshstream_connections_total" or a name with its labels) into *value: 0,
 * or -1 when the server did not answer 200 or has no such line. */
int ms_test_metric(uint16_t http_port, const char *series, uint64_t *value);

/* The value of a response header (case-insensitive name), copied into out. */
const char *ms_test_http_header(const ms_test_http_response *response, const char *name,
                                char *out, size_t size);

/* Whether one of the answer's Vary lines is exactly field (a server may send
 * several Vary lines; each names one field here). */
int ms_test_http_varies_on(const ms_test_http_response *r, const char *field);

/* Starts argv[0] with argv, stdout and stderr to log_path; returns the pid. */
pid_t ms_test_spawn(char *const argv[], const char *log_path);

/* Waits up to `seconds` for port_file to hold "PORT HTTP_PORT". 0 on success. */
int ms_test_wait_ports(const char *port_file, double seconds, uint16_t *port, uint16_t *http_port);

/* Starts meshserve on the archive folder on loopback, on listen_port (0: one
 * the system chooses) and an HTTP port the system chooses, both written to
 * port_file, stdout and stderr to log_path, with `extra`
 * arguments (NULL-terminated, may be NULL; at most 8) before the port options;
 * waits up to 15 s for the ports. Returns the pid, or 0 (the process killed, a
 * line on stderr) when it did not start. */
pid_t ms_test_meshserve_start(const char *archives, const char *const *extra,
                              uint16_t listen_port, const char *port_file, const char *log_path, uint16_t *port,
                              uint16_t *http_port);

/* Sends sig and waits up to `seconds` for the process to exit; returns its exit
 * status, or -1 if it had to be killed or died from a signal. */
int ms_test_stop(pid_t pid, int sig, double seconds);

#endif
