/* What the client core's parts pass each other (internal to client/core): the
 * byte source's received chunks (network or local responder -> decoder) and
 * the scheduler's wants (scheduler -> decoder -> byte source). Plain data:
 * nothing here calls anything. The queues themselves (ms_core's inbox and
 * want list, under its lock) are in ms_client_core_internal.h. */
#ifndef MS_CORE_QUEUE_H
#define MS_CORE_QUEUE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* What a range belongs to: a cell's geometry or APO payload, or (with an
 * index that comes by subtree) a subtree's stored bytes, by subtree id
 * (PROTOCOL.md: the same numbers on the wire). */
enum { STREAM_GEOMETRY = 0, STREAM_APO = 1, STREAM_INDEX = 2, STREAM_COLOUR = 3, STREAM_COUNT = 4 };

/* A received payload chunk (or a failed request: length 0, failed true),
 * passed from the network thread to the decode thread. `total`: the stored
 * size of the whole (a subtree's; 0 when not known). */
typedef struct chunk_msg {
    struct chunk_msg *next;
    uint64_t seq;
    uint32_t cell, offset, length, total;
    uint8_t stream;
    bool failed;
    uint8_t data[];
} chunk_msg;

/* A byte range the decode thread wants, best first. An INDEX want asks for
 * subtree `cell` from `start`; its end is the stored size when known, else
 * UINT32_MAX (the whole). */
typedef struct want {
    uint32_t cell, start, end;
    uint8_t stream;
    uint8_t priority;
    uint32_t decoded_growth; /* estimated decoded bytes the range adds */
} want;

typedef struct want_list {
    want *w;
    size_t n, cap;
} want_list;

#endif
