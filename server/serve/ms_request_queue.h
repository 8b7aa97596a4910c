/* One connection's outstanding cell requests: a priority queue (lowest
 * priority value first, ties in arrival order) that also finds a request by its
 * id, so that CANCEL, CLOSE_MODEL and the duplicate-id rule cost O(log n) per
 * request, never a scan of the id space.
 *
 * Ownership: the queue owns the requests pushed into it until they are
 * removed; ms_request_queue_free frees those still inside. Requests borrow their
 * model from the connection's open-model table. Thread-safety: one thread.
 */
#ifndef MS_REQUEST_QUEUE_H
#define MS_REQUEST_QUEUE_H

#include <stddef.h>
#include <stdint.h>

#include "ms_error.h"

struct ms_model;

typedef struct ms_cell_request {
    uint32_t id;             /* the client's request id, non-zero */
    uint8_t priority;        /* lower is sooner */
    uint8_t stream;          /* ms_proto_stream */
    uint32_t handle;         /* model handle the request names */
    struct ms_model *model;  /* borrowed: the handle's model */
    uint32_t cell;
    uint32_t next;           /* stream offset of the next byte to send */
    uint32_t end;            /* stream offset where the range ends */
    uint64_t seq;            /* arrival order, set by push */
    size_t heap_pos;         /* private */
    struct ms_cell_request *hash_next; /* private */
} ms_cell_request;

typedef struct ms_request_queue {
    ms_cell_request **heap;
    size_t count, capacity;
    ms_cell_request **buckets; /* id hash, chained */
    size_t bucket_count;       /* power of two, >= capacity */
    uint64_t next_seq;
    uint64_t queued_bytes;     /* sum of (end - next) over the queue */
} ms_request_queue;

void ms_request_queue_init(ms_request_queue *queue);
/* Frees every request still queued and the queue's arrays. */
void ms_request_queue_free(ms_request_queue *queue);

/* Makes room for `extra` more requests, so that the pushes of a batch that
 * passed its checks cannot fail halfway. MS_ERR_NOMEM on failure. */
ms_status ms_request_queue_reserve(ms_request_queue *queue, size_t extra, ms_error *err);

/* Adds r (room must have been reserved; r->id must not be queued). */
void ms_request_queue_push(ms_request_queue *queue, ms_cell_request *r);

/* The queued request with id, or NULL. */
ms_cell_request *ms_request_queue_find(const ms_request_queue *queue, uint32_t id);

/* The request to serve next, or NULL when empty. */
ms_cell_request *ms_request_queue_top(const ms_request_queue *queue);

/* Takes r out of the queue (the caller then owns it). */
void ms_request_queue_remove(ms_request_queue *queue, ms_cell_request *r);

/* Records that `bytes` of r were sent: advances r->next and queued_bytes. */
void ms_request_queue_sent(ms_request_queue *queue, ms_cell_request *r, uint32_t bytes);

#endif
